"""Test problems shared by several test files."""

import importlib.util
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

TRI = mesh.CellType.triangle
E, NU = ex.ANALYTIC_MATERIAL.E, ex.ANALYTIC_MATERIAL.nu


def strip_problem(comm, nx=32, ny=8, cell_type=TRI):
    """A 4 x 1 strip clamped on top, pushed down onto an obstacle under its long bottom side.

    Its long contact boundary is cut by the mesh partitioner, so with 2 ranks both own contact
    rows (on the examples' meshes Gamma_C ends up on one rank).
    """
    msh = mesh.create_rectangle(
        comm,
        [np.array([0.0, 0.0]), np.array([4.0, 1.0])],
        [nx, ny],
        cell_type,
        ghost_mode=mesh.GhostMode.none,
    )

    def classify(x):
        values = np.full(x.shape[1], ex.NEUMANN, dtype=np.int32)
        values[np.isclose(x[1], 1.0)] = ex.DIRICHLET
        values[np.isclose(x[1], 0.0)] = ex.CONTACT
        return values

    return ds.SignoriniProblem(
        msh,
        ex.tag_exterior_facets(msh, classify),
        contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,),
        E=E,
        nu=NU,
        body_force=(0.0, -1.0),
        gap=lambda x: 0.02 * (x[0] - 2.0) ** 2 - 0.01,
    )


def indented_block(comm, nx, ny, delta, s_L=1.0, s_E=1.0, radius=1.0):
    """(0, 1) x (0, 0.5) scaled by s_L, top clamped, bottom in possible contact with a disc of
    radius ``radius`` (paraboloid gap) touching at x = 0.5 and lowered by delta.

    nx and ny are chosen so that no macro triangle has two edges of equal length: dolfinx's
    refinement (Plaza) orders the edges of a cell by length, and a tie between equal edges is
    broken by round-off, so with ties the two unit systems would refine differently (seen with
    square cells: 640 of 4096 fine cells differed)."""
    msh = mesh.create_rectangle(
        comm, [(0.0, 0.0), (s_L, 0.5 * s_L)], [nx, ny], mesh.CellType.triangle,
        ghost_mode=mesh.GhostMode.none,
    )

    def classify(x):
        tags = np.full(x.shape[1], ex.NEUMANN)
        tags[np.isclose(x[1], 0.5 * s_L)] = ex.DIRICHLET
        tags[np.isclose(x[1], 0.0)] = ex.CONTACT
        return tags

    def gap(x):
        return s_L * (((x[0] / s_L - 0.5) ** 2) / (2 * radius) - delta)

    return ds.SignoriniProblem(
        msh, ex.tag_exterior_facets(msh, classify), contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,), E=10.0 * s_E, nu=0.3, gap=gap,
    )


#: The gmsh scripts of the project.
MESHES = Path(__file__).resolve().parents[1] / "meshes"


def mesh_script(name):
    """The module ``meshes/<name>.py`` (its ``build``, tags and ``projections``)."""
    spec = importlib.util.spec_from_file_location(f"meshes_{name}", MESHES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def from_model(build, **kwargs):
    """``(mesh, cell_tags, facet_tags)`` read from the gmsh model that ``build`` makes."""
    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if MPI.COMM_WORLD.rank == 0:
            gmsh.model.add("test")
            build(gmsh.model, **kwargs)
        return ds.read_mesh(gmsh.model, MPI.COMM_WORLD)
    finally:
        gmsh.finalize()


def estimate_rel(level) -> float:
    """The relative tolerance to which a level's estimates agree between one process and several.

    The patch weights agree to round-off. The hierarchical P2 weights (``weights="auto"`` on a level
    whose contact set is not resolved) are solved with SOR sweeps that are local to each process
    and stop at a relative residual of ``HIERARCHICAL_RTOL``, so their estimates agree to that
    tolerance (measured: 1e-5 on dolfinx 0.9, 1.9e-4 on 0.11 for the ghosted strip, whose
    partition differs between the versions).
    """
    from dwr_signorini.hierarchical import HIERARCHICAL_RTOL

    return 1e-8 if level.weights == "patch" else HIERARCHICAL_RTOL
