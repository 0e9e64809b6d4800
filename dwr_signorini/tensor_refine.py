"""Uniform refinement of quadrilateral and hexahedral meshes (dolfinx 0.9 refines simplices only).

Every quadrilateral is split into 4 and every hexahedron into 8 children by bisecting it along each
reference axis. The new nodes are the images under the (multi)linear coordinate map of the edge
midpoints, the face centres (3D) and the cell centre, so the refined mesh covers exactly the same
domain, also for non-affine (bilinear/trilinear) cells.

The parent-child data returned alongside the refined mesh follow the meaning of
``dolfinx.mesh.refine(msh, partitioner=None, option=RefinementOption.parent_cell_and_facet)``,
but are indexed by the *local cell index of the refined mesh* (see :func:`refine_uniform_tensor`).

Parallel layout: children stay on the process that owns their parent. Each new node gets a single
global index, taken from a block of consecutive indices per rank that holds, in this order, the
rank's owned vertices, owned edges, owned faces (3D) and owned cells of the parent mesh; the rank
supplies the coordinates of exactly its own block to :func:`dolfinx.mesh.create_mesh`.
"""

from collections.abc import Callable
from typing import Any

from mpi4py import MPI

import basix
import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import mesh as dmesh

from . import compat

__all__ = ["refine_uniform_tensor"]

_BASIX_CELL = {
    dmesh.CellType.quadrilateral: basix.CellType.quadrilateral,
    dmesh.CellType.hexahedron: basix.CellType.hexahedron,
}


def _reference_tables(
    cell_type: dmesh.CellType,
) -> tuple[npt.NDArray[np.int32], npt.NDArray[np.int32], npt.NDArray[np.int8]]:
    """Reference-cell tables of the uniform 2^d split of a tensor-product cell.

    The new nodes of a parent cell lie on the lattice ``g / 2`` with ``g`` in ``{0, 1, 2}^d``
    (reference coordinates); lattice point ``g`` has index ``g[0] + 3 g[1] + 9 g[2]``.

    Args:
        cell_type: ``quadrilateral`` or ``hexahedron``.

    Returns:
        ``(lattice_entity, child_nodes, child_parent_facet)``: ``lattice_entity[p] = (dim, i)``
        says that lattice point ``p`` is the node of the parent's local entity ``i`` of dimension
        ``dim`` (its vertex, edge midpoint, face centre or cell centre); ``child_nodes[k]`` are the
        lattice points of the vertices of child ``k`` in reference (tensor-product) order;
        ``child_parent_facet[k, j]`` is the local facet of the parent that contains local facet
        ``j`` of child ``k``, or -1 if that facet is interior to the parent.
    """
    bcell = _BASIX_CELL[cell_type]
    topology = basix.topology(bcell)
    tdim = len(topology) - 1
    # Reference vertices in {0, 1}^tdim, as integers.
    ref = np.rint(basix.geometry(bcell)[:, :tdim]).astype(np.int64)

    # Entity of every lattice point: the vertices of the entity are those that agree with the
    # point on all its even (i.e. vertex-aligned) coordinates.
    weights = 3 ** np.arange(tdim)
    lattice = (np.arange(3**tdim)[:, None] // weights) % 3
    lattice_entity = np.empty((lattice.shape[0], 2), dtype=np.int32)
    for p, g in enumerate(lattice):
        even = g % 2 == 0
        verts = {v for v in range(ref.shape[0]) if np.all(2 * ref[v, even] == g[even])}
        dim = int(np.count_nonzero(~even))
        matches = [i for i, e in enumerate(topology[dim]) if set(e) == verts]
        assert len(matches) == 1
        lattice_entity[p] = (dim, matches[0])

    # Children: child k sits at offset s in {0, 1}^tdim; its vertex v is lattice point s + ref[v].
    num_children = 2**tdim
    child_offsets = ref  # the reference vertices enumerate {0, 1}^tdim
    child_nodes = np.array([(s + ref) @ weights for s in child_offsets], dtype=np.int32)
    assert child_nodes.shape == (num_children, num_children)

    # Facet j of the reference cell is {x_axis = value}; the same facet of child s lies on the
    # parent's facet j iff s[axis] == value, and inside the parent otherwise.
    facets = topology[tdim - 1]
    child_parent_facet = np.full((num_children, len(facets)), -1, dtype=np.int8)
    for j, facet in enumerate(facets):
        fv = ref[list(facet)]
        axis = int(np.flatnonzero(np.all(fv == fv[0], axis=0))[0])
        value = fv[0, axis]
        child_parent_facet[child_offsets[:, axis] == value, j] = j
    return lattice_entity, child_nodes, child_parent_facet


def _keep_on_rank(rank: int, num_cell_vertices: int) -> Callable:
    """A cell partitioner (dolfinx 0.9 signature) that keeps every cell on the calling rank.

    Args:
        rank: Rank of the calling process.
        num_cell_vertices: Number of vertices per cell.

    Returns:
        ``partitioner(comm, nparts, cell_types, cells) -> AdjacencyList_int32``.
    """

    def partitioner(comm, nparts, cell_types, cells):
        num_cells = sum(np.asarray(c).size for c in cells) // num_cell_vertices
        dest = np.full(num_cells, rank, dtype=np.int32)
        return compat.cpp_adjacencylist(dest, np.arange(num_cells + 1, dtype=np.int32))

    return partitioner


def refine_uniform_tensor(
    msh: dmesh.Mesh,
) -> tuple[dmesh.Mesh, npt.NDArray[np.int32], npt.NDArray[np.int8]]:
    """Split each quadrilateral into 4 / each hexahedron into 8 (one uniform refinement).

    Only the cells owned by the calling process are refined (ghost cells of ``msh`` are ignored);
    the children stay on that process and the refined mesh has no ghost cells. The children have
    the orientation of their parent (same sign of the Jacobian determinant).

    Note:
        The edges (and in 3D the faces) of ``msh`` are created if they do not exist yet.

    Note:
        In dolfinx 0.9 ``dolfinx.mesh.refine`` returns ``parent_cell`` in the order in which the
        refined cells were *created*, i.e. entry ``i`` belongs to the refined cell with
        ``topology.original_cell_index == offset + i``, not to local cell ``i`` (``create_mesh``
        reorders cells). Here both arrays are indexed by the local cell index of the refined mesh,
        so they must not be passed to ``dolfinx.mesh.transfer_meshtag``.

    Args:
        msh: Quadrilateral or hexahedral mesh with degree-1 geometry.

    Returns:
        ``(fine_mesh, parent_cell, parent_facet)``: ``parent_cell[c]`` (int32, one entry per local
        cell of ``fine_mesh``) is the local index in ``msh`` of the parent of fine cell ``c``;
        ``parent_facet[c * nf + j]`` (int8, ``nf`` facets per cell) is the local facet index, in
        the parent cell's reference numbering, of the parent facet that contains local facet
        ``j`` of fine cell ``c``, or -1 if that facet lies in the interior of the parent.

    Raises:
        ValueError: If ``msh`` is not a quadrilateral/hexahedral mesh with degree-1 geometry.
    """
    topology = msh.topology
    cell_type = topology.cell_type
    if cell_type not in _BASIX_CELL:
        raise ValueError(f"refine_uniform_tensor needs quadrilaterals/hexahedra, not {cell_type}")
    cmap = compat.geometry_cmap(msh)
    if cmap.degree != 1:
        raise ValueError(f"refine_uniform_tensor needs degree-1 geometry, not degree {cmap.degree}")
    comm = msh.comm
    rank = comm.rank
    tdim = topology.dim
    num_cell_vertices = 2**tdim
    lattice_entity, child_nodes, child_parent_facet = _reference_tables(cell_type)

    for d in range(1, tdim):
        topology.create_entities(d)
    for d in range(tdim):
        topology.create_connectivity(tdim, d)
        topology.create_connectivity(d, tdim)
    maps = [topology.index_map(d) for d in range(tdim + 1)]
    node_index = _node_numbering(comm, maps)
    cells, created_parent_cell, created_parent_facet = _refined_cells(
        msh, node_index, lattice_entity, child_nodes, child_parent_facet
    )
    x_block = _block_coordinates(msh, maps)
    domain = ufl.Mesh(msh.ufl_domain().ufl_coordinate_element())
    fine = compat.create_mesh(
        comm, cells, x_block, domain, partitioner=_keep_on_rank(rank, num_cell_vertices)
    )

    # --- Parent data in the local cell order of the refined mesh ----------------------------------
    num_created = cells.shape[0]
    offset = comm.exscan(num_created, op=MPI.SUM)
    offset = 0 if offset is None or rank == 0 else offset
    fine_map = fine.topology.index_map(tdim)
    if fine_map.size_local != num_created or fine_map.num_ghosts != 0:
        raise RuntimeError("refined cells were not kept on the rank of their parent")
    created = np.asarray(fine.topology.original_cell_index, dtype=np.int64) - offset
    parent_cell = np.ascontiguousarray(created_parent_cell[created], dtype=np.int32)
    parent_facet = np.ascontiguousarray(created_parent_facet[created].reshape(-1), dtype=np.int8)
    return fine, parent_cell, parent_facet


def _node_numbering(comm: MPI.Comm, maps: list[Any]) -> list[npt.NDArray[np.int64]]:
    """Global indices of the refined mesh's nodes, one per entity of the coarse mesh.

    The nodes of each rank form one block: its owned vertices, edges (midpoints), faces and
    cells (centres), in that order.

    Args:
        comm: The mesh's communicator.
        maps: The index maps of the entities of dimension 0, ..., tdim.

    Returns:
        ``node_index[d][e]``: the global node of local entity ``e`` of dimension ``d`` (owned
        and ghost entities below the cells, owned cells).
    """
    rank, tdim = comm.rank, len(maps) - 1
    sizes = np.array([im.size_local for im in maps], dtype=np.int64)
    starts = np.array([im.local_range[0] for im in maps], dtype=np.int64)
    all_sizes = np.array(comm.allgather(sizes), dtype=np.int64).reshape(comm.size, tdim + 1)
    all_starts = np.array(comm.allgather(starts), dtype=np.int64).reshape(comm.size, tdim + 1)
    block_start = np.concatenate(([0], np.cumsum(all_sizes.sum(axis=1))[:-1]))
    # dim_start[r, d]: global index of the node of rank r's first owned entity of dimension d.
    dim_start = block_start[:, None] + np.cumsum(all_sizes, axis=1) - all_sizes

    node_index = []
    for d in range(tdim):
        im = maps[d]
        glob = np.concatenate(
            (im.local_range[0] + np.arange(im.size_local, dtype=np.int64), im.ghosts)
        ).astype(np.int64)
        owner = np.concatenate(
            (np.full(im.size_local, rank, dtype=np.int64), np.asarray(im.owners, dtype=np.int64))
        )
        node_index.append(dim_start[owner, d] + glob - all_starts[owner, d])
    node_index.append(dim_start[rank, tdim] + np.arange(sizes[tdim], dtype=np.int64))
    return node_index


def _refined_cells(
    msh: dmesh.Mesh,
    node_index: list[npt.NDArray[np.int64]],
    lattice_entity: np.ndarray,
    child_nodes: np.ndarray,
    child_parent_facet: np.ndarray,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int32], np.ndarray]:
    """The children of the owned cells, in the order they are created.

    Returns:
        ``(cells, parent_cell, parent_facet)``: the children's global nodes (one row per
        child), the local index of each child's parent and the parent facet of each of its
        facets (rows of the reference table, -1 inside the parent).
    """
    topology = msh.topology
    tdim = topology.dim
    num_cells = topology.index_map(tdim).size_local
    cell_entities = []
    for d in range(tdim):
        conn = topology.connectivity(tdim, d).array
        cell_entities.append(
            conn.reshape(-1, len(basix.topology(_BASIX_CELL[topology.cell_type])[d]))
        )
    cell_entities.append(np.arange(num_cells, dtype=np.int32)[:, None])
    lattice_nodes = np.empty((num_cells, lattice_entity.shape[0]), dtype=np.int64)
    for p, (d, i) in enumerate(lattice_entity):
        lattice_nodes[:, p] = node_index[d][cell_entities[d][:num_cells, i]]
    cells = lattice_nodes[:, child_nodes].reshape(-1, 2**tdim)
    num_children = child_nodes.shape[0]
    parent_cell = np.repeat(np.arange(num_cells, dtype=np.int32), num_children)
    parent_facet = np.tile(child_parent_facet, (num_cells, 1))
    return cells, parent_cell, parent_facet


def _block_coordinates(msh: dmesh.Mesh, maps: list[Any]) -> np.ndarray:
    """Coordinates of this rank's block of nodes.

    The means of each owned entity's vertices: the multilinear images of the reference
    midpoints and centres.
    """
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    x = msh.geometry.x
    coords = []
    for d in range(tdim):
        owned = np.arange(maps[d].size_local, dtype=np.int32)
        nodes = dmesh.entities_to_geometry(msh, d, owned).reshape(owned.size, -1)
        coords.append(x[nodes, :gdim].mean(axis=1).reshape(-1, gdim))
    dofmap = compat.geometry_dofmap(msh)[: maps[tdim].size_local]
    coords.append(x[dofmap, :gdim].mean(axis=1).reshape(-1, gdim))
    return np.ascontiguousarray(np.concatenate(coords, axis=0), dtype=x.dtype)
