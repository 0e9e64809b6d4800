"""The contact frame of friction (``docs/theory.md``): no slip read from a normal approach.

Two identical discs (the cylinders of :mod:`tests.test_pairs_friction`: R = 8, E = 200,
nu = 0.3, Coulomb mu = 0.3) pressed together by a vertical displacement of the top: the
mirror symmetry about the contact plane makes the tangential traction zero (Dundurs' beta = 0,
and exactly, for any finite body, since the problem is its own mirror image), with either arc
the slave side. Measured on the press step (``benchmarks/friction_frame.py``):
||lambda_t|| / ||mu lambda_n|| = 0.0067 (facets of 0.04) and 0.0021 (0.02), peak
|lambda_t| / (mu p0) 0.023 and 0.0041; with the slip along each slave facet's own tangent
0.27 on both meshes and peaks 0.58. Under shear the stick zone is centred (to round-off; 0.11
to 0.17 a off centre along the slave facets) and the L2 error of lambda_t against Cattaneo
falls with h (0.101, 0.058 on the second shear step, 0.0505, 0.0234 on the last, facets of
0.04, 0.02; along the slave facets 0.445, 0.441 and 0.105, 0.099).

The obstacles' frame normals against their closed forms at a few points.
"""

import itertools

from mpi4py import MPI

import basix.ufl
import numpy as np
import pytest
import ufl

import dwr_signorini as ds
from dwr_signorini import cases

from .problems import from_model
from .test_pairs_friction import MOD, MU, NU, PRESS, SHEAR, E, R, cylinders

COMM = MPI.COMM_WORLD
_CACHE: dict = {}


def lower_disc(h_contact, r_lower):
    """The upper disc of radius R on a lower one of radius ``r_lower`` (cached)."""
    if r_lower == R:
        return cylinders(h_contact)
    key = ("mesh", h_contact, r_lower)
    if key not in _CACHE:
        _CACHE[key] = from_model(MOD.build, r_lower=r_lower, r_upper=R, h=1.6,
                                 h_contact=h_contact, full=True)
    return _CACHE[key]


def disc_rows(h_contact, upper_slave=True, steps=0, r_lower=R, press=PRESS):
    """The Cattaneo-Mindlin measures of the press step (and ``steps`` shear steps)."""
    key = (h_contact, upper_slave, steps, r_lower, press, COMM.size)
    if key not in _CACHE:
        msh, cells, facets = lower_disc(h_contact, r_lower)
        arcs = (MOD.UPPER_ARC, MOD.LOWER_ARC)
        slave, master = arcs if upper_slave else arcs[::-1]
        tops = [(k * SHEAR / max(steps, 1), -press) for k in range(steps + 1)]
        problems = [ds.SignoriniProblem(
            msh, facets, contact=ds.ContactPair(slave=slave, master=master),
            dirichlet={MOD.LOWER_FLAT: (0.0, 0.0), MOD.UPPER_FLAT: top}, E=E, nu=NU,
            cell_tags=cells, friction=ds.Coulomb(MU),
            boundary_projection=MOD.projections(r_lower, R)) for top in tops]
        rows = []

        def keep(record, sol, est):
            rows.append(cases.measure_cattaneo_mindlin(sol, mu=MU, E=E, nu=NU, radius=R))

        ds.solve_path(problems, lambda u, lam, m, lam_t: lam_t * m.ds_contact, callback=keep,
                      history=False, verbose=False).destroy()
        _CACHE[key] = rows
    return _CACHE[key]


@pytest.mark.mpi
@pytest.mark.parametrize("upper_slave", [True, False])
def test_pressed_discs_have_no_tangential_traction(upper_slave):
    """||lambda_t|| / ||mu lambda_n|| under 0.02 and falling from facets of 0.04 to 0.02, the
    peak under 0.05 mu p0, the friction force of each half under 0.01 mu P_half (0.19 each,
    0.27 and 0.58 before the contact frame), with either arc the slave side."""
    coarse, fine = disc_rows(0.04, upper_slave)[0], disc_rows(0.02, upper_slave)[0]
    for m in (coarse, fine):
        assert m.rms_lam_t < 0.02, m.rms_lam_t
        assert m.max_lam_t < 0.05, m.max_lam_t
        assert abs(m.coupling) < 0.01, m.coupling
    assert fine.rms_lam_t < 0.85 * coarse.rms_lam_t, (coarse.rms_lam_t, fine.rms_lam_t)


@pytest.mark.mpi
@pytest.mark.parametrize("upper_slave", [True, False])
def test_disc_on_a_larger_disc(upper_slave):
    """A disc of radius 8 on one of radius 40 of the same material (beta = 0): the friction
    force of each half under 0.02 mu P_half and ||lambda_t|| under 0.06 ||mu lambda_n|| with
    either side the slave (measured 0.007 and 0.036, 0.045; with the slip along the slave
    facets -0.14, +0.13 and 0.20, 0.17)."""
    m = disc_rows(0.04, upper_slave, r_lower=40.0)[0]
    assert abs(m.coupling) < 0.02, m.coupling
    assert m.rms_lam_t < 0.06, m.rms_lam_t


@pytest.mark.xfail(strict=True, reason=(
    "||lambda_t|| / ||mu lambda_n|| = 0.036, 0.041 (upper side the slave) and 0.045, 0.042 "
    "(lower) on facets of 0.04, 0.02, the friction force of each half -0.0074, -0.0078 mu "
    "P_half: a residual that does not fall with h. It is the finite bodies' (the half discs of "
    "radius 8 and 40 are no half-planes): it falls with a / R at a fixed number of facets per a "
    "(test_disc_on_a_larger_disc_falls_with_a)"))
@pytest.mark.slow
@pytest.mark.mpi
def test_disc_on_a_larger_disc_falls_with_h():
    """||lambda_t|| / ||mu lambda_n|| falling from facets of 0.04 to 0.02, either side the
    slave."""
    for upper in (True, False):
        coarse = disc_rows(0.04, upper, r_lower=40.0)[0]
        fine = disc_rows(0.02, upper, r_lower=40.0)[0]
        assert fine.rms_lam_t < 0.85 * coarse.rms_lam_t, (coarse.rms_lam_t, fine.rms_lam_t)


@pytest.mark.slow
@pytest.mark.mpi
def test_disc_on_a_larger_disc_falls_with_a():
    """The residual of the disc on the larger disc is the finite bodies': the half-plane theory
    (beta = 0, lambda_t = 0) is the limit a / R -> 0, and its deviation falls with a. The press
    0.19, 0.0475, 0.011875 (a = 0.83, 0.38, 0.18) on facets of 0.02: the friction force of
    each half -0.0078, -0.0039, -0.0022 mu P_half (about 0.01 a mu P_half: the bulge of a
    half disc of radius R moves its contact points apart by a strain of order P / (E* R), which
    differs between R = 8 and R = 40; two discs of one radius are mirror images and have none),
    ||lambda_t|| / ||mu lambda_n|| 0.041, 0.025, 0.014. Asked: each quarter of the press at
    least 1.5 times smaller in |coupling| and smaller in the share."""
    rows = [disc_rows(0.02, True, r_lower=40.0, press=PRESS / 4**k)[0] for k in range(3)]
    for big, small in itertools.pairwise(rows):
        assert small.a < 0.6 * big.a, (big.a, small.a)
        assert abs(small.coupling) < abs(big.coupling) / 1.5, (big.coupling, small.coupling)
        assert small.rms_lam_t < big.rms_lam_t, (big.rms_lam_t, small.rms_lam_t)


@pytest.mark.mpi
def test_swapped_sides_give_the_same_traction():
    """Upper or lower arc the slave side: the same P, Q and stick half-width on every step of
    a path to Q / (mu P) = 0.96 (the frame is the bisector of the two normals)."""
    for a, b in zip(disc_rows(0.04, True, 4), disc_rows(0.04, False, 4), strict=True):
        assert a.P == pytest.approx(b.P, rel=1e-3)
        assert a.Q == pytest.approx(b.Q, rel=1e-3, abs=1e-3 * MU * a.P)
        assert abs(a.c_h - b.c_h) <= 0.5 * a.h_facet


@pytest.mark.mpi
def test_stick_zone_is_centred():
    """On every shear step the stick zone is centred within half a facet (0.17 a = 3 facets
    off centre before the contact frame) and within one facet of Cattaneo's half-width."""
    for m in disc_rows(0.04, True, 4)[1:]:
        assert m.num_stick > 0 and m.num_slip > 0
        assert abs(m.stick_center) <= 0.5 * m.h_facet, (m.stick_center, m.h_facet)
        assert abs(m.c_h - m.c) <= m.h_facet, (m.c_h, m.c, m.h_facet)


@pytest.mark.slow
@pytest.mark.mpi
def test_cattaneo_error_falls_with_h():
    """||lambda_t - q|| / ||q|| against Cattaneo's q on the shear steps: falling from facets of
    0.04 to 0.02 (module docstring)."""
    coarse, fine = disc_rows(0.04, True, 4), disc_rows(0.02, True, 4)
    for step in (2, 4):
        assert fine[step].l2_lam_t < 0.85 * coarse[step].l2_lam_t, (
            coarse[step].l2_lam_t, fine[step].l2_lam_t)
    assert all(abs(m.stick_center) <= 0.5 * m.h_facet for m in fine[1:])


# --------------------------------------------------------------------------------------------------
# The obstacles' frame normals
# --------------------------------------------------------------------------------------------------


def _evaluate(expr, point):
    return np.array([float(expr[i](point)) for i in range(ufl.shape(expr)[0])])


def _coordinate(dim):
    cell = "triangle" if dim == 2 else "tetrahedron"
    return ufl.SpatialCoordinate(ufl.Mesh(basix.ufl.element("Lagrange", cell, 1, shape=(dim,))))


@pytest.mark.parametrize("point, normal", [((0.3, 0.4), (0.6, -0.8)), ((0.3, 0.4), (-0.6, -0.8)),
                                           ((0.0, 1.0), (1.0, 0.0))])
def test_obstacle_frame_normals_2d(point, normal):
    """Plane: its own normal; Sphere: from the ray's entry point towards the centre; the body's
    normal where the ray misses."""
    x = _coordinate(2)
    n = ufl.as_vector(normal)
    miss = 10.0
    plane = ds.obstacles.Plane((0.0, -1.0), (0.0, -1.0))
    got = _evaluate(plane.surface_normal(x, n, miss), point)
    expected = (0.0, -1.0) if normal[1] < 0 else normal
    assert np.allclose(got, expected)
    sphere = ds.obstacles.Sphere((0.0, -2.0), 1.5)
    got = _evaluate(sphere.surface_normal(x, n, miss), point)
    t = float(sphere.gap(x, n, miss)(point))
    expected = normal
    if t < miss:
        y = np.array(point) + t * np.array(normal)
        expected = (np.array((0.0, -2.0)) - y) / 1.5
    assert np.allclose(got, expected), (got, expected, t)


def test_cylinder_frame_normal():
    """Cylinder: the entry point's normal, normal to the axis, towards the axis."""
    x = _coordinate(3)
    axis, point = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0), np.array([0.0, 0.0, -2.0])
    cylinder = ds.obstacles.Cylinder(point, axis, 1.0)
    for p, normal in itertools.product([(0.2, -0.1, 0.0), (1.0, 0.5, -0.5)],
                                       [(0.0, 0.0, -1.0), (0.1, 0.2, -0.97)]):
        nn = np.array(normal) / np.linalg.norm(normal)
        n = ufl.as_vector(nn)
        got = _evaluate(cylinder.surface_normal(x, n, 10.0), p)
        y = np.array(p) + float(cylinder.gap(x, n, 10.0)(p)) * nn
        d = point - y
        d -= (d @ axis) * axis
        assert np.allclose(got, d / np.linalg.norm(d)), (got, d)
        assert np.linalg.norm(d) == pytest.approx(1.0)


@pytest.mark.mpi
def test_coulomb_without_friction_is_the_frictionless_law():
    """mu = 0 makes Coulomb's law the frictionless one: every law measures in one contact frame.

    A block pressed onto a rigid ball (a curved obstacle, whose normal differs from the
    block's) and the two discs of the pairs (a curved pair): the normal force's total and the
    multiplier agree to round-off. Before every law used one frame, the frictionless law
    measured along the body's normal and Coulomb's along the obstacle's: the ball's total force
    differed by 1.2 % (0.17346 against 0.17561 on 16 x 8 macro cells).
    """
    from dolfinx import mesh

    from dwr_signorini import examples as ex

    msh = mesh.create_rectangle(COMM, [(0.0, 0.0), (1.0, 0.5)], [16, 8],
                                mesh.CellType.triangle, ghost_mode=mesh.GhostMode.none)


    tags = ex.tag_block_facets(msh, 0.5)
    ball = ds.obstacles.Sphere((0.5, -0.98), 1.0)
    block = [ds.SignoriniProblem(msh, tags, contact=ex.CONTACT, dirichlet=(ex.DIRICHLET,),
                                 E=10.0, nu=0.3, gap=ball, friction=law)
             for law in (None, ds.Coulomb(0.0))]
    dmsh, cells, facets = cylinders(0.08)
    discs = [ds.SignoriniProblem(
        dmsh, facets, contact=ds.ContactPair(slave=MOD.UPPER_ARC, master=MOD.LOWER_ARC),
        dirichlet={MOD.LOWER_FLAT: (0.0, 0.0), MOD.UPPER_FLAT: (0.0, -PRESS)}, E=E, nu=NU,
        cell_tags=cells, friction=law, boundary_projection=MOD.projections(R, R))
        for law in (None, ds.Coulomb(0.0))]
    for problems in (block, discs):
        forces, lams = [], []
        for problem in problems:
            with ds.solve(problem) as sol:
                force = ds.estimate(sol, lambda u, lam, m: lam * m.ds_contact,
                                    weights="patch").J_h
                forces.append(force)
                lams.append(sol.lam.x.array.copy())
        assert forces[0] > 0.0
        assert abs(forces[1] - forces[0]) <= 1e-10 * forces[0]
        scale = COMM.allreduce(np.abs(lams[0]).max(initial=0.0), op=MPI.MAX)
        assert np.abs(lams[1] - lams[0]).max(initial=0.0) <= 1e-10 * scale
