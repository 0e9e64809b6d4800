"""Friction between two elastic bodies (ds.ContactPair): Cattaneo-Mindlin for two cylinders.

Two identical cylinders (``meshes/hertz_cylinders_2d.py`` with ``full=True``: the half discs
|x| <= R below and above the contact point, R = 8, E = 200, nu = 0.3, plane strain; the data of
dolfinx_contact's cylinder demo) with Coulomb friction mu = 0.3, the upper arc the slave side.
The lower flat is clamped; the upper flat is displaced by (0, -press), then by
(k shear / 4, -press), k = 1, ..., 4, along ``ds.solve_path``. Identical materials make
Dundurs' beta vanish: the normal and the tangential problems uncouple, and the theory is that of
one cylinder on a rigid flat with 1/R_eff = 2/R and 1/E*_eff = 2 (1 - nu^2)/E, so that
a = 2 sqrt(R_eff P / (pi E*_eff)) = sqrt(4 P R (1 - nu^2) / (pi E)) is
:func:`~dwr_signorini.cases.hertz_half_width` of the rigid flat with R and E, and
:func:`~dwr_signorini.cases.measure_cattaneo_mindlin` measures the pair with (mu, E, nu, R).

Measured on macro contact facets of 0.05 (h_facet = 0.049, a = 0.693 at P = 10.36, 22,048 fine
cells), in macro facets:

* press: a = 0.6929 (P = 10.359), a_h - a = -0.08 facets (-0.6 %), the peak lambda_n 9.561
  against Hertz's p0 = 9.518 (+0.45 %), the relative L2 error of lambda_n against Hertz's
  profile 0.042. With the slip measured in the contact frame the press leaves no tangential
  traction (``tests/test_friction_frame.py``; with the slip along each slave facet's own
  tangent it left ||lambda_t|| = 0.27 ||mu p|| and a stick zone 0.17 a off centre under shear);
* shear, Q / (mu P) = 0.25, 0.50, 0.74, 0.96: c_h within one facet of c (from Cattaneo with the
  computed P and Q).

The history goal of the path (:func:`~dwr_signorini.path.history_goal`) is written for the
relative displacement u - P u; its derivative reaches u through the master trace P u too
(:class:`~dwr_signorini.goal.GoalForms`, :func:`~dwr_signorini.dual.dual_rhs`). Checked against
central differences: L(v) against the later step re-solved from u_old + e v (v on both bodies),
and the earlier step's dual solution of L against L re-evaluated at that step re-solved with a
body force.
"""

import itertools

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import cases

from .helpers import dual_against_finite_differences
from .problems import from_model, mesh_script

COMM = MPI.COMM_WORLD
R, E, NU, MU = 8.0, 200.0, 0.3, 0.3
PRESS, SHEAR, STEPS = 0.19, 0.1, 4
MOD = mesh_script("hertz_cylinders_2d")
_CACHE: dict = {}


def cylinders(h_contact, h=1.6):
    """The two half discs (mesh, cell tags, facet tags), cached per size."""
    key = ("mesh", h_contact, h)
    if key not in _CACHE:
        _CACHE[key] = from_model(MOD.build, r_lower=R, r_upper=R, h=h, h_contact=h_contact,
                                 full=True)
    return _CACHE[key]


def pair_path(h_contact=0.05, h=1.6, tops=None, friction=None, body_force=None):
    """The press step and the shear steps on the cylinders (tops: the upper flat's moves)."""
    msh, cells, facets = cylinders(h_contact, h)
    if tops is None:
        tops = [(k * SHEAR / STEPS, -PRESS) for k in range(STEPS + 1)]
    law = ds.Coulomb(MU) if friction is None else friction
    return [ds.SignoriniProblem(
        msh, facets, contact=ds.ContactPair(slave=MOD.UPPER_ARC, master=MOD.LOWER_ARC),
        dirichlet={MOD.LOWER_FLAT: (0.0, 0.0), MOD.UPPER_FLAT: top}, E=E, nu=NU,
        cell_tags=cells, friction=law, body_force=body_force,
        boundary_projection=MOD.projections(R, R)) for top in tops]


def friction_force(u, lam, m, lam_t):
    """Q, the tangential force on the slave arc."""
    return lam_t * m.ds_contact


def run_path(h_contact=0.05):
    """(measure, peak lambda_n, J_h) of every step of the path (no history estimates)."""
    key = ("path", h_contact, COMM.size)
    if key not in _CACHE:
        rows = []

        def keep(record, sol, est):
            lam = sol.lam.x.array[: sol.system.n_lam]
            peak = COMM.allreduce(float(np.max(lam, initial=0.0)), op=MPI.MAX)
            rows.append((cases.measure_cattaneo_mindlin(sol, mu=MU, E=E, nu=NU, radius=R),
                         peak, record.J_h))

        ds.solve_path(pair_path(h_contact), friction_force, callback=keep, weights="patch",
                      history=False, verbose=False).destroy()
        _CACHE[key] = rows
    return _CACHE[key]


@pytest.mark.mpi
def test_press_is_hertz_of_two_cylinders():
    """The press step: a_h within one facet of a = sqrt(4 P R (1 - nu^2) / (pi E)) (measured
    -0.08), the peak pressure within 2 % of p0 = 2 P / (pi a) (+0.45 %), lambda_n within 10 % of
    Hertz's profile (L2, 0.042), no tangential force (|Q| < 1e-3 mu P)."""
    m, peak, J_h = run_path()[0]
    assert 0.07 < m.a / R < 0.1
    assert abs(m.a_h - m.a) <= m.h_facet, (m.a_h, m.a, m.h_facet)
    assert abs(peak / m.p0 - 1.0) < 0.02, (peak, m.p0)
    assert m.l2_lam < 0.1
    assert abs(m.Q) < 1e-3 * MU * m.P
    assert J_h == pytest.approx(m.Q, rel=1e-10, abs=1e-12)


@pytest.mark.mpi
@pytest.mark.parametrize("step", [1, 2, 3, 4])
def test_stick_half_width_within_one_facet(step):
    """c_h against Cattaneo's c = a sqrt(1 - Q / (mu P)) (a from Hertz with the computed P):
    within one macro facet on every shear step, Q / (mu P) growing from 0.25 to 0.96, the stick
    zone shrinking step by step."""
    rows = run_path()
    m = rows[step][0]
    assert m.num_stick > 0 and m.num_slip > 0
    assert abs(m.c_h - m.c) <= m.h_facet, (m.c_h, m.c, m.h_facet)
    ratios = [r[0].ratio for r in rows]
    assert all(b > a for a, b in itertools.pairwise(ratios)), ratios
    assert 0.9 < ratios[-1] < 1.0
    c_h = [r[0].c_h for r in rows[1:]]
    assert all(b <= a for a, b in itertools.pairwise(c_h)), c_h


# --------------------------------------------------------------------------------------------------
# The history goal of a path with pairs
# --------------------------------------------------------------------------------------------------


def _direction(V, lower=1.0):
    """A displacement that moves the two bodies against each other (``lower`` scales the
    lower body's, the master side)."""
    v = fem.Function(V)
    v.interpolate(lambda x: np.where(
        x[1] > 0.0,
        np.vstack([1e-3 * (1.0 + 0.1 * x[0]), 1e-3 * np.cos(0.5 * x[0])]),
        lower * np.vstack([-1e-3 * np.cos(0.3 * x[0]), 2e-4 * x[0]])))
    return v


@pytest.mark.mpi
def test_history_goal_is_the_derivative_of_J_in_u_old():
    """L(v) of path.history_goal (the relative displacement v - P v) against central differences
    of the shear step's J re-solved from u_old + e v, v moving both bodies: to 1e-6; the
    master trace's share of L(v) is not small."""
    from dwr_signorini.path import history_goal

    p0, p1 = pair_path(0.1, 2.4, tops=[(0.0, -PRESS), (0.05, -PRESS)])
    disc0 = ds.discretize(p0)
    sol0 = ds.solve(disc0, rtol=1e-12)
    v = _direction(disc0.V)

    def step(shift):
        disc = disc0.for_problem(p1)
        u_old = fem.Function(disc0.V)
        u_old.x.array[:] = sol0.u.x.array + shift * v.x.array
        disc.set_u_old(u_old)
        return ds.solve(disc, rtol=1e-12)

    eps = 1e-3
    with step(0.0) as sol1, ds.estimate(sol1, friction_force, estimator="eta_p") as est1:
        assert sol1.num_stick > 0 and sol1.num_slip > 0
        L = history_goal(sol1, est1)
        m = sol1.disc.m

        def value(form):
            return COMM.allreduce(fem.assemble_scalar(sol1.disc.form(form)), op=MPI.SUM)

        predicted = value(L(v, sol1.lam, m, sol1.lam_t))
        master = value(L(_direction(disc0.V, lower=1.0), sol1.lam, m, sol1.lam_t)) - value(
            L(_direction(disc0.V, lower=0.0), sol1.lam, m, sol1.lam_t))
        values = []
        for sign in (1.0, -1.0):
            with step(sign * eps) as other:
                assert np.array_equal(other.system.active, sol1.system.active)
                with ds.estimate(other, friction_force, estimator="eta_p") as e:
                    values.append(e.J_h)
    sol0.destroy()
    fd = (values[0] - values[1]) / (2 * eps)
    assert abs(predicted) > 1e-3 * abs(est1.J_h)
    print(f"L(v) = {predicted:.10g}, fd = {fd:.10g}, master part {master:.4g}")
    assert fd == pytest.approx(predicted, rel=1e-6)
    assert abs(master) > 0.1 * abs(predicted), (master, predicted)


@pytest.mark.mpi
def test_history_goal_dual_against_finite_differences():
    """The dual solution of a history goal L (the second shear step's, at the first shear step:
    J'_u with the master trace's part P^T J'_{Pu}, dual.dual_rhs) predicts d/de L(u_h(e)) of
    the first shear step re-solved with the body force e (1, -0.5): to 1e-6 against central
    differences (measured -1.00668292e-4 against -1.006683084e-4 with the slip in the contact
    frame; 0.01463364453 against 0.01463364454 with the slip along the slave facets, where the
    dual without the master trace's part predicted -12.2). The shear is partly taken back in
    the second step, so that facets which slipped in the first stick in the second: with
    monotone loading L(u_h(e)) does not depend on e (the facets that stick at the later step
    stuck at the earlier one, where u - P u keeps its tangential part, and Coulomb's slipping
    rows carry no weight)."""
    from dwr_signorini.path import history_goal

    force = (1.0, -0.5)
    tops = [(0.0, -PRESS), (0.075, -PRESS), (0.06, -PRESS)]
    problems = pair_path(0.1, 2.4, tops=tops)
    disc0 = ds.discretize(problems[0])
    sols = [ds.solve(disc0, rtol=1e-12)]
    for p in problems[1:]:
        disc = disc0.for_problem(p)
        disc.set_u_old(sols[-1].u)
        sols.append(ds.solve(disc, rtol=1e-12))
    est2 = ds.estimate(sols[2], friction_force, estimator="eta_p")
    L = history_goal(sols[2], est2)
    loaded = {}

    def solve(e):
        if e not in loaded:
            loaded[e] = pair_path(0.1, 2.4, tops=tops[1:2],
                                  body_force=(e * force[0], e * force[1]))[0]
        disc = disc0.for_problem(loaded[e])
        disc.set_u_old(sols[0].u)
        return ds.solve(disc, rtol=1e-12)

    def same_sets(other, sol):
        assert np.array_equal(other.system.active, sol.system.active)

    predicted, fd = dual_against_finite_differences(
        solve, L, lambda v: force[0] * v[0] + force[1] * v[1], same_sets, eps=1e-4)
    for obj in (est2, *sols):
        obj.destroy()
    print(f"dual {predicted:.10g}, fd {fd:.10g}")
    assert abs(fd) > 5e-5
    assert fd == pytest.approx(predicted, rel=1e-6)
