"""A rigid obstacle under a given force with friction (:mod:`dwr_signorini.force`).

The obstacle moves by delta d, delta an unknown; with friction its motion along the contact
frame's tangents is a slip of the obstacle, so the tangential offsets are
B_l (u_old + t + (delta - delta_0) d) and the force balance is the obstacle's equilibrium
along d with the tangential tractions, sum_k int (-e_k . d) lam_k = F. Truths:

- change of control: the force-controlled frictional solution is the displacement-controlled
  one at the delta it finds (the obstacle placed there by hand, moved there from its given
  position on a path's step so that the slip sees the same motion): u, lambda_n, lambda_t to
  1e-8 relative, for a rigid disc pressed into a block with Coulomb mu = 0.3 (single solve;
  and a path: two force steps, then the block's top moved sideways with the force held);
  a flat approached obliquely (its motion drags the face) likewise;
- the balance: sum_k int (-e_k . d) lam_k = F to round-off, the tangential share not small;
- the dual's entry for delta is dJ/dF (a central difference in F);
- along a path, the history goal's rate in the earlier step's delta is dJ_k/d delta_0 (a
  central difference; -0.0457, 0 before the history goal took delta_0 in);
- the estimate's interval for int u_x on Gamma_C holds the J_h of meshes 4 and 8 times finer
  (higher-order weights; the patch weights miss it, as under displacement control: strict
  xfail).
"""

import math

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.obstacles import Cylinder, Plane, Sphere

from .helpers import global_max, integrate

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD
R = 1.0
F = 0.05
CENTRE = 0.45  # off the block's middle: an asymmetric contact
SHEAR = 0.003


def block(nx=24, ny=8):
    """The block [0, 1] x [0, 0.5]: contact at y = 0, the top clamped (or moved)."""
    msh = mesh.create_rectangle(COMM, [(0.0, 0.0), (1.0, 0.5)], [nx, ny],
                                mesh.CellType.triangle, ghost_mode=mesh.GhostMode.none)
    return msh, ex.tag_block_facets(msh, 0.5)


def problem(msh, tags, gap, top=(0.0, 0.0), law=None):
    """The block pressed by ``gap`` with ``law``, by default Coulomb's law with mu = 0.3."""
    return ds.SignoriniProblem(msh, tags, contact=ex.CONTACT, dirichlet={ex.DIRICHLET: top},
                               E=10.0, nu=0.3, model="plane_strain", gap=gap,
                               friction=law or ds.Coulomb(0.3))


def disc(lift=0.0, **force):
    """The rigid disc touching the block's bottom at x = CENTRE, lifted by ``lift``."""
    return Sphere((CENTRE, -R + lift), R, **force)


def moment(u, lam, m, lam_t):
    """A goal of (u, lambda_n, lambda_t): the x-moment of the contact force and int u_x."""
    return (lam_t * (m.x[0] - CENTRE) + 0.1 * lam + u[0]) * m.ds_contact


def run(problems):
    """Each step's (u, lambda_n, lambda_t, delta) along a path."""
    rows = []

    def keep(record, sol, est):
        rows.append((sol.u.x.array.copy(), sol.lam.x.array.copy(), sol.lam_t.x.array.copy(),
                     sol.obstacle_displacement))

    with ds.solve_path(problems, moment, weights="patch", callback=keep, verbose=False):
        pass
    return rows


def assert_same(a, b, rtol=1e-8):
    """The owned arrays (u, lambda_n, lambda_t) agree to ``rtol`` of each one's size."""
    for x, y in zip(a[:3], b[:3], strict=True):
        assert global_max(x - y) <= rtol * global_max(y), (global_max(x - y), global_max(y))


@pytest.mark.parametrize("law", [ds.Coulomb(0.3), ds.Tresca(0.05)], ids=["coulomb", "tresca"])
def test_single_press_is_displacement_control(law):
    """The disc pressed by F, against the disc moved from its touching position to delta on a
    path's step (the same motion the slip sees); the balance with its tangential share."""
    msh, tags = block()
    with ds.solve(problem(msh, tags, disc(force=F, direction=(0.0, 1.0)), law=law)) as sol:
        forced = (sol.u.x.array.copy(), sol.lam.x.array.copy(), sol.lam_t.x.array.copy())
        delta = sol.obstacle_displacement
        total = integrate(sol, sol.disc.force_balance((sol.lam, sol.lam_t)))
        normal = integrate(sol, sol.disc.force_balance((sol.lam, 0.0 * sol.lam_t)))
        slips = sol.num_slip
    assert total == pytest.approx(F, rel=1e-10)
    assert abs(total - normal) > 1e-3 * F  # the tangential tractions' share counts
    assert slips > 0  # the slip offsets' dependence on delta is exercised
    placed = run([problem(msh, tags, disc(), law=law),
                  problem(msh, tags, disc(delta), law=law)])
    assert_same(forced, placed[-1])


@pytest.mark.parametrize("law", [ds.Tresca(0.05), ds.Coulomb(0.3)], ids=repr)
def test_p2_weights_agree_under_friction(law):
    """The bordered P2 systems with the tangential entries: the hierarchical (two-level) and
    the factored P2 weights give one estimate (measured with Tresca: 6.16882e-6 both, 1e-6
    relative); with Coulomb the two-level operator has the coupled rows too."""
    msh, tags = block()
    etas = {}
    with ds.solve(problem(msh, tags, disc(force=F, direction=(0.0, 1.0)), law=law)) as sol:
        assert sol.num_slip > 0
        for kind in ("hierarchical", "higher_order"):
            with ds.estimate(sol, moment, weights=kind) as est:
                etas[kind] = est.eta
    assert etas["hierarchical"] == pytest.approx(etas["higher_order"], rel=1e-4)


def test_force_path_then_shear():
    """Two force steps, then the block's top moved sideways with the force held, against the
    displacement path through the deltas found (from the touching disc)."""
    msh, tags = block()
    forces, tops = (F / 2, F, F), [(0.0, 0.0), (0.0, 0.0), (SHEAR, 0.0)]
    forced = run([problem(msh, tags, disc(force=f, direction=(0.0, 1.0)), top)
                  for f, top in zip(forces, tops, strict=True)])
    deltas = [row[3] for row in forced]
    assert deltas[0] < deltas[1] and deltas[2] != pytest.approx(deltas[1], rel=1e-6)
    placed = run([problem(msh, tags, disc(d), top)
                  for d, top in zip([0.0, *deltas], [(0.0, 0.0), *tops], strict=True)])
    for a, b in zip(forced, placed[1:], strict=True):
        assert_same(a, b)
    assert global_max(forced[-1][2]) > 0.0


def test_oblique_flat():
    """A flat approached obliquely by F: its tangential motion drags the face; against the
    flat moved from its touching position to delta d on a path's step."""
    msh, tags = block()
    d = np.array([0.2, 1.0]) / math.hypot(0.2, 1.0)
    with ds.solve(problem(msh, tags, Plane((0.0, 0.0), (0.0, -1.0), force=F,
                                           direction=tuple(d)))) as sol:
        forced = (sol.u.x.array.copy(), sol.lam.x.array.copy(), sol.lam_t.x.array.copy())
        delta = sol.obstacle_displacement
        assert integrate(sol, sol.disc.force_balance((sol.lam, sol.lam_t))) == pytest.approx(
            F, rel=1e-10)
    placed = run([problem(msh, tags, Plane((0.0, 0.0), (0.0, -1.0))),
                  problem(msh, tags, Plane(tuple(delta * d), (0.0, -1.0)))])
    assert_same(forced, placed[-1])
    assert global_max(forced[2]) > 0.0


@pytest.mark.parametrize("law", [ds.Coulomb(0.3), ds.Frictionless()],
                         ids=["coulomb", "frictionless"])
def test_oblique_disc(law):
    """A disc approached obliquely: the frame (the disc's normal where the face's normal ray
    enters it) turns with delta; the same identity as for the disc pressed along the normal
    (the solve repeated at its delta until N's frame is that of delta: 3 solves, 14 Newton
    steps, N's last change 1.3e-10 (Coulomb); with N in the frame
    at delta = 0 the two controls had differed by u 2.3e-3, lambda_n 4.9e-4, lambda_t 5.2e-3
    relative)."""
    msh, tags = block()
    d = np.array([0.3, 1.0]) / math.hypot(0.3, 1.0)
    with ds.solve(problem(msh, tags, disc(force=F, direction=tuple(d)), law=law)) as sol:
        forced = (sol.u.x.array.copy(), *(f.x.array.copy() for f in sol.multipliers))
        delta = sol.obstacle_displacement
    moved = Sphere((CENTRE + delta * d[0], -R + delta * d[1]), R)
    with ds.solve(problem(msh, tags, moved, law=law)) as sol:
        once = (sol.u.x.array.copy(), *(f.x.array.copy() for f in sol.multipliers))
    if law.frictional:  # moved there from its touching position (the slip sees the motion)
        once = run([problem(msh, tags, disc(), law=law), problem(msh, tags, moved, law=law)])[-1]
    for x, y in zip(forced, once, strict=False):
        assert global_max(x - y) <= 1e-8 * global_max(y), (global_max(x - y), global_max(y))


def J_of(force):
    """The goal's value at the force-controlled solution under ``force``."""
    msh, tags = block(12, 4)
    with ds.solve(problem(msh, tags, disc(force=force, direction=(0.0, 1.0)))) as sol:
        return integrate(sol, moment(sol.u, sol.lam, sol.disc.m, sol.lam_t))


def test_zeta_is_the_goals_rate_in_the_force():
    """The dual of the bordered system with its tangential entries: zeta = dJ/dF (the force
    enters only the bordered row), against a central difference in F."""
    h = 1e-4 * F
    reference = (J_of(F + h) - J_of(F - h)) / (2 * h)
    msh, tags = block(12, 4)
    with ds.solve(problem(msh, tags, disc(force=F, direction=(0.0, 1.0)))) as sol, \
            ds.estimate(sol, moment, estimator="eta_p", weights="patch") as est:
        assert est.dual.zeta == pytest.approx(reference, rel=1e-6)


def ux(u, lam, m, lam_t):
    """int u_x on Gamma_C."""
    return u[0] * m.ds_contact


@pytest.mark.slow
@pytest.mark.parametrize(
    "weights",
    [
        "higher_order",
        pytest.param("patch", marks=pytest.mark.xfail(strict=True, reason=(
            "measured: J_h -3.845e-5, eta 3.96e-5, interval [-1.84e-5, 3.57e-5] against the "
            "reference -3.294e-5 (serial); the displacement-controlled step at the same delta "
            "gives [-1.85e-5, 3.61e-5]: the patch weights' miss, not the force control's"))),
    ],
)
def test_interval_holds_a_finer_reference(weights):
    """The estimate's interval for int u_x on Gamma_C holds the J_h of the meshes 4 and 8
    times finer (uncertain by their difference, 2.3e-7; the error is 5.5e-6). Measured
    (serial): higher-order weights eta 1.43e-5, interval [-4.04e-5, 1.6e-6] around J_h
    -3.845e-5, reference -3.294e-5."""
    values = []
    for n in (4, 8):
        msh, tags = block(24 * n, 8 * n)
        with ds.solve(problem(msh, tags, disc(force=F, direction=(0.0, 1.0)))) as sol:
            values.append(integrate(sol, ux(sol.u, sol.lam, sol.disc.m, sol.lam_t)))
    reference, uncertainty = values[1], abs(values[1] - values[0])
    msh, tags = block()
    with ds.solve(problem(msh, tags, disc(force=F, direction=(0.0, 1.0)))) as sol, \
            ds.estimate(sol, ux, weights=weights) as est:
        low, high = est.interval
        assert abs(reference - est.J_h) > 10 * uncertainty, (reference, est.J_h, uncertainty)
        assert low - uncertainty <= reference <= high + uncertainty, (low, reference, high)


@pytest.mark.slow
@pytest.mark.parametrize("law", [ds.Tresca(0.01), ds.Coulomb(0.3)], ids=["tresca", "coulomb"])
def test_cylinder_in_3d_is_displacement_control(law):
    """3D, the coupled rows of Tresca's ball and Coulomb's cone (their r = P(x) - J x is data
    of the iterate, left out of the unit response): a cylinder along x pressed by a force into
    a box, against the cylinder moved to its delta on a path's step. Measured (serial): u,
    lambda_n, lambda_t to 3e-13, 2e-14, 5e-11 (Tresca; 3 slipping, 2 sticking facets) and
    2e-12, 1e-13, 1e-11 (Coulomb). Slow for its forms' compilation (minutes on a cold cache)."""
    msh = mesh.create_box(COMM, [(0.0, 0.0, 0.0), (1.0, 0.25, 0.5)], [4, 4, 4],
                          mesh.CellType.tetrahedron, ghost_mode=mesh.GhostMode.none)
    tags = ex.tag_block_facets(msh, 0.5)

    def box(gap):
        return ds.SignoriniProblem(msh, tags, contact=ex.CONTACT,
                                   dirichlet={ex.DIRICHLET: (0.0, 0.0, 0.0)}, E=10.0, nu=0.3,
                                   model="3d", gap=gap, friction=law)

    def cylinder(lift=0.0, **force):
        return Cylinder((0.0, 0.11, -R + lift), (1.0, 0.0, 0.0), R, **force)

    with ds.solve(box(cylinder(force=0.01, direction=(0.0, 0.0, 1.0)))) as sol:
        forced = (sol.u.x.array.copy(), sol.lam.x.array.copy(), sol.lam_t.x.array.copy())
        delta = sol.obstacle_displacement
        assert sol.num_slip > 0
    rows = []

    def keep(record, s, est):
        rows.append((s.u.x.array.copy(), s.lam.x.array.copy(), s.lam_t.x.array.copy()))

    with ds.solve_path([box(cylinder()), box(cylinder(delta))],
                       lambda u, lam, m, lam_t: (lam_t[1] + lam) * m.ds_contact,
                       weights="patch", callback=keep, verbose=False):
        pass
    assert_same(forced, rows[-1])


def test_model_error_under_a_given_force_is_refused():
    """The model error's Newton step of the richer law does not border delta: refused, naming
    the obstacle, rather than computed with the obstacle at its given position."""
    msh, tags = block(6, 2)
    gap = disc(force=F, direction=(0.0, 1.0))
    with ds.solve(problem(msh, tags, gap, law=ds.Frictionless())) as sol:
        with pytest.raises(ValueError, match="Newton step does not border"):
            ds.estimate(sol, lambda u, lam, m: lam * m.ds_contact, weights="patch",
                        model_error=problem(msh, tags, gap)).destroy()


def test_history_goal_sees_the_previous_steps_delta():
    """Along a force path a step's offsets start from the previous step's delta_0 d: the
    history goal L (the step's sensitivity to its history, a goal of the earlier step) has
    the rate -L(d) in the earlier step's delta, against a central difference of the step's J
    in delta_0 (the earlier step's u held)."""
    from dwr_signorini.goal import GoalForms
    from dwr_signorini.path_history import history_goal

    msh, tags = block()
    first, second = (problem(msh, tags, disc(force=f, direction=(0.0, 1.0)))
                     for f in (F / 2, F))
    with ds.solve(first) as sol1:
        start = sol1.obstacle_displacement

        def step(delta_0):
            disc2 = sol1.disc.for_problem(second)
            disc2.set_u_old(sol1.u, None, delta_0)
            return ds.solve(disc2)

        def J(delta_0):
            with step(delta_0) as sol:
                return integrate(sol, moment(sol.u, sol.lam, sol.disc.m, sol.lam_t))

        h = 1e-4 * start
        reference = (J(start + h) - J(start - h)) / (2 * h)
        with step(start) as sol2, \
                ds.estimate(sol2, moment, estimator="eta_p", weights="patch") as est2:
            assert sol2.num_slip > 0 and sol2.num_stick > 0
            L = history_goal(sol2, est2)
            rate = GoalForms(L, sol1.u, sol1.lam, sol1.disc, (sol1.lam_t,)).rate(
                sol1.disc.fields.obstacle_displacement)
    assert rate == pytest.approx(reference, rel=1e-6)
    assert abs(rate) > 1e-3 * abs(J(start)) / start
