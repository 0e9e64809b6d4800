"""The facets of a contact pair's two sides: geometry, normals, cells, dofs and basis values.

What :mod:`~dwr_signorini.pairs` reads off the fine mesh before the mortar rule
(:mod:`~dwr_signorini.mortar`) meets the two sides: this rank's slave facets and owned master
facets (:mod:`~dwr_signorini.exchange` sends each rank those it needs), the global dofs of a
space on their cells, the values of its basis at points of those cells, and the sparse matrix
the trace is assembled into.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.sparse
from dolfinx import fem
from dolfinx import mesh as dmesh

from . import compat
from .mortar import check_planar, facet_normals, tabulate, warp

if TYPE_CHECKING:
    from .pairs import ContactPair

__all__ = [
    "Side",
    "cell_basis",
    "cell_dofs",
    "check_pair_facets",
    "csr_matrix",
    "entity_points",
    "facet_cell_blocks",
    "facet_rows_matrix",
    "facet_tag",
    "master_facets",
    "side_cells",
    "slave_facets",
    "windows",
]


@dataclass
class Side:
    """Facets of one side of a pair with their cells."""

    vertices: np.ndarray  # (m, nv, gdim)
    normals: np.ndarray  # (m, gdim)
    geometry: np.ndarray  # (m, nodes, gdim): the adjacent cell's geometry
    dofs: np.ndarray  # (m, ndofs): its global block dofs of V
    cell: np.ndarray  # (m,): its global cell index

    @staticmethod
    def fields() -> tuple[str, ...]:
        """The attributes in order."""
        return ("vertices", "normals", "geometry", "dofs", "cell")


def check_pair_facets(disc: Any) -> None:
    """Refuse warped quadrilateral facets of the pairs' macro facets, on every rank.

    (The macro ones: the children of a warped facet would not even be tagged on T_h.)
    """
    macro, tags = disc.macro_mesh, disc.problem.facet_tags
    fdim = macro.topology.dim - 1
    n_own = macro.topology.index_map(fdim).size_local
    found = [tags.find(t) for p in disc.problem.pairs for t in (p.slave, p.master)]
    facets = np.unique(np.concatenate(found)) if found else np.zeros(0, np.int32)
    facets = facets[facets < n_own].astype(np.int32)
    check_planar(disc.comm.allreduce(warp(entity_points(macro, fdim, facets)), op=MPI.MAX))


def windows(pair: ContactPair, vertices: np.ndarray) -> np.ndarray | float:
    """The pair's penetration window (default: each slave macro facet's diameter)."""
    if pair.window is not None:
        return pair.window
    d = np.linalg.norm(vertices[:, :, None] - vertices[:, None], axis=3)
    return 2.0 * d.max(axis=(1, 2)) if len(vertices) else np.zeros(0)


def slave_facets(disc: Any) -> tuple[Side, np.ndarray, np.ndarray]:
    """This rank's slave facets with their cells (no dofs), the cells' local index, the tag."""
    sub, fine = disc.slave_mesh, disc.mesh
    tdim = fine.topology.dim
    num = sub.topology.index_map(sub.topology.dim).size_local
    facets = disc.slave_to_fine[:num]
    x = sub.geometry.x[:, :sub.geometry.dim]
    vertices = x[compat.geometry_dofmap(sub)[:num]]
    f2c = fine.topology.connectivity(tdim - 1, tdim)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    return side_cells(fine, cells, vertices), cells, facet_tag(disc.facet_tags, facets)


def master_facets(disc: Any, tag: int) -> tuple[Side, np.ndarray]:
    """This rank's owned master facets of ``tag`` (no dofs) and the local cell beside each."""
    fine = disc.mesh
    tdim = fine.topology.dim
    n_own = fine.topology.index_map(tdim - 1).size_local
    facets = disc.facet_tags.find(tag)
    facets = facets[facets < n_own].astype(np.int32)
    f2c = fine.topology.connectivity(tdim - 1, tdim)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    return side_cells(fine, cells, entity_points(fine, tdim - 1, facets)), cells


def side_cells(msh: dmesh.Mesh, cells: np.ndarray, vertices: np.ndarray) -> Side:
    """The facets' cells: their geometry and global index; the facets' normals (no dofs)."""
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    geometry = msh.geometry.x[compat.geometry_dofmap(msh)[cells]][:, :, :gdim]
    normals = facet_normals(vertices, geometry.mean(axis=1)) if len(cells) else (
        np.zeros((0, gdim)))
    cell = msh.topology.index_map(tdim).local_to_global(cells)
    return Side(vertices, normals, geometry, np.zeros((len(cells), 0), np.int64), cell)


def cell_dofs(V: fem.FunctionSpace, cells: np.ndarray) -> np.ndarray:
    """V's global block dofs of the local ``cells``, shape (len(cells), dofs per cell)."""
    local = V.dofmap.list[np.asarray(cells, dtype=np.int32)]
    return V.dofmap.index_map.local_to_global(local.ravel()).reshape(local.shape)


def cell_basis(
    mesh: dmesh.Mesh, V: fem.FunctionSpace, geometry: np.ndarray, which: np.ndarray,
    y: np.ndarray,
) -> np.ndarray:
    """phi_j(y_q) of V's scalar element in the cell ``which[q]`` (geometry nodes ``geometry``)."""
    element = V.ufl_element().sub_elements[0].basix_element
    if V.element.needs_dof_transformations:
        raise NotImplementedError(
            "contact pairs need an element without dof transformations (Lagrange of degree <= 2)"
        )
    gdim = mesh.geometry.dim
    tdim = mesh.topology.dim
    if len(y) and geometry.shape[1] == tdim + 1 and gdim == tdim:  # affine simplices
        return tabulate(element, _affine_pull_back(geometry, which, y[:, :gdim]))
    cmap = compat.geometry_cmap(mesh)
    out = np.zeros((len(y), element.dim))
    order = np.argsort(which, kind="stable")  # the points of each cell, in one pass
    cuts = np.flatnonzero(np.diff(which[order])) + 1
    for at in np.split(order, cuts) if len(order) else []:
        X = cmap.pull_back(np.ascontiguousarray(y[at, :gdim]), geometry[which[at[0]]])
        out[at] = tabulate(element, X)
    return out


def _affine_pull_back(geometry: np.ndarray, which: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The reference points X of y_q in the affine simplices ``geometry[which[q]]``.

    x(X) = x_0 + sum_k X_k (x_k - x_0) on basix's reference simplex (vertex k at e_k), so
    X = A^{-1} (y - x_0) with A's columns x_k - x_0, inverted once per cell.
    """
    cells, at = np.unique(which, return_inverse=True)
    nodes = geometry[cells]
    origin = nodes[:, 0]
    inverse = np.linalg.inv(np.swapaxes(nodes[:, 1:] - origin[:, None], 1, 2))
    return np.einsum("qkd,qd->qk", inverse[at], y - origin[at])


def entity_points(msh: dmesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The geometry nodes of ``entities`` of dimension ``dim``, shape (m, nodes, gdim)."""
    gdim = msh.geometry.dim
    if len(entities) == 0:  # (entities_to_geometry divides by the count)
        simplex = msh.topology.cell_type in (
            dmesh.CellType.interval, dmesh.CellType.triangle, dmesh.CellType.tetrahedron)
        nodes = dim + 1 if simplex else 2**dim
        if dim == msh.topology.dim:
            nodes = compat.geometry_dofmap(msh).shape[1]
        return np.zeros((0, nodes, gdim))
    return msh.geometry.x[dmesh.entities_to_geometry(msh, dim, entities)][:, :, :gdim]


def facet_tag(tags: dmesh.MeshTags, facets: np.ndarray) -> np.ndarray:
    """The tag of each of ``facets`` (-1 where untagged)."""
    lookup = dict(zip(tags.indices.tolist(), tags.values.tolist(), strict=True))
    return np.array([lookup.get(int(f), -1) for f in facets], dtype=np.int64)


#: How many points :func:`facet_cell_blocks` expands at once, and about how many entries
#: :func:`facet_rows_matrix` writes at once (bounds their temporary memory).
BLOCK_CHUNK = 1 << 13


def facet_cell_blocks(
    facet: np.ndarray, key: np.ndarray, rows: np.ndarray, cols: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """sum_q rows_q cols_q^T over the points q of each (facet, key) pair.

    Args:
        facet: The facet of each point.
        key: The cell key of each point (the points of one pair share its rows' and columns'
            dofs).
        rows: The row values per point, shape (q, a).
        cols: The column values per point, shape (q, j).

    Returns:
        The first point of each pair (an index into the points) and the blocks, shape
        (pairs, a, j).
    """
    order = np.lexsort((key, facet))
    f, k = facet[order], key[order]
    start = np.flatnonzero(np.r_[True, (np.diff(f) != 0) | (np.diff(k) != 0)]) if len(f) else (
        np.zeros(0, np.int64))
    blocks = np.zeros((len(start), rows.shape[1], cols.shape[1]))
    owner = np.repeat(np.arange(len(start)), np.diff(np.r_[start, len(f)]))
    for lo in range(0, len(f), BLOCK_CHUNK):
        at, mine = order[lo:lo + BLOCK_CHUNK], owner[lo:lo + BLOCK_CHUNK]
        first = np.flatnonzero(np.r_[True, np.diff(mine) != 0])  # each pair once per chunk
        blocks[mine[first]] += np.add.reduceat(
            np.einsum("qa,qj->qaj", rows[at], cols[at]), first, axis=0)
    return order[start], blocks


def csr_matrix(
    comm: MPI.Comm, rows: list, cols: list, vals: list, first: int, row_sizes: tuple,
    col_sizes: tuple, bs: int = 1,
) -> PETSc.Mat:
    """An AIJ matrix from owned global rows, columns and values (duplicates summed).

    Args:
        comm: The communicator.
        rows: Global row indices (blocks of ``bs`` rows), arrays to concatenate.
        cols: Global column indices (blocks of ``bs`` columns), likewise.
        vals: The values, likewise.
        first: The first owned row (of the expanded rows).
        row_sizes: (owned, global) rows, expanded.
        col_sizes: (owned, global) columns, expanded.
        bs: Each value stands for the diagonal of a ``bs`` x ``bs`` block: entry (r, c) is
            (r bs + k, c bs + k) for k < bs, expanded after the duplicates are summed.
    """
    n = row_sizes[0] // bs
    r = np.concatenate(rows).astype(np.int64) - first // bs if rows else np.zeros(0, np.int64)
    c = np.concatenate(cols).astype(np.int64) if cols else np.zeros(0, np.int64)
    v = np.concatenate(vals) if vals else np.zeros(0)
    keep = v != 0.0
    summed = scipy.sparse.csr_matrix((v[keep], (r[keep], c[keep])),
                                     shape=(n, col_sizes[1] // bs))
    summed.sum_duplicates()  # (sorted column indices per row, as PETSc's CSR wants them)
    indptr, indices, data = _expand(summed, bs)
    return PETSc.Mat().createAIJ(
        size=(row_sizes, col_sizes),
        csr=(indptr.astype(PETSc.IntType), indices.astype(PETSc.IntType), data),
        comm=comm,
    )


def facet_rows_matrix(
    comm: MPI.Comm, rows: np.ndarray, facet: np.ndarray, cols: np.ndarray, blocks: np.ndarray,
    first: int, row_sizes: tuple, col_sizes: tuple, bs: int,
) -> PETSc.Mat:
    """An AIJ matrix of dense blocks whose rows are those of one facet (duplicates summed).

    The rows of a facet (a DG space's dofs on it) all see the same columns, the union of its
    blocks': the blocks are summed per (facet, column) once, and the CSR arrays of
    block (x) I_bs (entry (r, c) at (r bs + k, c bs + k), k < bs) are written from those
    sums directly, without a coordinate list per entry.

    Args:
        comm: The communicator.
        rows: The global block rows of each facet, shape (m, a) (each owned row once).
        facet: The facet of each block, shape (p,).
        cols: The global block columns of each block, shape (p, j).
        blocks: The blocks, shape (p, a, j).
        first: The first owned block row.
        row_sizes: (owned, global) rows, expanded.
        col_sizes: (owned, global) columns, expanded.
        bs: The block size.
    """
    m, a = rows.shape
    width = np.int64(max(col_sizes[1] // bs, 1))
    key, at = np.unique(facet[:, None] * width + cols, return_inverse=True)
    at = at.ravel()
    sums = np.stack([np.bincount(at, weights=blocks[:, k].ravel(), minlength=len(key))
                     for k in range(a)], axis=1) if len(key) else np.zeros((0, a))
    owner, column = key // width, key % width  # sorted by facet, then column
    count = np.bincount(owner, minlength=m)
    start = np.cumsum(count) - count
    n = row_sizes[0] // bs
    row_facet, row_k = np.zeros(n, np.int64), np.zeros(n, np.int64)
    local = (rows - first).ravel()
    row_facet[local] = np.repeat(np.arange(m), a)
    row_k[local] = np.tile(np.arange(a), m)
    # the expanded rows R bs + c (c < bs) of block row R, written a chunk of rows at a time
    sizes = np.repeat(count[row_facet], bs)
    indptr = np.zeros(n * bs + 1, np.int64)
    np.cumsum(sizes, out=indptr[1:])
    indices = np.empty(indptr[-1], PETSc.IntType)
    data = np.empty(indptr[-1])
    step = max(1, BLOCK_CHUNK // max(int(count.max(initial=1)), 1))
    for lo in range(0, n * bs, step):
        r = np.arange(lo, min(lo + step, n * bs))
        size = sizes[r]
        entry = np.repeat(start[row_facet[r // bs]] - indptr[r], size) + np.arange(
            indptr[r[0]], indptr[r[-1] + 1])
        out = slice(indptr[r[0]], indptr[r[-1] + 1])
        indices[out] = column[entry] * bs + np.repeat(r % bs, size)
        data[out] = sums[entry, np.repeat(row_k[r // bs], size)]
    return PETSc.Mat().createAIJ(size=(row_sizes, col_sizes),
                                 csr=(indptr.astype(PETSc.IntType), indices, data), comm=comm)


def _expand(block: scipy.sparse.csr_matrix, bs: int) -> tuple[np.ndarray, ...]:
    """The CSR arrays of block (x) I_bs (row r bs + k holds row r's entries at columns c bs + k)."""
    if bs == 1:
        return block.indptr, block.indices, block.data
    count = np.diff(block.indptr)
    row = np.repeat(np.arange(block.shape[0]), bs)
    k = np.tile(np.arange(bs), block.shape[0])
    sizes = count[row]
    indptr = np.concatenate([[0], np.cumsum(sizes)])
    gather = np.repeat(block.indptr[row] - indptr[:-1], sizes) + np.arange(indptr[-1])
    return indptr, block.indices[gather] * bs + np.repeat(k, sizes), block.data[gather]
