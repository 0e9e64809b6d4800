"""Bodies held only by contact, solved from zero (issue 58, item 1; :mod:`dwr_signorini.rigid`).

Where the Dirichlet conditions leave a rigid motion free, only the contact holds the body and
the Newton matrix of a set that leaves the motion free is singular; the Newton method completes
such a set (springs c_n on the facets the free motion reaches) and the solution is that of the
discrete problem. Truths:

- the mixed face of issue 48 (``tests/test_mixed_face.py``): the exact uniform state, from zero;
- a free body's equilibrium: the free rigid motion z has K z = 0, so the contact force balances
  the load on it exactly, int lambda_H (-n . e_y) = the load's resultant, to round-off, on every
  level of ``solve_adaptive`` and every step of ``solve_path``;
- the same discrete solution as the documented workaround (all facets active first), a different
  iteration path to the unique discrete solution;
- the last Newton matrix is the discrete problem's: for a linear goal J(w_h) = z_h . F;
- a body that no contact can hold raises a ValueError naming the motion and the tags.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import obstacles as ob

from .helpers import global_max, global_sum, integrate
from .problems import from_model, mesh_script
from .test_mixed_face import BOTTOM, TOP, D, E, P, block

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD


def pressed_disc(p=0.01, h_contact=0.02):
    """The quarter disc of ``meshes/hertz_2d.py`` (R = 1) pressed onto a flat by a traction p on
    its top (width 1): held along x by its symmetry plane, vertically only by the contact."""
    module = mesh_script("hertz_2d")
    msh, cells, facets = from_model(module.build, h=0.2, h_contact=h_contact, refine_radius=0.1)
    return ds.SignoriniProblem(
        msh, facets, contact=module.CONTACT, dirichlet={module.SYMMETRY: (0.0, None)},
        traction={module.TOP: (0.0, -p)}, E=1.0, nu=0.3, cell_tags=cells,
        gap=ob.Plane((0.0, 0.0), (0.0, -1.0)),
    )


def contact_force(sol, axis=1):
    """The contact force along -e_axis, int lambda_H (-n . e_axis) over Gamma_C (global)."""
    m = sol.disc.m
    return integrate(sol, -sol.lam * sol.disc.contact_frame()[axis] * m.ds_contact)


def test_mixed_face_from_zero():
    """The mixed face's exact uniform state u = (d, -p y / E), lambda = p, from zero in 1 step."""
    with ds.solve(block(COMM)) as sol:
        x = sol.u.function_space.tabulate_dof_coordinates()
        u = sol.u.x.array.reshape(-1, 2)
        exact = np.stack([np.full(len(x), D), -P * x[:, 1] / E], axis=1)
        assert global_max(np.abs(u - exact)) <= 1e-10 * max(D, P / E)
        assert global_max(np.abs(sol.lam.x.array - P)) <= 1e-10 * P
        assert sol.newton_iterations == 1
        assert sol.history[0]["held"] == sol.num_active > 0


def test_disc_from_zero_is_the_discrete_solution():
    """The pressed disc from zero: the contact force balances the load (p times the top's width
    1) to round-off, and the solution is the one the workaround (lam0 = 1) reaches."""
    p = 0.01
    disc = ds.discretize(pressed_disc(p))
    lam0 = fem.Function(disc.Q)
    lam0.x.array[:] = 1.0
    with ds.solve(disc) as sol, ds.solve(disc, initial_guess=(fem.Function(disc.V), lam0)) as ref:
        assert contact_force(sol) == pytest.approx(p, rel=1e-10)
        assert global_max(np.abs(sol.u.x.array - ref.u.x.array)) <= 1e-10 * global_max(
            np.abs(ref.u.x.array))
        assert global_max(np.abs(sol.lam.x.array - ref.lam.x.array)) <= 1e-10 * global_max(
            ref.lam.x.array)
        assert sol.newton_iterations <= 4 and sol.num_active > 1


def test_disc_dual_is_that_of_the_discrete_problem():
    """A linear goal J = int lambda + int u_y: J(w_h) = z_h . F with the final set (the last
    Newton matrix is the discrete problem's, no regularisation left in it)."""

    def goal(u, lam, m):
        return lam * m.ds_contact + u[1] * m.dx

    with ds.solve(pressed_disc()) as sol, ds.estimate(sol, goal, estimator="eta_p") as est:
        s = sol.system
        J = integrate(sol, goal(sol.u, sol.lam, sol.disc.m))
        F_lam = np.where(sol.active, -s.c_n * s.g.array, 0.0)
        y, xi = est.dual.y.x.array[: s.n_u], est.dual.xi.x.array[: s.n_lam]
        assert global_sum(y @ s.f.array + xi @ F_lam) == pytest.approx(J, rel=1e-10)


def test_sphere_from_zero():
    """The quarter hemisphere of ``meshes/hertz_3d.py`` (R = 1) pressed by a traction p on its
    quarter-disc top (area about pi / 4), held only vertically by the contact: the force
    balances."""
    module = mesh_script("hertz_3d")
    msh, cells, facets = from_model(module.build, h=0.3, h_contact=0.06, refine_radius=0.2)
    p = 0.002
    problem = ds.SignoriniProblem(
        msh, facets, contact=module.CONTACT, model="3d", E=1.0, nu=0.3, cell_tags=cells,
        dirichlet={module.SYMMETRY_X: (0.0, None, None), module.SYMMETRY_Y: (None, 0.0, None)},
        traction={module.TOP: (0.0, 0.0, -p)}, gap=ob.Plane((0.0, 0.0, 0.0), (0.0, 0.0, -1.0)),
    )
    with ds.solve(problem) as sol:
        top = integrate(sol, ufl.as_ufl(1.0) * sol.disc.m.ds(module.TOP))  # the polygon's area
        assert top == pytest.approx(np.pi / 4, rel=0.01)
        assert contact_force(sol, axis=2) == pytest.approx(p * top, rel=1e-10)
        assert sol.num_active > 1 and sol.newton_iterations <= 6


def test_disc_pressed_on_a_disc_from_zero():
    """Two quarter discs (``meshes/hertz_cylinders_2d.py``, ContactPair), the lower clamped at
    its flat, the upper (R = 1.5) pressed by a traction p on its flat: the force on the slave is
    1.5 p."""
    m = mesh_script("hertz_cylinders_2d")
    msh, cells, facets = from_model(m.build, h=0.3, h_contact=0.03, refine_radius=0.15)
    p = 0.01
    problem = ds.SignoriniProblem(
        msh, facets, contact=ds.ContactPair(slave=m.UPPER_ARC, master=m.LOWER_ARC),
        dirichlet={m.LOWER_FLAT: (0.0, 0.0), m.LOWER_SYMMETRY: (0.0, None),
                   m.UPPER_SYMMETRY: (0.0, None)},
        traction={m.UPPER_FLAT: (0.0, -p)}, E=1.0, nu=0.3, cell_tags=cells,
    )
    with ds.solve(problem) as sol:
        assert contact_force(sol) == pytest.approx(1.5 * p, rel=1e-10)
        assert sol.num_active > 1


def test_adaptive_and_path_from_zero():
    """``solve_adaptive`` and ``solve_path`` from zero: every level's and step's J_h, the
    contact force, is the load's resultant."""

    def force(u, lam, m):  # lambda acts along the flat's normal (0, -1)
        return lam * m.ds_contact

    p = 0.01
    with ds.solve_adaptive(pressed_disc(p), force, max_levels=2, verbose=False) as res:
        assert len(res.levels) == 2
        for r in res.levels:
            assert r.J_h == pytest.approx(p, rel=1e-10)
    first = block(COMM, p=P / 2)
    steps = [first, block(COMM, on=first)]
    with ds.solve_path(steps, force, verbose=False) as res:
        assert [r.J_h for r in res.steps] == pytest.approx([P / 2, P], rel=1e-10)


def test_pulled_away_raises_naming_the_motion():
    with pytest.raises(ValueError, match=r"pull|away") as info:
        ds.solve(pressed_disc(p=-0.01))
    message = str(info.value)
    assert "translation along (0, 1)" in message and "contact tags [1]" in message


def test_motion_no_contact_can_hold_raises():
    """Top prescribed only vertically: the block may slide along the frictionless flat."""
    with pytest.raises(ValueError, match="no contact facet can hold it") as info:
        ds.solve(block(COMM, p=0.0, dirichlet={TOP: (None, -0.01)}))
    assert "translation along (1, 0)" in str(info.value)
    assert f"contact tags [{BOTTOM}]" in str(info.value)


def test_hertz_disc_pressed_on_a_body_of_the_same_material():
    """asimov-contact's data, the disc on an elastic body of the same material under a given
    force, from zero: the quarter disc R = 8 of ``meshes/hertz_cylinders_2d.py`` pressed by
    P / 2 = 5 (P = 10 per unit length) on its flat, held vertically only by the contact, on the
    lower quarter disc of radius 200 (nearly a flat block, 25 times the disc's size), E = 200,
    nu = 0.3. Hertz: 1 / E* = 2 (1 - nu^2) / E, 1 / R = 1 / 8 + 1 / 200, a = sqrt(4 P R / (pi E*)),
    p0 = 2 P / (pi a). Measured (contact facets of 0.05): a +0.08 %, p0 +0.41 %, 10 steps."""
    R, R_lower, E, nu, P = 8.0, 200.0, 200.0, 0.3, 10.0
    m = mesh_script("hertz_cylinders_2d")
    msh, cells, facets = from_model(m.build, r_lower=R_lower, r_upper=R, h=4.0, h_contact=0.05,
                                    refine_radius=0.15)
    problem = ds.SignoriniProblem(
        msh, facets, contact=ds.ContactPair(slave=m.UPPER_ARC, master=m.LOWER_ARC),
        dirichlet={m.LOWER_FLAT: (0.0, 0.0), m.LOWER_SYMMETRY: (0.0, None),
                   m.UPPER_SYMMETRY: (0.0, None)},
        traction={m.UPPER_FLAT: (0.0, -P / 2 / R)}, E=E, nu=nu, cell_tags=cells,
        boundary_projection=m.projections(R_lower, R),
    )
    with ds.solve(problem) as sol:
        assert 2 * contact_force(sol) == pytest.approx(P, rel=1e-10)
        chi = ufl.conditional(ufl.gt(sol.lam, 0.0), 1.0, 0.0)
        a_h = integrate(sol, chi * sol.disc.m.ds_contact)
        p_h = global_max(sol.lam.x.array)
    E_star = E / (2 * (1 - nu**2))
    a = math.sqrt(4 * P / (1 / R + 1 / R_lower) / (math.pi * E_star))
    assert a_h == pytest.approx(a, rel=0.015)
    assert p_h == pytest.approx(2 * P / (math.pi * a), rel=0.015)
