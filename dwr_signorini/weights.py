"""Which weights ``weights="auto"`` of :func:`~dwr_signorini.estimator.estimate` takes.

The patch weights where they serve; P2 weights on a band around the contact zone
(:func:`unresolved_kind`, :mod:`~dwr_signorini.local_p2`) on a level whose contact set is not
resolved; the factored P2 weights of the whole mesh where J_h vanishes to round-off but the
patch estimate does not; those of the whole mesh (hierarchical, but factored for a law with
coupled rows in 3D, :func:`p2_kind`) on every level of a nearly incompressible material;
never P2 weights that would not fit in memory (predicted from global sizes, the same on every
rank, as the solver's method is chosen).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import fem

from .linalg import memory

__all__ = [
    "NEARLY_INCOMPRESSIBLE_NU",
    "nearly_incompressible",
    "p2_weights_fit",
    "p2_weights_memory",
]

logger = logging.getLogger("dwr_signorini.estimator")

#: Poisson's ratio from which ``weights="auto"`` takes P2 weights on every level: the P1 dual
#: solution locks like the primal one (lambda / mu >= 9), and its patch-wise recovery misses
#: the error. Measured on the Cattaneo-Mindlin path (nu = 0.49, ``benchmarks/README.md``): the
#: patch weights gave Ieff up to 3.1 and intervals that missed J on 7 of 10 judged steps, the P2
#: weights Ieff 0.99-1.08 and all 10 covered.
NEARLY_INCOMPRESSIBLE_NU = 0.45


def nearly_incompressible(problem: Any) -> bool:
    """Whether Poisson's ratio is at least :data:`NEARLY_INCOMPRESSIBLE_NU`.

    Args:
        problem: The problem; its nu a number, or one per cell tag (the largest counts).

    Returns:
        True for a nearly incompressible material; False for nu given as a callable of x.
    """
    nu = problem.nu
    if isinstance(nu, Mapping):
        values = [v for v in nu.values() if isinstance(v, (int, float))]
        return bool(values) and max(values) >= NEARLY_INCOMPRESSIBLE_NU
    return isinstance(nu, (int, float)) and nu >= NEARLY_INCOMPRESSIBLE_NU


#: Bytes per nonzero of an assembled sparse matrix: the value, the column index and the
#: sparsity pattern dolfinx builds before the matrix.
BYTES_PER_NONZERO = 24

#: Nonzeros per row of the vector P2 stiffness matrix on simplices, averaged over the vertex
#: and the edge rows (2D: 38 and 18, one vertex to three edges; 3D: about 195 and 70, one
#: vertex to six or seven edges).
P2_NONZEROS_PER_ROW = {2: 24, 3: 90}

#: Vectors of the P2 system's length that its solution holds: FGMRES(30) of
#: ``weights="hierarchical"`` keeps 60, the rest are right-hand sides, solutions and weights.
P2_VECTORS = 70


def p2_weights_memory(V2: fem.FunctionSpace, kind: str, free: int | None = None) -> int:
    """The bytes the P2 weights would take on the rank that holds most of V2 (collective).

    Args:
        V2: The vector P2 space on T_h.
        kind: ``"hierarchical"``, ``"higher_order"`` or ``"local"``.
        free: For ``"local"``, the band's unconstrained dofs
            (:attr:`~dwr_signorini.local_p2.ContactBand.free_dofs`): the matrix rows and the
            factors are the band's.

    Returns:
        Bytes.

    A rough prediction from the sizes alone, the same on every rank: the P2 stiffness matrix
    (:data:`P2_NONZEROS_PER_ROW` x :data:`BYTES_PER_NONZERO` a row) and :data:`P2_VECTORS`
    vectors of its length; for ``"higher_order"`` also the factors of the P2 system, estimated as
    the solver's probe does (:data:`~dwr_signorini.linalg.memory.ROUGH_BYTES` N^(4/3) in 3D,
    ROUGH_BYTES N log2 N in 2D, half as much again on the rank that needs most).
    """
    imap, bs = V2.dofmap.index_map, V2.dofmap.index_map_bs
    comm = V2.mesh.comm
    rows = comm.allreduce((imap.size_local + imap.num_ghosts) * bs, op=MPI.MAX)
    n = imap.size_global * bs
    band = 1.0 if kind != "local" else free / max(n, 1)  # the band's share of the rows
    tdim = V2.mesh.topology.dim
    need = rows * (band * P2_NONZEROS_PER_ROW[tdim] * BYTES_PER_NONZERO + 8 * P2_VECTORS)
    if kind in ("higher_order", "local"):
        n = max(int(band * n), 2)
        fill = n ** (4 / 3) if tdim == 3 else n * np.log2(n)
        need += 1.5 * memory.ROUGH_BYTES * fill / comm.size
    return int(need)


def p2_weights_fit(
    V2: fem.FunctionSpace, kind: str, free: int | None = None
) -> tuple[bool, int, int]:
    """Whether the P2 weights fit in memory, as the solver's factorisations must (collective).

    Args:
        V2: The vector P2 space on T_h.
        kind: ``"hierarchical"``, ``"higher_order"`` or ``"local"``.
        free: For ``"local"``, the band's unconstrained dofs (:func:`p2_weights_memory`).

    Returns:
        ``(fits, predicted bytes, available bytes per rank)``.

    They fit when :func:`p2_weights_memory` is at most
    :data:`~dwr_signorini.linalg.memory.FACTOR_FRACTION` of
    :func:`~dwr_signorini.linalg.memory.available_memory` (the budget
    ``DWR_SIGNORINI_MEMORY_BUDGET`` where set). Both are the same on every rank, so is the answer.
    """
    need = p2_weights_memory(V2, kind, free)
    available = memory.available_memory(V2.mesh.comm)
    return need <= memory.FACTOR_FRACTION * available, need, available


#: Dimensions in which ``"auto"`` takes the hierarchical P2 weights for a law with coupled rows
#: (Coulomb friction, Tresca friction in 3D); in the others the factored ones. Measured (seconds
#: of the estimate, factored / hierarchical, in one run each, FGMRES iterations dual + primal):
#: 2D Coulomb on the Hertz block of ``benchmarks/p2_weights_cost.py --nu 0.3 --law coulomb``,
#: 147k P1 DoFs, 5.79 / 4.54 on 1 rank and 8.93 / 6.76 on 2 (8 + 5), 15k DoFs 1.44 / 1.06 on
#: 2 ranks (7 + 5), 7k DoFs 0.28 / 0.23 on 1 (6 + 4); the long block of
#: ``benchmarks/region_level_cost.py`` (8.7k DoFs) 0.42 / 0.41 on 1 rank, 0.36 / 0.40 on 2.
#: 3D Coulomb on its box (``--dim 3``), every contact facet slipping: 4.5k DoFs 1.39 / 2.62 on
#: 1 rank, 1.50 / 2.59 on 2 (20 + 18), 30k DoFs (``--n 8``) 26.6 / 26.7 on 1 (32 + 28).
HIERARCHICAL_COUPLED_DIMS = (2,)


def p2_kind(sol: Any) -> str:
    """The P2 weights of ``"auto"``: hierarchical, but factored for coupled rows in 3D.

    A symmetric law, or coupled rows in :data:`HIERARCHICAL_COUPLED_DIMS`: ``"hierarchical"``;
    otherwise ``"higher_order"``.
    """
    tdim = sol.disc.mesh.topology.dim
    if sol.disc.problem.law.symmetric(tdim) or tdim in HIERARCHICAL_COUPLED_DIMS:
        return "hierarchical"
    return "higher_order"


def unresolved_kind(sol: Any) -> str:
    """The P2 weights of ``"auto"`` on a level whose contact set is not resolved.

    Args:
        sol: The solution.

    Returns:
        ``"local"`` (P2 on the band around the contact zone, :mod:`~dwr_signorini.local_p2`)
        for one body; :func:`p2_kind` for a contact pair, whose master side the band does not
        follow.
    """
    return "local" if sol.disc.slave_mesh is None else p2_kind(sol)


def second_weights(
    terms: Any, estimator: str, resolved: bool, J_h: float, roundoff: float, p2: str
) -> str | None:
    """The P2 weights with which ``"auto"`` computes the patch estimate again, or None.

    ``p2`` where the contact set is not resolved (the patch recovery of z_h misses the
    contact). The factored ``"higher_order"`` ones where J_h vanishes to round-off but the
    patch estimate does not: J vanishes by symmetry, the estimate is then the patch weights'
    own error (:mod:`~dwr_signorini.interval`), and the iterated P2 weights would leave an
    error of their relative residual in it (measured on 2 ranks: -2.2e-8 where the error is 0).
    """
    if abs(J_h) <= roundoff < abs(terms.value(estimator)):
        return "higher_order"
    return None if resolved else p2


def memory_fallback(sol: Any, rec: Any, kind: str, free: int | None = None) -> str | None:
    """None where the P2 weights ``kind`` fit in memory, else the sentence that says why not."""
    fits, need, available = p2_weights_fit(rec.V2h, kind, free)
    if fits:
        return None
    gib = 2.0**30
    note = (
        f"weights='auto': patch weights instead of {kind!r} P2 weights, which would need "
        f"about {need / gib:.2f} GiB a rank where {available / gib:.2f} GiB are available "
        f"(at most {memory.FACTOR_FRACTION:.0%} of it is used)"
    )
    if sol.disc.comm.rank == 0:
        logger.warning(note)
    return note


