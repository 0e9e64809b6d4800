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
from .collective import on_root

__all__ = ["read_mesh"]


def _model_dimension(model: Any) -> int:
    """The largest dimension of an entity of the gmsh model (2: plane mesh, 3: volume)."""
    entities = model.getEntities()
    return max((d for d, _ in entities), default=0)


def _check_arguments(path_or_model: Any, comm: Any, rank: Any, gdim: Any) -> None:
    """TypeError or ValueError naming the argument of :func:`read_mesh` that is wrong."""
    if not isinstance(path_or_model, (str, os.PathLike)) and not hasattr(
        path_or_model, "getEntities"
    ):
        raise TypeError(
            "path_or_model must be a path to a .msh file or a gmsh model (gmsh.model), got "
            f"{path_or_model!r}"
        )
    if not isinstance(comm, MPI.Comm):
        raise TypeError(f"comm must be an mpi4py communicator (e.g. MPI.COMM_WORLD), got {comm!r}")
    if isinstance(rank, bool) or not isinstance(rank, int) or not 0 <= rank < comm.size:
        raise ValueError(
            f"rank must be an integer in [0, {comm.size}) (the rank that reads), got {rank!r}"
        )
    if gdim not in (None, 2, 3) or isinstance(gdim, bool):
        raise ValueError(f"gdim must be 2, 3 or None (the model's dimension), got {gdim!r}")


def _check_model(model: Any) -> None:
    """ValueError naming path_or_model if the gmsh model holds no mesh (on the reading rank)."""
    try:
        tags = model.mesh.getNodes()[0]
    except Exception as err:
        raise ValueError(f"path_or_model: the gmsh model cannot be read: {err}") from err
    if len(tags) == 0:
        raise ValueError(
            "path_or_model: the gmsh model has no mesh; generate it first "
            "(gmsh.model.mesh.generate(dim)) or pass a .msh file"
        )
    dims = {d for d, _ in model.getPhysicalGroups()}
    if _model_dimension(model) not in dims:  # dolfinx cannot read the cells without them
        raise _no_groups("cell")


def _no_groups(name: str) -> ValueError:
    """The error of a mesh without physical groups of ``name`` (``"cell"``, ``"facet"``)."""
    return ValueError(
        f"read_mesh: the mesh has no physical groups of {name}s; add them in gmsh "
        "(gmsh.model.addPhysicalGroup) to get tags for the materials and boundaries"
    )


def _open(comm: MPI.Comm, rank: int, path: str) -> None:
    """gmsh.open the file on ``rank``; its failure on every rank, naming path_or_model."""
    import gmsh

    def read() -> None:
        gmsh.clear()
        try:
            gmsh.open(path)
        except Exception as err:
            raise ValueError(
                f"path_or_model {path!r} could not be read as a gmsh mesh (expected a .msh "
                f"file written by gmsh): {err}"
            ) from err

    on_root(comm, "read_mesh", read, root=rank)


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
        TypeError: ``path_or_model`` or ``comm`` of the wrong type.
        ValueError: If the file is not a gmsh mesh, the mesh has no physical groups of cells or
            of facets, or ``rank`` or ``gdim`` are out of range (on every rank: the reading
            rank's errors are raised collectively, :mod:`dwr_signorini.collective`).
        ImportError: If the gmsh Python module is missing.
    """
    _check_arguments(path_or_model, comm, rank, gdim)
    import gmsh

    owns_session = False
    model, path = path_or_model, None
    if isinstance(path_or_model, (str, os.PathLike)):
        path = os.fspath(path_or_model)
        exists = comm.bcast(os.path.isfile(path) if comm.rank == rank else None, root=rank)
        if not exists:
            raise FileNotFoundError(f"read_mesh: no mesh file {path!r}")
        if not gmsh.isInitialized():
            gmsh.initialize()
            owns_session = True
        gmsh.option.setNumber("General.Terminal", 0)
        model = gmsh.model
    try:
        if path is not None:
            _open(comm, rank, path)
        on_root(comm, "read_mesh", _check_model, model, root=rank)
        if gdim is None:
            gdim = comm.bcast(
                on_root(comm, "read_mesh", _model_dimension, model, root=rank), root=rank
            )
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
            raise _no_groups(name)
    return msh, cell_tags, facet_tags
