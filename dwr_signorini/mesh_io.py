"""Meshes from gmsh: ``read_mesh(path_or_model, comm) -> (mesh, cell_tags, facet_tags)``.

A ``.msh`` file (or a gmsh model built with the gmsh Python API, e.g. by the scripts in the
project's ``meshes/`` folder) becomes an unghosted dolfinx mesh with the cell tags and facet tags
of its physical groups. Unghosted, because the refinement carries facet tags through the parent
maps and ``dolfinx.mesh.transfer_meshtag`` refuses ghosted meshes (shared/DESIGN.md §5); the
estimator needs no ghost cells. The gmsh model is read on one rank and distributed.
"""

from __future__ import annotations

import os
from typing import Any

from mpi4py import MPI

from dolfinx import mesh as dmesh

from . import compat

__all__ = ["read_mesh"]


def _model_dimension(model: Any) -> int:
    """The largest dimension of an entity of the gmsh model (2: plane mesh, 3: volume)."""
    entities = model.getEntities()
    return max((d for d, _ in entities), default=0)


def read_mesh(
    path_or_model: str | os.PathLike[str] | Any,
    comm: MPI.Comm = MPI.COMM_WORLD,
    rank: int = 0,
    gdim: int | None = None,
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """Read a gmsh mesh with its physical groups as cell and facet tags.

    Args:
        path_or_model: A ``.msh`` file, or a gmsh model (``gmsh.model``) with a generated mesh
            on rank ``rank``.
        comm: The communicator to distribute the mesh on (collective).
        rank: The rank that holds the model / reads the file.
        gdim: Geometric dimension; default the model's dimension (a 2D mesh lies in the plane).

    Returns:
        ``(mesh, cell_tags, facet_tags)``, the mesh unghosted (``GhostMode.none``).

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: If the mesh has no physical groups of cells or of facets.
        ImportError: If the gmsh Python module is missing.
    """
    import gmsh

    owns_session = False
    model = path_or_model
    if isinstance(path_or_model, (str, os.PathLike)):
        path = os.fspath(path_or_model)
        exists = comm.bcast(os.path.isfile(path) if comm.rank == rank else None, root=rank)
        if not exists:
            raise FileNotFoundError(f"read_mesh: no mesh file {path!r}")
        if not gmsh.isInitialized():
            gmsh.initialize()
            owns_session = True
        gmsh.option.setNumber("General.Terminal", 0)
        if comm.rank == rank:
            gmsh.clear()
            gmsh.open(path)
        model = gmsh.model
    try:
        if gdim is None:
            gdim = comm.bcast(_model_dimension(model) if comm.rank == rank else None, root=rank)
        partitioner = compat.cell_partitioner(dmesh.GhostMode.none)
        msh, cell_tags, facet_tags = compat.gmsh_model_to_mesh(
            model, comm, rank, gdim=gdim, partitioner=partitioner
        )
    finally:
        if owns_session:
            gmsh.finalize()
    for name, tags in (("cell", cell_tags), ("facet", facet_tags)):
        count = 0 if tags is None else len(tags.values)
        if comm.allreduce(count, op=MPI.SUM) == 0:
            raise ValueError(
                f"read_mesh: the mesh has no physical groups of {name}s; add them in gmsh "
                "(gmsh.model.addPhysicalGroup) to get tags for the materials and boundaries"
            )
    return msh, cell_tags, facet_tags
