"""Extreme gaps: never reached (plain linear elasticity), touching, initial penetration, sharply
varying, pulled away, the whole boundary active and grazing, each against a closed form or the
discrete contact conditions (19)."""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

from . import fem_compat
from .helpers import (
    contact_conditions,
    global_max,
    integrate,
    owned,
    same_solution,
)
from .problems import TRI, block, loaded_block, make

DIRICHLET, NEUMANN, CONTACT = ex.DIRICHLET, ex.NEUMANN, ex.CONTACT


# --------------------------------------------------------------------------------------------------
# 3. Gaps
# --------------------------------------------------------------------------------------------------


def _linear_elasticity(sol):
    """The same P1 problem without contact, solved by a plain dolfinx LinearProblem."""
    disc, problem = sol.disc, sol.disc.problem
    V, m = disc.V, disc.m
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = ufl.inner(problem.sigma(u), problem.epsilon(v)) * m.dx
    L = ufl.inner(ufl.as_vector(problem.body_force), v) * m.dx
    for tag, t in problem.traction.items():
        L += ufl.inner(ufl.as_vector(t), v) * m.ds(tag)
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
    lp = fem_compat.linear_problem(a, L, bcs=disc.bcs, petsc_options=options)
    return lp.solve()


@pytest.mark.mpi
def test_gap_never_reached_is_linear_elasticity():
    """g = +1e3: nothing touches; u_h is the plain linear-elastic P1 solution (dolfinx
    LinearProblem on the same fine mesh), lambda = 0, and the estimate has no contact term."""
    sol = ds.solve(loaded_block(MPI.COMM_WORLD, 1e3))
    assert sol.num_active == 0
    assert sol.newton_iterations == 1
    comm = sol.disc.comm
    u_lin = _linear_elasticity(sol)
    u, lam = owned(sol)
    assert global_max(u - u_lin.x.array[: len(u)], comm) <= 1e-10 * global_max(u, comm)
    assert global_max(lam, comm) == 0.0
    est = ds.estimate(sol, lambda u, lam, m: u[1] * m.dx + lam * m.ds_contact)
    assert est.contact_term == 0.0


@pytest.mark.mpi
def test_touching_gap_zero_and_tiny_gap():
    """g = 0 (touching) and g = 1e-12: both converge with the contact conditions; the tiny gap
    changes the solution by O(1e-12) only (Lipschitz dependence on g), with the same active set.
    Without loads, g = 0 leaves the body at rest: u = 0, lambda = 0 exactly."""
    comm = MPI.COMM_WORLD
    zero = ds.solve(loaded_block(comm, 0.0))
    tiny = ds.solve(loaded_block(comm, 1e-12))
    for sol in (zero, tiny):
        contact_conditions(sol)
        assert sol.num_active > 0
    assert np.array_equal(zero.active, tiny.active)
    u0, l0 = owned(zero)
    u1, l1 = owned(tiny)
    assert global_max(u1 - u0, comm) <= 1e-10
    assert global_max(l1 - l0, comm) <= 1e-8 * global_max(l0, comm)
    rest = ds.solve(make(*block(comm, 4, 4), gap=0.0))
    assert rest.num_active == 0 and rest.newton_iterations == 1
    assert global_max(owned(rest)[0], comm) == 0.0 and global_max(owned(rest)[1], comm) == 0.0


@pytest.mark.mpi
@pytest.mark.parametrize(
    "gap",
    [lambda x: -0.01 + 0.0 * x[0], lambda x: -0.01 - 0.02 * x[0] ** 2],
    ids=["uniform", "varying"],
)
def test_initial_penetration_pushes_the_body(gap):
    """g < 0 everywhere and no loads: the obstacle alone deforms the body. The contact
    conditions hold, the contact force is compressive, and the solution is positively
    homogeneous in g: doubling the penetration doubles u and lambda, same active set."""
    comm = MPI.COMM_WORLD
    msh, tags = block(comm, 8, 8)
    sol = ds.solve(make(msh, tags, gap=gap))
    contact_conditions(sol)
    assert sol.num_active > 0
    assert integrate(sol, sol.lam * sol.disc.m.ds_contact) > 0
    msh, tags = block(comm, 8, 8)
    double = ds.solve(make(msh, tags, gap=lambda x: 2.0 * gap(x)))
    same_solution(sol, double, 2.0, 2.0)


@pytest.mark.mpi
def test_sharply_varying_gap_3d_obstacle():
    """Example 5.3's obstacle (C^0, 0.05 deep) on a coarse mesh, load-free as in the paper:
    partial contact, the contact conditions hold, the contact force is compressive."""
    comm = MPI.COMM_WORLD
    sol = ds.solve(ex.obstacle_problem(comm, (1, 4, 4)))
    assert 0 < sol.num_active < sol.disc.num_contact_elements
    assert sol.newton_iterations <= 10
    contact_conditions(sol)
    assert integrate(sol, sol.lam * sol.disc.m.ds_contact) > 0


@pytest.mark.mpi
def test_body_pulled_away_has_empty_active_set():
    """Loads pulling the body off the obstacle (g = 0): empty active set, lambda = 0, and u is
    the contact-free solution (the same as with an unreachable gap)."""
    comm = MPI.COMM_WORLD
    pulled = ds.solve(loaded_block(comm, 0.0, body_force=(0.0, 0.5)))
    free = ds.solve(loaded_block(comm, 1e3, body_force=(0.0, 0.5)))
    assert pulled.num_active == 0
    assert global_max(owned(pulled)[1], comm) == 0.0
    same_solution(free, pulled)
    contact_conditions(pulled)


@pytest.mark.mpi
def test_whole_contact_boundary_active_uniaxial_layer():
    """A layer of thickness t = 1 with nu = 0, clamped on top, resting on the obstacle (g = 0)
    under its weight rho: the solution is one-dimensional, u_y = rho / (2E) (y^2 - t y), and
    the obstacle carries half the weight: lambda = rho t / 2 on every facet. Q1 on a
    rectangular grid reduces to 1D linear elements (the hats are products a(x) b(y)), which
    are nodally exact with exact end reactions, so lambda_H is exact too."""
    comm = MPI.COMM_WORLD
    rho = 0.3
    msh, tags = block(comm, 6, 4, lx=3.0, cell_type=mesh.CellType.quadrilateral)
    sol = ds.solve(make(msh, tags, nu=0.0, body_force=(0.0, -rho), gap=0.0))
    assert sol.num_active == sol.disc.num_contact_elements
    _, lam = owned(sol)
    assert global_max(lam - rho / 2, comm) <= 1e-10 * rho
    contact_conditions(sol)


def _grazing(comm, n):
    """Example 5.1 on the n-times refined 12 x 8 macro mesh: (solution, distance from the
    bi-active state on the facets with |y| > 1/2), the distance being max_i lambda_i / max
    lambda + max_i |(N u - g)_i| / |E_i| / max |g|."""
    sol = ds.solve(ex.analytic_problem(comm, 12 * n, 8 * n, TRI))
    assert sol.newton_iterations <= 6
    r, size, lam = contact_conditions(sol)
    sub = sol.disc.contact_mesh
    y = mesh.compute_midpoints(sub, sub.topology.dim, np.arange(len(lam), dtype=np.int32))[:, 1]
    grazing = np.abs(y) > 0.5
    assert comm.allreduce(int(grazing.sum()), op=MPI.SUM) > 0
    max_g = 9.0 / 256.0  # |g| = 9 (y^2 - 1/4)^4 is largest at y = 0
    distance = (
        global_max(lam[grazing], comm) / global_max(lam, comm)
        + global_max(r[grazing] / size[grazing], comm) / max_g
    )
    return sol, distance


@pytest.mark.mpi
def test_grazing_contact_example_5_1():
    """Example 5.1: the exact solution is in contact on all of Gamma_C, with lambda = 0 and
    u_n = g together (bi-active) for |y| >= 1/2. Newton converges without cycling on this
    degenerate set, the contact conditions (19) hold, and on the grazing facets lambda_H and the
    gap residual are small and approach the bi-active state under refinement."""
    comm = MPI.COMM_WORLD
    _, coarse = _grazing(comm, 1)
    _, fine = _grazing(comm, 2)
    assert fine < 0.05
    assert fine < 0.7 * coarse
