"""Validation of the macro mesh T_H and its tags: each error names its argument.

Pure functions as in :mod:`dwr_signorini.validation`: the mesh and its facet tags, the cell tags
(and that a material given per cell tag covers every cell), that every tag the data use marks a
boundary facet, that a plane obstacle faces some contact facet, and that a boundary projection
moves no vertex far (:data:`MAX_PROJECTION_MOVE`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

from . import compat
from .collective import collective, shadow
from .obstacles import Plane

__all__ = [
    "MAX_PROJECTION_MOVE",
    "check_cell_tags",
    "check_cells_covered",
    "check_mesh",
    "check_plane_faces_body",
    "check_projection_fits",
    "check_projection_moves",
    "check_tags",
    "projected_points",
    "projection_nodes",
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


#: The largest move of a vertex by ``boundary_projection``, as a fraction of the local mesh
#: size (the largest diameter of the cells at the vertex). A new vertex of a refined edge on a
#: circle of radius R moves by the sagitta, about h^2 / (8 R) for a chord h: beyond half the mesh
#: size the mesh does not resolve the surface, or the projection is not onto it.
MAX_PROJECTION_MOVE = 0.5


def _vertex_sizes(msh: dmesh.Mesh) -> np.ndarray:
    """The largest diameter of the local cells at each geometry node (local)."""
    dofmap = compat.geometry_dofmap(msh)
    x = msh.geometry.x[dofmap]  # (cells, nodes, 3)
    diameters = np.zeros(len(dofmap))
    for i in range(dofmap.shape[1]):
        for j in range(i + 1, dofmap.shape[1]):
            diameters = np.maximum(diameters, np.linalg.norm(x[:, i] - x[:, j], axis=1))
    sizes = np.zeros(len(msh.geometry.x))
    np.maximum.at(sizes, dofmap.ravel(), np.repeat(diameters, dofmap.shape[1]))
    return sizes


def projected_points(
    f: Any, points: np.ndarray, tag: int, gdim: int
) -> np.ndarray:
    """``f(points)`` as a checked array of shape (gdim or 3, n) (local; ValueError naming it).

    Args:
        f: The projection of ``boundary_projection[tag]``.
        points: The points, shape (3, n).
        tag: Its facet tag, for the message.
        gdim: The geometric dimension.

    Raises:
        ValueError: A result of the wrong shape, or NaN/Inf (naming the first such point).
    """
    new = np.asarray(f(points), dtype=float)
    if new.ndim != 2 or new.shape[1] != points.shape[1] or new.shape[0] not in (gdim, 3):
        raise ValueError(
            f"boundary_projection[{tag}] must return an array of shape (3, n) or "
            f"({gdim}, n) for points of shape (3, n), got {new.shape}"
        )
    finite = np.all(np.isfinite(new[:gdim]), axis=0)
    if not np.all(finite):
        where = tuple(float(c) for c in points[:gdim, int(np.flatnonzero(~finite)[0])])
        raise ValueError(
            f"boundary_projection[{tag}] returned NaN or Inf for the vertex at {where} (a "
            "point where the surface's projection is undefined, such as a sphere's centre: "
            "is the tag or the surface the right one?)"
        )
    return new


def check_projection_moves(
    msh: dmesh.Mesh, tag: int, nodes: np.ndarray, new: np.ndarray
) -> None:
    """Refuse a projection that moves a vertex by more than :data:`MAX_PROJECTION_MOVE` h.

    Collective (one ``allgather``): every rank raises the same error, for the vertex with the
    largest move relative to its local mesh size h.

    Args:
        msh: The mesh, its vertices not yet moved.
        tag: The facet tag of the projection, for the message.
        nodes: The geometry nodes to be moved (local indices).
        new: Their new coordinates, shape (len(nodes), gdim).

    Raises:
        ValueError: Naming the tag, the vertex, the distance and the local mesh size.
    """
    gdim = msh.geometry.dim
    worst = (0.0, (), 0.0, 0.0)
    if len(nodes):
        old = msh.geometry.x[nodes, :gdim]
        distance = np.linalg.norm(new - old, axis=1)
        h = _vertex_sizes(msh)[nodes]
        ratio = distance / np.maximum(h, np.finfo(float).tiny)
        k = int(np.argmax(ratio))
        worst = (float(ratio[k]), tuple(float(c) for c in old[k]), float(distance[k]), float(h[k]))
    gathered = shadow(msh.comm).allgather(worst) if msh.comm.size > 1 else [worst]
    ratio, vertex, distance, h = max(gathered, key=lambda w: w[0])
    if ratio > MAX_PROJECTION_MOVE:
        raise ValueError(
            f"boundary_projection[{tag}] moves the vertex at {vertex} by {distance:.6g}, "
            f"{ratio:.3g} times the local mesh size {h:.6g} (at most {MAX_PROJECTION_MOVE} "
            "allowed): the projection is not onto the surface these facets lie on (a wrong "
            "radius or centre?), or the mesh is far too coarse for it"
        )


def check_projection_fits(
    msh: dmesh.Mesh, facet_tags: dmesh.MeshTags, projection: Mapping[int, Any]
) -> None:
    """Check ``boundary_projection`` on the vertices T_H has: they must lie on the surfaces.

    Collective. The mesh is not changed; each projection is applied to the vertices of its
    facets and :func:`check_projection_moves` refuses a large move.

    Raises:
        ValueError: As :func:`projected_points` and :func:`check_projection_moves` (on every
            rank; an exception of the projection itself, too, naming it).
    """
    gdim = msh.geometry.dim
    for tag, f in projection.items():
        nodes = projection_nodes(msh, facet_tags, tag)
        new = np.zeros((0, gdim))
        with collective(msh.comm, f"boundary_projection[{tag}]"):
            if nodes.size:
                points = msh.geometry.x[nodes].T.copy()
                new = projected_points(f, points, tag, gdim)[:gdim].T
        check_projection_moves(msh, tag, nodes, new)


def projection_nodes(msh: dmesh.Mesh, facet_tags: dmesh.MeshTags, tag: int) -> np.ndarray:
    """The local geometry nodes of the facets tagged ``tag`` (local)."""
    fdim = msh.topology.dim - 1
    facets = facet_tags.find(tag).astype(np.int32)
    if not len(facets):  # (entities_to_geometry divides by the count)
        return np.zeros(0, dtype=np.int32)
    return np.unique(dmesh.entities_to_geometry(msh, fdim, facets, False))
