"""Shared test set-up: collective clean-up after each test and an MPI-aware temporary directory."""

from mpi4py import MPI
from petsc4py import PETSc

import pytest


@pytest.fixture(autouse=True)
def _collective_garbage_cleanup():
    """PETSc objects a test dropped without destroy() wait in PETSc's garbage (petsc4py defers
    the destruction of parallel objects): clean it up collectively between tests."""
    yield
    PETSc.garbage_cleanup(MPI.COMM_WORLD)


@pytest.fixture
def mpi_tmp_path(tmp_path):
    """A temporary directory that is the same on every rank (rank 0's)."""
    return MPI.COMM_WORLD.bcast(tmp_path, root=0)
