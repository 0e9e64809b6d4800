"""Test problems shared by several test files."""

import importlib.util
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

TRI = mesh.CellType.triangle
E, NU = ex.ANALYTIC_MATERIAL.E, ex.ANALYTIC_MATERIAL.nu


def tag_by_midpoint(msh, default, rules):
    """Facet tags of every exterior facet of ``msh``: ``default``, then each ``(tag, where)`` of
    ``rules`` in order (a later rule overrides an earlier one), ``where`` mapping the facets'
    midpoints, shape ``(3, num_facets)``, to a boolean mask."""
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, fdim + 1)
    facets = mesh.exterior_facet_indices(msh.topology).astype(np.int32)
    mid = mesh.compute_midpoints(msh, fdim, facets).T
    values = np.full(facets.size, default, dtype=np.int32)
    for tag, where in rules:
        values[where(mid)] = tag
    return mesh.meshtags(msh, fdim, facets, values)


#: The examples' facet tags of a block clamped on top, in possible contact at the bottom.
top_clamped_tags = ex.tag_block_facets


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

    return ds.SignoriniProblem(
        msh,
        top_clamped_tags(msh, 1.0),
        contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,),
        E=E,
        nu=NU,
        body_force=(0.0, -1.0),
        gap=lambda x: 0.02 * (x[0] - 2.0) ** 2 - 0.01,
    )


def indented_block(comm, nx, ny, delta, s_L=1.0, s_E=1.0, radius=1.0, nu=0.3):
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


    def gap(x):
        return s_L * (((x[0] / s_L - 0.5) ** 2) / (2 * radius) - delta)

    return ds.SignoriniProblem(
        msh, ex.tag_block_facets(msh, 0.5 * s_L), contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,), E=10.0 * s_E, nu=nu, gap=gap,
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

    The patch weights and the factored P2 ones (``"higher_order"``, and ``"local"``, which
    ``weights="auto"`` takes on a level whose contact set is not resolved) agree to round-off.
    The hierarchical P2 weights are solved iteratively (the coarse step by the factors of each
    partition, the smoother's eigenvalue estimate from a random start) and stop at a relative
    residual of ``HIERARCHICAL_RTOL``, so their estimates agree to that tolerance.
    """
    from dwr_signorini.hierarchical import HIERARCHICAL_RTOL

    return HIERARCHICAL_RTOL if level.weights == "hierarchical" else 1e-8


def block(comm, nx, ny, lx=1.0, ly=1.0, transform=None, cell_type=TRI):
    """(0, lx) x (0, ly): top clamped, bottom y = 0 in possible contact, sides free.

    ``transform`` maps the coordinates (an array (2, n)) onto the same rectangle (grading).
    """
    msh = mesh.create_rectangle(
        comm, [(0.0, 0.0), (lx, ly)], [nx, ny], cell_type, ghost_mode=mesh.GhostMode.none
    )
    if transform is not None:
        msh.geometry.x[:, :2] = np.asarray(transform(msh.geometry.x[:, :2].T)).T
    return msh, top_clamped_tags(msh, ly)


def cantilever(comm, nx, ny, length, diagonal=mesh.DiagonalType.right):
    """(0, length) x (0, 1) clamped at x = 0, bottom y = 0 in possible contact."""
    msh = mesh.create_rectangle(
        comm,
        [(0.0, 0.0), (length, 1.0)],
        [nx, ny],
        TRI,
        ghost_mode=mesh.GhostMode.none,
        diagonal=diagonal,
    )

    def classify(x):
        tags = np.full(x.shape[1], ex.NEUMANN)
        tags[np.isclose(x[0], 0.0)] = ex.DIRICHLET
        tags[np.isclose(x[1], 0.0) & (x[0] > 1e-12)] = ex.CONTACT
        return tags

    return msh, ex.tag_exterior_facets(msh, classify)


def make(msh, tags, **kwargs):
    """A SignoriniProblem with the tags of :func:`block` and small defaults."""
    args = {"contact": ex.CONTACT, "dirichlet": (ex.DIRICHLET,), "E": 1.0, "nu": 0.3}
    args.update(kwargs)
    return ds.SignoriniProblem(msh, tags, **args)


def loaded_block(comm, gap, body_force=(0.02, -0.1), n=8):
    """The n x n :func:`block` under a body force and a downward traction on its sides."""
    msh, tags = block(comm, n, n)
    return make(msh, tags, body_force=body_force, traction={ex.NEUMANN: (0.0, -0.01)}, gap=gap)


#: A gap, piecewise constant on the 10 unit macro facets of the cantilever's bottom, for which
#: the plain semi-smooth Newton method (primal-dual active set) cycles with period 3. Found by
#: running the method on the Schur complement N K^-1 N^T of this mesh for random gaps; a P-matrix
#: linear complementarity problem has a unique solution, which the least-index safeguard finds.
CYCLING_GAP = [-2.2, 0.6, -0.4, -1.4, 0.3, -1.1, -1.0, 1.7, 0.8, -0.6]


def cycling_cantilever(comm):
    """Cantilever 10 x 1 (one macro cell high): bending makes N K^-1 N^T far from an M-matrix."""
    msh, tags = cantilever(comm, 10, 1, 10.0)

    def gap(x):
        g = ufl.as_ufl(1e-3 * CYCLING_GAP[-1])
        for i in range(len(CYCLING_GAP) - 2, -1, -1):
            g = ufl.conditional(ufl.lt(x[0], i + 1.0), 1e-3 * CYCLING_GAP[i], g)
        return g

    return make(msh, tags, gap=gap)
