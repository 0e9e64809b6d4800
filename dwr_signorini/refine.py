"""Refinement of the macro mesh: uniform or at marked cells, with parent maps and facet tags.

Simplices are refined by ``dolfinx.mesh.refine`` with children kept on their parent's process
(``partitioner=None``); quadrilaterals and hexahedra, which dolfinx cannot refine, uniformly by
:mod:`dwr_signorini.tensor_refine`. The parent cell of each fine cell comes from the refinement,
the parent facet of each fine facet from the geometry (:func:`fine_to_macro_facets`), and facet
tags are carried through it (:func:`facet_tags_on_fine`); cell tags (materials) go from parent to
child (:func:`cell_tags_on_fine`).

Curved boundaries (``boundary_projection`` of the problem): after each refinement of the macro
mesh T_H (:func:`refine_marked`) the vertices on the projected facet tags are moved onto the true
surface (:func:`project_boundary`; the old vertices already lie on it, so only the new ones
move). The fine mesh T_h of a discretisation stays the exact uniform refinement of its T_H, so the
patch reconstructions stay exact and parent facets still come from the refinement. A move that
would invert (or flatten) a cell is refused with an error naming the tag, and the mesh is left
unchanged.
"""

from __future__ import annotations

from collections.abc import Callable

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import mesh as dmesh
from dolfinx.cpp import mesh as _cpp_mesh

from . import compat
from .collective import collective, shadow
from .mesh_validation import check_projection_moves, projected_points, projection_nodes
from .problem import SignoriniProblem

__all__ = [
    "RULES",
    "cell_tags_on_fine",
    "facet_tags_on_fine",
    "fine_cells",
    "fine_to_macro_facets",
    "marked_edges",
    "num_entities",
    "project_boundary",
    "refine_marked",
    "refine_uniform",
    "refine_with_tags",
]


def num_entities(msh: dmesh.Mesh, dim: int) -> int:
    """Local (owned and ghost) entities of dimension ``dim``."""
    imap = msh.topology.index_map(dim)
    return imap.size_local + imap.num_ghosts


def refine_uniform(
    macro: dmesh.Mesh, edges: npt.NDArray[np.int32] | None = None
) -> tuple[dmesh.Mesh, npt.NDArray[np.int32]]:
    """One refinement (uniform, or of the given edges), children kept on their parent's process.

    Simplices use ``dolfinx.mesh.refine`` (Plaza's algorithm, which keeps the mesh conforming);
    quadrilaterals and hexahedra, which dolfinx cannot refine, are split into 4 / 8 by
    :func:`dwr_signorini.tensor_refine.refine_uniform_tensor` (uniform refinement only).

    Returns:
        The fine mesh and the parent cell of each local fine cell (parent facets are found
        geometrically, see :func:`fine_to_macro_facets`).
    """
    tdim = macro.topology.dim
    if macro.topology.cell_type in (dmesh.CellType.triangle, dmesh.CellType.tetrahedron):
        fine, parent_cell = _refine_without_ties(macro, edges)
    else:
        if edges is not None:
            raise ValueError(
                "adaptive refinement needs a simplex mesh (triangles/tetrahedra); "
                "quadrilateral and hexahedral meshes can only be refined uniformly"
            )
        from .tensor_refine import refine_uniform_tensor

        fine, parent_cell, _ = refine_uniform_tensor(macro)
    fine.topology.create_entities(tdim - 1)
    return fine, np.asarray(parent_cell, dtype=np.int32)


#: The size of the map under which :func:`_refine_without_ties` refines: large against the
#: round-off of edge lengths, small against the differences of lengths that are not equal.
TIE_BREAK = 1e-7


def _tie_breaking_map(x: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """The points x moved by ``x_i -> c_i + (x_i - c_i) (1 + TIE_BREAK (s_i + r_i^2 w_i))``.

    c is the centre of the mesh's bounding box, r = (x - c) / radius, and s, w have irrational
    entries: equally long edges of a face that point in different directions, or lie at
    different places, differ by about TIE_BREAK times their length after the map. It commutes
    with the mirrors in the planes through c normal to the axes, so a mesh symmetric about
    its centre line is refined symmetrically.
    """
    gdim = x.shape[1]
    s = np.sqrt([2.0, 3.0, 5.0][:gdim])
    w = np.sqrt([7.0, 11.0, 13.0][:gdim])
    r = (x - centre) / radius
    return centre + (x - centre) * (1.0 + TIE_BREAK * (s + (r * r) @ np.outer(w, w[::-1])))


def _bounding_box(msh: dmesh.Mesh) -> tuple[np.ndarray, float]:
    """The centre of the mesh's bounding box and its half-diagonal (collective)."""
    gdim = msh.geometry.dim
    x = msh.geometry.x[:, :gdim]
    lo = x.min(axis=0) if len(x) else np.full(gdim, np.inf)
    hi = x.max(axis=0) if len(x) else np.full(gdim, -np.inf)
    msh.comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    msh.comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    return 0.5 * (lo + hi), max(0.5 * float(np.linalg.norm(hi - lo)), 1e-300)


def _restore_geometry(
    fine: dmesh.Mesh, parent_cell: np.ndarray, macro: dmesh.Mesh, moved: np.ndarray,
    original: np.ndarray,
) -> None:
    """Each fine vertex put back where it belongs: a vertex of its parent, or an edge midpoint.

    Every fine vertex is, in the moved coordinates, a vertex or an edge midpoint of the parent
    of each of its cells; it takes that point's original coordinates (exactly the old vertex,
    the midpoint to round-off).
    """
    gdim = macro.geometry.dim
    fine_dofs = compat.geometry_dofmap(fine)[: len(parent_cell)]
    # each fine node once, with the first local cell it belongs to (any cell gives the same
    # point: a vertex, or the midpoint 0.5 (a + b) of the same edge)
    nodes, first_at = np.unique(fine_dofs.ravel(), return_index=True)
    macro_dofs = compat.geometry_dofmap(macro)[parent_cell[first_at // fine_dofs.shape[1]]]
    nv = macro_dofs.shape[1]
    pairs = [(a, b) for a in range(nv) for b in range(a, nv)]  # a == b: the vertex itself
    first, second = (macro_dofs[:, list(p)] for p in zip(*pairs, strict=True))
    y = fine.geometry.x
    offset = y[nodes, None, :gdim] - 0.5 * (moved[first] + moved[second])
    nearest = np.einsum("ijk,ijk->ij", offset, offset).argmin(axis=1)
    rows = np.arange(len(nodes))
    y[nodes, :gdim] = 0.5 * (original[first[rows, nearest]] + original[second[rows, nearest]])


def _refine_without_ties(
    macro: dmesh.Mesh, edges: npt.NDArray[np.int32] | None
) -> tuple[dmesh.Mesh, npt.NDArray[np.int32]]:
    """The refinement of dolfinx with the ties between equally long edges broken by geometry.

    Plaza's refinement bisects each face at its longest edge; between edges of equal length
    dolfinx picks by vertex numbers (global indices in 3D, the local order in 2D), which depend
    on the partition: the same marked edges gave 260 of 5376 cells different on 2 ranks and
    serially (example 5.3 on 2 x 6 x 6 boxes, its second level). The mesh is refined under the
    map of :func:`_tie_breaking_map` instead, which makes the longest edge of a face unique
    and the same on any number of ranks (but on faces symmetric about a plane through the
    centre), and the refined mesh's vertices are then put back (:func:`_restore_geometry`).
    """
    gdim = macro.geometry.dim
    x = macro.geometry.x
    original = x[:, :gdim].copy()
    centre, radius = _bounding_box(macro)
    moved = _tie_breaking_map(original, centre, radius)
    x[:, :gdim] = moved
    try:
        fine, parent_cell, _ = compat.refine(macro, edges)
    finally:
        x[:, :gdim] = original
    parent_cell = np.asarray(parent_cell, dtype=np.int32)
    _restore_geometry(fine, parent_cell, macro, moved, original)
    return fine, parent_cell


def fine_to_macro_facets(
    macro: dmesh.Mesh,
    fine: dmesh.Mesh,
    parent_cell: npt.NDArray[np.int32],
    macro_facets: npt.NDArray[np.int32] | None = None,
) -> npt.NDArray[np.int32]:
    """For each fine facet, the macro facet containing it (-1 for facets inside macro cells).

    Decided geometrically from the parent cell: a facet of a child lies on a facet of its (convex)
    parent iff its midpoint lies in that facet's hyperplane. Only facets of local fine cells are
    set. (The ``parent_facet`` array of ``dolfinx.mesh.refine`` is not used: with dolfinx 0.9 it
    did not match the refined topology's local facet numbering in our checks.)

    Args:
        macro: The coarse mesh.
        fine: Its refinement.
        parent_cell: The macro cell of each local fine cell.
        macro_facets: Only look for fine facets on these macro facets (local indices; e.g. the
            tagged ones), and only in the children of their cells; None: all macro facets.
    """
    tdim = macro.topology.dim
    fdim = tdim - 1
    macro.topology.create_connectivity(tdim, fdim)
    fine.topology.create_connectivity(tdim, fdim)
    fine.topology.create_connectivity(fdim, tdim)
    nf = _cpp_mesh.cell_num_entities(fine.topology.cell_type, fdim)
    nfm = _cpp_mesh.cell_num_entities(macro.topology.cell_type, fdim)
    num_fine_cells = fine.topology.index_map(tdim).size_local
    fine_c2f = fine.topology.connectivity(tdim, fdim).array.reshape(-1, nf)[:num_fine_cells]
    macro_c2f = macro.topology.connectivity(tdim, fdim).array.reshape(-1, nfm)

    out = np.full(num_entities(fine, fdim), -1, dtype=np.int32)
    candidates = macro_c2f[parent_cell[:num_fine_cells]]  # (cells, nfm)
    wanted = None
    if macro_facets is not None:
        wanted = np.zeros(num_entities(macro, fdim), dtype=bool)
        wanted[macro_facets] = True
        cells = np.flatnonzero(wanted[candidates].any(axis=1))
        fine_c2f, candidates = fine_c2f[cells], candidates[cells]
    if len(fine_c2f) == 0:  # dolfinx 0.9 fails on empty entity lists
        return out
    mids = dmesh.compute_midpoints(fine, fdim, fine_c2f.ravel()).reshape(-1, nf, 1, 3)
    nodes = dmesh.entities_to_geometry(macro, fdim, candidates.ravel().astype(np.int32), False)
    x = macro.geometry.x[nodes[:, :tdim]].reshape(-1, 1, nfm, tdim, 3)
    a = x[..., 0, :]
    if tdim == 2:
        t = x[..., 1, :] - a
        normal = np.stack([-t[..., 1], t[..., 0], np.zeros_like(t[..., 0])], axis=-1)
    else:
        normal = np.cross(x[..., 1, :] - a, x[..., 2, :] - a)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    h = np.linalg.norm(x[..., 1, :] - a, axis=-1)
    dist = np.abs(np.sum((mids - a) * normal, axis=-1))  # (cells, nf, nfm)
    on = dist <= 1e-8 * h
    if np.any(on.sum(axis=2) > 1):
        raise RuntimeError("a fine facet lies on two facets of its parent cell")
    if wanted is not None:
        on &= wanted[candidates][:, None, :]
    cells, local, k = np.nonzero(on)
    out[fine_c2f[cells, local]] = candidates[cells, k]
    return out


def facet_tags_on_fine(
    macro_tags: dmesh.MeshTags, fine: dmesh.Mesh, to_macro: npt.NDArray[np.int32], num_macro: int
) -> dmesh.MeshTags:
    """Carry facet tags from a mesh to its refinement through the parent-facet map.

    Args:
        macro_tags: Facet tags of the coarse mesh.
        fine: The refined mesh.
        to_macro: The coarse facet of each fine facet, -1 inside coarse cells
            (:func:`fine_to_macro_facets`).
        num_macro: Local facets of the coarse mesh.
    """
    fdim = fine.topology.dim - 1
    tag_of = np.full(num_macro, -1, dtype=np.int32)
    tag_of[macro_tags.indices] = macro_tags.values
    fine_facets = np.flatnonzero(to_macro >= 0)
    values = tag_of[to_macro[fine_facets]]
    keep = values >= 0
    return dmesh.meshtags(fine, fdim, fine_facets[keep].astype(np.int32), values[keep])


def cell_tags_on_fine(
    macro_tags: dmesh.MeshTags | None,
    fine: dmesh.Mesh,
    parent_cell: npt.NDArray[np.int32],
    num_macro: int,
) -> dmesh.MeshTags | None:
    """Cell tags of a refinement: each local fine cell takes its parent's tag (None stays None).

    Args:
        macro_tags: Cell tags of the coarse mesh, or None.
        fine: The refined mesh.
        parent_cell: The coarse cell of each local fine cell.
        num_macro: Local (owned and ghost) cells of the coarse mesh.
    """
    if macro_tags is None:
        return None
    tag_of = np.full(num_macro, -1, dtype=np.int32)
    tag_of[macro_tags.indices] = macro_tags.values
    values = tag_of[parent_cell]
    cells = np.flatnonzero(values >= 0).astype(np.int32)
    return dmesh.meshtags(fine, fine.topology.dim, cells, values[cells])


def _corner_jacobians(msh: dmesh.Mesh) -> npt.NDArray[np.float64]:
    """The Jacobian determinant at every corner of every local cell (simplices: one per cell).

    For quadrilaterals/hexahedra (vertices in lexicographic order) the derivative of the
    (multi)linear map at a corner along axis k is the difference of the two vertices of the
    edge along k, so these are the exact corner Jacobians, whose signs decide inversion.
    """
    tdim = msh.topology.dim
    dofmap = compat.geometry_dofmap(msh)
    x = msh.geometry.x[dofmap][..., :tdim]  # (cells, nodes, tdim)
    if msh.topology.cell_type in (dmesh.CellType.triangle, dmesh.CellType.tetrahedron):
        return np.linalg.det(x[:, 1:] - x[:, :1])[:, None]
    dets = []
    for corner in range(2**tdim):
        cols = []
        for k in range(tdim):
            low, high = corner & ~(1 << k), corner | (1 << k)
            cols.append(x[:, high] - x[:, low])
        dets.append(np.linalg.det(np.stack(cols, axis=-1)))
    return np.stack(dets, axis=1)


def project_boundary(
    msh: dmesh.Mesh,
    facet_tags: dmesh.MeshTags,
    projection: dict[int, Callable[[np.ndarray], np.ndarray]],
) -> None:
    """Move the vertices on the tagged facets onto their surfaces, in place (collective).

    Every rank moves its copies of the vertices with the same callable, so shared vertices
    stay shared. Checked before: no vertex moves by more than half the local mesh size
    (:func:`~dwr_signorini.mesh_validation.check_projection_moves`). Checked afterwards: no
    corner Jacobian of a local cell changes sign or drops below 1e-10 of its old size.

    Args:
        msh: A mesh with affine (degree 1) geometry.
        facet_tags: Its facet tags.
        projection: ``{facet tag: f}`` with ``f(x)`` for an array of shape (3, n) returning the
            points on the true surface, shape (3, n) or (gdim, n).

    Raises:
        RuntimeError: If a move would invert or flatten a cell (the mesh is then unchanged):
            the macro mesh is too coarse near that curved boundary for its refinement.
        ValueError: If a projection returns an array of the wrong shape or non-finite values
            (on any rank: then on every rank, as a ``CollectiveValueError`` naming it and the
            vertex; an exception the callable raises likewise, :mod:`dwr_signorini.collective`),
            or moves a vertex by more than
            :data:`~dwr_signorini.mesh_validation.MAX_PROJECTION_MOVE` times the local mesh
            size (naming the tag, the vertex, the distance; the mesh is then unchanged).
    """
    gdim = msh.geometry.dim
    x = msh.geometry.x
    before = _corner_jacobians(msh)
    saved = x.copy()
    for tag, f in projection.items():
        nodes = projection_nodes(msh, facet_tags, tag)
        new = np.zeros((0, gdim))
        try:  # the user's f on this rank's points; its error, or a bad result, on every rank
            with collective(msh.comm, f"boundary_projection[{tag}]"):
                if nodes.size:
                    new = projected_points(f, x[nodes].T.copy(), tag, gdim)[:gdim].T
            check_projection_moves(msh, tag, nodes, new)
        except Exception:
            x[:] = saved
            raise
        x[nodes, :gdim] = new
        after = _corner_jacobians(msh)
        bad = (np.sign(after) != np.sign(before)) | (np.abs(after) < 1e-10 * np.abs(before))
        count = msh.comm.allreduce(int(bad.any(axis=1).sum()), op=MPI.SUM)
        if count:
            distance, vertex = _largest_move(msh, bad.any(axis=1), saved)
            x[:] = saved
            raise RuntimeError(
                f"boundary_projection[{tag}]: moving the new vertices onto the surface would "
                f"invert or flatten {count} cell(s) of the refined macro mesh (the vertex at "
                f"{vertex} would move by {distance:.6g}), so no vertex was moved. Start from a "
                "finer mesh near that boundary (its facets must be small against the radius of "
                "curvature) or refine less there"
            )


def _largest_move(
    msh: dmesh.Mesh, bad_cells: np.ndarray, saved: np.ndarray
) -> tuple[float, tuple[float, ...]]:
    """The largest move of a vertex of the ``bad_cells`` (``saved``: the old coordinates).

    Collective (one ``allgather``): the same vertex and distance on every rank.
    """
    gdim = msh.geometry.dim
    nodes = np.unique(compat.geometry_dofmap(msh)[bad_cells])
    moves = np.linalg.norm(msh.geometry.x[nodes] - saved[nodes], axis=1)
    local = (0.0, ())
    if nodes.size:
        k = int(np.argmax(moves))
        local = (float(moves[k]), tuple(float(c) for c in saved[nodes[k], :gdim]))
    return max(shadow(msh.comm).allgather(local), key=lambda m: m[0])


#: Which edges of the marked cells are refined (``rule`` of :func:`refine_marked`).
RULES = ("edges", "longest_edge")


def marked_edges(
    msh: dmesh.Mesh, cells: npt.NDArray[np.int32], rule: str = "edges"
) -> npt.NDArray[np.int32]:
    """The edges to refine for the marked cells: all their edges, or each one's longest.

    ``"edges"`` refines every edge of a marked cell (a marked triangle splits into 4, a
    tetrahedron into 8, and the closure spreads). ``"longest_edge"`` bisects each marked cell
    through its longest edge only; Plaza's refinement then adds what conformity needs, so the
    mesh grows by less for the same marks. Ties between edges of equal length are broken by
    the edges' local order.
    """
    if rule not in RULES:
        raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
    tdim = msh.topology.dim
    msh.topology.create_entities(1)
    msh.topology.create_connectivity(tdim, 1)
    if rule == "edges":
        edges = dmesh.compute_incident_entities(msh.topology, cells, tdim, 1)
        return np.unique(edges).astype(np.int32)
    c2e = msh.topology.connectivity(tdim, 1)
    per_cell = c2e.links(0).size if c2e.num_nodes else 0
    if len(cells) == 0 or per_cell == 0:
        return np.zeros(0, dtype=np.int32)
    edges = c2e.array.reshape(-1, per_cell)[cells]
    nodes = dmesh.entities_to_geometry(msh, 1, edges.ravel().astype(np.int32), False)
    x = msh.geometry.x
    length = np.linalg.norm(x[nodes[:, 0]] - x[nodes[:, 1]], axis=1).reshape(edges.shape)
    longest = edges[np.arange(len(cells)), np.argmax(length, axis=1)]
    return np.unique(longest).astype(np.int32)


def refine_marked(
    problem: SignoriniProblem, cells: npt.NDArray[np.int32] | None, rule: str = "edges"
) -> tuple[SignoriniProblem, npt.NDArray[np.int32]]:
    """Refine the macro mesh at the marked cells and carry the facet tags.

    Args:
        problem: The problem on the current macro mesh T_H.
        cells: Local indices of marked macro cells (simplices), or ``None`` for a uniform
            refinement (any cell type).
        rule: Which edges of the marked cells are refined (:func:`marked_edges`).

    Cell tags go from parent to child; with ``problem.boundary_projection`` the vertices on
    those facet tags are moved onto their surfaces (:func:`project_boundary`).

    Returns:
        The problem on the refined macro mesh, and the parent of each new macro cell.
    """
    macro = problem.mesh
    tdim = macro.topology.dim
    edges = None if cells is None else marked_edges(macro, cells, rule)
    fine, parent_cell, _, tags = refine_with_tags(problem, edges)
    cell_tags = cell_tags_on_fine(problem.cell_tags, fine, parent_cell, num_entities(macro, tdim))
    if problem.boundary_projection:
        project_boundary(fine, tags, problem.boundary_projection)
    return problem.with_mesh(fine, tags, cell_tags), parent_cell


def refine_with_tags(
    problem: SignoriniProblem, edges: npt.NDArray[np.int32] | None
) -> tuple[dmesh.Mesh, npt.NDArray[np.int32], npt.NDArray[np.int32], dmesh.MeshTags]:
    """Refine the macro mesh (:func:`refine_uniform`) and carry its facet tags.

    Returns:
        The fine mesh, the parent cell of each local fine cell, the macro facet of each fine
        facet (:func:`fine_to_macro_facets`, for the tagged macro facets) and the fine facet tags.
    """
    macro = problem.mesh
    fdim = macro.topology.dim - 1
    macro.topology.create_entities(fdim)
    fine, parent_cell = refine_uniform(macro, edges)
    to_macro = fine_to_macro_facets(macro, fine, parent_cell, problem.facet_tags.indices)
    tags = facet_tags_on_fine(problem.facet_tags, fine, to_macro, num_entities(macro, fdim))
    return fine, parent_cell, to_macro, tags


def fine_cells(problem: SignoriniProblem) -> int:
    """The cells of the fine mesh T_h of ``problem`` (2^d per macro cell).

    Args:
        problem: A problem on its macro mesh T_H.

    Returns:
        The global number of cells of T_h.
    """
    tdim = problem.mesh.topology.dim
    return problem.mesh.topology.index_map(tdim).size_global * 2**tdim
