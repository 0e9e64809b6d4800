"""Cattaneo-Mindlin in 2D (dwr_signorini.cases.cattaneo_mindlin_2d) against the theory.

A half-cylinder (``meshes/cattaneo_2d.py``, R = 1, E = 1, nu = 0.49, plane strain) pressed onto
a rigid flat (a / R = 0.094) and sheared in four steps to Q / (mu P) = 0.69 with Coulomb
friction mu = 0.3, solved by ``ds.solve_path``. Truth is the half-plane theory (Hertz,
Cattaneo, Mindlin) for the computed P and Q: the stick half-width c = a sqrt(1 - Q / (mu P))
and the traction q(x).

* The computed stick half-width (half the extent of the sticking macro facets) is within one
  macro facet of c on the last and an intermediate shear step (measured on the default mesh,
  facets of 0.01 at the contact: -0.45 and -0.32 facets; the computed zone is a little small,
  by 0.2-1.2 facets on meshes of 0.02 to 0.0025).
* The slip is measured in the flat's frame (``docs/theory.md``): the half-disc's own finite
  size then shows as an odd tangential traction on the press step that the half-plane theory
  does not have (the strict xfails below, with their numbers); the numbers that follow were
  measured with the slip along each slave facet's own tangent, which partly hid it.
* The relative L2 error of lambda_t against q decreases under refinement of the contact facets
  (0.315, 0.223, 0.158, 0.103 at facets of 0.02, 0.01, 0.005, 0.0025, about h^0.55) and stays
  below l2_best + 0.2: l2_best is the error of the best facet-wise constant approximation of q
  (computed from the theory on the same facets: 0.18, 0.10, 0.047, 0.025), and 0.2 bounds
  what the P1 element adds at nu = 0.49: lambda_t oscillates from facet to facet by about
  +-0.08 mu p0 in the stick zone (volumetric locking, lambda / mu = 49), about 0.1 of ||q||.
* Two processes give the serial numbers.

About 6 s serial without the ``slow`` test (which adds facets of 0.0025, about 15 s).
"""

import itertools

from mpi4py import MPI

import pytest

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.cases import cattaneo_mindlin_3d as cm

COMM = MPI.COMM_WORLD
MU = cases.CM_DEFAULTS["mu"]
_CACHE: dict = {}


def run_path(h_contact, comm=COMM):
    """The measures (cases.CMMeasure) and J_h of every step of the default path."""
    key = (h_contact, comm.size)
    if key not in _CACHE:
        rows = []

        def keep(record, sol, est):
            rows.append((cases.measure_cattaneo_mindlin(sol), record.J_h, record.num_stick,
                         record.num_slip))

        problems = cases.cattaneo_mindlin_path(comm, h_contact=h_contact)
        ds.solve_path(problems, ex.goal_friction_force(), callback=keep,
                      verbose=False).destroy()
        _CACHE[key] = rows
    return _CACHE[key]


@pytest.mark.mpi
def test_setting_is_cattaneo_mindlins():
    """The default path is in the theory's range: a / R about 0.1, the press step's Q about 0,
    Q growing to 0.6-0.7 mu P, J_h = Q (the friction force), the facets counted by solve_path."""
    rows = run_path(0.01)
    assert len(rows) == 1 + cases.CM_DEFAULTS["steps"]
    a_over_r = rows[-1][0].a / cases.CM_DEFAULTS["radius"]
    assert 0.08 < a_over_r < 0.11
    assert abs(rows[0][0].ratio) < 0.01
    ratios = [m.ratio for m, *_ in rows]
    assert all(b > a for a, b in itertools.pairwise(ratios)), ratios
    assert 0.6 < ratios[-1] < 0.7
    for m, J_h, num_stick, num_slip in rows:
        assert J_h == pytest.approx(m.Q, rel=1e-10, abs=1e-14)
        assert (num_stick, num_slip) == (m.num_stick, m.num_slip)
    # the whole contact is Hertz's within one facet, on every step
    assert all(abs(m.a_error_facets) < 1.0 for m, *_ in rows)


@pytest.mark.mpi
@pytest.mark.parametrize("step", [2, 4])
def test_stick_half_width_within_one_facet(step):
    """c_h against c = a sqrt(1 - Q / (mu P)) on an intermediate and the last shear step: within
    one macro facet, and the stick zone shrinks step by step as the theory's."""
    rows = run_path(0.01)
    m = rows[step][0]
    assert m.num_stick > 0 and m.num_slip > 0
    assert abs(m.c_h - m.c) <= m.h_facet, (m.c_h, m.c, m.h_facet)
    c_h = [r[0].c_h for r in rows[1:]]
    assert all(b <= a for a, b in itertools.pairwise(c_h)), c_h


@pytest.mark.mpi
def test_traction_error_decreases_under_refinement():
    """||lambda_t - q|| / ||q|| on the last shear step, facets of 0.02, 0.01, 0.005 at the
    contact: decreasing (0.461, 0.337, 0.269 measured); lambda_n against Hertz's profile within
    20 %."""
    errors = []
    for h_contact in (0.02, 0.01, 0.005):
        m = run_path(h_contact)[-1][0]
        assert m.l2_lam < 0.2
        errors.append(m.l2_lam_t)
    assert all(b < 0.85 * a for a, b in itertools.pairwise(errors)), errors


@pytest.mark.xfail(strict=True, reason=(
    "the half-disc is not a half-plane: on a frictionless flat its contact points move outwards "
    "(u_x = +1.7e-4 at a/2, nu = 0.49; the half-plane's beta = 0.02 moves them inwards), so "
    "sticking needs an odd traction on the press step (friction force of each half 0.21, 0.17, "
    "0.19 mu P_half on facets of 0.02, 0.01, 0.005, not falling with h) that Cattaneo does not "
    "have: ||lambda_t - q|| / ||q|| = 0.461, 0.337, 0.269 against l2_best + 0.2 = 0.385, 0.298, "
    "0.246, the stick zone 0.13 a off centre. The discrete solution converges (the press's "
    "friction force of each half 0.21, 0.17, 0.19, 0.18 on facets down to 0.0025, the stick zone "
    "0.21, 0.16, 0.13, 0.16 a off centre on the last step; the flat's frame is its own normal): "
    "the truth misses, not the method. The half-plane's beta = 0.0196 is not 0, the finite "
    "half-disc bulges its contact points outwards (at nu = 0.4999 the press leaves 0.60, 0.21 "
    "of the halves' Coulomb limit at a / R = 0.107, 0.049), and P1 locks at nu = 0.49 (the "
    "press's rms lambda_t 0.50, 0.33, 0.28, 0.25 mu p); at a / R = 0.042, 0.019 on 9 facets per "
    "a the error is 0.299, 0.234 against 0.287, 0.294 and the stick zone 0.06, 0.13 a off "
    "centre. The two identical discs (beta = 0 by symmetry at nu = 0.3) meet Cattaneo: "
    "tests/test_friction_frame.py"))
@pytest.mark.mpi
def test_traction_error_within_the_half_plane_bound():
    """||lambda_t - q|| / ||q|| on the last shear step below the best facet-wise
    approximation's error + 0.2 (module docstring), facets of 0.02, 0.01, 0.005."""
    for h_contact in (0.02, 0.01, 0.005):
        m = run_path(h_contact)[-1][0]
        assert m.l2_lam_t < m.l2_best + 0.2, (h_contact, m.l2_lam_t, m.l2_best)


@pytest.mark.xfail(strict=True, reason=(
    "the finite body's odd press traction (see test_traction_error_within_the_half_plane_bound): "
    "||lambda_t - q|| / ||q|| = 0.666 on facets of 0.0025 (step 2) against l2_best + 0.2 = "
    "0.248"))
@pytest.mark.slow
@pytest.mark.mpi
def test_traction_error_decreases_on_finer_meshes():
    """As above with facets of 0.005 and 0.0025, on the last and an intermediate step; the
    stick half-width within 1.5 facets of theory on the finer mesh (it comes out small by up
    to 1.2 facets on these meshes: the discrete traction undershoots q's square-root rise at
    the stick boundary, where the P1 oscillation tips facets into slip)."""
    coarse, fine = run_path(0.005), run_path(0.0025)
    for step in (2, 4):
        assert fine[step][0].l2_lam_t < 0.9 * coarse[step][0].l2_lam_t
        assert fine[step][0].l2_lam_t < fine[step][0].l2_best + 0.2
        m = fine[step][0]
        assert abs(m.c_h - m.c) <= 1.5 * m.h_facet, (m.c_h, m.c, m.h_facet)


@pytest.mark.mpi
def test_serial_and_parallel_agree():
    """The path on COMM_WORLD and on COMM_SELF (one per rank): the same stick and slip sets,
    forces, stick half-widths and errors to round-off (trivially equal on one process)."""
    world, single = run_path(0.02), run_path(0.02, MPI.COMM_SELF)
    for (mw, jw, *sets_w), (ms, js, *sets_s) in zip(world, single, strict=True):
        assert sets_w == sets_s
        assert (mw.num_stick, mw.num_slip) == (ms.num_stick, ms.num_slip)
        assert jw == pytest.approx(js, rel=1e-8, abs=1e-14)
        for key in ("P", "Q", "a_h", "c_h", "l2_lam_t", "l2_lam"):
            assert getattr(mw, key) == pytest.approx(getattr(ms, key), rel=1e-8, abs=1e-14), key


def test_theory_functions():
    """The formulas: the stick zone is the contact at Q = 0 and vanishes at Q = mu P; q is
    mu p in the slip zone, its integral is Q (Johnson 1985, eq. 7.10), beta(1/2) = 0."""
    import numpy as np

    P, R, E, nu = 0.009, 1.0, 1.0, 0.49
    a, p0 = cases.hertz_half_width(P, R, E, nu)
    assert 2 * P / (np.pi * a) == pytest.approx(p0)
    assert cases.stick_half_width(a, 0.0, MU, P) == pytest.approx(a)
    assert cases.stick_half_width(a, MU * P, MU, P) == 0.0
    with pytest.raises(ValueError, match="slides"):
        cases.stick_half_width(a, 1.01 * MU * P, MU, P)
    assert cases.dundurs_beta(0.5) == 0.0
    assert cases.dundurs_beta(0.49) == pytest.approx(0.0196, abs=1e-4)
    Q = 0.6 * MU * P
    c = cases.stick_half_width(a, Q, MU, P)
    x = np.linspace(-a, a, 200001)
    q = cases.cm_traction(x, a, c, p0, MU)
    assert np.trapezoid(q, x) == pytest.approx(Q, rel=1e-5)
    assert np.trapezoid(cases.hertz_pressure(x, a, p0), x) == pytest.approx(P, rel=1e-5)
    slip = np.abs(x) >= c
    assert np.allclose(q[slip], MU * cases.hertz_pressure(x[slip], a, p0))


# --------------------------------------------------------------------------------------------------
# 3D: a sphere (the half y >= 0 of meshes/hertz_3d.py) on a rigid flat
# --------------------------------------------------------------------------------------------------
#
# The path of cm.CM_DEFAULTS_3D (R = 1, E = 1, nu = 0.49, mu = 0.3, a / R = 0.105, Q / (mu P) up
# to 0.81 in four shear steps) on macro facets of 0.03 at the contact (19,264 fine cells; about
# 15 s serial, 8 s on 2 ranks; patch weights and no history estimates: the estimates are not
# tested here). Truth is Hertz and Mindlin for the computed whole-sphere P and Q:
# a = (3 P R / (4 E*))^(1/3) and c = a (1 - Q / (mu P))^(1/3). Measured (c_h - c and a_h - a
# in mean edges of the contact facets, h_facet = 0.0287 and 0.0201):
#
#   h_contact  Q/(mu P)  0.24   0.45   0.64   0.81    a_h - a   L2(lam_t.e_x - q) last step
#   0.03       c_h - c  -0.90  -0.98  -0.89  -0.74    -0.36     0.67 (best P0: 0.18)
#   0.02       c_h - c  -1.10  -1.17  -0.95  -1.23    -0.43     0.67 (best P0: 0.15)
#
# The computed stick zone is systematically small by about one facet (in 2D by 0.2-1.2): lambda_n
# oscillates from facet to facet by about +-0.3 p0 (rms, P0 multipliers against P1 displacements
# at nu = 0.49; +-0.15 p0 at nu = 0.3), and a sticking facet whose lambda_n is low reaches its
# Coulomb limit and slips. The same oscillation rides on lambda_t (mu lambda_n on every slipping
# facet), so its L2 error against q does not fall under refinement at these sizes and is not
# tested; it is reported by the demo (``--dim 3``).

_CACHE_3D: dict = {}


def run_path_3d(h_contact=cm.CM_DEFAULTS_3D["h_contact"], comm=COMM):
    """The measures and J_h of every step of the default 3D path (as :func:`run_path`)."""
    key = (h_contact, comm.size)
    if key not in _CACHE_3D:
        rows = []

        def keep(record, sol, est):
            rows.append((cases.measure_cattaneo_mindlin(sol), record.J_h, record.num_stick,
                         record.num_slip))

        problems = cm.cattaneo_mindlin_path_3d(comm, h_contact=h_contact)
        ds.solve_path(problems, ex.goal_friction_force(), callback=keep, weights="patch",
                      history=False, verbose=False).destroy()
        _CACHE_3D[key] = rows
    return _CACHE_3D[key]


@pytest.mark.mpi
def test_setting_is_mindlins_3d():
    """The 3D path is in the theory's range: a / R about 0.1, no friction force in the press
    step, Q growing to about 0.8 mu P; Q = 2 J_h (the half body's friction force, doubled);
    the whole contact radius (the disc of the active facets' area) within one facet of Hertz's
    on every step (measured: -0.36 facets on 0.03, -0.43 on 0.02: the boundary facets that are
    partly in contact count as out)."""
    rows = run_path_3d()
    assert len(rows) == 1 + cm.CM_DEFAULTS_3D["steps"]
    m0 = rows[0][0]
    assert m0.dim == 3
    assert 0.09 < m0.a / cm.CM_DEFAULTS_3D["radius"] < 0.12
    assert abs(m0.ratio) < 0.01
    ratios = [m.ratio for m, *_ in rows]
    assert all(b > a for a, b in itertools.pairwise(ratios)), ratios
    assert 0.7 < ratios[-1] < 0.9
    for m, J_h, num_stick, num_slip in rows:
        assert m.Q == pytest.approx(2 * J_h, rel=1e-10, abs=1e-14)
        assert (num_stick, num_slip) == (m.num_stick, m.num_slip)
        assert abs(m.a_h - m.a) <= m.h_facet, (m.a_h, m.a, m.h_facet)
        assert m.h_facet < 1.1 * cm.CM_DEFAULTS_3D["h_contact"]


@pytest.mark.xfail(strict=True, reason=(
    "the sphere is not a half-space (as the half-disc, see "
    "test_traction_error_within_the_half_plane_bound): with the slip in the obstacle's frame "
    "c_h - c = -1.54 facets on step 2 (c_h = 0.0421, c = 0.0863, h_facet = 0.0287), and c_h "
    "0.0421, 0.0498, 0.0401 on steps 2-4, not shrinking step by step"))
@pytest.mark.mpi
@pytest.mark.parametrize("step", [2, 4])
def test_stick_radius_3d(step):
    """c_h (the radius of the disc of the sticking facets' area) against Mindlin's
    c = a (1 - Q / (mu P))^(1/3) on an intermediate and the last shear step: measured -0.98 and
    -0.74 facets on the default mesh, -1.17 and -1.23 on facets of 0.02 (the table above):
    small by about one facet, so the test asks for -1.5 <= (c_h - c) / h_facet <= 0.5. The stick
    zone is off-centre by less than a facet and shrinks step by step as the theory's."""
    rows = run_path_3d()
    m = rows[step][0]
    assert m.num_stick > 0 and m.num_slip > 0
    assert -1.5 * m.h_facet <= m.c_h - m.c <= 0.5 * m.h_facet, (m.c_h, m.c, m.h_facet)
    assert abs(m.stick_center) < m.h_facet
    c_h = [r[0].c_h for r in rows[2:]]
    assert all(b <= a for a, b in itertools.pairwise(c_h)), c_h


@pytest.mark.mpi
def test_serial_and_parallel_agree_3d():
    """The 3D path on COMM_WORLD and on COMM_SELF agree to the discretisation, not to round-off:
    the fine mesh (the uniform refinement of the macro tetrahedra) has the same vertices but
    other tetrahedra on 2 processes (the inner diagonal of each refined tetrahedron depends on
    the partition; it even differs between two 2-process runs). Measured on 2 processes: P
    differs by 2e-4 relative, Q by 7e-4 of itself on the shear steps (5e-8 = 2e-4 mu P / 2 on
    the press step, where Q is about 0), the stick sets by one facet. Tested: P to 1e-3, Q to
    5e-3 mu P, the numbers of sticking facets to 2, the radii to half a facet (equal on one
    process)."""
    world, single = run_path_3d(comm=COMM), run_path_3d(comm=MPI.COMM_SELF)
    for (mw, jw, *_), (ms, js, *_) in zip(world, single, strict=True):
        assert mw.P == pytest.approx(ms.P, rel=1e-3)
        assert abs(jw - js) <= 5e-3 * MU * ms.P / 2, (jw, js)
        assert abs(mw.num_stick - ms.num_stick) <= 2
        assert abs(mw.c_h - ms.c_h) <= 0.5 * ms.h_facet
        assert abs(mw.a_h - ms.a_h) <= 0.5 * ms.h_facet


def test_theory_functions_3d():
    """Hertz's and Mindlin's formulas for a sphere: the pressure integrates to P, the traction
    to Q (Johnson 1985, eqs. 4.23, 7.43); c = a at Q = 0 and 0 at Q = mu P; q = mu p on
    c <= r <= a."""
    import numpy as np

    P, R, E, nu = 0.004, 1.0, 1.0, 0.49
    a, p0 = cm.hertz_radius(P, R, E, nu)
    assert a == pytest.approx((3 * P * R * (1 - nu**2) / (4 * E)) ** (1 / 3))
    assert cm.stick_radius(a, 0.0, MU, P) == pytest.approx(a)
    assert cm.stick_radius(a, MU * P, MU, P) == 0.0
    with pytest.raises(ValueError, match="slides"):
        cm.stick_radius(a, 1.01 * MU * P, MU, P)
    Q = 0.6 * MU * P
    c = cm.stick_radius(a, Q, MU, P)
    r = np.linspace(0.0, a, 400001)
    q = cm.cm_traction_3d(r, a, c, p0, MU)
    assert np.trapezoid(2 * np.pi * r * q, r) == pytest.approx(Q, rel=1e-5)
    p = cases.hertz_pressure(r, a, p0)
    assert np.trapezoid(2 * np.pi * r * p, r) == pytest.approx(P, rel=1e-5)
    slip = r >= c
    assert np.allclose(q[slip], MU * p[slip])
    assert np.all(q[~slip] < MU * p[~slip])
