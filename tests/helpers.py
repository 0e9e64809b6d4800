"""Checks and reductions shared by several test files.

Reductions over all ranks (:func:`integrate`, :func:`global_max`, :func:`global_min`,
:func:`global_sum`), the owned entries of a solution, goals several files use, the discrete
contact conditions (19), and the finite-difference check of the dual solution. The test problems
are in ``tests/problems.py`` (frictional patch tests: ``tests/friction_cases.py``).
"""

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

import dwr_signorini as ds
from dwr_signorini import examples as ex

#: Quadrature for the data in the checks: exact for the polynomial gaps used here.
EXACT_DATA = {"quadrature_degree": 8}


def integrate(sol, form):
    """A scalar form on the fine mesh (it may use lam), summed over all ranks."""
    return sol.disc.comm.allreduce(fem.assemble_scalar(sol.disc.form(form)), op=MPI.SUM)


def global_max(values, comm=MPI.COMM_WORLD):
    """Global max |values| (0 for no values anywhere)."""
    return comm.allreduce(float(np.max(np.abs(values), initial=0.0)), op=MPI.MAX)


def global_min(values, comm=MPI.COMM_WORLD):
    """Global min of values (inf for no values anywhere)."""
    return comm.allreduce(float(np.min(values, initial=np.inf)), op=MPI.MIN)


def global_sum(value, comm=MPI.COMM_WORLD):
    """The sum of a local number over all ranks."""
    return comm.allreduce(float(value), op=MPI.SUM)


def owned(sol):
    """Owned (u, lam) arrays of the solution."""
    return sol.u.x.array[: sol.system.n_u], sol.lam.x.array[: sol.system.n_lam]


def total_force(u, lam, m):
    """The goal int_{Gamma_C} lambda_n ds: the total contact force."""
    return lam * m.ds_contact


def linear_friction_goal(u, lam, m, lam_t):
    """A goal linear in (u, lambda_n, lambda_t) of a 2D frictional problem, on Gamma_C."""
    return (lam_t + 0.5 * lam + ufl.dot(u, ufl.as_vector((1.0, 2.0)))) * m.ds_contact


def assemble_q(disc, form):
    """Owned entries of a vector on Lambda_H (one per macro contact facet)."""
    vec = fem_petsc.assemble_vector(disc.form(form))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = vec.array.copy()
    vec.destroy()
    return out


def contact_conditions(sol, tol=1e-9):
    """Check the discrete contact conditions (19), assembled from their definition.

    (N u - g)_i = int_{E_i} (u . n - g) <= 0, lam_i >= 0 and lam_i (N u - g)_i = 0, each relative
    to the size of its terms. Returns (N u - g, M, lam) on the owned facets.
    """
    disc, comm = sol.disc, sol.disc.comm
    m, mu = disc.m, ufl.TestFunction(disc.Q)
    ds_c = m.ds_contact(metadata=EXACT_DATA)
    gap = disc.problem.gap_expr(m.x)
    r = assemble_q(disc, mu * (ufl.dot(sol.u, m.n) - gap) * ds_c)
    g = assemble_q(disc, mu * gap * ds_c)
    size = assemble_q(disc, mu * ds_c)
    u, lam = owned(sol)
    gap_scale = global_max(size, comm) * global_max(u, comm) + global_max(g, comm)
    force_scale = global_max(size * lam, comm)
    assert global_max(np.maximum(r, 0.0), comm) <= tol * gap_scale, "penetration"
    assert global_min(lam, comm) >= -tol * force_scale, "negative contact force"
    assert global_max(size * lam * r, comm) <= tol * force_scale * gap_scale, "complementarity"
    return r, size, lam


def same_solution(a, b, scale_u=1.0, scale_lam=1.0, rtol=1e-9):
    """u_b = scale_u u_a and lam_b = scale_lam lam_a (owned entries), same active set."""
    comm = a.disc.comm
    ua, la = owned(a)
    ub, lb = owned(b)
    assert global_max(ub - scale_u * ua, comm) <= rtol * global_max(scale_u * ua, comm)
    assert global_max(lb - scale_lam * la, comm) <= rtol * max(
        global_max(scale_lam * la, comm), 1e-300)
    assert np.array_equal(a.active, b.active)
    assert a.newton_iterations == b.newton_iterations


def example_variant(base, **data):
    """The frictional example ``base`` (its mesh, tags and Dirichlet values; E = 10, nu = 0.3)
    with the gap, friction law and loads of ``data``."""
    return ds.SignoriniProblem(
        base.mesh, base.facet_tags, contact=ex.CONTACT, dirichlet=base.dirichlet_values,
        E=10.0, nu=0.3, **data,
    )


def with_body_force(base, body_force):
    """The frictional example ``base`` with a body force (:func:`example_variant`)."""
    return example_variant(base, gap=base.gap, friction=base.law, body_force=body_force)


def check_frictionless_limit(tresca, free):
    """Tresca's law with a tiny threshold (``tresca``) solves as the frictionless ``free``: the
    same u and lambda_n to 1e-8 (relative, max norm), lambda_t at most 1e-12."""
    with ds.solve(tresca) as a, ds.solve(free) as b:
        assert a.num_active > 0 and b.lam_t is None
        assert global_max(a.u.x.array - b.u.x.array) <= 1e-8 * global_max(b.u.x.array)
        assert global_max(a.lam.x.array - b.lam.x.array) <= 1e-8 * global_max(b.lam.x.array)
        assert global_max(a.lam_t.x.array) <= 1e-12


def dual_against_finite_differences(solve, goal, load, same_sets, eps=1e-5):
    """The dual's d/de J(w_h(e)) at e = 0 and its central difference from re-solved problems.

    Args:
        solve: ``eps -> Solution`` of the problem with the body force ``eps`` times a direction.
        goal: The goal J.
        load: ``v -> `` the direction . v (UFL), the load of ``eps = 1``.
        same_sets: ``(other, sol) ->`` asserts that the re-solved ``other`` has the sets of
            ``sol`` (so that J is differentiable there).
        eps: The step of the central difference.

    Returns:
        ``(predicted, fd)``: z_h . [int load(v) dx; 0] and (J(eps) - J(-eps)) / (2 eps).
    """
    with solve(0.0) as sol, ds.estimate(sol, goal, estimator="eta_p") as est:
        v = ufl.TestFunction(sol.disc.V)
        vec = fem_petsc.assemble_vector(sol.disc.form(load(v) * sol.disc.m.dx))
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(vec, sol.system.bcs)
        predicted = global_sum(est.dual.y.x.array[: sol.system.n_u] @ vec.array)
        vec.destroy()
        values = []
        for sign in (1.0, -1.0):
            with solve(sign * eps) as other:
                same_sets(other, sol)
                with ds.estimate(other, goal, estimator="eta_p") as e:
                    values.append(e.J_h)
    return predicted, (values[0] - values[1]) / (2 * eps)
