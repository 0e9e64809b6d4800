"""The master facets of a pair that each rank's slave facets need, sent by their owners.

The mortar rule of a slave facet F (:mod:`~dwr_signorini.mortar`) reads only the master facets
in F's shadow (:func:`~dwr_signorini.mortar.in_shadow`), and the candidate search
(:func:`~dwr_signorini.search.candidate_parts`) only those whose centres lie within
:func:`~dwr_signorini.search.search_radius` of F's centre. So no rank needs the whole master
surface: :class:`MasterExchange` gathers only the ranks' boxes (each rank's slave facets'
centres, enlarged by their search radius), and each rank sends the master facets whose centres
lie in a box to that box's rank (:meth:`MasterExchange.boxes`); the few slave facets that their
candidates do not cover (searched against every master facet) are sent to every rank, which
returns the master facets in their shadow (:meth:`MasterExchange.shadows`). Each master facet
keeps its global number (the order of the owners' ranks, then of their facets), in which each
slave facet meets them: the rule is the same on any number of ranks.
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np
from dolfinx import fem

from .mortar import facet_reach, in_shadow
from .pair_facets import Side, cell_dofs

__all__ = ["MasterExchange"]


class MasterExchange:
    """The master facets of one pair held by this rank: its own that it needs and others'.

    Collective (every rank builds one per pair, and calls :meth:`boxes` and :meth:`shadows`
    together).

    Args:
        comm: The mesh's communicator.
        own: This rank's owned master facets of the pair (``dofs`` empty).
        cells: The local cell beside each of them.

    Attributes:
        side: The held master facets (``dofs`` empty; in the order they arrived, only
            appended to, so that indices into them stay valid).
        number: Their global numbers.
        reach: The largest reach of a master facet of the pair, over all ranks.
    """

    def __init__(self, comm: MPI.Comm, own: Side, cells: np.ndarray) -> None:
        self.comm, self.own, self.cells = comm, own, cells
        counts = comm.allgather(len(own.cell))
        self.first = int(np.sum(counts[:comm.rank]))
        gdim = own.normals.shape[1]
        self.side = Side(own.vertices[:0], own.normals[:0], own.geometry[:0],
                         np.zeros((0, 0), np.int64), own.cell[:0])
        self.number = np.zeros(0, np.int64)
        self._source = np.zeros(0, np.int64)  # the rank each held facet came from
        self._centres, reach = facet_reach(own.vertices) if len(own.cell) else (
            np.zeros((0, gdim)), np.zeros(0))
        self.reach = comm.allreduce(float(reach.max(initial=0.0)), op=MPI.MAX)

    def boxes(self, centres: np.ndarray, radius: np.ndarray) -> None:
        """Receive the master facets whose centres lie within ``radius`` of ``centres``.

        Args:
            centres: This rank's slave facets' centres, shape (m, gdim).
            radius: Their search radii (:func:`~dwr_signorini.search.search_radius`).
        """
        gdim = self._centres.shape[1]
        lo = (centres - radius[:, None]).min(axis=0) if len(centres) else np.full(gdim, np.inf)
        hi = (centres + radius[:, None]).max(axis=0) if len(centres) else np.full(gdim, -np.inf)
        boxes = self.comm.allgather((lo, hi))
        self._send([np.flatnonzero(np.all((self._centres >= a) & (self._centres <= b), axis=1))
                    for a, b in boxes])

    def shadows(self, slave: np.ndarray, normals: np.ndarray, windows: np.ndarray) -> None:
        """Receive every master facet in the shadow of the slave facets given.

        Args:
            slave: This rank's slave facets searched against every master facet, (m, nv, gdim).
            normals: Their outward unit normals.
            windows: Their penetration windows.
        """
        centres, reach = facet_reach(slave)
        asked = self.comm.allgather((centres, normals, reach, windows))
        own_centres, own_reach = facet_reach(self.own.vertices) if len(self.own.cell) else (
            self._centres, np.zeros(0))
        wanted = []
        for c, n, r, w in asked:
            hit = np.zeros(len(own_centres), dtype=bool)
            for i in range(len(c)):
                hit |= in_shadow(own_centres, own_reach, self.own.normals, c[i], n[i], r[i],
                                 w[i])
            wanted.append(np.flatnonzero(hit))
        self._send(wanted)

    def _send(self, wanted: list[np.ndarray]) -> None:
        """Send each rank the own facets it wants, keep the new ones received."""
        fields = Side.fields()
        out = [(self.first + w, *(getattr(self.own, f)[w] for f in fields)) for w in wanted]
        received = self.comm.alltoall(out)
        for source, (number, *values) in enumerate(received):
            new = ~np.isin(number, self.number)
            self.number = np.concatenate([self.number, number[new]])
            self._source = np.concatenate([self._source, np.full(int(new.sum()), source)])
            self.side = Side(*(np.concatenate([getattr(self.side, f), v[new]]) if f != "dofs"
                               else np.zeros((len(self.number), 0), np.int64)
                               for f, v in zip(fields, values, strict=True)))

    def dofs(self, V: fem.FunctionSpace) -> np.ndarray:
        """V's global block dofs of the held facets' cells (collective).

        Args:
            V: The displacement space.

        Returns:
            Shape (held facets, dofs per cell), in the order of :attr:`side`.
        """
        own = cell_dofs(V, self.cells)
        wanted = self.comm.alltoall([self.number[self._source == r]
                                     for r in range(self.comm.size)])  # global numbers
        received = self.comm.alltoall([own[w - self.first] for w in wanted])
        out = np.zeros((len(self.number), V.dofmap.dof_layout.num_dofs), np.int64)
        for r, values in enumerate(received):
            out[self._source == r] = values
        return out
