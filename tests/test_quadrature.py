"""Quadrature degrees: polynomial integrands exact at UFL's estimate, data at the data degree."""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import compat
from dwr_signorini import examples as ex
from dwr_signorini.quadrature import (
    DATA_QUADRATURE_DEGREE,
    expand_integer_powers,
    is_polynomial,
    with_quadrature_degrees,
)


@pytest.fixture(scope="module")
def setting():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 5, 3, diagonal=mesh.DiagonalType.crossed)
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 1, (2,))))
    w = fem.Function(fem.functionspace(msh, ("Lagrange", 2, (2,))))
    u.interpolate(lambda x: np.vstack([np.sin(3 * x[0]) + x[1], np.cos(x[0] * x[1])]))
    w.interpolate(lambda x: np.vstack([np.exp(x[0]) * x[1], x[0] ** 3 - x[1]]))
    return msh, u, w, ufl.SpatialCoordinate(msh), fem.Constant(msh, 2.0)


def test_classification(setting):
    _, u, w, x, c = setting
    polynomial = [ufl.inner(ufl.grad(u), ufl.grad(w)), x[0] ** 2 * w[0], x[0] / c * w[1], -u[0]]
    other = [
        ufl.sin(x[0]) * w[0],
        x[0] / x[1],
        ufl.sqrt(x[0]),
        abs(x[0]),
        x[0] ** 0.5,
        ufl.conditional(ufl.lt(x[0], 0.5), 1.0, 0.0),
        ufl.max_value(x[0], 0.1),
        ufl.exp(u[0]),
    ]
    assert all(is_polynomial(e) for e in polynomial)
    assert not any(is_polynomial(e) for e in other)


@pytest.mark.mpi
def test_polynomial_integrands_are_exact_and_cheaper(setting):
    """UFL's estimate integrates a(u_h, w) + (x^3, w) exactly: equal to a degree-12 rule."""
    msh, u, w, x, _ = setting
    comm = msh.comm
    form = (ufl.inner(ufl.grad(u), ufl.grad(w)) + x[0] ** 3 * w[1]) * ufl.dx + u[0] * w[1] * ufl.ds
    chosen = with_quadrature_degrees(form)
    degrees = sorted(itg.metadata()["quadrature_degree"] for itg in chosen.integrals())
    assert max(degrees) < DATA_QUADRATURE_DEGREE
    fine = ufl.Form([i.reconstruct(metadata={"quadrature_degree": 12}) for i in form.integrals()])
    values = [comm.allreduce(fem.assemble_scalar(fem.form(f)), op=MPI.SUM) for f in (chosen, fine)]
    assert np.isclose(values[0], values[1], rtol=1e-13, atol=0)


def test_data_gets_the_data_degree_and_explicit_degrees_stay(setting):
    _, _, w, x, _ = setting
    form = ufl.sin(x[0]) * w[0] * ufl.dx + w[1] * ufl.dx(metadata={"quadrature_degree": 3})
    degrees = [
        itg.metadata()["quadrature_degree"] for itg in with_quadrature_degrees(form).integrals()
    ]
    assert sorted(degrees) == sorted([DATA_QUADRATURE_DEGREE, 3])
    assert with_quadrature_degrees(form, None) is form


def test_non_affine_cells_use_the_data_degree():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2, cell_type=mesh.CellType.quadrilateral)
    v = fem.Function(fem.functionspace(msh, ("Lagrange", 1)))
    (itg,) = with_quadrature_degrees(v * ufl.dx).integrals()
    assert itg.metadata()["quadrature_degree"] == DATA_QUADRATURE_DEGREE


def _powers(expr):
    return [n for n in ufl.corealg.traversal.unique_pre_traversal(expr)
            if isinstance(n, ufl.algebra.Power)]


@pytest.mark.mpi
def test_integer_powers_become_products_with_the_same_values(setting):
    """x**n and the pow calls of derivatives (n f**(n-1) f') are products; other powers stay."""
    msh, u, _, x, _ = setting
    comm = msh.comm
    a = x[0] ** 2 / 18.0 + 0.5
    data = ufl.as_vector(((x[1] - a) ** 4 * (x[0] + 3.0) ** 7.0, ufl.sin(x[0]) ** 3 * u[1] ** 2))
    expr = ufl.div(ufl.grad(data)) + ufl.as_vector((x[0] ** 0.5, (x[1] + 1.0) ** -2))
    expanded = expand_integer_powers(expr)
    left = _powers(expanded)
    assert sorted(float(p.ufl_operands[1]) for p in left) == [-2.0, 0.5]
    # The same (finite) values at the DG2 nodes, and the same integral of a form.
    V = fem.functionspace(msh, ("DG", 2, (2,)))
    values = []
    for e in (expr, expanded):
        f = fem.Function(V)
        f.interpolate(fem.Expression(e, compat.interpolation_points(V.element)))
        values.append(f.x.array.copy())
    assert np.all(np.isfinite(values[0]))
    assert np.allclose(values[0], values[1], rtol=1e-12, atol=1e-12)
    assert np.abs(values[0]).max() > 1.0
    form = ufl.inner(expr, expr) * ufl.dx(metadata={"quadrature_degree": 8})
    form_expanded = expand_integer_powers(form)
    assert not [p for i in form_expanded.integrals() for p in _powers(i.integrand())
                if float(p.ufl_operands[1]).is_integer() and float(p.ufl_operands[1]) > 1]
    integrals = [comm.allreduce(fem.assemble_scalar(fem.form(f)), op=MPI.SUM)
                 for f in (form, form_expanded)]
    assert np.isclose(integrals[0], integrals[1], rtol=1e-12, atol=0)


def _analytic_problem(comm, quadrature_degree):
    msh, tags = ex.analytic_2d_mesh(comm, 12, 8, mesh.CellType.triangle)
    mat = ex.ANALYTIC_MATERIAL
    return ds.SignoriniProblem(
        msh, tags, contact=ex.CONTACT, dirichlet=(ex.DIRICHLET,), E=mat.E, nu=mat.nu,
        model=mat.model, body_force=ex.analytic_body_force, gap=ex.analytic_gap,
        quadrature_degree=quadrature_degree,
    )


def _goal(u, lam, m):
    return u[0] * m.ds_contact


@pytest.mark.mpi
def test_the_problem_degree_reaches_the_solver_and_the_estimate():
    """Galerkin orthogonality at the problem's degree (example 5.1, whose body force is not a
    polynomial): the discrete equation tested with u_h itself (0 on Gamma_D),
    l(u_h) - a(u_h, u_h) - (lambda_h, u_h . n)_GC, vanishes to round-off with the problem's
    degree 3 and not with the default 8, which the solver did not use. ``estimate`` takes the
    problem's degree unless told otherwise, and a refined problem keeps it."""
    comm = MPI.COMM_WORLD
    problem = _analytic_problem(comm, 3)
    assert problem.quadrature_degree == 3
    assert problem.with_mesh(problem.mesh, problem.facet_tags).quadrature_degree == 3
    with ds.solve(problem, method="block") as sol:
        m = sol.disc.m
        f = ex.analytic_body_force(m.x)  # no tractions on Gamma_N in example 5.1

        def assemble(degree, load_only=False):
            form = ufl.inner(f, sol.u) * m.dx(metadata={"quadrature_degree": degree})
            if not load_only:
                form -= (problem.elastic_form(sol.u, sol.u, m.dx)
                         + sol.lam * ufl.dot(sol.u, m.n) * m.ds_contact)
            local = fem.assemble_scalar(sol.disc.form(form))
            return comm.allreduce(local, op=MPI.SUM)

        scale = abs(assemble(3, load_only=True))
        assert scale > 0
        assert abs(assemble(3)) < 1e-11 * scale
        assert abs(assemble(DATA_QUADRATURE_DEGREE)) > 1e-7 * scale
        eta = {q: ds.estimate(sol, _goal, quadrature_degree=q) for q in ("problem", 3, 8)}
        try:
            # the same degree: the same estimate up to the round-off of the dual solve (its
            # first call may factor the last Newton matrix where the step reused old factors)
            assert eta["problem"].eta == pytest.approx(eta[3].eta, rel=1e-12, abs=0.0)
            assert abs(eta[8].eta - eta[3].eta) > 1e-9 * abs(eta[3].eta)
        finally:
            for est in eta.values():
                est.destroy()


def _weighted_goal(u, lam, m):
    """Linear in u, with a weight that is not a polynomial (J_{a,m}'s cut-off function)."""
    return ex.omega(m.x, -0.5) * u[0] * m.dx


@pytest.mark.mpi
def test_the_goal_value_and_its_derivative_share_the_problem_degree():
    """For a goal linear in u, J(u_h) = J'(u_h)(u_h): the value ``estimate`` reports and the
    right-hand side of the dual problem (the vector of J'_u) satisfy this identity to round-off
    only if both integrate the non-polynomial weight with the same rule, the problem's degree 3,
    under which the value differs from that of the default degree 8."""
    from dwr_signorini.dual import dual_rhs
    from dwr_signorini.goal import GoalForms

    comm = MPI.COMM_WORLD
    problem = _analytic_problem(comm, 3)
    with ds.solve(problem, method="block") as sol:
        system = sol.system
        goal = GoalForms(_weighted_goal, sol.u, sol.lam, sol.disc)
        rhs = system.x.duplicate()
        try:
            # zero on the Dirichlet rows, where u_h = 0 (example 5.1 clamps Gamma_D)
            j_u = dual_rhs(system, goal, rhs).array_r[: system.n_u]
            derivative = comm.allreduce(float(j_u @ sol.u.x.array[: system.n_u]), op=MPI.SUM)
        finally:
            rhs.destroy()
        form = _weighted_goal(sol.u, sol.lam, sol.disc.m)
        eight = ufl.Form([i.reconstruct(metadata={"quadrature_degree": DATA_QUADRATURE_DEGREE})
                          for i in form.integrals()])
        J8 = comm.allreduce(fem.assemble_scalar(sol.disc.form(eight)), op=MPI.SUM)
        with ds.estimate(sol, _weighted_goal) as est:
            assert abs(derivative) > 0
            assert est.J_h == pytest.approx(derivative, rel=1e-12, abs=0)
            assert abs(est.J_h - J8) > 1e-9 * abs(J8)
