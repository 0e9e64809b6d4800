"""Tresca friction (dwr_signorini.laws) against independent truth.

* s -> 0 is the frictionless problem; s huge under a tangential load sticks (T u = 0);
* patch tests exact to round-off: a block pressed onto a rigid plane and sheared by a prescribed
  top displacement, below the threshold (full stick, lambda_t = mu delta, u_t = 0) and above it
  (full slip, lambda_t = s, the rigid slip a = delta - s / mu that statics gives);
* the discrete problem against its dual, a bound-constrained quadratic programme in (lambda_n,
  lambda_t), solved by L-BFGS-B with a sparse factorisation of K (another method, same discrete
  problem);
* the dual solution: adjoint consistency for a linear goal and the derivative of J with respect
  to a load against finite differences of re-solved problems;
* the estimate of the friction force against a reference from J_h alone on an adaptive run;
* bad input, named.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

from .friction_cases import BOTTOM, SIDES, TOP, block_tags
from .helpers import (
    check_frictionless_limit,
    dual_against_finite_differences,
    example_variant,
    global_max,
    global_sum,
    linear_friction_goal,
    with_body_force,
)

COMM = MPI.COMM_WORLD
E, NU = 10.0, 0.3
MU = E / (2 * (1 + NU))
LMBDA = E * NU / ((1 + NU) * (1 - 2 * NU))
PRESS, SHEAR = 0.01, 0.02
LEFT, RIGHT = SIDES[:2]


def patch_problem(s, comm=COMM, n=6, cell_type=mesh.CellType.triangle, law=None):
    """The unit square on a rigid plane y = 0, its top displaced by (SHEAR, -PRESS).

    The exact solution is linear: u = (a + (SHEAR - a) y, -PRESS y) with the rigid slip a = 0
    (stick) when mu SHEAR < s, else a = SHEAR - s / mu (slip): sigma_xy = mu (SHEAR - a),
    sigma_yy = -(lambda + 2 mu) PRESS, sigma_xx = -lambda PRESS (plane strain), which the sides
    carry as tractions. On Gamma_C (n = (0, -1), t = (1, 0)): lambda_n = (lambda + 2 mu) PRESS,
    lambda_t = sigma_xy. ``law`` replaces Tresca(s) by a law whose threshold on this problem
    is s (Coulomb(s / lambda_n)).
    """
    msh = mesh.create_unit_square(comm, n, n, cell_type, ghost_mode=mesh.GhostMode.none)
    a = 0.0 if MU * SHEAR < s else SHEAR - s / MU
    sxx, sxy = -LMBDA * PRESS, MU * (SHEAR - a)
    problem = ds.SignoriniProblem(
        msh, block_tags(msh, height=1.0), contact=BOTTOM, dirichlet={TOP: (SHEAR, -PRESS)},
        E=E, nu=NU, traction={RIGHT: (sxx, sxy), LEFT: (-sxx, -sxy)}, gap=0.0,
        friction=ds.Tresca(s) if law is None else law,
    )
    return problem, a, sxy


def _bottom_displacement(sol):
    """u at the fine vertices on y = 0 (owned and ghost), as an (n, 2) array."""
    V = sol.disc.V
    x = V.tabulate_dof_coordinates()
    on = np.isclose(x[:, 1], 0.0)
    return sol.u.x.array.reshape(-1, 2)[on]


# --------------------------------------------------------------------------------------------------
# Limits and patch tests
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_tiny_threshold_is_frictionless():
    """s = 1e-12: the solution is the frictionless one to 1e-8 (relative, max norm)."""
    tresca = ex.friction_problem(COMM, s=1e-12)
    free = example_variant(tresca, gap=ex.friction_gap(ex.FRICTION_DEFAULTS["radius"]))
    check_frictionless_limit(tresca, free)


@pytest.mark.mpi
def test_huge_threshold_under_a_tangential_load_sticks():
    """s = 1e8 and the top moved sideways only: the contact boundary does not slip,
    (T u)_i = int_E_i u_t = 0 on every macro contact facet to round-off."""
    msh = mesh.create_unit_square(COMM, 6, 6, ghost_mode=mesh.GhostMode.none)
    problem = ds.SignoriniProblem(
        msh, block_tags(msh, height=1.0), contact=BOTTOM, dirichlet={TOP: (SHEAR, 0.0)},
        E=E, nu=NU, gap=0.0, friction=ds.Tresca(1e8),
    )
    with ds.solve(problem) as sol:
        alg = sol.system.algebra
        _, T_u = alg.components_of(alg.gap_residual(sol.u.x.petsc_vec))  # (T u - 0)
        assert sol.num_slip == 0
        assert global_max(T_u) <= 1e-12 * SHEAR
        assert global_max(sol.lam_t.x.array) > 1e-3  # it is held by friction


@pytest.mark.mpi
@pytest.mark.parametrize("cell_type", [mesh.CellType.triangle, mesh.CellType.quadrilateral],
                         ids=["tri", "quad"])
@pytest.mark.parametrize("s", [1.0, 0.05], ids=["stick", "slip"])
@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_patch_test_is_exact(s, cell_type, law):
    """Full stick (mu SHEAR = 0.077 < s = 1) and full slip (s = 0.05): lambda_n, lambda_t and
    u on Gamma_C are the exact ones to round-off, the friction force's estimate is round-off.
    With Coulomb's law the threshold is mu_f lambda_n, mu_f = s / lambda_n: the same solution
    (its normal and tangential rows coupled on the slipping facets)."""
    lam_n = (LMBDA + 2 * MU) * PRESS
    coulomb = ds.Coulomb(s / lam_n) if law == "coulomb" else None
    problem, a, sxy = patch_problem(s, cell_type=cell_type, law=coulomb)
    with ds.solve(problem) as sol:
        n_contact = sol.disc.num_contact_elements
        assert sol.num_active == n_contact
        assert (sol.num_stick, sol.num_slip) == ((n_contact, 0) if a == 0 else (0, n_contact))
        assert global_max(sol.lam.x.array - lam_n) <= 1e-12 * lam_n
        assert global_max(sol.lam_t.x.array - sxy) <= 1e-12 * sxy
        bottom = _bottom_displacement(sol)
        assert np.allclose(bottom[:, 0], a, rtol=0.0, atol=1e-14)
        assert np.allclose(bottom[:, 1], 0.0, rtol=0.0, atol=1e-14)
        with ds.estimate(sol, ex.goal_friction_force()) as est:
            assert est.J_h == pytest.approx(sxy, rel=1e-12)  # |Gamma_C| = 1
            assert abs(est.eta) <= 1e-12 * sxy and abs(est.eta_p) <= 1e-12 * sxy
            low, high = est.interval
            assert low <= sxy * (1 + 1e-12) and high >= sxy * (1 - 1e-12)


# --------------------------------------------------------------------------------------------------
# The discrete problem against its dual quadratic programme (serial: scipy)
# --------------------------------------------------------------------------------------------------


def _scipy(mat):
    import scipy.sparse as sp

    indptr, indices, data = mat.getValuesCSR()
    return sp.csr_matrix((data, indices, indptr), shape=mat.getSize())


@pytest.mark.skipif(COMM.size > 1, reason="the reference QP is assembled with scipy, serially")
def test_discrete_problem_equals_its_dual_qp_by_lbfgsb():
    """The frictional problem is min 1/2 u.Ku - f.u + sum_i s_i |(T u)_i| subject to N u <= g;
    its dual is min 1/2 r.K^-1 r + lam_n.g, r = f - N^T lam_n - T^T lam_t, under lam_n >= 0,
    |lam_t,i| <= s. L-BFGS-B on that dual (a sparse LU of K for K^-1) gives the multipliers of
    the Newton solution to 1e-6, with facets below the threshold and at it."""
    from scipy.optimize import minimize
    from scipy.sparse.linalg import splu

    s = 0.05
    with ds.solve(ex.friction_problem(COMM, nx=9, ny=4, s=s)) as sol:
        alg = sol.system.algebra
        stick = alg.components_of(sol.system.active)[1]
        assert stick.any() and not stick.all()  # facets at the threshold and below it
        K = splu(_scipy(alg.K).tocsc())
        B = _scipy(alg.N)  # [N; T], the components' rows stacked
        f, g, n = alg.f.array.copy(), alg.g.array.copy(), alg.n_q
        bound = alg.bounds[1] / alg.M.array[n:]  # the facet means of s

        def dual(lam):
            w = K.solve(f - B.T @ lam)
            value = 0.5 * (f - B.T @ lam) @ w + lam[:n] @ g[:n]
            grad = -(B @ w) + np.concatenate([g[:n], np.zeros(n)])
            return value, grad

        bounds = [(0.0, None)] * n + [(-b, b) for b in bound]
        res = minimize(dual, np.zeros(2 * n), jac=True, method="L-BFGS-B", bounds=bounds,
                       options={"ftol": 1e-15, "gtol": 1e-13, "maxiter": 10000})
        newton = sol.stacked()
        assert np.max(np.abs(res.x - newton)) <= 1e-6 * np.max(np.abs(newton)), res.message
        assert np.allclose(bound, s)


# --------------------------------------------------------------------------------------------------
# The dual solution
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_adjoint_consistency_for_a_linear_goal():
    """With the final sets the primal map is linear, A w_h = F with F = [f; -c g on the
    constrained rows; M free on the free rows]; the dual solves A^T z_h = J', so for a linear
    goal J(w_h) = z_h . F to round-off, each part of F contributing."""
    with ds.solve(ex.friction_problem(COMM)) as sol, ds.estimate(sol, linear_friction_goal) as est:
        assert est.goal_is_linear and sol.num_stick > 0 and sol.num_slip > 0
        s = sol.system
        constrained = s.active
        F_lam = np.where(constrained, -s.c_n * s.g.array, s.M.array * s.free)
        y = est.dual.y.x.array[: s.n_u]
        xi = sol.stacked(est.dual.multipliers)
        parts = [global_sum(y @ s.f.array), global_sum(xi @ F_lam)]
        assert sum(parts) == pytest.approx(est.J_h, rel=1e-10, abs=0.0)
        n = s.algebra.n_q
        slip_part = global_sum(xi[n:] @ F_lam[n:])
        assert abs(slip_part) > 1e-3 * abs(est.J_h)  # the slip rows' right-hand side counts


@pytest.mark.mpi
def test_dual_is_the_derivative_of_J_against_finite_differences():
    """d/de J(w_h(e)) for the body force (e, 0) at e = 0, by central differences of re-solved
    problems (whose sets do not change), equals z_h . [int e_x . v; 0]."""
    goal = ex.goal_friction_force()

    def solve(eps):
        return ds.solve(with_body_force(ex.friction_problem(COMM), (eps, 0.0)))

    def same_sets(other, sol):
        assert np.array_equal(other.system.active, sol.system.active)
        assert np.array_equal(np.sign(other.system.free), np.sign(sol.system.free))

    predicted, fd = dual_against_finite_differences(solve, goal, lambda v: v[0], same_sets)
    assert abs(predicted) > 1e-3
    assert fd == pytest.approx(predicted, rel=1e-6)


# --------------------------------------------------------------------------------------------------
# The estimate of the friction force
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_effectivity_of_the_friction_force_estimate():
    """An adaptive run for the total friction force: a reference from J_h alone (the finest
    of 9 levels, its uncertainty the change from the level before); Ieff of eta in [1/3, 3] on
    every level the reference can judge (error >= 10 x its uncertainty), and the interval
    contains the reference on those levels."""
    with ds.solve_adaptive(ex.friction_problem(COMM), ex.goal_friction_force(), max_levels=9,
                           verbose=False) as res:
        levels = res.levels
    reference, uncertainty = levels[-1].J_h, abs(levels[-1].J_h - levels[-2].J_h)
    judged = [r for r in levels[:-2] if abs(reference - r.J_h) >= 10 * uncertainty]
    assert len(judged) >= 4, [r.J_h for r in levels]
    for r in judged:
        ieff = (reference - r.J_h) / r.eta
        assert 1 / 3 <= ieff <= 3, (r.level, ieff)
        assert r.J_low - uncertainty <= reference <= r.J_high + uncertainty, r.level
    assert all(r.num_stick > 0 and r.num_slip > 0 for r in levels)


# --------------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("s", "error", "match"),
    [
        (0.0, ValueError, "finite number > 0"),
        (-1.0, ValueError, "finite number > 0"),
        (float("nan"), ValueError, "finite number > 0"),
        (float("inf"), ValueError, "finite number > 0"),
        ("0.1", TypeError, "s must be a number"),
        (True, TypeError, "s must be a number"),
        ({}, ValueError, "empty dict"),
        ({"a": 1.0}, TypeError, "integer contact tags"),
        ({3: -1.0}, ValueError, r"Tresca\(s\)\[3\]"),
    ],
)
def test_bad_threshold_is_rejected(s, error, match):
    with pytest.raises(error, match=match):
        ds.Tresca(s)


def test_bad_friction_arguments_are_rejected():
    base = ex.friction_problem(MPI.COMM_SELF, nx=5, ny=3)

    def make(friction):
        return ds.SignoriniProblem(
            base.mesh, base.facet_tags, contact=ex.CONTACT, dirichlet=base.dirichlet_values,
            gap=0.0, friction=friction,
        )

    with pytest.raises(ValueError, match="not contact tags"):
        make(ds.Tresca({ex.CONTACT: 1.0, ex.NEUMANN: 1.0}))
    with pytest.raises(TypeError, match="friction must be None"):
        make(0.3)
    with pytest.raises(TypeError, match=r"Tresca\(s\)"):
        make(ds.Tresca(lambda x: np.sin(x[0])))  # numpy, not UFL
    assert make(None).friction is None and make(ds.Frictionless()).friction is None


def test_four_argument_goal_on_a_frictionless_problem_is_rejected():
    base = ex.friction_problem(MPI.COMM_SELF, nx=5, ny=3)
    problem = ds.SignoriniProblem(
        base.mesh, base.facet_tags, contact=ex.CONTACT, dirichlet=base.dirichlet_values,
        gap=base.gap,
    )
    with ds.solve(problem) as sol:
        with pytest.raises(ValueError, match="frictionless"):
            ds.estimate(sol, ex.goal_friction_force())


def test_three_argument_goal_serves_a_frictional_problem():
    """A goal without lam_t works with friction (its derivative in lam_t is zero)."""
    with ds.solve(ex.friction_problem(MPI.COMM_SELF, nx=5, ny=3)) as sol:
        with ds.estimate(sol, lambda u, lam, m: lam * m.ds_contact) as est:
            assert est.J_h > 0
            assert est.dual.xi_t is not None


# --------------------------------------------------------------------------------------------------
# Units and data given in other forms
# --------------------------------------------------------------------------------------------------


def _scaled(comm, s_L=1.0, s_E=1.0, s=None, nx=17, ny=7):
    """The friction demo's problem with lengths scaled by s_L and stresses by s_E."""
    d = ex.FRICTION_DEFAULTS
    msh = mesh.create_rectangle(comm, [(0.0, 0.0), (s_L, 0.5 * s_L)], [nx, ny],
                                mesh.CellType.triangle, ghost_mode=mesh.GhostMode.none)


    def gap(x):
        return s_L * (x[0] / s_L - 0.5) ** 2 / (2.0 * d["radius"])

    return ds.SignoriniProblem(
        msh, ex.tag_block_facets(msh, 0.5 * s_L), contact=ex.CONTACT,
        dirichlet={ex.DIRICHLET: (d["shear"] * s_L, -d["press"] * s_L)}, E=10.0 * s_E, nu=0.3,
        gap=gap, friction=ds.Tresca(d["s"] * s_E if s is None else s),
    )


@pytest.mark.mpi
def test_estimate_is_invariant_under_a_change_of_units():
    """Lengths x 1e-3, stresses x 1e6: the friction force, eta_p, eta and the contact term
    scale by s_E s_L to 1e-8 (c = E / H keeps lambda + c u a stress in any units)."""
    s_L, s_E = 1e-3, 1e6
    values = []
    for scale in ((1.0, 1.0), (s_L, s_E)):
        with ds.solve(_scaled(COMM, *scale)) as sol:
            with ds.estimate(sol, ex.goal_friction_force()) as est:
                values.append({k: getattr(est, k) for k in ("J_h", "eta_p", "eta",
                                                             "contact_term")})
                values[-1]["sets"] = (sol.num_active, sol.num_stick, sol.num_slip)
    ref, other = values
    assert ref.pop("sets") == other.pop("sets")
    for key, value in ref.items():
        assert other[key] / (s_L * s_E) == pytest.approx(
            value, rel=1e-8, abs=1e-8 * abs(ref["eta"])), key


@pytest.mark.mpi
def test_threshold_as_a_callable_or_per_tag_is_the_number():
    """s as a constant callable of x, or as {contact tag: s}: the same solution as the number."""
    s = ex.FRICTION_DEFAULTS["s"]
    results = []
    for data in (s, lambda x: s + 0.0 * x[0], {ex.CONTACT: s}):
        with ds.solve(_scaled(COMM, s=data)) as sol:
            results.append((sol.u.x.array.copy(), sol.lam_t.x.array.copy()))
    for u, lam_t in results[1:]:
        assert global_max(u - results[0][0]) <= 1e-12 * global_max(results[0][0])
        assert global_max(lam_t - results[0][1]) <= 1e-12 * global_max(results[0][1])


@pytest.mark.mpi
def test_threshold_per_contact_tag():
    """Gamma_C in two tags (x < 1/2, x > 1/2) with s = 0.05 and 0.03: |lambda_t| <= s of its tag on
    every macro contact facet, = s on the slipping ones, both thresholds reached somewhere."""
    base = _scaled(COMM)
    tags = base.facet_tags
    msh = base.mesh
    mids = mesh.compute_midpoints(msh, 1, tags.indices)
    values = tags.values.copy()
    values[(values == ex.CONTACT) & (mids[:, 0] > 0.5)] = 6
    split = mesh.meshtags(msh, 1, tags.indices, values)
    s = {ex.CONTACT: 0.05, 6: 0.03}
    problem = ds.SignoriniProblem(
        msh, split, contact=(ex.CONTACT, 6), dirichlet=base.dirichlet_values, E=10.0, nu=0.3,
        gap=base.gap, friction=ds.Tresca(s),
    )
    with ds.solve(problem) as sol:
        n = sol.system.algebra.n_q
        x = mesh.compute_midpoints(sol.disc.macro_mesh, 1, sol.disc.contact_mesh_to_macro)
        dofs = sol.disc.Q.dofmap.list[: len(x), 0]
        owned = dofs < n
        bound = np.where(x[owned, 0] > 0.5, 0.03, 0.05)
        lam_t = np.abs(sol.lam_t.x.array[dofs[owned]])
        slip = ~sol.system.algebra.components_of(sol.system.active)[1][dofs[owned]]
        assert np.all(lam_t <= bound * (1 + 1e-12))
        assert np.allclose(lam_t[slip], bound[slip], rtol=1e-12)
        reached = [COMM.allreduce(bool(np.any(slip & (bound == b))), op=MPI.LOR)
                   for b in (0.05, 0.03)]
        assert all(reached), reached
