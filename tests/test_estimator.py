"""Acceptance tests of the dual problem and the error estimators eta_p and eta (Sections 3-5).

Truth used here is independent of the estimator code: the identity J(w_h) = z_h . F of the
transposed Newton system, the discrete dual equations (11)-(12) assembled from their definition,
the paper's Tables 1 and 2, the exact quantities of interest of Example 5.1, standard DWR
identities of the contact-free (linear) problem with an independently computed P2 solution, and
serial against parallel runs.
"""

import math

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.estimator import ncp_scale_function
from dwr_signorini.examples import analytic_problem
from dwr_signorini.goal import GoalForms
from dwr_signorini.quadrature import DATA_QUADRATURE_DEGREE, with_quadrature_degrees
from dwr_signorini.residuals import contact_violation, dual_residual, primal_residual

from . import fem_compat
from .helpers import global_sum, integrate
from .problems import strip_problem

TRI, QUAD = mesh.CellType.triangle, mesh.CellType.quadrilateral
E, NU = ex.ANALYTIC_MATERIAL.E, ex.ANALYTIC_MATERIAL.nu

# Paper, Tables 1 (J_a1) and 2 (J_a2): M_Omega, E_rel, Ieff(eta_p), Ieff(eta); levels L = 0 ... 4.
PAPER_TABLE_1 = [
    (384, 2.57243e-2, 0.91869, 0.38317),
    (1536, 1.36313e-2, 1.60751, 0.99145),
    (6144, 3.76048e-3, 1.02681, 1.01653),
    (24576, 9.49684e-4, 1.00536, 1.00546),
    (98304, 2.37789e-4, 1.00134, 1.00137),
]
PAPER_TABLE_2 = [
    (384, 9.59089e-2, 1.13982, 0.14453),
    (1536, 2.50765e-1, 1.17490, 0.85087),
    (6144, 5.50751e-2, 1.06133, 0.95967),
    (24576, 1.32901e-2, 1.08439, 0.99017),
    (98304, 3.29218e-3, 1.09121, 0.99752),
]
TABLES = {
    "J_a1": (ex.goal_a(-0.5), ex.exact_J_a(-0.5), PAPER_TABLE_1),
    "J_a2": (ex.goal_a2(), ex.exact_J_a2(E, NU), PAPER_TABLE_2),
}


# --------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------


#: Problems for the checks that also run on 2 ranks.
CASES = {
    "analytic-tri": lambda comm: analytic_problem(comm, 24, 16, TRI),
    "analytic-quad": lambda comm: analytic_problem(comm, 24, 16, QUAD),
    "strip-tri": lambda comm: strip_problem(comm, 32, 8, TRI),
    "strip-quad": lambda comm: strip_problem(comm, 32, 8, QUAD),
}


def paper_level(comm, level, cell_type=QUAD):
    """Level L of the paper's uniform meshes: 12 x 8 * 2^L macro cells."""
    return analytic_problem(comm, 12 * 2**level, 8 * 2**level, cell_type)


def linear_goal(u, lam, m):
    """A goal linear in (u, lambda), with a volume and a contact part."""
    return (u[0] + 0.5 * m.x[1] * u[1]) * m.dx + (1.0 + m.x[1] ** 2) * lam * m.ds_contact


def mixed_goal(u, lam, m):
    """A nonlinear goal in u and lambda: J_a1 + J_a2."""
    return ex.goal_a(-0.5)(u, lam, m) + ex.goal_a2()(u, lam, m)


def energy_goal(u, lam, m):
    """A nonlinear goal in u and lambda for any domain."""
    return ufl.inner(m.sigma(u), m.epsilon(u)) * m.dx + m.x[0] * lam**2 * m.ds_contact


def global_norm(comm, local):
    return math.sqrt(comm.allreduce(float(np.dot(local, local)), op=MPI.SUM))


def assemble_owned(sol, form, bcs=()):
    """Assemble a linear form on the fine mesh (it may use lam) and return the owned entries."""
    vec = fem_petsc.assemble_vector(sol.disc.form(form))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    if bcs:
        fem_petsc.set_bc(vec, list(bcs))
    out = vec.array.copy()
    vec.destroy()
    return out


def active_indicator(sol):
    """chi_H: 1 on the active macro contact facets of the final Newton step, in Lambda_H."""
    chi = fem.Function(sol.disc.Q)
    n_lam = sol.system.n_lam
    chi.x.array[:n_lam] = sol.active.astype(float)
    chi.x.scatter_forward()
    return chi


def ieff(J_exact, J_h, estimate):
    return (J_exact - J_h) / estimate


# --------------------------------------------------------------------------------------------------
# The discrete dual problem
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["analytic-tri", "analytic-quad", "strip-tri"])
def test_adjoint_consistency_for_a_linear_goal(case):
    """With the final active set the primal map is linear, A w_h = F; the dual solves
    A^T z_h = J', so for a linear goal J(w_h) = J'(w_h) = z_h . F to round-off."""
    sol = ds.solve(CASES[case](MPI.COMM_WORLD))
    assert 0 < sol.num_active < sol.disc.num_contact_elements
    est = ds.estimate(sol, linear_goal, estimator="eta_p")
    assert est.goal_is_linear
    comm, s = sol.disc.comm, sol.system
    J_direct = integrate(sol, linear_goal(sol.u, sol.lam, sol.disc.m))
    # Right-hand side of the last Newton system: [f; -D_A g] (see NewtonSystem.solve_active).
    F_u = s.f.array
    # The contact rows of the NCP with scale c read c (N u)_A = c g_A: F_lam = -c g on A.
    F_lam = np.where(sol.active, -s.c_n * s.g.array, 0.0)
    y = est.dual.y.x.array[: s.n_u]
    xi = est.dual.xi.x.array[: s.n_lam]
    z_dot_F = global_sum(y @ F_u + xi @ F_lam, comm)
    assert z_dot_F == pytest.approx(J_direct, rel=1e-10, abs=0.0)
    assert est.J_h == pytest.approx(J_direct, rel=1e-12, abs=0.0)
    # Both parts contribute (so the check covers the contact rows).
    assert abs(global_sum(xi @ F_lam, comm)) > 1e-3 * abs(J_direct)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("case", "goal"),
    [
        pytest.param("analytic-tri", linear_goal, id="analytic-tri-linear"),
        pytest.param("analytic-quad", mixed_goal, id="analytic-quad-mixed"),
        pytest.param("analytic-tri", ex.goal_a2(), id="analytic-tri-J_a2"),
        pytest.param("strip-quad", energy_goal, id="strip-quad-energy"),
    ],
)
def test_dual_solution_solves_the_discrete_dual_problem(case, goal):
    """(11) a(v, y) - int chi xi v_n = J'_u(v) for v in V_h (Dirichlet rows excluded) and
    (12) int mu y_n + int (1 - chi) xi mu = J'_lam(mu) for mu in Lambda_H, J' with data
    integrated at the problem's quadrature degree (as the dual residual of the estimator)."""
    sol = ds.solve(CASES[case](MPI.COMM_WORLD))
    est = ds.estimate(sol, goal, estimator="eta_p")
    y, xi = est.dual.y, est.dual.xi
    disc, comm = sol.disc, sol.disc.comm
    m = disc.m
    chi = active_indicator(sol)
    v, mu = ufl.TestFunction(disc.V), ufl.TestFunction(disc.Q)
    J = goal(sol.u, sol.lam, m)
    # Hooke's law written out here (plane strain), independent of the package's.
    lmbda, mu_s = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
    eps = ufl.sym(ufl.grad(v))
    sigma = 2 * mu_s * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)
    a_vy = assemble_owned(sol, ufl.inner(sigma, ufl.sym(ufl.grad(y))) * m.dx, disc.bcs)
    # b_h(xi, v) = int c chi xi v_n with the scale c of the NCP (dwr_signorini.residuals).
    c_scale = fem.Function(disc.Q)
    c_scale.x.array[: sol.system.n_lam] = sol.system.c_n
    c_scale.x.scatter_forward()
    b = assemble_owned(sol, c_scale * chi * xi * ufl.dot(v, m.n) * m.ds_contact, disc.bcs)
    degree = disc.problem.quadrature_degree
    dJ_u = with_quadrature_degrees(ufl.derivative(J, sol.u, v), degree)
    Ju = (
        assemble_owned(sol, dJ_u, disc.bcs)
        if not ufl.algorithms.expand_derivatives(dJ_u).empty()
        else np.zeros_like(a_vy)
    )
    scale_u = max(global_norm(comm, a_vy), global_norm(comm, b), global_norm(comm, Ju))
    assert scale_u > 0.0
    assert global_norm(comm, a_vy - b - Ju) <= 1e-10 * scale_u

    yn = assemble_owned(sol, mu * ufl.dot(y, m.n) * m.ds_contact)
    c = assemble_owned(sol, (1.0 - chi) * xi * mu * m.ds_contact)
    dJ_lam = with_quadrature_degrees(ufl.derivative(J, sol.lam, mu), degree)
    Jl = (
        assemble_owned(sol, dJ_lam)
        if not ufl.algorithms.expand_derivatives(dJ_lam).empty()
        else np.zeros_like(yn)
    )
    scale_lam = max(global_norm(comm, yn), global_norm(comm, c), global_norm(comm, Jl))
    assert scale_lam > 0.0
    assert global_norm(comm, yn + c - Jl) <= 1e-10 * scale_lam


# --------------------------------------------------------------------------------------------------
# The paper's Tables 1 and 2 (Example 5.1, quadrilaterals, patch-wise reconstructions)
# --------------------------------------------------------------------------------------------------


def _table_rows(levels):
    rows = {name: [] for name in TABLES}
    for level in levels:
        sol = ds.solve(paper_level(MPI.COMM_WORLD, level))
        for name, (goal, J_exact, paper) in TABLES.items():
            assert sol.disc.num_cells == paper[level][0]
            est = ds.estimate(sol, goal, estimator="eta", weights="patch")
            err = J_exact - est.J_h
            rows[name].append((abs(err) / abs(J_exact), err / est.eta_p, err / est.eta))
    return rows


@pytest.mark.parametrize("levels", [pytest.param(4, id="L0-3")])  # ~ 5 s
def test_paper_tables(levels):
    """Tables 1 and 2: E_rel within 0.5 % of the paper's on every level; Ieff(eta_p) within 0.02
    at L = 2, and both effectivity indices within 0.01 from L = 3 on.

    (On L = 0, 1 the effectivity indices are pre-asymptotic and depend on details of the
    reconstructions that the paper leaves open; they are not compared.)
    """
    rows = _table_rows(range(levels))
    for name, (_, _, paper) in TABLES.items():
        for level, (e_rel, ieff_p, ieff_pd) in enumerate(rows[name]):
            assert e_rel == pytest.approx(paper[level][1], rel=5e-3), (name, level)
            if level == 2:
                assert abs(ieff_p - paper[level][2]) <= 0.02, (name, level)
            if level >= 3:
                assert abs(ieff_p - paper[level][2]) <= 0.01, (name, level)
                assert abs(ieff_pd - paper[level][3]) <= 0.01, (name, level)


#: The paper's Figure 4 (M_Omega = 98304): Ieff of J_a(m) for m in [-3, 0] between about 1.0008
#: and 1.0014 (the figure's axis); with a margin of 1e-4 for reading a plot.
FIGURE_4_BAND = (1.0007, 1.0015)


def test_paper_tables_level_4_and_figure_4():
    """L = 4 (98304 cells) with the paper's c = 1: the rows of Tables 1 and 2 (E_rel within
    0.5 %, both effectivity indices within 0.001 of the paper's, J_a1's about 1.001), and the
    Figure 4 sweep over the midpoint m inside the figure's band. One solve, five estimates."""
    sol = ds.solve(paper_level(MPI.COMM_WORLD, 4), ncp_scale=1.0)
    assert sol.disc.num_cells == 98304
    for goal, J_exact, paper in TABLES.values():
        with ds.estimate(sol, goal) as est:
            err = J_exact - est.J_h
            assert abs(err) / abs(J_exact) == pytest.approx(paper[4][1], rel=5e-3)
            assert abs(err / est.eta_p - paper[4][2]) <= 1e-3
            assert abs(err / est.eta - paper[4][3]) <= 1e-3
    for m in (-3.0, -2.0, 0.0):  # the ends and the lowest point of the paper's curve
        with ds.estimate(sol, ex.goal_a(m)) as est:
            ieff_eta = (ex.exact_J_a(m) - est.J_h) / est.eta
            assert FIGURE_4_BAND[0] <= ieff_eta <= FIGURE_4_BAND[1], (m, ieff_eta)
    sol.destroy()


# --------------------------------------------------------------------------------------------------
# Triangles with higher-order (P2) weights
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("level", "bound"),
    [
        # |Ieff - 1| behaves like O(h^2) once asymptotic (a factor ~ 4 per level between
        # 12288 and 49152 cells, see DESIGN.md §5): 0.04 on the coarser level is the 0.01 of
        # the finer one, times 4.
        pytest.param(2, 0.04, id="12288-cells"),
        pytest.param(3, 0.01, id="49152-cells"),
    ],
)
def test_triangles_higher_order_weights_are_sharp(level, bound):
    goal, J_exact = ex.goal_a(-0.5), ex.exact_J_a(-0.5)
    sol = ds.solve(paper_level(MPI.COMM_WORLD, level, TRI))
    assert sol.disc.num_cells == 768 * 4**level
    est = ds.estimate(sol, goal, estimator="eta", weights="higher_order")
    assert abs(ieff(J_exact, est.J_h, est.eta_p) - 1.0) <= bound
    assert abs(ieff(J_exact, est.J_h, est.eta) - 1.0) <= bound


# --------------------------------------------------------------------------------------------------
# Indicators, and serial against parallel
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("case", "goal", "estimator"),
    [
        ("analytic-tri", mixed_goal, "eta"),
        ("analytic-tri", mixed_goal, "eta_p"),
        ("analytic-quad", mixed_goal, "eta"),
        ("strip-tri", energy_goal, "eta"),
        ("strip-quad", energy_goal, "eta_p"),
    ],
    ids=lambda v: getattr(v, "__name__", v),
)
def test_indicators_sum_to_the_estimate(case, goal, estimator):
    """The cell indicators (the integrands times a DG0 test function, assembled as a vector)
    sum to the estimate assembled as one global functional, by another path: dolfinx's scalar
    assembly of rho(w_h)(A z_h - z_h) - C(w_h)(xi_H) (+ rho* for eta), with the patch weights
    reconstructed again here."""
    sol = ds.solve(CASES[case](MPI.COMM_WORLD))
    est = ds.estimate(sol, goal, estimator=estimator, weights="patch")
    assert est.value == (est.eta if estimator == "eta" else est.eta_p)
    ind = est.indicators
    assert ind.function_space.mesh is sol.disc.mesh
    n_local = ind.function_space.dofmap.index_map.size_local
    total = global_sum(ind.x.array[:n_local].sum(), sol.disc.comm)
    disc, m, rec, z = sol.disc, sol.disc.m, est.reconstructor, est.dual
    c = ncp_scale_function(sol)
    w_y = rec.weight(rec.patch_quadratic(z.y), z.y)
    w_xi = rec.patch_linear_multiplier(z.xi) - z.xi
    gap = disc.problem.gap_expr(m.x)
    primal = primal_residual(sol, w_y, w_xi, c)
    contact = contact_violation(sol.u, sol.lam, z.xi, gap, m.n, m.ds_contact, c)
    if estimator == "eta_p":
        form = primal - contact
    else:
        w_u = rec.weight(rec.patch_quadratic(sol.u), sol.u)
        w_lam = rec.patch_linear_multiplier(sol.lam) - sol.lam
        dual = dual_residual(sol, GoalForms(goal, sol.u, sol.lam, disc), z, w_u, w_lam, c)
        form = 0.5 * primal + 0.5 * dual - contact
    form = with_quadrature_degrees(form, DATA_QUADRATURE_DEGREE)
    value = global_sum(fem.assemble_scalar(disc.form(form)), sol.disc.comm)
    assert total == pytest.approx(value, rel=1e-10)


def _estimates(comm, case, goal, weights):
    sol = ds.solve(CASES[case](comm))
    est = ds.estimate(sol, goal, estimator="eta", weights=weights)
    return {
        "J_h": est.J_h,
        "eta_p": est.eta_p,
        "eta": est.eta,
        "contact_term": est.contact_term,
    }


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("case", "goal", "weights"),
    [
        ("analytic-tri", mixed_goal, "patch"),
        ("analytic-tri", mixed_goal, "higher_order"),
        ("analytic-quad", mixed_goal, "patch"),
        ("strip-tri", energy_goal, "higher_order"),
        ("strip-quad", energy_goal, "patch"),
    ],
    ids=lambda v: getattr(v, "__name__", v),
)
def test_serial_and_parallel_estimates_agree(case, goal, weights):
    par = _estimates(MPI.COMM_WORLD, case, goal, weights)
    ser = _estimates(MPI.COMM_SELF, case, goal, weights)
    for key in ("J_h", "eta_p", "eta"):
        assert par[key] == pytest.approx(ser[key], rel=1e-9, abs=0.0), key
    scale = abs(ser["eta_p"])
    assert par["contact_term"] == pytest.approx(ser["contact_term"], rel=1e-9, abs=1e-9 * scale)


# --------------------------------------------------------------------------------------------------
# Without contact: the standard DWR estimator
# --------------------------------------------------------------------------------------------------


def contact_free_load(x):
    """A polynomial load: every quadrature rule of the package and of UFL integrates it exactly
    against P1/P2 functions, so the DWR identities below hold to round-off."""
    return ufl.as_vector((1.0 + x[1], -0.5 * x[0]))


def _p2_solution(sol):
    """The contact-free P2 solution on the fine mesh, computed with dolfinx only."""
    disc = sol.disc
    msh, m = disc.mesh, disc.m
    V2 = fem.functionspace(msh, ("Lagrange", 2, (msh.geometry.dim,)))
    u, v = ufl.TrialFunction(V2), ufl.TestFunction(V2)
    a = ufl.inner(ex.stress(u, E, NU), ufl.sym(ufl.grad(v))) * m.dx
    L = ufl.inner(contact_free_load(m.x), v) * m.dx
    facets = disc.facet_tags.find(ex.DIRICHLET)
    dofs = fem.locate_dofs_topological(V2, msh.topology.dim - 1, facets)
    bc = fem.dirichletbc(np.zeros(msh.geometry.dim), dofs, V2)
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
    return fem_compat.linear_problem(a, L, bcs=[bc], petsc_options=options).solve()


def _volume_part(u, m):
    return (u[0] + 0.5 * m.x[1] * u[1]) * m.dx


def contact_free_goal(u, lam, m):
    """Linear in u; the lambda part is inert without contact."""
    return _volume_part(u, m) + lam * m.ds_contact


@pytest.mark.mpi
@pytest.mark.parametrize("cell_type", [TRI, QUAD], ids=["tri", "quad"])
def test_without_contact_higher_order_estimate_is_the_p2_error(cell_type):
    """Gap 1e3: nothing is active, C(w_h)(xi_H) = 0, and with P2 weights both estimators equal
    the standard DWR estimate which, for a linear problem and a linear goal, is exactly
    J(u_2) - J(u_h) with the P2 solution u_2 (Galerkin orthogonality in V_h and in V_2)."""
    problem = analytic_problem(
        MPI.COMM_WORLD, 12, 8, cell_type, gap=1e3, body_force=contact_free_load
    )
    sol = ds.solve(problem)
    assert sol.num_active == 0
    est = ds.estimate(sol, contact_free_goal, estimator="eta", weights="higher_order")
    assert est.contact_term == 0.0
    u2 = _p2_solution(sol)
    m = sol.disc.m
    J_u2 = sol.disc.comm.allreduce(fem.assemble_scalar(fem.form(_volume_part(u2, m))), op=MPI.SUM)
    J_uh = integrate(sol, contact_free_goal(sol.u, sol.lam, m))
    assert est.J_h == pytest.approx(J_uh, rel=1e-12)
    difference = J_u2 - J_uh
    assert abs(difference) > 1e-6 * abs(J_uh)
    assert est.eta_p == pytest.approx(difference, rel=1e-8)
    assert est.eta == pytest.approx(difference, rel=1e-8)


@pytest.mark.mpi
def test_without_contact_patch_estimate_has_no_contact_part():
    """Gap 1e3 with the paper's patch weights: the contact term vanishes, eta_p is the plain
    residual rho(w_h)(i z_h - z_h), and xi_H is the P0 function of (12) with chi = 0:
    int (xi + y_n) mu = J'_lam(mu) = 0 for J_a1."""
    sol = ds.solve(analytic_problem(MPI.COMM_WORLD, 12, 8, QUAD, gap=1e3))
    assert sol.num_active == 0
    assert np.all(sol.lam.x.array == 0.0)
    est = ds.estimate(sol, ex.goal_a(-0.5), estimator="eta", weights="patch")
    assert est.contact_term == 0.0
    assert est.eta_p == est.rho
    assert est.eta == pytest.approx(0.5 * (est.rho + est.rho_star), rel=1e-14)
    mu = ufl.TestFunction(sol.disc.Q)
    m = sol.disc.m
    residual = assemble_owned(sol, (est.dual.xi + ufl.dot(est.dual.y, m.n)) * mu * m.ds_contact)
    yn = assemble_owned(sol, ufl.dot(est.dual.y, m.n) * mu * m.ds_contact)
    comm = sol.disc.comm
    assert global_norm(comm, residual) <= 1e-10 * global_norm(comm, yn)


# --------------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_solution():
    return ds.solve(analytic_problem(MPI.COMM_WORLD, 6, 4, TRI))


def _goal_with_argument(u, lam, m):
    return ufl.inner(u, ufl.TestFunction(u.ufl_function_space())) * m.dx


_OTHER_MESH = {}


def _goal_on_other_mesh(u, lam, m):
    if "mesh" not in _OTHER_MESH:
        _OTHER_MESH["mesh"] = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    return ufl.inner(u, u) * ufl.dx(domain=_OTHER_MESH["mesh"])


BAD_GOALS = [
    ("returns-float", lambda u, lam, m: 1.0, TypeError, "UFL form"),
    ("returns-expression", lambda u, lam, m: ufl.inner(u, u), TypeError, "UFL form"),
    ("not-callable", "J", TypeError, "callable"),
    ("has-argument", _goal_with_argument, ValueError, "argument"),
    ("lam-over-dx", lambda u, lam, m: lam * m.dx, ValueError, "lam"),
    ("lam-over-neumann", lambda u, lam, m: lam * m.ds(ex.NEUMANN), ValueError, "lam"),
    ("other-mesh", _goal_on_other_mesh, ValueError, "another mesh"),
]


@pytest.mark.parametrize(
    ("goal", "error", "match"), [pytest.param(g, e, s, id=i) for i, g, e, s in BAD_GOALS]
)
def test_bad_goal_is_rejected(small_solution, goal, error, match):
    with pytest.raises(error, match=match):
        ds.estimate(small_solution, goal)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"estimator": "foo"}, "estimator"), ({"weights": "foo"}, "weights")],
    ids=["estimator", "weights"],
)
def test_bad_estimator_options_are_rejected(small_solution, kwargs, match):
    with pytest.raises(ValueError, match=match):
        ds.estimate(small_solution, ex.goal_a(-0.5), **kwargs)


def test_estimate_rejects_other_objects():
    with pytest.raises(TypeError, match="Solution"):
        ds.estimate("not a solution", ex.goal_a(-0.5))
