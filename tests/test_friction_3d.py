"""Tresca friction in 3D (the ball projection, coupled Newton rows) against independent truth.

* patch tests exact to round-off: a cube pressed onto a rigid plane and sheared obliquely by a
  prescribed top displacement, below the threshold (full stick) and above it (full slip, the
  traction of magnitude s along the shear and the rigid slip that statics gives);
* s -> 0 is the frictionless problem; s huge under a tangential load sticks (T u = 0);
* the discrete problem against its dual, a quadratic programme over lambda_n >= 0 and the discs
  |lambda_t| <= s, solved by accelerated projected gradients (another method, same problem);
* the dual solution: adjoint consistency for a linear goal, and the derivative of the friction
  force with respect to a load against finite differences of re-solved problems (which sees the
  coupled rows of the slipping facets: a fixed slip direction would give another derivative);
* the estimate's invariance under a change of units; bad input, named.
"""

import itertools

from mpi4py import MPI

import numpy as np
import pytest
import ufl
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
    with_body_force,
)

COMM = MPI.COMM_WORLD
E, NU = 10.0, 0.3
MU = E / (2 * (1 + NU))
LMBDA = E * NU / ((1 + NU) * (1 - 2 * NU))
PRESS = 0.01
SHEAR = np.array([0.012, 0.016])  # oblique to the tangent basis (e_x, -e_y) of the bottom
X0, X1, Y0, Y1 = SIDES


def patch_problem(s, n=4, law=None):
    """The unit cube on a rigid plane z = 0, its top displaced by (SHEAR, -PRESS).

    The exact solution is linear: u = (a + (SHEAR - a) z, -PRESS z) with the rigid slip a = 0
    (stick) when mu |SHEAR| < s, else a = SHEAR - (s / mu) SHEAR / |SHEAR| (slip, the traction
    of magnitude s along the slip): sigma_xz, sigma_yz = mu (SHEAR - a),
    sigma_zz = -(lambda + 2 mu) PRESS, sigma_xx = sigma_yy = -lambda PRESS, which the sides
    carry as tractions. On Gamma_C (n = -e_z): lambda_n = (lambda + 2 mu) PRESS and the
    tangential traction vector lambda_t = (sigma_xz, sigma_yz, 0). ``law`` replaces Tresca(s)
    by a law whose threshold on this problem is s (Coulomb(s / lambda_n)).
    """
    msh = mesh.create_unit_cube(COMM, n, n, n, ghost_mode=mesh.GhostMode.none)
    magnitude = np.linalg.norm(SHEAR)
    a = np.zeros(2) if MU * magnitude < s else SHEAR - (s / MU) * SHEAR / magnitude
    sxz, syz = MU * (SHEAR - a)
    sxx = -LMBDA * PRESS
    traction = {X1: (sxx, 0.0, sxz), X0: (-sxx, 0.0, -sxz), Y1: (0.0, sxx, syz),
                Y0: (0.0, -sxx, -syz)}
    problem = ds.SignoriniProblem(
        msh, block_tags(msh, height=1.0), contact=BOTTOM, dirichlet={TOP: (*SHEAR, -PRESS)},
        E=E, nu=NU, traction=traction, gap=0.0, friction=ds.Tresca(s) if law is None else law,
    )
    return problem, a, np.array([sxz, syz, 0.0])


def example(comm=COMM, s=0.2, **kwargs):
    """The sheared block on a sphere (examples.friction_problem, 3D), stick and slip facets."""
    return ex.friction_problem(comm, nx=6, ny=3, dim=3, radius=4.0, s=s, **kwargs)


# --------------------------------------------------------------------------------------------------
# Patch tests and limits
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("s", [1.0, 0.05], ids=["stick", "slip"])
@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_patch_test_is_exact(s, law):
    """Full stick (mu |SHEAR| = 0.077 < s = 1) and full slip (s = 0.05) under an oblique shear:
    lambda_n, the traction vector lambda_t and u on Gamma_C are the exact ones to round-off; the
    estimate of the friction force along x is round-off and its interval holds the exact one.
    With Coulomb's law the threshold is mu_f lambda_n, mu_f = s / lambda_n: the same solution."""
    coulomb = ds.Coulomb(s / ((LMBDA + 2 * MU) * PRESS)) if law == "coulomb" else None
    problem, a, traction = patch_problem(s, law=coulomb)
    with ds.solve(problem, rtol=1e-13) as sol:  # Newton on the slip direction: to round-off
        n_contact = sol.disc.num_contact_elements
        assert sol.method == "block" and sol.num_active == n_contact
        assert (sol.num_stick, sol.num_slip) == ((n_contact, 0) if s == 1.0 else (0, n_contact))
        lam_n = (LMBDA + 2 * MU) * PRESS
        assert global_max(sol.lam.x.array - lam_n) <= 1e-12 * lam_n
        lam_t = sol.lam_t.x.array.reshape(-1, 3)
        assert global_max(lam_t - traction) <= 1e-12 * np.linalg.norm(traction)
        if s < 1.0:  # on the disc's boundary, along the slip
            assert np.allclose(np.linalg.norm(traction), s, rtol=1e-14)
        x = sol.disc.V.tabulate_dof_coordinates()
        bottom = sol.u.x.array.reshape(-1, 3)[np.isclose(x[:, 2], 0.0)]
        assert global_max(bottom[:, :2] - a) <= 1e-14 and global_max(bottom[:, 2]) <= 1e-14
        with ds.estimate(sol, ex.goal_friction_force()) as est:
            assert est.J_h == pytest.approx(traction[0], rel=1e-12)  # |Gamma_C| = 1
            assert abs(est.eta) <= 1e-12 * traction[0] and abs(est.eta_p) <= 1e-12 * traction[0]
            low, high = est.interval
            assert low <= traction[0] * (1 + 1e-12) and high >= traction[0] * (1 - 1e-12)


@pytest.mark.mpi
@pytest.mark.parametrize("law", ["tresca", "coulomb"])
def test_slipping_facets_converge_quadratically(law):
    """The slip direction is found by Newton's method on the ball's derivative (with Coulomb's
    law, the cone's, whose threshold moves with lambda_n): the NCP residual of the full-slip
    patch test falls at least quadratically once it is below 0.02."""
    coulomb = ds.Coulomb(0.05 / ((LMBDA + 2 * MU) * PRESS)) if law == "coulomb" else None
    problem, _, _ = patch_problem(0.05, law=coulomb)
    with ds.solve(problem) as sol:
        residuals = [h["residual_ncp"] for h in sol.history]
    tail = [r for r in residuals if 1e-14 < r < 0.02]
    assert len(tail) >= 2, residuals
    for before, after in itertools.pairwise(tail):
        assert after <= 10 * before**2, residuals


@pytest.mark.mpi
def test_tiny_threshold_is_frictionless():
    """s = 1e-12: the solution is the frictionless one to 1e-8 (relative, max norm)."""
    tresca = example(s=1e-12)
    check_frictionless_limit(tresca, example_variant(tresca, gap=tresca.gap))


@pytest.mark.mpi
def test_huge_threshold_under_a_tangential_load_sticks():
    """s = 1e8 and the top moved sideways only: (T u)_i = 0 on every macro contact facet, in
    both tangent directions, to round-off."""
    msh = mesh.create_unit_cube(COMM, 3, 3, 3, ghost_mode=mesh.GhostMode.none)
    problem = ds.SignoriniProblem(
        msh, block_tags(msh, height=1.0), contact=BOTTOM, dirichlet={TOP: (*SHEAR, 0.0)},
        E=E, nu=NU, gap=0.0, friction=ds.Tresca(1e8),
    )
    with ds.solve(problem) as sol:
        alg = sol.system.algebra
        _, T1u, T2u = alg.components_of(alg.gap_residual(sol.u.x.petsc_vec))
        assert sol.num_slip == 0
        assert max(global_max(T1u), global_max(T2u)) <= 1e-12 * np.linalg.norm(SHEAR)
        assert global_max(sol.lam_t.x.array) > 1e-3  # it is held by friction


# --------------------------------------------------------------------------------------------------
# The discrete problem against its dual quadratic programme (serial: scipy)
# --------------------------------------------------------------------------------------------------


def _scipy(mat):
    import scipy.sparse as sp

    indptr, indices, data = mat.getValuesCSR()
    return sp.csr_matrix((data, indices, indptr), shape=mat.getSize())


def _project(lam, n, bound):
    """Onto lambda_n >= 0 and the discs |(lambda_t1, lambda_t2)_i| <= bound_i."""
    out = lam.copy()
    out[:n] = np.maximum(out[:n], 0.0)
    t = out[n:].reshape(2, n)
    norm = np.hypot(t[0], t[1])
    scale = np.minimum(1.0, np.divide(bound, norm, out=np.ones_like(norm), where=norm > 0))
    out[n:] = (t * scale).ravel()
    return out


@pytest.mark.skipif(COMM.size > 1, reason="the reference QP is assembled with scipy, serially")
def test_discrete_problem_equals_its_dual_qp():
    """The discrete problem is min 1/2 u.Ku - f.u + sum_i s_i |(T u)_i| (T u in R^2) subject to
    N u <= g; its dual is min 1/2 r.K^-1 r + lam_n.g, r = f - B^T lam, over lam_n >= 0 and the
    discs |lam_t,i| <= s. Accelerated projected gradients (FISTA with restarts, a sparse LU of K)
    give the multipliers of the Newton solution to 1e-7, with facets inside the disc and on
    its boundary, slipping in directions that are not those of the tangent basis."""
    from scipy.sparse.linalg import splu

    with ds.solve(example()) as sol:
        alg = sol.system.algebra
        assert sol.num_stick > 0 and sol.num_slip > 0
        K = splu(_scipy(alg.K).tocsc())
        B = _scipy(alg.N)  # [N; T1; T2], the components' rows stacked
        f, g, n = alg.f.array.copy(), alg.g.array.copy(), alg.n_q
        bound = alg.bounds[1] / alg.M.array[n : 2 * n]  # the facet means of s
        linear = np.concatenate([g[:n], np.zeros(2 * n)])

        def gradient(lam):
            return -(B @ K.solve(f - B.T @ lam)) + linear

        v = np.random.default_rng(0).standard_normal(3 * n)  # power iteration: the step 1/L
        for _ in range(50):
            v = B @ K.solve(B.T @ v)
            L = np.linalg.norm(v)
            v /= L
        lam = y = np.zeros(3 * n)
        t = 1.0
        for _ in range(20000):
            new = _project(y - gradient(y) / L, n, bound)
            if np.max(np.abs(new - lam)) <= 1e-15 * max(np.max(np.abs(new)), 1e-300):
                lam = new
                break
            t_new = 0.5 * (1 + np.sqrt(1 + 4 * t * t))
            restart = (y - new) @ (new - lam) > 0  # the gradient restart of O'Donoghue-Candes
            y = new if restart else new + (t - 1) / t_new * (new - lam)
            t = 1.0 if restart else t_new
            lam = new
        newton = sol.stacked()
        assert np.max(np.abs(lam - newton)) <= 1e-7 * np.max(np.abs(newton))
        slip = np.hypot(newton[n : 2 * n], newton[2 * n :]) > bound * (1 - 1e-12)
        angles = np.arctan2(newton[2 * n :], newton[n : 2 * n])[slip]
        assert slip.any() and np.ptp(angles) > 0.1  # several slip directions (0.33 rad)


# --------------------------------------------------------------------------------------------------
# The dual solution
# --------------------------------------------------------------------------------------------------


def linear_goal(u, lam, m, lam_t):
    return (lam_t[0] + 2.0 * lam_t[1] + 0.5 * lam
            + ufl.dot(u, ufl.as_vector((1.0, 2.0, 0.5)))) * m.ds_contact


@pytest.mark.mpi
def test_adjoint_consistency_for_a_linear_goal():
    """With the final sets and slip directions the Newton step is linear, A w_h = F; the dual
    solves A^T z_h = J', so for a linear goal J(w_h) = z_h . F to round-off, the coupled rows
    of the slipping facets contributing."""
    with ds.solve(example()) as sol, ds.estimate(sol, linear_goal) as est:
        assert est.goal_is_linear and sol.num_stick > 0 and sol.num_slip > 0
        s = sol.system
        b_lam = s.b.array_r[s.n_u :]
        F_lam = np.where(s.active, s.c_n * b_lam, b_lam)  # xi = xi^(1) / c on constrained rows
        y = est.dual.y.x.array[: s.n_u]
        xi = sol.stacked(est.dual.multipliers)
        total = global_sum(y @ s.f.array) + global_sum(xi @ F_lam)
        assert total == pytest.approx(est.J_h, rel=1e-10, abs=0.0)
        coupled = np.zeros(s.n_lam, dtype=bool)
        for cp in s.couplings:
            coupled[cp.rows.ravel()] = True
        # without the coupled rows' part the identity would fail at 1e-10
        assert abs(global_sum(xi[coupled] @ F_lam[coupled])) > 1e-6 * abs(est.J_h)


@pytest.mark.mpi
def test_dual_is_the_derivative_of_J_against_finite_differences():
    """d/de J(w_h(e)) for the body force (e, e, 0) at e = 0, by central differences of re-solved
    problems (whose sets do not change), equals z_h . [int (e_x + e_y) . v; 0]."""
    goal = ex.goal_friction_force()
    base = example()

    def solve(eps):
        return ds.solve(with_body_force(base, (eps, eps, 0.0)))

    def same_sets(other, sol):
        assert np.array_equal(other.system.active, sol.system.active)
        assert np.array_equal(other.slip, sol.slip)
        assert sol.num_slip > 0

    predicted, fd = dual_against_finite_differences(
        solve, goal, lambda v: v[0] + v[1], same_sets)
    assert abs(predicted) > 1e-3
    assert fd == pytest.approx(predicted, rel=1e-6)


# --------------------------------------------------------------------------------------------------
# Units, weights, bad input
# --------------------------------------------------------------------------------------------------


def _scaled(s_L, s_E):
    """The 3D example with lengths scaled by s_L and stresses by s_E."""
    d = ex.FRICTION_DEFAULTS
    msh = mesh.create_box(COMM, [np.zeros(3), np.array([s_L, s_L, 0.5 * s_L])], [6, 6, 3],
                          mesh.CellType.tetrahedron, ghost_mode=mesh.GhostMode.none)


    def gap(x):
        return ((x[0] - 0.5 * s_L) ** 2 + (x[1] - 0.5 * s_L) ** 2) / (2.0 * 4.0 * s_L)

    return ds.SignoriniProblem(
        msh, ex.tag_block_facets(msh, 0.5 * s_L), contact=ex.CONTACT,
        dirichlet={ex.DIRICHLET: (d["shear"] * s_L, 0.0, -d["press"] * s_L)}, E=10.0 * s_E,
        nu=0.3, gap=gap, friction=ds.Tresca(d["s"] * s_E),
    )


@pytest.mark.mpi
def test_estimate_is_invariant_under_a_change_of_units():
    """Lengths x 1e-3, stresses x 1e6: the friction force, eta_p, eta and the contact term
    scale by s_E s_L^2 to 1e-8, with the same stick and slip sets."""
    s_L, s_E = 1e-3, 1e6
    values = []
    for scale in ((1.0, 1.0), (s_L, s_E)):
        with ds.solve(_scaled(*scale)) as sol:
            with ds.estimate(sol, ex.goal_friction_force(), weights="patch") as est:
                values.append({k: getattr(est, k) for k in ("J_h", "eta_p", "eta",
                                                             "contact_term")})
                values[-1]["sets"] = (sol.num_active, sol.num_stick, sol.num_slip)
    ref, other = values
    assert ref.pop("sets") == other.pop("sets")
    assert ref["J_h"] > 0
    for key, value in ref.items():
        assert other[key] / (s_L**2 * s_E) == pytest.approx(
            value, rel=1e-8, abs=1e-8 * abs(ref["eta"])), key


@pytest.mark.mpi
def test_higher_order_weights_solve_the_coupled_p2_system():
    """weights="higher_order" factors the P2 Newton system of the final sets and slip
    directions by LU; on the full-slip patch test, where P1 is exact, its estimate is
    round-off, and on the example it is of the size of the patch weights' estimate."""
    problem, _, traction = patch_problem(0.05, n=3)
    with ds.solve(problem, rtol=1e-13) as sol:
        with ds.estimate(sol, ex.goal_friction_force(), weights="higher_order") as est:
            assert est.weights == "higher_order" and abs(est.eta) <= 1e-12 * traction[0]
    with ds.solve(example()) as sol:
        with ds.estimate(sol, ex.goal_friction_force(), weights="higher_order") as p2, \
                ds.estimate(sol, ex.goal_friction_force(), weights="patch") as patch:
            assert p2.eta != 0.0 and 1 / 3 <= p2.eta / patch.eta <= 3


def test_symmetric_only_paths_are_refused_by_name():
    """The Schur path and a Cholesky factorisation need symmetric Newton matrices: each
    refused with an error naming what to use instead."""
    problem = example(MPI.COMM_SELF)
    with pytest.raises(ValueError, match=r"method=.schur.*method=.block."):
        ds.solve(problem, method="schur")
    with pytest.raises(ValueError, match=r"pc_type .cholesky.*LU"):
        ds.solve(problem, petsc_options={"pc_type": "cholesky",
                                         "pc_factor_mat_solver_type": "mumps"})
