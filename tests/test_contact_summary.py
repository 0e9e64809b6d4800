"""``ds.contact_summary`` against theory (issue 58, item 5).

* A block pressed by a uniform traction p on a rigid flat (nu = 0, its top free to move down):
  the exact solution is uniform, lambda = p, which P0 multipliers contain, so the force is
  p times the area, the mean and peak pressure are p, the centre is the face's centre and the
  second moment that of a uniform pressure (2D: p b^3 2 / 3 for the half-width b; 3D:
  p / 6 on the unit square), to round-off; 2D and 3D. With Tresca's s < the shear the block
  slides: the friction force is -s times the area (against the slip), every facet slips (2D
  and 3D, the sides carrying the uniform shear stress s).
* Hertz (2D, the data of a peer code's demo: R = 8, E = 200, nu = 0.3, a load of 10 per unit
  length): a quarter disc pressed by a traction on its top and held vertically only by the
  contact. The force equals the applied load by equilibrium (to round-off), the radius from the
  moments is Hertz's a within 1.5 % and the peak is p0 within 1.5 % (measured: -1.4 %, +1.2 %:
  the model's own error, a finite body), the contact set's width a within one macro facet.
* Hertz (3D, a quarter ball under a load): the force equals the load on the meshed top to
  round-off, the radius from the moments is Hertz's within 3 % (measured -2.5 %), the radius of
  the contact set's area within one contact facet.
* Cattaneo-Mindlin (2D): the stick zone's extent is 2 c = 2 a sqrt(1 - Q / (mu P)) within one
  macro facet at each end, for the P and Q the summary reports.
* Every number is the same on every rank and the same serially and on 2 ranks (the block).
"""

import math

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini import obstacles as ob
from tests.helpers import integrate
from tests.problems import from_model, mesh_script, tag_by_midpoint

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD
BOTTOM, SIDES, TOP = 1, 2, 4
E, P, D, S = 10.0, 0.3, 0.05, 0.1


def _tags(msh, top):
    """BOTTOM at height 0, TOP at ``top``, SIDES elsewhere (height: the last coordinate)."""
    up = msh.geometry.dim - 1
    return tag_by_midpoint(msh, SIDES, ((BOTTOM, lambda x: np.isclose(x[up], 0.0)),
                                        (TOP, lambda x: np.isclose(x[up], top))))


def pressed_block(dim, friction=None):
    """The block (2 x 1 in 2D, the unit cube in 3D) on the plane y = 0 (z = 0), pressed by p."""
    if dim == 2:
        msh = mesh.create_rectangle(COMM, [(0.0, 0.0), (2.0, 1.0)], [6, 3],
                                    ghost_mode=mesh.GhostMode.none)
        # sheared by d along x where friction acts (the mixed face of test_mixed_face)
        top = (D, None) if friction is not None else (0.0, None)
        # the sliding block carries the shear stress s: sigma n on its sides
        load = {TOP: (0.0, -P), **({SIDES: side_shear} if friction is not None else {})}
    else:
        msh = mesh.create_unit_cube(COMM, 3, 3, 3, ghost_mode=mesh.GhostMode.none)
        top = (D, 0.0, None) if friction is not None else (0.0, 0.0, None)
        load = {TOP: (0.0, 0.0, -P), **({SIDES: side_shear_3d} if friction is not None else {})}
    problem = ds.SignoriniProblem(
        msh, _tags(msh, 1.0), contact=BOTTOM, dirichlet={TOP: top}, E=E, nu=0.0,
        traction=load, gap=0.0, friction=friction,
    )
    disc = ds.discretize(problem)
    guess = [fem.Function(disc.Q) for _ in sol_components(problem)]
    guess[0].x.array[:] = 1.0  # contact active from the start: nothing else holds the block up
    # rtol 1e-12: the 3D slip direction (a nonlinear equation) to round-off, not to 1e-8
    return ds.solve(disc, initial_guess=(fem.Function(disc.V), *guess), rtol=1e-12)


def side_shear(x):
    """sigma n = (0, -+s) on the sides x = 0 and x = 2 of the sliding block (sigma_xy = s)."""
    return ufl.as_vector((0.0, ufl.conditional(ufl.lt(x[0], 1.0), -S, S)))


def side_shear_3d(x):
    """sigma n = (0, 0, -+s) on the sides x = 0 and x = 1 of the sliding cube, 0 on y = 0, 1."""
    shear = ufl.conditional(ufl.lt(x[0], 1e-8), -S, ufl.conditional(ufl.gt(x[0], 1 - 1e-8), S,
                                                                    0.0))
    return ufl.as_vector((0.0, 0.0, shear))


def sol_components(problem):
    return range(1 if problem.friction is None else problem.mesh.geometry.dim)


def same_on_every_rank(summary):
    flat = np.concatenate([np.atleast_1d(np.asarray(v, dtype=float)) for v in
                           vars(summary).values() if v is not None])
    assert all(np.array_equal(flat, other) for other in COMM.allgather(flat))


@pytest.mark.parametrize("dim", [2, 3])
def test_uniformly_pressed_block(dim):
    with pressed_block(dim) as sol:
        s = ds.contact_summary(sol)
    area = 2.0 if dim == 2 else 1.0
    up = np.zeros(dim)
    up[-1] = 1.0
    assert np.allclose(s.force, P * area * up, rtol=0, atol=1e-12)
    assert s.normal_force == pytest.approx(P * area, rel=1e-12)
    assert s.area == pytest.approx(area, rel=1e-12)
    assert s.mean_pressure == pytest.approx(P, rel=1e-12)
    assert s.peak_pressure == pytest.approx(P, rel=1e-12)
    centre = np.full(dim, 0.5)
    centre[0] = 1.0 if dim == 2 else 0.5
    centre[-1] = 0.0
    assert np.allclose(s.centre, centre, atol=1e-12)
    if dim == 2:  # int_{-1}^{1} p x^2 dx = 2 p / 3; uniform: a = 2 b / sqrt(3), b = 1
        assert s.second_moment == pytest.approx(2 * P / 3, rel=1e-12)
        assert s.radius == pytest.approx(2 / math.sqrt(3), rel=1e-12)
    else:  # the unit square: int p (x^2 + y^2) = p / 6; a = sqrt(5 M2 / (2 P)) = sqrt(5 / 12)
        assert s.second_moment == pytest.approx(P / 6, rel=1e-12)
        assert s.radius == pytest.approx(math.sqrt(5 / 12), rel=1e-12)
    assert s.friction_force is None and s.stick_area is None and s.slip_area is None
    same_on_every_rank(s)


@pytest.mark.parametrize("dim", [2, 3])
def test_sliding_block_friction_force(dim):
    """Tresca's s < the shear: the block slides in +x, friction -s per unit area, all slip."""
    with pressed_block(dim, ds.Tresca(S)) as sol:
        s = ds.contact_summary(sol)
    area = 2.0 if dim == 2 else 1.0
    friction = np.zeros(dim)
    friction[0] = -S * area
    assert np.allclose(s.friction_force, friction, atol=1e-12)
    assert np.allclose(s.force, friction + np.eye(dim)[-1] * P * area, atol=1e-12)
    assert s.slip_area == pytest.approx(area, rel=1e-12)
    assert s.stick_area == 0.0
    same_on_every_rank(s)


HERTZ = mesh_script("hertz_2d")
R, E_H, NU_H, LOAD = 8.0, 200.0, 0.3, 10.0  # LOAD per unit length, of the whole cylinder
H_CONTACT = 0.01 * R


def test_hertz_cylinder_under_a_load():
    msh, cells, facets = from_model(HERTZ.build, radius=R, h=0.25 * R, h_contact=H_CONTACT,
                                    refine_radius=0.15)
    q = LOAD / (2 * R)  # on the top of the quarter disc (width R), half the load
    problem = ds.SignoriniProblem(
        msh, facets, contact=HERTZ.CONTACT, dirichlet={HERTZ.SYMMETRY: (0.0, None)},
        traction={HERTZ.TOP: (0.0, -q)}, E=E_H, nu=NU_H, gap=ob.Plane((0.0, 0.0), (0.0, -1.0)),
        cell_tags=cells,
    )
    disc = ds.discretize(problem)
    lam0 = fem.Function(disc.Q)
    lam0.x.array[:] = 1.0
    with ds.solve(disc, initial_guess=(fem.Function(disc.V), lam0)) as sol:
        s = ds.contact_summary(sol, centre=(0.0, 0.0))
    a, p0 = cases.hertz_half_width(LOAD, R, E_H, NU_H)
    assert s.force[1] == pytest.approx(LOAD / 2, rel=1e-10)  # equilibrium: the applied load
    assert s.normal_force == pytest.approx(LOAD / 2, rel=2e-3)  # the arc's normals tilt
    assert s.radius == pytest.approx(a, rel=0.015)
    assert s.peak_pressure == pytest.approx(p0, rel=0.015)
    assert abs(s.area - a) <= H_CONTACT  # the half contact, within one macro facet
    same_on_every_rank(s)


HERTZ_3D = mesh_script("hertz_3d")


def test_hertz_ball_under_a_load():
    """The quarter ball (R = 1, E = 1, nu = 0.3) pressed by q on its top, 1/4 of the load 0.01.

    Measured: the radius from the moments -2.5 %, -1.9 %, -1.7 % of Hertz's on contact facets of
    0.03, 0.02, 0.015 (towards the finite ball's own error), the radius of the contact set's
    area -6.1 %, -5.1 %, -4.5 %; the peak +22 %, +50 %, +43 % (the caveat of peak_pressure).
    """
    load, h_contact = 0.01, 0.03
    msh, cells, facets = from_model(HERTZ_3D.build, radius=1.0, h=0.3, h_contact=h_contact,
                                    refine_radius=0.15)
    q = load / np.pi  # on the top disc of radius 1 (of which the quarter carries a quarter)
    problem = ds.SignoriniProblem(
        msh, facets, contact=HERTZ_3D.CONTACT, E=1.0, nu=0.3, cell_tags=cells,
        dirichlet={HERTZ_3D.SYMMETRY_X: (0.0, None, None),
                   HERTZ_3D.SYMMETRY_Y: (None, 0.0, None)},
        traction={HERTZ_3D.TOP: (0.0, 0.0, -q)},
        gap=ob.Plane((0.0, 0.0, 0.0), (0.0, 0.0, -1.0)),
    )
    disc = ds.discretize(problem)
    lam0 = fem.Function(disc.Q)
    lam0.x.array[:] = 1.0
    with ds.solve(disc, initial_guess=(fem.Function(disc.V), lam0)) as sol:
        s = ds.contact_summary(sol, centre=(0.0, 0.0, 0.0))
        applied = integrate(sol, q * disc.m.ds(HERTZ_3D.TOP))  # on the meshed (polygonal) top
    assert s.force[2] == pytest.approx(applied, rel=1e-10)  # equilibrium
    a = (3 * load / (4 / (1 - 0.3**2))) ** (1 / 3)
    assert s.radius == pytest.approx(a, rel=0.03)
    assert abs(math.sqrt(4 * s.area / math.pi) - a) <= h_contact
    same_on_every_rank(s)


def test_cattaneo_mindlin_stick_extent():
    mu = cases.CM_DEFAULTS["mu"]
    summaries = []
    problems = cases.cattaneo_mindlin_path(COMM, h_contact=0.01)
    ds.solve_path(problems, ex.goal_friction_force(), verbose=False, history=False,
                  callback=lambda r, sol, e: summaries.append(ds.contact_summary(sol))).destroy()
    d = cases.CM_DEFAULTS
    for s in summaries[2:]:  # the shear steps with stick and slip zones
        a, _ = cases.hertz_half_width(s.normal_force, d["radius"], d["E"], d["nu"])
        Q = abs(s.friction_force[0])
        c = cases.stick_half_width(a, Q, mu, s.normal_force)
        assert 0.0 < s.slip_area
        assert abs(s.stick_area - 2 * c) <= 2 * 0.01, (s.stick_area, 2 * c)
        assert s.stick_area + s.slip_area == pytest.approx(s.area, rel=1e-12)
        same_on_every_rank(s)
