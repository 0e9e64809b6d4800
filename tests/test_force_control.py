"""A rigid obstacle under a given force (issue 58, item 2; :mod:`dwr_signorini.force`).

``ds.obstacles.Plane(..., force=F)`` / ``Sphere(..., force=F, direction=d)``: the obstacle's rigid
displacement delta along d is an unknown of the discrete problem (a bordered Newton step).
Truths:

- force control = displacement control at the displacement it finds: the obstacle placed at
  delta by hand gives the same J and lambda_H (to 1e-10);
- a flat punch's equilibrium: on a flat contact face the multipliers integrate to F to
  round-off;
- the dual of the bordered system: for a goal linear in (u, lambda) and delta (a goal sees delta
  as ``m.obstacle_displacement``), J(w_h) = z_h . r + zeta F with the final active set (r the
  last step's right-hand side);
- Hertz's line contact under a given force (asimov-contact's data: R = 8, E = 200, nu = 0.3, a
  load of 10 per unit length): half-width and peak pressure within 1.5 %.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import obstacles as ob

from .helpers import global_max, global_sum, integrate
from .problems import block, from_model, make, mesh_script

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD
F = 0.05


def punch(gap):
    """The unit square (8 x 8 macro cells) clamped on top, its flat bottom in contact."""
    msh, tags = block(COMM, 8, 8)
    return make(msh, tags, gap=gap, E=1.0)


def n_c(sol):
    """The normal of the contact frame, along which lambda acts."""
    return sol.disc.contact_frame()


def goal(u, lam, m):
    """A goal linear in (u, lambda)."""
    return lam * m.ds_contact + u[1] * m.dx


@pytest.mark.parametrize(
    ("forced", "placed"),
    [
        (lambda: ob.Plane((0.0, 0.0), (0.0, -1.0), force=F),
         lambda d: ob.Plane((0.0, d), (0.0, -1.0))),
        (lambda: ob.Sphere((0.5, -2.0), 2.0, force=F, direction=(0.0, 1.0)),
         lambda d: ob.Sphere((0.5, -2.0 + d), 2.0)),
    ],
    ids=["plane", "disc"],
)
def test_force_control_is_displacement_control_at_its_displacement(forced, placed):
    msh, tags = block(COMM, 8, 8)
    with ds.solve(make(msh, tags, gap=forced(), E=1.0)) as sol:
        delta = sol.obstacle_displacement
        m = sol.disc.m
        # the contact force on the obstacle against its direction (0, 1) balances F
        assert integrate(sol, -sol.lam * n_c(sol)[1] * m.ds_contact) == pytest.approx(F, rel=1e-12)
        J = integrate(sol, goal(sol.u, sol.lam, m))
        with ds.solve(make(msh, tags, gap=placed(delta), E=1.0)) as ref:
            assert integrate(ref, goal(ref.u, ref.lam, ref.disc.m)) == pytest.approx(J, rel=1e-10)
            scale = global_max(np.abs(ref.lam.x.array))
            assert global_max(np.abs(sol.lam.x.array - ref.lam.x.array)) <= 1e-10 * scale
        assert delta > 0 and sol.num_active > 0


def test_flat_punch_multipliers_integrate_to_the_force():
    with ds.solve(punch(ob.Plane((0.0, -0.01), (0.0, -1.0), force=F))) as sol:
        assert integrate(sol, sol.lam * sol.disc.m.ds_contact) == pytest.approx(F, rel=1e-12)
        assert sol.obstacle_displacement > 0.01  # it closed the gap and pressed
        assert sol.newton_iterations <= 3


def goal_with_delta(u, lam, m):
    """A goal linear in (u, lambda, delta): the obstacle's displacement enters as a Constant."""
    return goal(u, lam, m) + 2.0 * m.obstacle_displacement * m.ds_contact


@pytest.mark.parametrize("J_goal", [goal, goal_with_delta], ids=["u-lam", "u-lam-delta"])
def test_dual_of_the_bordered_system(J_goal):
    """J(w_h) = z_h . r + zeta F for a linear goal, r = [f; -g_hat on A] the last step's
    right-hand side (g_hat = g(delta) - m delta, the plane's gap at delta = 0)."""
    with ds.solve(punch(ob.Plane((0.0, 0.0), (0.0, -1.0), force=F))) as sol, \
            ds.estimate(sol, J_goal, estimator="eta_p", weights="patch") as est:
        s = sol.system
        alg = s.algebra
        g_hat = s.g.array - alg.gap_rate * sol.obstacle_displacement
        F_lam = np.where(sol.active, -s.c_n * g_hat, 0.0)
        y, xi = est.dual.y.x.array[: s.n_u], est.dual.xi.x.array[: s.n_lam]
        zeta = s.force_control.zeta
        J = integrate(sol, J_goal(sol.u, sol.lam, sol.disc.m))
        assert global_sum(y @ s.f.array + xi @ F_lam) + zeta * F == pytest.approx(J, rel=1e-10)
        assert est.J_h == pytest.approx(J, rel=1e-12)
        assert abs(zeta * F) > 1e-3 * abs(J)  # the obstacle's entry contributes


def test_estimate_takes_patch_weights_only():
    with ds.solve(punch(ob.Plane((0.0, 0.0), (0.0, -1.0), force=F))) as sol:
        with pytest.raises(ValueError, match="weights='patch'"):
            ds.estimate(sol, goal, weights="higher_order")


def test_hertz_line_contact_under_a_given_force():
    """The quarter disc of ``meshes/hertz_2d.py`` with R = 8 (top clamped, symmetry x = 0), a
    rigid flat pressed up into it by half of P = 10 per unit length: a = sqrt(4 P R / (pi E*)),
    p0 = 2 P / (pi a). Measured (contact facets of 0.015): a -1.0 %, p0 +0.3 %."""
    R, E, nu, P = 8.0, 200.0, 0.3, 10.0
    module = mesh_script("hertz_2d")
    msh, cells, facets = from_model(module.build, radius=R, h=R / 5, h_contact=0.015,
                                    refine_radius=0.15)
    problem = ds.SignoriniProblem(
        msh, facets, contact=module.CONTACT, E=E, nu=nu, cell_tags=cells,
        dirichlet={module.TOP: (0.0, 0.0), module.SYMMETRY: (0.0, None)},
        gap=ob.Plane((0.0, 0.0), (0.0, -1.0), force=P / 2),
        boundary_projection=module.projections(R),
    )
    with ds.solve(problem) as sol:
        m = sol.disc.m
        assert 2 * integrate(sol, -sol.lam * n_c(sol)[1] * m.ds_contact) == pytest.approx(
            P, rel=1e-12)
        a_h = integrate(sol, ufl.conditional(ufl.gt(sol.lam, 0.0), 1.0, 0.0) * m.ds_contact)
        p_h = global_max(sol.lam.x.array)
    a = math.sqrt(4 * P * R / (math.pi * E / (1 - nu**2)))
    p0 = 2 * P / (math.pi * a)
    assert a_h == pytest.approx(a, rel=0.015)
    assert p_h == pytest.approx(p0, rel=0.015)


def test_bad_force_input():
    with pytest.raises(ValueError, match="needs direction="):
        ob.Sphere((0.0, 0.0), 1.0, force=1.0)
    with pytest.raises(ValueError, match="force must be a finite number > 0"):
        ob.Plane((0.0, 0.0), (0.0, -1.0), force=-1.0)
    with pytest.raises(ValueError, match="direction is the direction of a force"):
        ob.Plane((0.0, 0.0), (0.0, -1.0), direction=(0.0, 1.0))
    with pytest.raises(ValueError, match="method='block'"):
        ds.solve(punch(ob.Plane((0.0, 0.0), (0.0, -1.0), force=F)), method="schur")
    # pushed away from the body: no facet is ever reached
    away = ob.Plane((0.0, -0.01), (0.0, -1.0), force=F, direction=(0.0, -1.0))
    with pytest.raises(ValueError, match="the approach of the obstacle Plane"):
        ds.solve(punch(away))


def test_cylinder_force_control_is_displacement_control():
    """A 3D block clamped on top pressed by a rigid cylinder along x under it, given its force."""
    msh = mesh.create_box(COMM, [(0.0, 0.0, 0.0), (1.0, 1.0, 0.5)], [4, 4, 2],
                          mesh.CellType.tetrahedron, ghost_mode=mesh.GhostMode.none)

    def classify(x):
        tags = np.full(x.shape[1], ex.NEUMANN)
        tags[np.isclose(x[2], 0.5)] = ex.DIRICHLET
        tags[np.isclose(x[2], 0.0)] = ex.CONTACT
        return tags

    tags = ex.tag_exterior_facets(msh, classify)

    def cylinder(lift, **force):
        return ob.Cylinder((0.0, 0.5, -1.0 + lift), (1.0, 0.0, 0.0), 1.0, **force)

    def problem(gap):
        return make(msh, tags, gap=gap, E=1.0, model="3d")

    with ds.solve(problem(cylinder(0.0, force=F, direction=(0.0, 0.0, 1.0)))) as sol:
        m = sol.disc.m
        assert integrate(sol, -sol.lam * n_c(sol)[2] * m.ds_contact) == pytest.approx(F, rel=1e-12)
        with ds.solve(problem(cylinder(sol.obstacle_displacement))) as ref:
            scale = global_max(np.abs(ref.lam.x.array))
            assert global_max(np.abs(sol.lam.x.array - ref.lam.x.array)) <= 1e-10 * scale
            assert sol.num_active == ref.num_active > 0


@pytest.mark.slow
def test_hertz_point_contact_under_a_given_force():
    """The quarter hemisphere of ``meshes/hertz_3d.py`` (R = 1, top clamped, symmetry planes
    x = 0 and y = 0), a rigid flat pressed up into it by a quarter of P = 0.0015:
    a = (3 P R / (4 E*))^(1/3), p0 = 3 P / (2 pi a^2). Measured (contact facets of 0.01, 15 s):
    the radius of the active area -2.2 %, the peak +0.9 % (the peak of lambda_H on a polyhedral
    surface overshoots, the radius is resolved to a facet)."""
    E, nu, P = 1.0, 0.3, 0.0015
    module = mesh_script("hertz_3d")
    msh, cells, facets = from_model(module.build, h=0.3, h_contact=0.01, refine_radius=0.11)
    problem = ds.SignoriniProblem(
        msh, facets, contact=module.CONTACT, E=E, nu=nu, cell_tags=cells,
        dirichlet={module.TOP: (0.0, 0.0, 0.0), module.SYMMETRY_X: (0.0, None, None),
                   module.SYMMETRY_Y: (None, 0.0, None)},
        gap=ob.Plane((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), force=P / 4),
        boundary_projection=module.projections(),
    )
    with ds.solve(problem) as sol:
        m = sol.disc.m
        assert 4 * integrate(sol, -sol.lam * n_c(sol)[2] * m.ds_contact) == pytest.approx(
            P, rel=1e-12)
        area = 4 * integrate(sol, ufl.conditional(ufl.gt(sol.lam, 0.0), 1.0, 0.0) * m.ds_contact)
        p_h = global_max(sol.lam.x.array)
    a = (3 * P / (4 * E / (1 - nu**2))) ** (1 / 3)
    p0 = 3 * P / (2 * math.pi * a**2)
    assert math.sqrt(area / math.pi) == pytest.approx(a, rel=0.03)
    assert p_h == pytest.approx(p0, rel=0.015)


def test_adaptive_levels_carry_the_obstacle_displacement():
    """``solve_adaptive`` (patch weights) under a given force: each level starts from the last
    level's delta, and each level's J_h, the force on the flat punch, is F to round-off."""

    def force(u, lam, m):
        return lam * m.ds_contact

    problem = punch(ob.Plane((0.0, 0.0), (0.0, -1.0), force=F))
    with ds.solve_adaptive(problem, force, max_levels=2, weights="patch", verbose=False) as res:
        assert [r.J_h for r in res.levels] == pytest.approx([F, F], rel=1e-12)
        assert res.levels[1].newton_iterations <= 2


def test_load_path_of_forces():
    """``solve_path`` with the force raised step by step: each step balances its force."""
    msh, tags = block(COMM, 8, 8)
    steps = [make(msh, tags, gap=ob.Plane((0.0, -0.01), (0.0, -1.0), force=f), E=1.0)
             for f in (F / 2, F)]

    def force(u, lam, m):
        return lam * m.ds_contact

    with ds.solve_path(steps, force, weights="patch", verbose=False) as res:
        assert [r.J_h for r in res.steps] == pytest.approx([F / 2, F], rel=1e-12)
