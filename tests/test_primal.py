"""Acceptance tests of the primal solver (Section 4 of the paper, Examples 5.1-5.3).

Truth used here is independent of this package: the analytic solution of Example 5.1
(convergence rates), the algebraic contact conditions (19) at convergence, serial against
parallel runs, the problem data of the paper, and fixed points of the Newton iteration.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.examples import analytic_problem, bar_problem, obstacle_problem

from .helpers import global_max, integrate, owned
from .problems import strip_problem

TRI, QUAD = mesh.CellType.triangle, mesh.CellType.quadrilateral
QUADRATURE = {"quadrature_degree": 8}


# --------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------


#: Problems for the checks that also run on 2 ranks.
CASES = {
    "analytic-tri": lambda comm: analytic_problem(comm, 24, 16, TRI),
    "analytic-quad": lambda comm: analytic_problem(comm, 24, 16, QUAD),
    "bar-tri": lambda comm: bar_problem(comm, 8, 32),
    "strip-tri": lambda comm: strip_problem(comm, 32, 8, TRI),
    "strip-quad": lambda comm: strip_problem(comm, 32, 8, QUAD),
}


def analytic_errors(sol):
    """L2 and H1-seminorm errors of u_h and the L2(Gamma_C) error of lambda_H (Example 5.1)."""
    m = sol.disc.m
    dx = m.dx(metadata=QUADRATURE)
    ds_c = m.ds_contact(metadata=QUADRATURE)
    e = sol.u - ex.analytic_displacement(m.x)
    e_lam = sol.lam - ex.analytic_contact_pressure(m.x)
    return (
        math.sqrt(integrate(sol, ufl.inner(e, e) * dx)),
        math.sqrt(integrate(sol, ufl.inner(ufl.grad(e), ufl.grad(e)) * dx)),
        math.sqrt(integrate(sol, e_lam**2 * ds_c)),
    )


def rates(errors):
    """Convergence rates in h for halving h from one entry to the next."""
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def transfer(V_to, f):
    """Interpolate ``f`` into ``V_to`` (a space on another mesh, also in parallel)."""
    msh = V_to.mesh
    imap = msh.topology.index_map(msh.topology.dim)
    cells = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
    data = fem.create_interpolation_data(V_to, f.function_space, cells, padding=1e-10)
    out = fem.Function(V_to)
    out.interpolate_nonmatching(f, cells, data)
    out.x.scatter_forward()
    return out


# --------------------------------------------------------------------------------------------------
# Example 5.1: convergence to the analytic solution
# --------------------------------------------------------------------------------------------------


def test_analytic_triangles_converge_at_optimal_rates():
    """P1 on triangles, 6 uniform levels (48 ... 49152 fine cells): L2 ~ h^2, H1 ~ h, lambda_H."""
    comm = MPI.COMM_WORLD
    errs, cells, iterations = [], [], []
    for k in range(6):
        sol = ds.solve(analytic_problem(comm, 3 * 2**k, 2 * 2**k, TRI))
        errs.append(analytic_errors(sol))
        cells.append(sol.disc.num_cells)
        iterations.append(sol.newton_iterations)
    assert cells == [48 * 4**k for k in range(6)]
    l2, h1, lam = np.array(errs).T
    # The two finest levels are in the asymptotic range.
    assert np.all(np.abs(rates(l2)[-2:] - 2.0) <= 0.15), rates(l2)
    assert np.all(np.abs(rates(h1)[-2:] - 1.0) <= 0.15), rates(h1)
    # lambda_H -> lambda_n in L2(Gamma_C): decreasing on the finest levels, and clearly smaller.
    assert np.all(np.diff(lam[-3:]) < 0.0), lam
    assert lam[-1] < 0.2 * lam[0], lam
    assert max(iterations) <= 8, iterations


@pytest.mark.parametrize(
    "levels",
    [pytest.param(4, id="L0-3"), pytest.param(5, id="L0-4", marks=pytest.mark.slow)],
)
def test_analytic_quadrilaterals_paper_meshes(levels):
    """Q1 on the paper's meshes (M_Omega = 384 * 4^L, M_C = 8 * 2^L): optimal rates."""
    comm = MPI.COMM_WORLD
    errs = []
    for k in range(levels):
        sol = ds.solve(analytic_problem(comm, 12 * 2**k, 8 * 2**k, QUAD))
        assert sol.disc.num_cells == 384 * 4**k
        assert sol.disc.num_contact_elements == 8 * 2**k
        assert sol.newton_iterations <= 8
        errs.append(analytic_errors(sol))
    l2, h1, lam = np.array(errs).T
    assert abs(rates(l2)[-1] - 2.0) <= 0.15, rates(l2)
    assert abs(rates(h1)[-1] - 1.0) <= 0.15, rates(h1)
    assert lam[-1] < lam[-2], lam


# --------------------------------------------------------------------------------------------------
# The algebraic problem (19) at convergence
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("case", list(CASES))
def test_contact_conditions_hold_at_convergence(case):
    """N u - g <= 0, M lam >= 0, (M lam)_i (N u - g)_i = 0 and K u + N^T lam = f, to round-off."""
    comm = MPI.COMM_WORLD
    sol = ds.solve(CASES[case](comm))
    system = sol.system
    if case.startswith("strip") and comm.size > 1:
        # The point of the strip: Gamma_C is shared by the ranks.
        assert comm.allreduce(system.n_lam > 0, op=MPI.LAND)
    _, lam = owned(sol)
    gap = system.algebra.gap_residual(sol.u.x.petsc_vec)  # N u - g, owned rows
    Mlam = system.M.array * lam
    gap_scale = global_max(system.g.array, comm)
    lam_scale = global_max(Mlam, comm)
    assert gap_scale > 0.0 and lam_scale > 0.0
    tol = 1e-10
    assert np.all(gap <= tol * gap_scale), gap.max()
    assert np.all(Mlam >= -tol * lam_scale), Mlam.min()
    assert np.all(np.abs(Mlam * gap) <= tol * lam_scale * gap_scale)
    # The reported active set is the one of the solution: N u = g there, lam = 0 elsewhere.
    active = sol.active
    assert np.all(np.abs(gap[active]) <= tol * gap_scale)
    assert np.all(lam[~active] == 0.0)
    assert sol.num_active == comm.allreduce(int(active.sum()), op=MPI.SUM)
    assert 0 < sol.num_active <= sol.disc.num_contact_elements
    # Equilibrium K u + N^T lam = f (Dirichlet rows included: there u = 0 = f).
    r = system.f.duplicate()
    system.K.mult(sol.u.x.petsc_vec, r)
    lam_vec = system.N.createVecLeft()
    lam_vec.array[:] = lam
    reaction = system.f.duplicate()
    system.NT.mult(lam_vec, reaction)
    r.axpy(1.0, reaction)
    r.axpy(-1.0, system.f)
    assert r.norm() <= 1e-9 * max(system.f.norm(), reaction.norm())
    for vec in (r, lam_vec, reaction):
        vec.destroy()
    # The NCP residual (20) of the package vanishes too.
    assert global_max(system.algebra.ncp_residual(sol.u.x.petsc_vec, lam), comm) <= tol * lam_scale


# --------------------------------------------------------------------------------------------------
# Serial against parallel
# --------------------------------------------------------------------------------------------------


def _summary(sol):
    m = sol.disc.m
    return {
        "u_L2": math.sqrt(integrate(sol, ufl.inner(sol.u, sol.u) * m.dx)),
        "J_a1": integrate(sol, ex.goal_a(-0.5)(sol.u, sol.lam, m)),
        "int_lam": integrate(sol, sol.lam * m.ds_contact),
        "newton_iterations": sol.newton_iterations,
        "num_active": sol.num_active,
        "num_cells": sol.disc.num_cells,
        "num_dofs": sol.disc.num_dofs,
    }


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["analytic-tri", "analytic-quad", "strip-tri", "strip-quad"])
def test_serial_and_parallel_agree(case):
    """The same problem on COMM_WORLD and on COMM_SELF: same numbers to 1e-10 relative."""
    par = _summary(ds.solve(CASES[case](MPI.COMM_WORLD)))
    ser = _summary(ds.solve(CASES[case](MPI.COMM_SELF)))
    for key in ("newton_iterations", "num_active", "num_cells", "num_dofs"):
        assert par[key] == ser[key], key
    for key in ("u_L2", "J_a1", "int_lam"):
        assert par[key] == pytest.approx(ser[key], rel=1e-10, abs=0.0), key
    assert ser["int_lam"] > 0.0


# --------------------------------------------------------------------------------------------------
# Examples 5.2 and 5.3
# --------------------------------------------------------------------------------------------------


def test_bar_example_solves_with_partial_contact():
    """Example 5.2 (plane stress bar): part of Gamma_C is in contact, part is not."""
    sol = ds.solve(bar_problem(MPI.COMM_WORLD))
    n_c = sol.disc.num_contact_elements
    assert n_c == 4
    assert 0 < sol.num_active < n_c
    assert sol.newton_iterations <= 8
    # The volume force pushes the bar in +x, onto the obstacle: a positive contact force.
    assert integrate(sol, sol.lam * sol.disc.m.ds_contact) > 0.0


@pytest.mark.parametrize(
    "cell_type", [mesh.CellType.tetrahedron, mesh.CellType.hexahedron], ids=["tet", "hex"]
)
def test_obstacle_example_as_in_the_paper(cell_type):
    """Example 5.3 as in the paper: no loads, the obstacle alone deforms the body."""
    sol = ds.solve(obstacle_problem(MPI.COMM_WORLD, cell_type=cell_type))
    tet = cell_type == mesh.CellType.tetrahedron
    # Gamma_C = [0, 0.5]^2 is 4 x 4 macro squares, split into 2 triangles each on tetrahedra.
    n_c = sol.disc.num_contact_elements
    assert n_c == (32 if tet else 16)
    assert sol.disc.num_cells == (2 * 8 * 8) * (6 * 8 if tet else 8)
    assert 0 < sol.num_active < n_c
    assert sol.newton_iterations <= 8
    # The obstacle penetrates the undeformed body (g < 0 near its tip) and pushes it back.
    assert integrate(sol, sol.lam * sol.disc.m.ds_contact) > 0.0


# --------------------------------------------------------------------------------------------------
# Warm start
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_warm_start_needs_no_more_iterations():
    """Bar (Example 5.2), uniformly refined: a warm start from the coarse u_h (lam = 0) needs no
    more Newton steps than the cold start, and its iteration count stays bounded.

    The bar and not Example 5.1: there the cold start (u, lam) = 0 already guesses the active set
    {g < 0}, which is exactly the strictly active part of the exact solution, and the bi-active
    rest (lam = 0 = u_n - g for |y| > 1/2) makes the count a matter of round-off; a warm start
    there took 1 Newton step more than the cold one on some levels (with lam_0 = 0 and with
    lam_0 interpolated), which says nothing about the warm start.
    """
    comm = MPI.COMM_WORLD
    coarse = None
    cold_its, warm_its = [], []
    for k in range(4):
        problem = bar_problem(comm, 2 * 2**k, 8 * 2**k)
        cold = ds.solve(problem)
        if coarse is not None:
            disc = ds.discretize(problem)
            guess = (transfer(disc.V, coarse.u), fem.Function(disc.Q))
            warm = ds.solve(disc, initial_guess=guess)
            assert warm.num_active == cold.num_active
            u_cold, _ = owned(cold)
            u_warm, _ = owned(warm)
            scale = global_max(u_cold, comm)
            assert global_max(u_warm - u_cold, comm) <= 1e-9 * scale
            cold_its.append(cold.newton_iterations)
            warm_its.append(warm.newton_iterations)
        coarse = cold
    assert all(w <= c for w, c in zip(warm_its, cold_its, strict=True)), (warm_its, cold_its)
    assert max(warm_its) <= 8, warm_its


@pytest.mark.mpi
@pytest.mark.parametrize("case", ["analytic-quad", "strip-tri"])
def test_solution_is_a_fixed_point(case):
    """Started from its own solution, the Newton method stops after one (identical) step."""
    sol = ds.solve(CASES[case](MPI.COMM_WORLD))
    again = ds.solve(sol.disc, initial_guess=(sol.u, sol.lam))
    assert again.newton_iterations == 1
    assert np.array_equal(again.active, sol.active)
    u, lam = owned(sol)
    u2, lam2 = owned(again)
    comm = sol.disc.comm
    assert global_max(u2 - u, comm) <= 1e-10 * global_max(u, comm)
    assert global_max(lam2 - lam, comm) <= 1e-10 * global_max(lam, comm)


def test_initial_guess_on_other_spaces_is_rejected():
    sol = ds.solve(analytic_problem(MPI.COMM_WORLD, 6, 4, TRI))
    other = ds.discretize(analytic_problem(MPI.COMM_WORLD, 6, 4, TRI))
    with pytest.raises(ValueError, match="initial_guess"):
        ds.solve(other, initial_guess=(sol.u, sol.lam))


# --------------------------------------------------------------------------------------------------
# Problems driven by the obstacle alone
# --------------------------------------------------------------------------------------------------


def test_load_free_and_tiny_load_problems_driven_by_the_obstacle():
    """No loads (and then a negligible load), an obstacle that penetrates the body.

    Regression test: without loads the load form was empty (IndexError), and with a tiny load the
    equilibrium residual, measured relative to ||f|| only, never fell below rtol.
    """

    def gap(x):
        return -0.01 + 0.02 * x[1] ** 2

    comm = MPI.COMM_WORLD
    free = ds.solve(analytic_problem(comm, 12, 8, TRI, body_force=None, gap=gap))
    tiny = ds.solve(analytic_problem(comm, 12, 8, TRI, body_force=(1e-8, 0.0), gap=gap))
    assert 0 < free.num_active < free.disc.num_contact_elements
    assert np.array_equal(free.active, tiny.active)
    u_free, _ = owned(free)
    u_tiny, _ = owned(tiny)
    assert global_max(u_tiny - u_free, comm) <= 1e-6 * global_max(u_free, comm)


# --------------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------------


def _bad_cell_tags(msh, tags):
    tdim = msh.topology.dim
    n = msh.topology.index_map(tdim).size_local
    cells = np.arange(n, dtype=np.int32)
    return {"facet_tags": mesh.meshtags(msh, tdim, cells, np.full(n, 3, dtype=np.int32))}


BAD_INPUT = [
    # id, change of the arguments, error, a regex the message must contain
    ("contact-tag-unused", lambda m, t: {"contact": 7}, ValueError, "contact tag 7"),
    ("contact-is-dirichlet", lambda m, t: {"dirichlet": (1, 3)}, ValueError, "contact.*dirichlet"),
    ("E-zero", lambda m, t: {"E": 0.0}, ValueError, r"\bE\b"),
    ("E-negative", lambda m, t: {"E": -10.0}, ValueError, r"\bE\b"),
    ("E-nan", lambda m, t: {"E": float("nan")}, ValueError, r"\bE\b"),
    ("nu-half", lambda m, t: {"nu": 0.5}, ValueError, r"\bnu\b"),
    ("nu-minus-one", lambda m, t: {"nu": -1.0}, ValueError, r"\bnu\b"),
    ("gap-nan", lambda m, t: {"gap": float("nan")}, ValueError, r"\bgap\b"),
    ("gap-inf", lambda m, t: {"gap": float("inf")}, ValueError, r"\bgap\b"),
    ("gap-string", lambda m, t: {"gap": "0.1"}, TypeError, r"\bgap\b"),
    ("model-3d-on-2d", lambda m, t: {"model": "3d"}, ValueError, r"\bmodel\b"),
    ("model-unknown", lambda m, t: {"model": "axisymmetric"}, ValueError, r"\bmodel\b"),
    ("cell-tags", _bad_cell_tags, ValueError, "facet_tags"),
    ("body-force-3", lambda m, t: {"body_force": (1.0, 0.0, 0.0)}, ValueError, "body_force"),
    ("body-force-1", lambda m, t: {"body_force": (1.0,)}, ValueError, "body_force"),
    ("body-force-nan", lambda m, t: {"body_force": (float("nan"), 0.0)}, ValueError, "body_force"),
    (
        "body-force-callable-3",
        lambda m, t: {"body_force": lambda x: ufl.as_vector((x[0], x[1], 0.0))},
        ValueError,
        "body_force",
    ),
    ("traction-on-contact", lambda m, t: {"traction": {3: (1.0, 0.0)}}, ValueError, "traction"),
    ("traction-length", lambda m, t: {"traction": {2: (1.0, 0.0, 0.0)}}, ValueError, "traction"),
    ("contact-not-int", lambda m, t: {"contact": 3.0}, TypeError, r"\bcontact\b"),
]


@pytest.mark.parametrize(
    ("change", "error", "match"),
    [pytest.param(c, e, s, id=i) for i, c, e, s in BAD_INPUT],
)
def test_bad_input_is_rejected_with_a_clear_message(change, error, match):
    msh, tags = ex.analytic_2d_mesh(MPI.COMM_WORLD, 6, 4, TRI)
    kwargs = {
        "facet_tags": tags,
        "contact": ex.CONTACT,
        "dirichlet": (ex.DIRICHLET,),
        "E": 10.0,
        "nu": 0.3,
        "gap": 0.0,
    }
    kwargs.update(change(msh, tags))
    with pytest.raises(error, match=match):
        ds.SignoriniProblem(msh, **kwargs)


def test_solve_rejects_other_objects():
    with pytest.raises(TypeError, match="SignoriniProblem"):
        ds.solve("not a problem")


# --------------------------------------------------------------------------------------------------
# Q1 on hexahedra against P1 on tetrahedra (contact-free)
# --------------------------------------------------------------------------------------------------


def _box_compliance(n, cell_type):
    """A contact-free box (gap = 1e3): the compliance int f . u dx of a clamped box."""
    problem = obstacle_problem(
        MPI.COMM_WORLD, (n, 2 * n, 2 * n), cell_type, E=1.0, body_force=(1.0, 0.0, 0.5), gap=1e3
    )
    sol = ds.solve(problem)
    assert sol.num_active == 0
    return integrate(sol, ufl.inner(ufl.as_vector((1.0, 0.0, 0.5)), sol.u) * sol.disc.m.dx)


def test_hexahedra_and_tetrahedra_agree_without_contact():
    """Q1 (hex) and P1 (tet) compliances agree to well within their discretisation errors."""
    hexes = [_box_compliance(n, mesh.CellType.hexahedron) for n in (1, 2)]
    tets = [_box_compliance(n, mesh.CellType.tetrahedron) for n in (1, 2)]
    # Conforming displacement methods: the compliance a(u_h, u_h) grows under refinement.
    assert hexes[0] < hexes[1] and tets[0] < tets[1]
    # The two discretisations differ by much less than either changes under refinement.
    change = min(hexes[1] - hexes[0], tets[1] - tets[0])
    assert abs(hexes[1] - tets[1]) <= 0.25 * change
    assert abs(hexes[1] - tets[1]) <= 0.01 * hexes[1]


@pytest.mark.mpi
@pytest.mark.parametrize(
    "build",
    [
        lambda c: analytic_problem(c, 6, 4, mesh.CellType.triangle),
        lambda c: obstacle_problem(c, (1, 4, 4)),
    ],
    ids=["2d", "3d"],
)
def test_fine_facet_tags_cover_the_macro_tags(build):
    """The fine facet tags carried through the parent facets measure what the macro tags do
    (every tag, before and after a marked refinement), and searching parent facets only next to
    tagged macro facets finds what the search over all macro facets finds on them."""
    from dwr_signorini.spaces import discretize, fine_to_macro_facets, refine_marked

    problem = build(MPI.COMM_WORLD)
    comm = problem.mesh.comm
    tdim = problem.mesh.topology.dim
    num_cells = problem.mesh.topology.index_map(tdim).size_local
    marked, _ = refine_marked(problem, np.arange(0, num_cells, 3, dtype=np.int32))
    for coarse in (problem, marked):
        disc = discretize(coarse)

        def measure(msh, tags, value):
            ds_ = ufl.Measure("ds", domain=msh, subdomain_data=tags)
            local = fem.assemble_scalar(fem.form(1.0 * ds_(value)))
            return comm.allreduce(local, op=MPI.SUM)

        values = sorted(set().union(*comm.allgather(set(coarse.facet_tags.values.tolist()))))
        for value in values:
            fine = measure(disc.mesh, disc.facet_tags, int(value))
            assert math.isclose(fine, measure(coarse.mesh, coarse.facet_tags, int(value)),
                                rel_tol=1e-12)
        full = fine_to_macro_facets(coarse.mesh, disc.mesh, disc.parent_cell)
        tagged = np.isin(full, coarse.facet_tags.indices)
        assert np.array_equal(disc.fine_to_macro_facet, np.where(tagged, full, -1))
