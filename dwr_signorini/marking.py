"""Patch indicators and marking of macro cells (Section 4: localisation, patch structure).

The cell indicators on T_h are summed over the children of each macro cell (the paper's patches);
macro cells are marked globally across MPI ranks, by a fixed fraction of the cells with the largest
|eta_K| or by Doerfler's bulk criterion on the indicator mass. :func:`mark_for_growth` finds the
fraction for which the refined macro mesh has about a given multiple of the cells.
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from .problem import SignoriniProblem
from .refine import refine_marked
from .spaces import Discretization

__all__ = ["STRATEGIES", "mark", "mark_for_growth", "patch_indicators"]

STRATEGIES = ("fixed_fraction", "doerfler")

TIE_TOLERANCE = 1e-8


def patch_indicators(disc: Discretization, indicators: npt.NDArray[np.floating]) -> np.ndarray:
    """Sum signed fine-cell indicators over the children of each owned macro cell.

    Args:
        disc: The discretisation (gives the parent of every local fine cell).
        indicators: Values on the owned fine cells.

    Returns:
        One value per owned macro cell.
    """
    num_macro = disc.macro_mesh.topology.index_map(disc.macro_mesh.topology.dim).size_local
    n = len(disc.parent_cell)
    return np.bincount(disc.parent_cell, weights=indicators[:n], minlength=num_macro)[:num_macro]


def _global_threshold(comm: MPI.Comm, values: np.ndarray, strategy: str, fraction: float) -> float:
    """The smallest |eta_K| that is marked, identical on every rank."""
    all_values = np.concatenate(comm.allgather(np.abs(values)))
    if all_values.size == 0 or not np.any(all_values > 0):
        return np.inf
    order = np.sort(all_values)[::-1]
    if strategy == "fixed_fraction":
        k = max(1, int(np.ceil(fraction * order.size)))
    else:
        mass = np.cumsum(order)
        k = int(np.searchsorted(mass, fraction * mass[-1] * (1 - 1e-14))) + 1
    return float(order[min(k, order.size) - 1])


def mark(
    disc: Discretization,
    indicators: npt.NDArray[np.floating],
    strategy: str = "fixed_fraction",
    fraction: float = 0.2,
) -> npt.NDArray[np.int32]:
    """Mark macro cells for refinement.

    Args:
        disc: The discretisation.
        indicators: Signed indicators on the owned fine cells.
        strategy: ``"fixed_fraction"`` (the fraction of macro cells with the largest |eta_K|)
            or ``"doerfler"`` (the fewest cells holding ``fraction`` of sum |eta_K|).
        fraction: In (0, 1].

    Returns:
        Local indices of the marked (owned) macro cells.
    """
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction!r}")
    eta_K = patch_indicators(disc, indicators)
    threshold = _global_threshold(disc.comm, eta_K, strategy, fraction)
    # Cells tied with the threshold up to round-off are all marked: symmetric problems have
    # many equal indicators, and summation order (serial or parallel) must not pick among them.
    return np.flatnonzero(np.abs(eta_K) >= threshold * (1.0 - TIE_TOLERANCE)).astype(np.int32)


def mark_for_growth(
    disc: Discretization,
    problem: SignoriniProblem,
    indicators: npt.NDArray[np.floating],
    strategy: str,
    growth: float,
    rule: str = "edges",
    trials: int = 8,
) -> tuple[npt.NDArray[np.int32], SignoriniProblem, npt.NDArray[np.int32], float]:
    """Mark so that the refined macro mesh has about ``growth`` times the cells of this one.

    The number of new cells grows monotonically with the marking fraction, so the fraction is
    found by bisection on (0, 1], refining the macro mesh for each trial (cheap against a
    solve) and keeping the trial whose cell ratio is closest to ``growth``.

    Args:
        disc: The discretisation of ``problem``.
        problem: The problem on the current macro mesh.
        indicators: Signed indicators on the owned fine cells.
        strategy: ``"fixed_fraction"`` or ``"doerfler"``.
        growth: The wanted ratio of macro cells, next level / this level, > 1.
        rule: The refinement rule (:func:`~dwr_signorini.refine.marked_edges`).
        trials: Most refinements tried.

    Returns:
        The marked cells, the refined problem, the parent map and the fraction used.
    """
    if not growth > 1.0:
        raise ValueError(f"growth must be a number > 1, got {growth!r}")
    tdim = problem.mesh.topology.dim
    cells_now = problem.mesh.topology.index_map(tdim).size_global
    lo, hi = 0.0, 1.0
    best = None
    for _ in range(trials):
        fraction = 0.5 * (lo + hi) if best is not None else min(1.0, (growth - 1.0) / 3.0)
        marked = mark(disc, indicators, strategy, fraction)
        refined, parent = refine_marked(problem, marked, rule)
        ratio = refined.mesh.topology.index_map(tdim).size_global / cells_now
        if best is None or abs(np.log(ratio / growth)) < abs(np.log(best[4] / growth)):
            best = (marked, refined, parent, fraction, ratio)
        if abs(ratio / growth - 1.0) < 0.05:
            break
        lo, hi = (fraction, hi) if ratio < growth else (lo, fraction)
    marked, refined, parent, fraction, _ = best
    return marked, refined, parent, fraction
