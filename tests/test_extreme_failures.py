"""Solver failures are loud (the iteration limit, dependent contact constraints, MUMPS out of
memory, inaccurate linear solvers, NaN data, each raised with the Newton history) and the
least-index safeguard breaks the cycling of the active sets."""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.linalg import iterative_petsc_options

from .helpers import (
    contact_conditions,
    same_solution,
)
from .problems import block, cycling_cantilever, loaded_block, make

TET = mesh.CellType.tetrahedron
DIRICHLET, NEUMANN, CONTACT = ex.DIRICHLET, ex.NEUMANN, ex.CONTACT


# --------------------------------------------------------------------------------------------------
# 5. Solver failures are loud; the cycling safeguard
# --------------------------------------------------------------------------------------------------

@pytest.mark.mpi
@pytest.mark.parametrize("ncp_scale", [1e-6, "physical", 1e6])
def test_active_set_cycling_is_broken_by_the_safeguard(ncp_scale):
    """The plain active-set iteration revisits an active set on this problem; the solver detects
    it, switches to the least-index rule, and converges to the solution of the contact
    conditions. Whatever c_n (1e-6, E / H, 1e6), the iterates are the same: after the
    first step, (N u - g)_A = 0 and lambda_I = 0, so c_n drops out of the active-set test."""
    comm = MPI.COMM_WORLD
    sol = ds.solve(cycling_cantilever(comm), ncp_scale=ncp_scale)
    assert any(h["safeguard"] for h in sol.history)
    contact_conditions(sol)
    reference = ds.solve(cycling_cantilever(comm))
    sizes = [h["num_active"] for h in sol.history]
    assert sizes == [h["num_active"] for h in reference.history]
    same_solution(reference, sol)


@pytest.mark.mpi
def test_iteration_limit_raises_with_history():
    """Too few Newton steps: ConvergenceError with one history entry per iterate."""
    with pytest.raises(ds.ConvergenceError, match="max_iterations=3") as info:
        ds.solve(cycling_cantilever(MPI.COMM_WORLD), max_iterations=3)
    assert len(info.value.history) == 4
    assert [h["iteration"] for h in info.value.history] == [0, 1, 2, 3]


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("method", "options"),
    [("block", None), ("schur", None), ("schur", iterative_petsc_options())],
    ids=["block", "schur-direct", "schur-krylov"],
)
def test_dependent_contact_constraints_raise(method, options):
    """Degenerate 3D configuration: a 1 x 1 x 1 box clamped on its four sides, Gamma_C its bottom
    (two macro triangles). Their fine nodes are all clamped except the centre, so the two
    multipliers act on one normal displacement: with both active the Newton matrix (block path)
    and S_AA (Schur path) are singular. The solver raises ConvergenceError with the history
    instead of returning garbage."""
    comm = MPI.COMM_WORLD
    msh = mesh.create_box(
        comm, [(0, 0, 0), (1, 1, 1)], [1, 1, 1], TET, ghost_mode=mesh.GhostMode.none
    )

    def classify(x):
        tags = np.full(x.shape[1], DIRICHLET)
        tags[np.isclose(x[2], 1.0)] = NEUMANN
        tags[np.isclose(x[2], 0.0)] = CONTACT
        return tags

    problem = make(msh, ex.tag_exterior_facets(msh, classify), model="3d", gap=-0.01)
    with pytest.raises(ds.ConvergenceError, match=r"Newton step 0.*singular") as info:
        ds.solve(problem, method=method, petsc_options=options)
    assert len(info.value.history) == 1


@pytest.mark.mpi
@pytest.mark.parametrize("method", ["block", "schur"])
def test_mumps_out_of_memory_is_named(method):
    """A factorisation that MUMPS cannot fit (here: its working memory capped at 1 MB by
    ICNTL(23)) is reported as such, with the option to change, not as a singular matrix."""
    match = r"mat_mumps_icntl_23 allows \(INFOG\(1\) = -19"
    with pytest.raises(ds.ConvergenceError, match=match) as info:
        ds.solve(loaded_block(MPI.COMM_WORLD, 0.0, n=32), method=method,
                 petsc_options={"mat_mumps_icntl_23": 1})
    assert "singular" not in str(info.value)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("options", "match", "steps"),
    [
        ({"ksp_type": "gmres", "pc_type": "none", "ksp_max_it": 3}, "did not converge", 1),
        (
            {"ksp_type": "gmres", "pc_type": "jacobi", "ksp_rtol": 1e-5, "ksp_max_it": 10**5},
            "stationary but the residuals",
            3,
        ),
    ],
    ids=["krylov-stopped", "krylov-loose"],
)
def test_inaccurate_linear_solver_raises_with_history(options, match, steps):
    """A Krylov solver stopped after 3 iterations, and one accepted by PETSc at a loose
    tolerance: the failed solve, or the iterate that does not satisfy the equations, is
    reported with the Newton history and never returned."""
    with pytest.raises(ds.ConvergenceError, match=match) as info:
        ds.solve(loaded_block(MPI.COMM_WORLD, 0.0), petsc_options=options)
    assert len(info.value.history) == steps
    assert "petsc_options" in str(info.value)


@pytest.mark.mpi
@pytest.mark.parametrize(
    "data",
    [
        {"body_force": lambda x: ufl.as_vector((float("nan"), 0.0))},
        # NaN only in x > 3/4: on one rank in parallel; the check must still be collective.
        {
            "body_force": lambda x: ufl.as_vector(
                (ufl.conditional(ufl.gt(x[0], 0.75), ufl.sqrt(x[0] - 2.0), 0.0), 0.0)
            )
        },
        {"gap": lambda x: ufl.ln(x[0] - 2.0)},
        {"traction": {NEUMANN: lambda x: ufl.as_vector((0.0, float("inf")))}},
    ],
    ids=["nan-body-force", "nan-on-one-rank", "nan-gap", "inf-traction"],
)
def test_nan_data_raises_at_once_on_every_rank(data):
    """NaN/Inf in the data raise ConvergenceError before the first Newton step, on all ranks."""
    comm = MPI.COMM_WORLD
    msh, tags = block(comm, 4, 4)
    with pytest.raises(ds.ConvergenceError, match="NaN or Inf") as info:
        ds.solve(make(msh, tags, **data))
    assert info.value.history == []
