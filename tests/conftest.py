"""Shared test set-up: collective clean-up after each test and an MPI-aware temporary directory."""

import gc

from mpi4py import MPI

import pytest


@pytest.fixture(autouse=True)
def _collective_teardown():
    """PETSc objects are destroyed collectively: collect garbage on every rank, then wait."""
    yield
    gc.collect()
    MPI.COMM_WORLD.Barrier()


@pytest.fixture
def mpi_tmp_path(tmp_path):
    """A temporary directory that is the same on every rank (rank 0's)."""
    return MPI.COMM_WORLD.bcast(tmp_path, root=0)
