"""Alternative linear solvers give the same results as the reference direct block solve."""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.newton import iterative_petsc_options


@pytest.mark.mpi
def test_iterative_fieldsplit_matches_direct_3d():
    """FGMRES + Schur field split + GAMG reproduces the MUMPS solution, dual and estimate."""
    msh, tags = ex.obstacle_3d_mesh(MPI.COMM_WORLD, n=(2, 8, 8))
    problem = ds.SignoriniProblem(msh, tags, contact=3, dirichlet=(1,), E=1e5, nu=0.3,
                                  model="3d", gap=ex.obstacle_gap)
    results = []
    for opts in (None, iterative_petsc_options()):
        sol = ds.solve(problem, petsc_options=opts)
        est = ds.estimate(sol, ex.goal_obstacle(), petsc_options=opts)
        local = fem.assemble_scalar(fem.form(sol.u[0] ** 2 * sol.disc.m.dx))
        norm = np.sqrt(msh.comm.allreduce(local, op=MPI.SUM))
        results.append((sol.num_active, est.J_h, est.eta, norm))
    (a0, J0, e0, n0), (a1, J1, e1, n1) = results
    assert a0 == a1 and a0 > 0
    assert np.isclose(J1, J0, rtol=1e-7)
    assert np.isclose(n1, n0, rtol=1e-7)
    assert np.isclose(e1, e0, rtol=1e-5)
