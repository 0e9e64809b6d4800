"""Balance the macro mesh over the ranks after adaptive refinement.

``dolfinx.mesh.refine`` keeps each child on its parent's rank
(:func:`~dwr_signorini.compat.refine`), and adaptive refinement concentrates where the goal
needs it, typically at the contact zone: level by level a few ranks come to hold most of the
cells. On 2 ranks, adaptive example 5.3 from 3 x 12 x 12 boxes had 0.51, 0.64, 0.73, 0.78,
0.79 of its fine cells on one rank on levels 0-4 (``benchmarks/large_3d.py``), so two ranks ran
such a level at most 1.27 times as fast as one.

:func:`rebalance` gives the refined macro mesh T_H to the graph partitioner again
(:func:`dolfinx.mesh.create_mesh` with the cells and nodes it has, by their global numbers) when
the rank that holds most has more than :data:`REBALANCE_THRESHOLD` times the mean of a mesh of
at least :data:`REBALANCE_MIN_CELLS` cells per rank, and carries
its facet and cell tags to the new distribution (:func:`dolfinx.io.distribute_entity_data`). The
mesh is the same; only its distribution changes. The fine mesh T_h is refined from it as before,
children on their parent's rank. :func:`rebalance_level` also returns where each cell came
from (:class:`CellOrigin`: its rank and local index before, and its parent in the last level's
macro mesh), so the warm start of the next level
(:func:`~dwr_signorini.transfer.transfer_solution`) evaluates the last level's reconstructions
in the known parent cells on the ranks that hold them, as without redistribution: the same
values, no point location.
"""

from __future__ import annotations

from dataclasses import dataclass

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import fem, graph
from dolfinx import io as dio
from dolfinx import mesh as dmesh

from . import compat
from .problem import SignoriniProblem

__all__ = [
    "REBALANCE_MIN_CELLS",
    "REBALANCE_THRESHOLD",
    "CellOrigin",
    "imbalance",
    "rebalance",
    "rebalance_level",
]

#: Cells on the fullest rank over the mean above which :func:`rebalance` redistributes ...
REBALANCE_THRESHOLD = 1.2
#: ... a macro mesh of at least this many cells per rank. Smaller levels cost little, and
#: their refinement stays independent of the number of ranks (a redistributed mesh is numbered
#: anew, and the refinement breaks ties between equally long edges by the numbering).
REBALANCE_MIN_CELLS = 10_000


def imbalance(msh: dmesh.Mesh) -> float:
    """The owned cells of the fullest rank over the mean (1 on one rank; collective).

    Args:
        msh: A mesh.

    Returns:
        max / mean of the ranks' owned cells.
    """
    tdim = msh.topology.dim
    owned = msh.comm.allgather(msh.topology.index_map(tdim).size_local)
    return max(owned) * len(owned) / max(1, sum(owned))


def _entity_nodes(msh: dmesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The global geometry node numbers of ``entities`` (rows), as create_mesh numbered them."""
    nodes = dmesh.entities_to_geometry(msh, dim, entities.astype(np.int32))
    imap = msh.geometry.index_map()
    return imap.local_to_global(nodes.ravel()).reshape(nodes.shape).astype(np.int64)


def _owned_tags(msh: dmesh.Mesh, tags: dmesh.MeshTags) -> tuple[np.ndarray, np.ndarray]:
    """The tagged entities this rank owns (each entity sent once) and their values."""
    msh.topology.create_entities(tags.dim)
    owned = tags.indices < msh.topology.index_map(tags.dim).size_local
    return tags.indices[owned], tags.values[owned]


def _tags_on(new: dmesh.Mesh, old: dmesh.Mesh, tags: dmesh.MeshTags) -> dmesh.MeshTags:
    """``tags`` of ``old`` on the redistributed mesh ``new``."""
    entities, values = _owned_tags(old, tags)
    nodes = _entity_nodes(old, tags.dim, entities)
    new.topology.create_entities(tags.dim)
    new.topology.create_connectivity(tags.dim, new.topology.dim)
    local, local_values = dio.distribute_entity_data(new, tags.dim, nodes, values)
    local = local.astype(np.int32).reshape(-1, tags.dim + 1)  # simplex entities
    result = dmesh.meshtags_from_entities(new, tags.dim, graph.adjacencylist(local),
                                          local_values.astype(tags.values.dtype))
    result.name = tags.name
    return result


@dataclass(frozen=True)
class CellOrigin:
    """Where the cells of a redistributed macro mesh were, and their parents there.

    Cell ``c`` of the redistributed mesh (local numbering) was cell ``index[c]`` of the refined
    macro mesh on rank ``rank[c]``; there, ``parent[i]`` is the cell of the last level's macro
    mesh that contains that rank's old cell ``i`` (the parent map of the refinement).
    """

    comm: MPI.Comm
    rank: npt.NDArray[np.int32]
    index: npt.NDArray[np.int32]
    parent: npt.NDArray[np.int32]

    def evaluate(
        self, function: fem.Function, points: np.ndarray, cells: npt.NDArray[np.int32]
    ) -> np.ndarray:
        """``function`` of the last level's macro mesh at points of the redistributed cells.

        Each point is sent to the rank that held its cell before, evaluated there in that
        cell's parent and the value sent back (collective).

        Args:
            function: A function on the last level's macro mesh (its old distribution).
            points: Points, shape (n, 3), each in the redistributed cell ``cells[i]``.
            cells: Local cells of the redistributed mesh.

        Returns:
            The values, shape (n, value size).
        """
        width = int(np.prod(function.ufl_shape, dtype=int))
        dest = self.rank[cells]
        order = np.argsort(dest, kind="stable")
        counts = np.bincount(dest, minlength=self.comm.size)
        index, received = _exchange(self.comm, self.index[cells][order], counts)
        x, _ = _exchange(self.comm, np.ascontiguousarray(points[order], dtype=np.float64), counts)
        values = np.zeros((len(index), width))
        if len(index):
            values[:] = function.eval(x, self.parent[index]).reshape(len(index), width)
        back, _ = _exchange(self.comm, values, received)
        out = np.empty_like(back)
        out[order] = back
        return out


def _exchange(
    comm: MPI.Comm, rows: np.ndarray, counts: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Rows grouped by destination rank (``counts`` per rank) sent there.

    Returns the rows that arrived, grouped by source rank, and how many came from each.
    """
    received = np.asarray(comm.alltoall([int(c) for c in counts]), dtype=np.int64)
    width = int(np.prod(rows.shape[1:], dtype=int))
    out = np.empty((int(received.sum()), *rows.shape[1:]), dtype=rows.dtype)

    def spec(buffer: np.ndarray, n: np.ndarray) -> list:
        n = np.asarray(n, dtype=np.int64) * width
        return [buffer, (n.tolist(), (np.cumsum(n) - n).tolist())]

    comm.Alltoallv(spec(np.ascontiguousarray(rows), counts), spec(out, received))
    return out, received


def rebalance_level(
    problem: SignoriniProblem,
    macro_parent: npt.NDArray[np.int32] | None,
    threshold: float | None = None,
    min_cells: int | None = None,
) -> tuple[SignoriniProblem, npt.NDArray[np.int32] | CellOrigin | None]:
    """The next level's problem and parent map, redistributed if unbalanced (:func:`rebalance`).

    Args:
        problem: The refined problem (its macro mesh refined from the last level's).
        macro_parent: The last level's macro cell of each of its local cells, or None.
        threshold: See :func:`rebalance`.
        min_cells: See :func:`rebalance`.

    Returns:
        ``(problem, macro_parent)`` as given where the mesh stays, or the redistributed problem
        and the :class:`CellOrigin` of its cells (None without a parent map).
    """
    moved = _redistributed(problem, threshold, min_cells)
    if moved is None:
        return problem, macro_parent
    balanced, original = moved
    if macro_parent is None:
        return balanced, None
    comm = problem.mesh.comm
    tdim = problem.mesh.topology.dim
    offsets = np.cumsum([0, *comm.allgather(problem.mesh.topology.index_map(tdim).size_local)])
    rank = np.searchsorted(offsets, original, side="right") - 1
    index = original - offsets[rank]
    return balanced, CellOrigin(
        comm, rank.astype(np.int32), index.astype(np.int32), np.asarray(macro_parent, np.int32)
    )


def rebalance(
    problem: SignoriniProblem, threshold: float | None = None, min_cells: int | None = None
) -> SignoriniProblem | None:
    """The problem on its macro mesh redistributed by the graph partitioner, if unbalanced.

    Args:
        problem: A problem on a (refined) macro mesh with linear simplex geometry.
        threshold: Redistribute when :func:`imbalance` exceeds it (default
            :data:`REBALANCE_THRESHOLD`) ...
        min_cells: ... and the mesh has at least this many cells per rank (default
            :data:`REBALANCE_MIN_CELLS`).

    Returns:
        The problem on the redistributed mesh with its tags, or None where the mesh was
        balanced or small (or on one rank).
    """
    moved = _redistributed(problem, threshold, min_cells)
    return None if moved is None else moved[0]


def _redistributed(
    problem: SignoriniProblem, threshold: float | None, min_cells: int | None
) -> tuple[SignoriniProblem, npt.NDArray[np.int64]] | None:
    """:func:`rebalance`, with the original (global input) index of each new local cell."""
    threshold = REBALANCE_THRESHOLD if threshold is None else threshold
    min_cells = REBALANCE_MIN_CELLS if min_cells is None else min_cells
    msh = problem.mesh
    comm: MPI.Comm = msh.comm
    cells = msh.topology.index_map(msh.topology.dim).size_global
    if comm.size == 1 or cells < min_cells * comm.size or imbalance(msh) <= threshold:
        return None
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    imap = msh.geometry.index_map()
    x = np.ascontiguousarray(msh.geometry.x[: imap.size_local, :gdim])
    num_cells = msh.topology.index_map(tdim).size_local
    dofmap = compat.geometry_dofmap(msh)[:num_cells]
    cells = imap.local_to_global(dofmap.ravel()).reshape(dofmap.shape).astype(np.int64)
    new = compat.create_mesh(comm, cells, x, msh.ufl_domain(),
                             partitioner=compat.cell_partitioner(dmesh.GhostMode.none))
    facet_tags = _tags_on(new, msh, problem.facet_tags)
    cell_tags = None if problem.cell_tags is None else _tags_on(new, msh, problem.cell_tags)
    num_new = new.topology.index_map(tdim).size_local
    original = np.asarray(new.topology.original_cell_index[:num_new], dtype=np.int64)
    return problem.with_mesh(new, facet_tags, cell_tags), original
