"""The contact search of a pair shared between the ranks, whoever owns the slave facets.

The volume partition of a mesh often puts a contact face on one rank (a face is a small part of
the volume): that rank then owns nearly all slave facets and builds nearly the whole master
trace, while the solve is shared. The largest part of the trace, the candidate search and the
clipping of each slave facet against its candidates
(:func:`~dwr_signorini.search.candidate_parts`), needs only the facet, its normal and window,
and the master facets within its search radius (:func:`~dwr_signorini.search.search_radius`).
:func:`search_parts` moves that work, not the mesh partition:

1. every rank's number of slave facets c_r is gathered, and each rank searches as many as the
   others (:func:`search_counts`; the rest of the trace, the Gauss points, the bases, the
   projection and its matrix, stays with the owner, after the search);
2. a rank searching fewer than it owns sends the surplus (its facets last along the axis of
   their widest spread, so each batch is a compact strip) with the held master facets whose
   centres lie within the batch's search radii, their global numbers, and the pair's largest
   master reach (:func:`transfers` says to whom: in the order of the ranks);
3. each rank searches the batches it received and its own kept facets, and returns each
   batch's rule (its masters as global numbers) and the facets the candidates left over;
4. the owner maps the results back onto its facets and held masters.

Each facet is searched as on its owner (the same master facets within its radius, met in the
order of their global numbers), so the rule is the unbalanced one: the same pieces, in the same
order. The split depends only on the counts and the coordinates, never on timings.
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np

from . import search
from .mortar import MortarRule, facet_reach
from .search import search_radius

__all__ = ["search_counts", "search_parts", "transfers"]


def search_counts(counts: np.ndarray) -> np.ndarray:
    """How many slave facets each rank searches: as many as the others, to one facet.

    Only the search is shared: the rest of each facet's trace (its Gauss points, bases,
    projection and matrix rows) follows on its owner once every search is back, so the time to
    the rule is that of the rank searching most, and the split levels the search itself:
    k_r = floor(N / p), plus one on the first N mod p ranks (N facets, p ranks).

    Args:
        counts: The slave facets each rank owns.

    Returns:
        The facets each rank searches (summing to ``counts.sum()``).
    """
    counts = np.asarray(counts, dtype=np.int64)
    total, size = int(counts.sum()), len(counts)
    return total // size + (np.arange(size) < total % size).astype(np.int64)


def transfers(counts: np.ndarray, searched: np.ndarray) -> list[tuple[int, int, int]]:
    """Who sends how many slave facets to whom: (source, destination, number), in rank order.

    Surpluses c_r - k_r > 0 are matched to deficits in the order of the ranks (two pointers).
    """
    surplus = np.asarray(counts, dtype=np.int64) - np.asarray(searched, dtype=np.int64)
    give = [[r, int(s)] for r, s in enumerate(surplus) if s > 0]
    take = [[r, int(-s)] for r, s in enumerate(surplus) if s < 0]
    out, i, j = [], 0, 0
    while i < len(give) and j < len(take):
        k = min(give[i][1], take[j][1])
        out.append((give[i][0], take[j][0], k))
        give[i][1] -= k
        take[j][1] -= k
        i += give[i][1] == 0
        j += take[j][1] == 0
    return out


def _batches(comm: MPI.Comm, slave: np.ndarray) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """This rank's slave facets it searches itself, and those it sends to each rank.

    The facets are ordered along the axis of their centres' widest spread (stable); the last
    ones go, in the order of :func:`transfers`' destinations.
    """
    counts = np.array(comm.allgather(len(slave)), dtype=np.int64)
    moves = [m for m in transfers(counts, search_counts(counts)) if m[0] == comm.rank]
    if not moves:
        return np.arange(len(slave), dtype=np.int64), {}
    centres = slave.mean(axis=1)
    axis = int(np.argmax(centres.max(axis=0) - centres.min(axis=0)))
    order = np.argsort(centres[:, axis], kind="stable")
    end = len(order) - sum(k for _, _, k in moves)
    kept, out = np.sort(order[:end]), {}
    for _, dest, k in moves:
        out[dest] = np.sort(order[end:end + k])
        end += k
    return kept, out


def search_parts(
    comm: MPI.Comm, slave: np.ndarray, normals: np.ndarray, windows: np.ndarray,
    master: tuple[np.ndarray, np.ndarray, np.ndarray], reach: float, balance: bool = True,
) -> tuple[list[MortarRule], np.ndarray]:
    """:func:`~dwr_signorini.search.candidate_parts` of this rank's slave facets, shared out.

    Collective (module docstring). The result is that of ``candidate_parts(slave, normals,
    vertices, master_normals, None, windows, reach, numbers)`` on this rank.

    Args:
        comm: The mesh's communicator.
        slave: This rank's slave facets of the pair, (m, nv, gdim).
        normals: Their outward unit normals.
        windows: Their penetration windows.
        master: The held master facets: vertices, outward unit normals, global numbers.
        reach: The largest reach of a master facet of the pair, over all ranks.
        balance: Whether to share the work out (False: every rank searches its own facets).

    Returns:
        The rules of the facets their candidates cover (``facet`` indexing ``slave``,
        ``master`` indexing the held master facets), and the facets left over (sorted).
    """
    kept, batches = _batches(comm, slave) if balance else (np.arange(len(slave)), {})
    vertices, master_normals, numbers = master
    centres = facet_reach(vertices)[0] if len(vertices) else np.zeros((0, slave.shape[2]))
    out: list = [None] * comm.size
    for dest, at in batches.items():
        near = _within(centres, slave[at], windows[at], reach)
        out[dest] = (slave[at], normals[at], windows[at], vertices[near], master_normals[near],
                     numbers[near])
    received = comm.alltoall(out) if balance else out
    replies = [None if b is None else _search_batch(*b, reach) for b in received]
    parts, full = _search_local(slave, normals, windows, master, reach, kept)  # meanwhile
    answers = comm.alltoall(replies) if balance else replies
    order = np.argsort(numbers, kind="stable")
    for dest, at in batches.items():
        rule, left = answers[dest]
        held = order[np.searchsorted(numbers, rule.master, sorter=order)]
        parts.append(MortarRule(at[rule.facet], rule.points, rule.weights, held, rule.gap))
        full = np.concatenate([full, at[left]])
    return parts, np.sort(full)


def _within(centres: np.ndarray, slave: np.ndarray, windows: np.ndarray,
            reach: float) -> np.ndarray:
    """The master facets whose centres lie in the box of the slave facets' search balls."""
    if len(slave) == 0:
        return np.zeros(0, np.int64)
    slave_centres = facet_reach(slave)[0]
    radius = search_radius(slave, windows, reach)[:, None]
    lo = (slave_centres - radius).min(axis=0)
    hi = (slave_centres + radius).max(axis=0)
    return np.flatnonzero(np.all((centres >= lo) & (centres <= hi), axis=1))


def _search_local(
    slave: np.ndarray, normals: np.ndarray, windows: np.ndarray,
    master: tuple[np.ndarray, np.ndarray, np.ndarray], reach: float, kept: np.ndarray,
) -> tuple[list[MortarRule], np.ndarray]:
    """The search of the facets ``kept`` on this rank, indexed as ``slave``."""
    vertices, master_normals, numbers = master
    parts, full = search.candidate_parts(slave[kept], normals[kept], vertices, master_normals,
                                         None, windows[kept], reach, numbers)
    parts = [MortarRule(kept[r.facet], r.points, r.weights, r.master, r.gap) for r in parts]
    return parts, kept[full]


def _search_batch(
    slave: np.ndarray, normals: np.ndarray, windows: np.ndarray, vertices: np.ndarray,
    master_normals: np.ndarray, numbers: np.ndarray, reach: float,
) -> tuple[MortarRule, np.ndarray]:
    """A batch received: its rule (masters as global numbers) and the facets left over."""
    parts, full = search.candidate_parts(slave, normals, vertices, master_normals, None,
                                         windows, reach, numbers)
    if not parts:
        empty = np.zeros(0)
        return MortarRule(empty.astype(np.int64), np.zeros((0, slave.shape[2])), empty,
                          empty.astype(np.int64), empty), full
    (rule,) = parts
    return MortarRule(rule.facet, rule.points, rule.weights, numbers[rule.master],
                      rule.gap), full
