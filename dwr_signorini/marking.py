"""Patch indicators and marking of macro cells (Section 4: localisation, patch structure).

The cell indicators on T_h are summed over the children of each macro cell (the paper's patches);
macro cells are marked globally across MPI ranks, by a fixed fraction of the cells with the largest
|eta_K| or by Doerfler's bulk criterion on the indicator mass. :func:`mark_for_growth` finds the
fraction for which the refined macro mesh has about a given multiple of the cells;
:func:`mark_at_most` marks by a fraction unless that would grow the mesh by more than a given
ratio, and then marks for that ratio. :func:`marking_defaults` gives a run that sets none of
``fraction``, ``growth`` and ``strategy`` its rule: a fixed fraction of 0.2 in 2D, Doerfler's
criterion with theta = 0.3 and at most twice the cells per level in 3D.

One level of a run (:func:`refine_level`, for the loop of :func:`~dwr_signorini.solve_adaptive`
and :func:`~dwr_signorini.solve_path`) marks the macro cells, refines them
(:mod:`dwr_signorini.refine`) and redistributes the refined macro mesh over the ranks where
their shares are unequal (:func:`~dwr_signorini.partition.rebalance_level`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from .partition import rebalance_level
from .problem import SignoriniProblem
from .refine import refine_marked
from .spaces import Discretization
from .timing import timed

if TYPE_CHECKING:
    from .estimator import Estimate

__all__ = [
    "DEFAULT_DOERFLER_3D",
    "DEFAULT_FRACTION",
    "DEFAULT_MAX_GROWTH_3D",
    "STRATEGIES",
    "MarkingRule",
    "mark",
    "mark_at_most",
    "mark_for_growth",
    "marking_defaults",
    "patch_indicators",
    "refine_level",
    "search_fraction",
    "threshold",
]

STRATEGIES = ("fixed_fraction", "doerfler")

TIE_TOLERANCE = 1e-8

T = TypeVar("T")

#: The default of ``fraction`` for adaptive runs in 2D (a fixed fraction of the cells).
DEFAULT_FRACTION = 0.2

#: theta of Doerfler's criterion, the default marking of adaptive runs in 3D.
DEFAULT_DOERFLER_3D = 0.3

#: The most cells a default 3D level may have, as a multiple of the last level's.
DEFAULT_MAX_GROWTH_3D = 2.0


@dataclass(frozen=True)
class MarkingRule:
    """How a run marks: ``strategy`` with ``fraction``, or for ``growth``; ``max_growth`` caps.

    Attributes:
        strategy: ``"fixed_fraction"`` or ``"doerfler"``.
        fraction: The marking fraction, or ``None`` with ``growth``.
        growth: The wanted ratio of cells per level (:func:`mark_for_growth`), or ``None``.
        max_growth: With ``fraction``: the most cells a level may have as a multiple of the
            last level's (:func:`mark_at_most`), or ``None`` (no cap).

    Raises:
        ValueError: A ``strategy``, ``fraction`` or ``growth`` of the wrong value, or both a
            ``fraction`` and a ``growth``, naming them.
    """

    strategy: str
    fraction: float | None
    growth: float | None
    max_growth: float | None = None

    def __post_init__(self) -> None:
        strategy, fraction, growth = self.strategy, self.fraction, self.growth
        if strategy not in STRATEGIES:
            raise ValueError(f"strategy must be one of {STRATEGIES} or None, got {strategy!r}")
        if fraction is not None and (
            isinstance(fraction, bool)
            or not isinstance(fraction, (int, float))
            or not 0.0 < fraction <= 1.0
        ):
            raise ValueError(f"fraction must be a number in (0, 1] or None, got {fraction!r}")
        if fraction is not None and growth is not None:
            raise ValueError(
                f"give fraction or growth, not both (got fraction={fraction!r}, growth={growth!r})"
            )
        if growth is not None and (
            isinstance(growth, bool)
            or not isinstance(growth, (int, float))
            or not 1.0 < growth < 1e3
        ):
            raise ValueError(f"growth must be a number in (1, 1000) or None, got {growth!r}")


def marking_defaults(
    problem: SignoriniProblem,
    fraction: float | None,
    growth: float | None,
    strategy: str | None = None,
) -> MarkingRule:
    """The marking of a run: what it sets, the rest from the dimension's defaults.

    A run that sets ``fraction`` or ``growth`` marks with them (``strategy`` defaults to a
    fixed fraction). A run that sets neither marks, in 2D, the fraction 0.2 of the cells with
    the largest indicators, and in 3D by Doerfler's criterion with theta = 0.3 (the fewest
    cells holding 30 % of sum |eta_K|), refining at most twice the cells per level
    (:func:`mark_at_most`). In 3D a fixed fraction spreads: the edges of a marked tetrahedron
    split its neighbours too, and on the first levels, where the indicators of most cells are
    tied, a fraction of 0.2 refines every cell. Doerfler's set follows the indicator mass: on
    the 3D indentation it is the contact zone, about 3-20 % more cells on the first levels,
    where a fixed growth of 2 refines far from the contact as well (``benchmarks/payoff_3d.py``).

    Args:
        problem: The problem on the first macro mesh (its dimension decides).
        fraction: The run's ``fraction``, or ``None``.
        growth: The run's ``growth``, or ``None``.
        strategy: The run's ``strategy``, or ``None``.

    Returns:
        The :class:`MarkingRule`.
    """
    if fraction is not None or growth is not None:
        return MarkingRule(strategy or "fixed_fraction", fraction, growth)
    if problem.mesh.topology.dim == 3:
        if strategy in (None, "doerfler"):
            return MarkingRule("doerfler", DEFAULT_DOERFLER_3D, None, DEFAULT_MAX_GROWTH_3D)
        return MarkingRule(strategy, DEFAULT_FRACTION, None, DEFAULT_MAX_GROWTH_3D)
    return MarkingRule(strategy or "fixed_fraction", DEFAULT_FRACTION, None)


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


def threshold(comm: MPI.Comm, values: np.ndarray, strategy: str, fraction: float) -> float:
    """The smallest |eta_K| that is marked, identical on every rank.

    Args:
        comm: The processes holding ``values``.
        values: This rank's indicators (cells, or the model indicators of contact facets).
        strategy: ``"fixed_fraction"`` or ``"doerfler"`` (as :func:`mark`).
        fraction: In (0, 1].

    Returns:
        The threshold (``inf`` without values, 0 where all are zero).
    """
    all_values = np.concatenate(comm.allgather(np.abs(values)))
    if all_values.size == 0:
        return np.inf
    if not np.any(all_values > 0):  # all tied at zero (round-off): all are marked
        return 0.0
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
    floor: float = 0.0,
) -> npt.NDArray[np.int32]:
    """Mark macro cells for refinement.

    Cells whose indicators are equal up to a relative :data:`TIE_TOLERANCE` are marked
    alike, and indicators of at most ``floor`` in magnitude count as zero: where J vanishes by
    symmetry every indicator is round-off, and marking by it would refine one side of a
    symmetric mesh and not the other (and differently on different partitions). Where all of
    them count as zero, every cell is marked.

    Args:
        disc: The discretisation.
        indicators: Signed indicators on the owned fine cells.
        strategy: ``"fixed_fraction"`` (the fraction of macro cells with the largest |eta_K|)
            or ``"doerfler"`` (the fewest cells holding ``fraction`` of sum |eta_K|).
        fraction: In (0, 1].
        floor: The round-off of the estimate (:attr:`Estimate.roundoff`), or 0.

    Returns:
        Local indices of the marked (owned) macro cells.
    """
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction!r}")
    eta_K = patch_indicators(disc, indicators)
    eta_K[np.abs(eta_K) <= floor] = 0.0
    least = threshold(disc.comm, eta_K, strategy, fraction)
    # Cells tied with the threshold up to round-off are all marked: symmetric problems have
    # many equal indicators, and summation order (serial or parallel) must not pick among them.
    return np.flatnonzero(np.abs(eta_K) >= least * (1.0 - TIE_TOLERANCE)).astype(np.int32)


def _first_fraction(growth: float, tdim: int) -> float:
    """A first guess of the marking fraction for ``growth``.

    A marked simplex has up to 2**tdim children, and the closure that keeps the mesh conforming
    refines several times as many cells again: ratio - 1 ~ 4 (2**tdim - 1) fraction (about what
    the adaptive levels of examples 5.2 and 5.3 and of the 3D indentation show).
    """
    return min(1.0, (growth - 1.0) / (4.0 * (2**tdim - 1)))


def _next_fraction(
    growth: float,
    below: tuple[float, float] | None,
    above: tuple[float, float] | None,
    flat: bool = False,
) -> float:
    """The next trial fraction from the closest trials below and above ``growth``.

    ``below`` and ``above`` are ``(fraction, ratio)`` of the largest fraction whose ratio fell
    short and of the smallest whose ratio exceeded ``growth``. The new cells grow about like a
    power of the fraction, so the fraction is interpolated (or, with one side known,
    extrapolated linearly, at most by a factor 32) in log(ratio - 1) against log(fraction);
    where that is undefined or leaves the bracket, the bracket is bisected geometrically. With
    ``flat`` (the last two trials gave about the same count: small meshes' counts go in steps)
    a one-sided step at least halves or doubles the fraction, and a bracket is bisected.
    """
    target = np.log(growth - 1.0)

    def extrapolate(point: tuple[float, float]) -> float:
        fraction, ratio = point
        if ratio <= 1.0:
            return 8.0 * fraction
        factor = float(np.clip((growth - 1.0) / (ratio - 1.0), 1 / 32, 32.0))
        if flat:
            factor = min(factor, 0.5) if ratio > growth else max(factor, 2.0)
        return fraction * factor

    if below is None:
        return extrapolate(above)
    if above is None:
        return min(1.0, extrapolate(below))
    (f_lo, r_lo), (f_hi, r_hi) = below, above
    if r_lo > 1.0 and not flat:
        t = (target - np.log(r_lo - 1.0)) / (np.log(r_hi - 1.0) - np.log(r_lo - 1.0))
        fraction = float(np.exp(np.log(f_lo) + t * (np.log(f_hi) - np.log(f_lo))))
        # stay clear of the bracket's ends, where the cell counts are already known
        if f_lo * (f_hi / f_lo) ** 0.1 < fraction < f_hi * (f_lo / f_hi) ** 0.1:
            return fraction
    return float(np.sqrt(f_lo * f_hi))


def mark_for_growth(
    disc: Discretization,
    problem: SignoriniProblem,
    indicators: npt.NDArray[np.floating],
    strategy: str,
    growth: float,
    rule: str = "edges",
    trials: int = 8,
    floor: float = 0.0,
) -> tuple[npt.NDArray[np.int32], SignoriniProblem, npt.NDArray[np.int32], float]:
    """Mark so that the refined macro mesh has about ``growth`` times the cells of this one.

    The number of new cells grows monotonically with the marking fraction, so the fraction is
    found by a safeguarded secant search in log-log (:func:`search_fraction`) on (0, 1], refining
    the macro mesh for each trial (cheap against a solve, but not free: one to four trials are
    typical, up to ``trials`` where the count goes in steps) and keeping the trial whose cell
    ratio is closest to ``growth``.

    Args:
        disc: The discretisation of ``problem``.
        problem: The problem on the current macro mesh.
        indicators: Signed indicators on the owned fine cells.
        strategy: ``"fixed_fraction"`` or ``"doerfler"``.
        growth: The wanted ratio of macro cells, next level / this level, > 1.
        rule: The refinement rule (:func:`~dwr_signorini.refine.marked_edges`).
        trials: Most refinements tried.
        floor: Indicators counted as zero (:func:`mark`).

    Returns:
        The marked cells, the refined problem, the parent map and the fraction used.
    """
    if not growth > 1.0:
        raise ValueError(f"growth must be a number > 1, got {growth!r}")
    tdim = problem.mesh.topology.dim
    cells_now = problem.mesh.topology.index_map(tdim).size_global

    def trial(fraction: float) -> tuple[float, tuple]:
        marked = mark(disc, indicators, strategy, fraction, floor)
        refined, parent = refine_marked(problem, marked, rule)
        ratio = refined.mesh.topology.index_map(tdim).size_global / cells_now
        return ratio, (marked, refined, parent)

    fraction, _, (marked, refined, parent), _ = search_fraction(
        trial, growth, _first_fraction(growth, tdim), trials
    )
    return marked, refined, parent, fraction


def mark_at_most(
    disc: Discretization,
    problem: SignoriniProblem,
    indicators: npt.NDArray[np.floating],
    strategy: str,
    fraction: float,
    max_growth: float,
    rule: str = "edges",
    floor: float = 0.0,
) -> tuple[npt.NDArray[np.int32], SignoriniProblem, npt.NDArray[np.int32], float]:
    """Mark by ``fraction``, or for ``max_growth`` where that fraction would refine more.

    The cells that ``strategy`` and ``fraction`` mark are refined; if the refined macro mesh
    has more than ``max_growth`` times the cells of this one, the marking is that of
    :func:`mark_for_growth` with ``growth=max_growth`` instead.

    Args:
        disc: The discretisation of ``problem``.
        problem: The problem on the current macro mesh.
        indicators: Signed indicators on the owned fine cells.
        strategy: ``"fixed_fraction"`` or ``"doerfler"``.
        fraction: In (0, 1].
        max_growth: The most cells of the next level as a multiple of this level's, > 1.
        rule: The refinement rule (:func:`~dwr_signorini.refine.marked_edges`).
        floor: Indicators counted as zero (:func:`mark`).

    Returns:
        The marked cells, the refined problem, the parent map and the fraction used.

    Raises:
        ValueError: If ``max_growth`` is not a number > 1.
    """
    if not max_growth > 1.0:
        raise ValueError(f"max_growth must be a number > 1, got {max_growth!r}")
    tdim = problem.mesh.topology.dim
    marked = mark(disc, indicators, strategy, fraction, floor)
    refined, parent = refine_marked(problem, marked, rule)
    cells = (problem.mesh.topology.index_map(tdim).size_global,
             refined.mesh.topology.index_map(tdim).size_global)
    if cells[1] <= max_growth * cells[0]:
        return marked, refined, parent, fraction
    return mark_for_growth(
        disc, problem, indicators, strategy, max_growth, rule, floor=floor
    )


def search_fraction(
    trial: Callable[[float], tuple[float, T]], growth: float, first: float, trials: int = 8
) -> tuple[float, float, T, int]:
    """The marking fraction in (0, 1] whose cell ratio is closest to ``growth``.

    ``trial(fraction)`` returns the ratio of cells (refined / now), non-decreasing in the
    fraction, and whatever the caller keeps of the trial. Trials stop when a ratio is within
    5 % of ``growth``, when the fraction 1 still falls short, when the bracket around
    ``growth`` has closed to 1 % (the count jumps across ``growth`` there) or after ``trials``;
    the next fraction comes from :func:`_next_fraction`.

    Returns:
        ``(fraction, ratio, kept, number of trials)`` of the trial closest to ``growth`` in
        log(ratio / growth).
    """
    below = above = best = None
    ratios: list[float] = []
    fraction = first
    for _ in range(trials):
        ratio, kept = trial(fraction)
        ratios.append(ratio)
        if best is None or abs(np.log(ratio / growth)) < abs(np.log(best[1] / growth)):
            best = (fraction, ratio, kept)
        if abs(ratio / growth - 1.0) < 0.05 or (ratio < growth and fraction >= 1.0):
            break
        if ratio < growth:
            below = (fraction, ratio)
        else:
            above = (fraction, ratio)
        if below is not None and above is not None and above[0] < 1.01 * below[0]:
            break
        flat = len(ratios) > 1 and abs(ratios[-1] / ratios[-2] - 1.0) < 0.02
        fraction = _next_fraction(growth, below, above, flat)
    return (*best, len(ratios))


def refine_level(
    disc: Any,
    current: SignoriniProblem,
    est: Estimate,
    refinement: str,
    marking: MarkingRule | None,
    refinement_rule: str,
) -> tuple[np.ndarray, SignoriniProblem, Any]:
    """Mark and refine one level: the next level's macro mesh (collective).

    Adaptive refinement marks the macro cells by their patch indicators as ``marking`` says
    (:func:`mark`, :func:`mark_for_growth` with ``growth``, :func:`mark_at_most` with
    ``max_growth``), refines them (:func:`~dwr_signorini.refine.refine_marked`) and
    redistributes the result where the ranks hold unequal shares of it
    (:func:`~dwr_signorini.partition.rebalance_level`). Uniform refinement takes T_h, the
    uniform refinement of T_H, as the next macro mesh, or refines T_H again where
    ``boundary_projection`` moves the new vertices. The phases are timed as ``"mark"`` and
    ``"refine"`` (:func:`~dwr_signorini.timing.timed`).

    Args:
        disc: The discretisation of ``current``.
        current: The problem on this level's macro mesh T_H.
        est: This level's estimate (its cell indicators drive the marking).
        refinement: ``"adaptive"`` or ``"uniform"``.
        marking: The run's :class:`MarkingRule` (adaptive; ignored when uniform).
        refinement_rule: ``"edges"`` or ``"longest_edge"`` (:func:`marked_edges`).

    Returns:
        ``(marked, next_problem, macro_parent)``: the local marked macro cells (none when
        uniform), the problem on the next macro mesh, and the parent of each of its cells
        (a :class:`~dwr_signorini.partition.CellOrigin` where the mesh was redistributed).
    """
    if refinement == "adaptive":
        with timed("mark"):
            marked, next_problem, macro_parent = _mark_and_refine(
                disc, current, est.indicators.x.array, marking, refinement_rule,
                getattr(est, "roundoff", 0.0),
            )
        with timed("refine"):
            next_problem, macro_parent = rebalance_level(next_problem, macro_parent)
        return marked, next_problem, macro_parent
    with timed("refine"):
        if current.boundary_projection:  # refine again, projecting the new vertices
            next_problem, macro_parent = refine_marked(current, None)
        else:  # T_h, the uniform refinement of T_H, is the next macro mesh
            next_problem = current.with_mesh(disc.mesh, disc.facet_tags, disc.cell_tags)
            macro_parent = disc.parent_cell
    return np.zeros(0, dtype=np.int32), next_problem, macro_parent


def _mark_and_refine(
    disc: Any,
    current: SignoriniProblem,
    indicators: npt.NDArray[np.floating],
    marking: MarkingRule,
    rule: str,
    floor: float = 0.0,
) -> tuple[npt.NDArray[np.int32], SignoriniProblem, Any]:
    """The marked cells, the refined problem and its parent map, as ``marking`` says."""
    if marking.growth is not None:
        marked, refined, parent, _ = mark_for_growth(
            disc, current, indicators, marking.strategy, marking.growth, rule, floor=floor
        )
    elif marking.max_growth is not None:
        marked, refined, parent, _ = mark_at_most(
            disc, current, indicators, marking.strategy, marking.fraction, marking.max_growth,
            rule, floor,
        )
    else:
        marked = mark(disc, indicators, marking.strategy, marking.fraction, floor)
        refined, parent = refine_marked(current, marked, rule)
    return marked, refined, parent
