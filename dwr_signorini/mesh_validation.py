"""Validation of the macro mesh T_H and its tags: each error names its argument.

Pure functions as in :mod:`dwr_signorini.validation`: the mesh and its facet tags, the cell tags
(and that a material given per cell tag covers every cell), that every tag the data use marks a
boundary facet, and that a plane obstacle faces some contact facet.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

from . import compat
from .collective import shadow
from .obstacles import Plane

__all__ = [
    "check_cell_tags",
    "check_cells_covered",
    "check_mesh",
    "check_plane_faces_body",
    "check_tags",
]


def check_mesh(mesh: Any, facet_tags: Any) -> None:
    """The macro mesh T_H: a 2D or 3D affine mesh with cells, ``facet_tags`` its facet tags.

    Creates the facets of ``mesh`` (collective).
    """
    if not isinstance(mesh, dmesh.Mesh):
        raise TypeError(f"mesh must be a dolfinx.mesh.Mesh, got {type(mesh).__name__}")
    if not isinstance(facet_tags, dmesh.MeshTags):
        raise TypeError(
            f"facet_tags must be dolfinx.mesh.MeshTags, got {type(facet_tags).__name__}"
        )
    tdim = mesh.topology.dim
    cpp_topology = getattr(mesh.topology, "_cpp_object", None)
    if cpp_topology is not None and facet_tags.topology is not cpp_topology:
        raise ValueError(
            "facet_tags belong to another mesh: create them on `mesh` "
            "(dolfinx.mesh.meshtags(mesh, ...)) or read them together with it (gmshio)"
        )
    if facet_tags.dim != tdim - 1:
        raise ValueError(
            f"facet_tags has dimension {facet_tags.dim}, but the facets of this mesh have "
            f"dimension {tdim - 1}: pass the facet tags, not cell tags"
        )
    mesh.topology.create_entities(tdim - 1)
    num_facets = mesh.topology.index_map(tdim - 1)
    if (
        num_facets is not None
        and len(facet_tags.indices)
        and int(facet_tags.indices.max()) >= (num_facets.size_local + num_facets.num_ghosts)
    ):
        raise ValueError(
            "facet_tags index facets that `mesh` does not have: another mesh's tags?"
        )
    if mesh.topology.index_map(tdim).size_global == 0:
        raise ValueError("mesh has no cells: pass the macro mesh T_H of the body")
    if tdim not in (2, 3) or mesh.geometry.dim != tdim:
        raise ValueError("mesh must be a 2D mesh in the plane or a 3D volume mesh")
    if compat.geometry_cmap(mesh).degree != 1:
        raise ValueError(
            "only meshes with affine/multilinear geometry (degree 1) are supported"
        )


def check_cell_tags(
    cell_tags: Any, mesh: dmesh.Mesh, E: Any, nu: Any
) -> dmesh.MeshTags | None:
    """The cell tags of ``mesh``, needed when ``E`` or ``nu`` is given per cell tag.

    Args:
        cell_tags: The argument as given (``None`` or MeshTags of the cells of ``mesh``).
        mesh: The macro mesh T_H.
        E: Young's modulus as given (only whether it is a dict matters here).
        nu: Poisson's ratio as given (likewise).

    Returns:
        The cell tags, or ``None``.
    """
    per_tag = [name for name, v in (("E", E), ("nu", nu)) if isinstance(v, Mapping)]
    if cell_tags is None:
        if per_tag:
            raise ValueError(
                f"{per_tag[0]} is given per cell tag, so cell_tags (the MeshTags of the "
                "cells of `mesh`, e.g. from ds.read_mesh) are needed"
            )
        return None
    if not isinstance(cell_tags, dmesh.MeshTags):
        raise TypeError(f"cell_tags must be dolfinx.mesh.MeshTags, got {cell_tags!r}")
    tdim = mesh.topology.dim
    if cell_tags.dim != tdim:
        raise ValueError(
            f"cell_tags has dimension {cell_tags.dim}, the cells of the mesh {tdim}"
        )
    cpp_topology = getattr(mesh.topology, "_cpp_object", None)
    if cpp_topology is not None and cell_tags.topology is not cpp_topology:
        raise ValueError("cell_tags belong to another mesh: pass the tags of `mesh`")
    return cell_tags


def check_cells_covered(
    values: Mapping[int, float], name: str, mesh: dmesh.Mesh, tags: dmesh.MeshTags
) -> None:
    """Every owned cell carries a tag of ``values`` (collective)."""
    num = mesh.topology.index_map(mesh.topology.dim).size_local
    covered = np.zeros(num, dtype=bool)
    keep = np.isin(tags.values, list(values)) & (tags.indices < num)
    covered[tags.indices[keep]] = True
    comm = shadow(mesh.comm)
    missing = comm.allreduce(int((~covered).sum()), op=MPI.SUM)
    if missing:
        present = sorted(set(comm.allreduce(list(map(int, np.unique(tags.values))))))
        raise ValueError(
            f"{name} is given for cell tags {sorted(values)}, but {missing} cells carry none "
            f"of them (cell tags present: {present})"
        )


def check_plane_faces_body(
    plane: Plane, name: str, mesh: dmesh.Mesh, facet_tags: dmesh.MeshTags,
    tags: tuple[int, ...],
) -> None:
    """Some facet of the contact tags ``tags`` faces ``plane`` (outward normal . its normal > 0).

    A plane whose normal points into the body lies behind every contact facet: no facet can
    touch it and J would come out in [0, 0] without a word. Collective.
    """
    normals = _outward_facet_normals(mesh, facet_tags, tags)
    facing = int(np.sum(normals @ plane.normal > 1e-12))
    comm = shadow(mesh.comm)
    facing, count = comm.allreduce(np.array([facing, len(normals)]), op=MPI.SUM)
    if count and not facing:  # (no contact facet at all: check_tags names the tag)
        found = comm.allgather(np.unique(np.round(normals, 6), axis=0).tolist())
        seen = sorted({tuple(v) for part in found for v in part})
        raise ValueError(
            f"{name}: {plane!r} lies behind the body: no contact facet faces it (the "
            f"outward normals of contact tag(s) {list(tags)} are {seen[:4]}, and the "
            "normal of a Plane points into the obstacle, away from the body); flip the "
            "normal, e.g. Plane(point, normal="
            f"{tuple(float(-c) + 0.0 for c in plane.normal)})"
        )


def _outward_facet_normals(
    msh: dmesh.Mesh, facet_tags: dmesh.MeshTags, tags: Sequence[int]
) -> np.ndarray:
    """Outward unit normals (rows) of the owned facets of ``msh`` with the facet tags ``tags``."""
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    num = msh.topology.index_map(fdim).size_local
    facets = np.unique(np.concatenate([facet_tags.find(t) for t in tags]))
    facets = facets[facets < num].astype(np.int32)
    if facets.size == 0:
        return np.zeros((0, gdim))
    x = msh.geometry.x[:, :gdim]
    fx = x[dmesh.entities_to_geometry(msh, fdim, facets)]
    if tdim == 2:
        t = fx[:, 1] - fx[:, 0]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    else:
        n = np.cross(fx[:, 1] - fx[:, 0], fx[:, 2] - fx[:, 0])
    f_to_c = msh.topology.connectivity(fdim, tdim)
    cells = np.array([f_to_c.links(f)[0] for f in facets], dtype=np.int32)
    centroids = x[dmesh.entities_to_geometry(msh, tdim, cells)].mean(axis=1)
    sign = np.sign(np.sum(n * (fx.mean(axis=1) - centroids), axis=1))
    n *= sign[:, None]
    return n / np.linalg.norm(n, axis=1)[:, None]


def check_tags(
    mesh: dmesh.Mesh,
    facet_tags: dmesh.MeshTags,
    used: Sequence[tuple[str, int]],
    contact_tags: tuple[int, ...],
) -> None:
    """Every tag used marks a boundary facet somewhere, contact tags no common facet.

    Args:
        mesh: The macro mesh T_H.
        facet_tags: Its facet tags.
        used: ``(argument, tag)`` of every tag the data use, in the order to check them.
        contact_tags: The contact tags.
    """
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, fdim + 1)
    boundary = dmesh.exterior_facet_indices(mesh.topology)
    comm = shadow(mesh.comm)
    for name, tag in used:
        facets = facet_tags.find(tag)
        count = comm.allreduce(int(np.isin(facets, boundary).sum()), op=MPI.SUM)
        if count == 0:
            present = sorted(set(comm.allreduce(list(map(int, np.unique(facet_tags.values))))))
            raise ValueError(
                f"{name} tag {tag} marks no boundary facet of the mesh (tags present: "
                f"{present}); pass the tag that facet_tags give that boundary"
            )
    if len(contact_tags) > 1:
        facets = np.concatenate([np.unique(facet_tags.find(t)) for t in contact_tags])
        shared = comm.allreduce(int(len(facets) - len(np.unique(facets))), op=MPI.SUM)
        if shared:
            raise ValueError(
                f"contact tags {contact_tags} overlap: {shared} facets carry two of "
                "them; each contact facet must belong to one contact tag"
            )
