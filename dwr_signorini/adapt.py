"""The adaptive loop: solve, estimate, mark, refine (the only loop over levels).

Each level solves Signorini's problem on T_h (warm-started from the previous level), estimates the
error in J with eta or eta_p, sums the indicators over the patches (macro cells), marks them, and
refines the macro mesh T_H with the edges of the marked cells; the next fine mesh is one uniform
refinement of the new macro mesh.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

from .algebra import check_ncp_scale
from .collective import call_collectively, on_root
from .estimator import ESTIMATORS, WEIGHTS, Estimate, estimate
from .goal import Goal
from .io import OutputDirectory, check_output_dir, write_csv, write_json
from .lifetime import Releasable
from .marking import STRATEGIES, MarkingRule, marking_defaults, refine_level
from .newton import METHODS, Solution, solve
from .problem import SignoriniProblem
from .refine import RULES, fine_cells
from .spaces import discretize
from .timing import timed
from .transfer import transfer_solution

__all__ = ["AdaptiveResult", "LevelRecord", "solve_adaptive", "transfer_solution"]

logger = logging.getLogger(__name__)

REFINEMENTS = ("adaptive", "uniform")


@dataclass
class LevelRecord:
    """One row of the table of an adaptive or uniform run (the paper's Tables 1-3).

    Attributes:
        level: The level, from 0.
        num_cells: M_Omega, cells of T_h.
        num_macro_cells: Cells of T_H.
        num_contact_elements: M_C, macro contact facets (multipliers).
        num_dofs: Displacement DoFs.
        num_active: Active multipliers at convergence (0: no facet is in contact, see
            ``no_contact``).
        J_h: J(w_h).
        eta_p: The primal estimator.
        eta: The primal-dual estimator, or ``None`` when only eta_p was asked for.
        estimate: The estimator that drove the run (eta or eta_p).
        contact_term: C(w_h)(xi_H).
        active_set_remainder: R_A (:attr:`Estimate.active_set_remainder`).
        newton_iterations: Newton steps of this level.
        num_marked: Macro cells marked on this level for the next (over all ranks).
        time: Seconds per phase (``solve``, ``dual``, ``estimate``, ``refine``, ..., ``total``).
        rel_error: E_rel against the ``exact`` of :func:`solve_adaptive`, else ``None``.
        ieff_p: Ieff of eta_p against ``exact``, else ``None``.
        ieff: Ieff of eta against ``exact``, else ``None``.
        J_low: The lower end of the interval for J(w) (:attr:`Estimate.interval`, under the
            assumptions of :mod:`~dwr_signorini.interval`).
        J_high: Its upper end.
        J_best: The best estimate of J(w), the centre of [J_low, J_high]: J_h corrected by the
            estimate (:attr:`Estimate.J_best`). J_h itself is often outside the interval.
        no_contact: Whether no facet is in contact on this level (``num_active == 0``).
        weights_fallback: Why ``weights="auto"`` kept the patch weights where P2 ones did not
            fit in memory (:attr:`Estimate.weights_fallback`), else ``None``.
        weights: The weights the level's estimate used ("patch", "hierarchical", ...).
        resolved: Whether the level's contact set counted as resolved.
        num_stick: With friction, macro contact facets in contact that stick, else None.
        num_slip: With friction, macro contact facets in contact that slip, else None.
        method: The linear solver of the level's Newton steps (:attr:`Solution.method`:
            ``"block"``, ``"schur"`` or ``"krylov"``).
    """

    level: int
    num_cells: int
    num_macro_cells: int
    num_contact_elements: int
    num_dofs: int
    num_active: int
    J_h: float
    eta_p: float
    eta: float | None
    estimate: float
    contact_term: float
    active_set_remainder: float
    newton_iterations: int
    num_marked: int = 0
    time: dict[str, float] = field(default_factory=dict)
    rel_error: float | None = None
    ieff_p: float | None = None
    ieff: float | None = None
    J_low: float | None = None
    J_high: float | None = None
    J_best: float | None = None
    no_contact: bool = False
    weights_fallback: str | None = None
    weights: str = ""
    resolved: bool = True
    num_stick: int | None = None
    num_slip: int | None = None
    method: str = ""

    def as_dict(self) -> dict[str, Any]:
        """The record as a plain dict.

        Returns:
            The fields by name, the timings nested under ``time``.
        """
        return asdict(self)


@dataclass
class AdaptiveResult(Releasable):
    """The levels of a run and the last solution and estimate.

    Owns the last level's solution and estimate: release them with :meth:`destroy`
    (collective), or use the result as a context manager.

    Attributes:
        levels: One :class:`LevelRecord` per level.
        solution: The last level's :class:`~dwr_signorini.Solution`.
        estimate: The last level's :class:`~dwr_signorini.Estimate`.
        problem: The problem on the last level's macro mesh.
        meta: The run's settings (written by :meth:`to_json`).
        comm: The mesh communicator.
        converged: Whether the run stopped on ``tol``: J_high - J_low <= 2 tol on the last
            level. False when it ended at ``max_levels`` or ``max_cells`` without that, and
            always without ``tol``.
        stopped_by: Why the run stopped: ``"tol"`` (converged), ``"max_levels"`` or
            ``"max_cells"``; with ``verbose`` one line on rank 0 says so.
        next_cells: The fine cells of the level after the last one refined (what
            ``max_cells`` was compared with).
    """

    levels: list[LevelRecord]
    solution: Solution | None = field(default=None, repr=False)
    estimate: Estimate | None = field(default=None, repr=False)
    problem: SignoriniProblem | None = field(default=None, repr=False)
    meta: dict[str, Any] = field(default_factory=dict)
    comm: MPI.Comm = field(default_factory=lambda: MPI.COMM_WORLD, repr=False)
    converged: bool = False
    stopped_by: str = ""
    next_cells: int = 0

    def destroy(self) -> None:
        """Release the last level's solution and estimate (collective; idempotent)."""
        if self.solution is not None:
            self.solution.destroy()
        if self.estimate is not None:
            self.estimate.destroy()


    def rows(self) -> list[dict[str, Any]]:
        """The table as a list of dicts.

        Returns:
            One :meth:`LevelRecord.as_dict` per level.
        """
        return [r.as_dict() for r in self.levels]

    def to_csv(self, path: str | Path) -> None:
        """Write the table as CSV (rank 0 of the mesh communicator writes; collective).

        Args:
            path: The CSV file, in an existing directory.
        """
        on_root(self.comm, f"to_csv({str(path)!r})", write_csv, path, self.rows())

    def to_json(self, path: str | Path) -> None:
        """Write the table and the run's settings as JSON (rank 0 writes; collective).

        Args:
            path: The JSON file, in an existing directory (written atomically).
        """
        data = {"meta": self.meta, "levels": self.rows()}
        on_root(self.comm, f"to_json({str(path)!r})", write_json, path, data)


def _validate(
    problem: Any,
    goal: Any,
    refinement: str,
    fraction: Any,
    strategy: str | None,
    max_levels: Any,
    max_cells: Any,
    tol: Any,
    estimator: str,
    weights: str,
    method: str,
    exact: Any,
    callback: Any,
    refinement_rule: Any = "edges",
    growth: Any = None,
    verbose: Any = True,
    output_dir: Any = None,
) -> None:
    if not isinstance(problem, SignoriniProblem):
        raise TypeError(f"problem must be a SignoriniProblem, got {type(problem).__name__}")
    if not callable(goal):
        raise TypeError(f"goal must be a callable goal(u, lam, m) -> ufl.Form, got {goal!r}")
    if refinement not in REFINEMENTS:
        raise ValueError(f"refinement must be one of {REFINEMENTS}, got {refinement!r}")
    if strategy is not None and strategy not in STRATEGIES:
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
    if isinstance(max_levels, bool) or not isinstance(max_levels, int) or max_levels < 1:
        raise ValueError(f"max_levels must be an integer >= 1, got {max_levels!r}")
    if max_cells is not None and (
        isinstance(max_cells, bool) or not isinstance(max_cells, int) or max_cells < 1
    ):
        raise ValueError(f"max_cells must be a positive integer or None, got {max_cells!r}")
    if tol is not None and (not isinstance(tol, (int, float)) or not tol > 0):
        raise ValueError(f"tol must be a positive number or None, got {tol!r}")
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    if method is not None and method not in METHODS:
        raise ValueError(f"method must be one of {METHODS} or None, got {method!r}")
    if weights not in WEIGHTS:
        raise ValueError(f"weights must be one of {WEIGHTS}, got {weights!r}")
    if exact is not None and (not isinstance(exact, (int, float)) or not math.isfinite(exact)):
        raise ValueError(f"exact must be a finite number (the exact J) or None, got {exact!r}")
    if refinement_rule not in RULES:
        raise ValueError(f"refinement_rule must be one of {RULES}, got {refinement_rule!r}")
    if growth is not None and (
        isinstance(growth, bool) or not isinstance(growth, (int, float)) or not 1.0 < growth < 1e3
    ):
        raise ValueError(f"growth must be a number in (1, 1000) or None, got {growth!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {callback!r}")
    if not isinstance(verbose, bool):
        raise TypeError(f"verbose must be True or False, got {verbose!r}")
    if output_dir is not None and not isinstance(output_dir, (str, os.PathLike)):
        raise TypeError(
            f"output_dir must be a path (str or pathlib.Path) or None, got {output_dir!r}"
        )
    simplex = problem.mesh.topology.cell_type in (
        dmesh.CellType.triangle,
        dmesh.CellType.tetrahedron,
    )
    if refinement == "adaptive" and not simplex:
        raise ValueError(
            "adaptive refinement needs a simplex mesh (triangles/tetrahedra); "
            "quadrilateral/hexahedral meshes support refinement='uniform' only"
        )


def _progress(comm: MPI.Comm, record: LevelRecord, label: str | None = None) -> None:
    """The progress line of a level (or of a load step, ``label``) on rank 0."""
    if comm.rank == 0:
        friction = (
            "" if record.num_stick is None
            else f"stick/slip {record.num_stick:d}/{record.num_slip:d}  "
        )
        contact = "no contact  " if record.no_contact else ""
        fallback = ", memory" if record.weights_fallback else ""
        label = f"level {record.level:2d}" if label is None else label
        print(
            f"{label}  cells {record.num_cells:8d}  dofs {record.num_dofs:8d}  "
            f"J_best {record.J_best: .6e}  J in [{record.J_low: .6e}, {record.J_high: .6e}]  "
            f"J_h {record.J_h: .6e}  "
            f"estimate {record.estimate: .3e} ({record.weights}{fallback})  {contact}{friction}"
            f"newton {record.newton_iterations:2d} ({record.method})  "
            f"{record.time['total']:7.2f} s",
            flush=True,
        )


def solve_adaptive(
    problem: SignoriniProblem,
    goal: Goal,
    refinement: str = "adaptive",
    fraction: float | None = None,
    strategy: str | None = None,
    max_levels: int = 8,
    max_cells: int | None = None,
    tol: float | None = None,
    estimator: str = "eta",
    weights: str = "auto",
    exact: float | None = None,
    output_dir: str | Path | None = None,
    callback: Callable[[LevelRecord, Solution, Estimate], None] | None = None,
    petsc_options: dict[str, Any] | None = None,
    method: str | None = None,
    verbose: bool = True,
    ncp_scale: str | float = "physical",
    refinement_rule: str = "edges",
    growth: float | None = None,
) -> AdaptiveResult:
    """Goal-oriented adaptive (or uniform) refinement for Signorini's problem.

    Args:
        problem: The problem on the initial macro mesh.
        goal: ``goal(u, lam, m) -> ufl.Form``, the quantity of interest J.
        refinement: ``"adaptive"`` (mark and refine, simplices only) or ``"uniform"``.
        fraction: Marking fraction in (0, 1] (of cells, or of indicator mass for Doerfler).
            Without ``fraction`` and ``growth``: a fixed fraction of 0.2 in 2D; in 3D
            Doerfler's criterion with theta = 0.3 and at most twice the cells per level
            (:func:`~dwr_signorini.marking.marking_defaults`).
        strategy: ``"fixed_fraction"``, ``"doerfler"`` or ``None``: Doerfler where the 3D
            default marking applies, else a fixed fraction.
        max_levels: Number of levels (solves) at most.
        max_cells: Stop before a level whose fine mesh would exceed this many cells.
        tol: Stop when the interval for J is at most ``2 tol`` wide, J_high - J_low <= 2 tol
            (:attr:`~dwr_signorini.Estimate.interval`, which contains the active-set
            remainder R_A of Proposition 4, large while the contact set is not resolved);
            ``AdaptiveResult.converged`` tells whether that happened, and with ``verbose`` a
            line says so when it did not.
        estimator: ``"eta"`` or ``"eta_p"``: drives marking and the stopping test.
        weights: ``"auto"`` (patch weights, P2 weights on levels whose contact set is not
            resolved), ``"patch"``, ``"higher_order"`` or ``"hierarchical"`` (see
            :func:`~dwr_signorini.estimate`).
        exact: The exact J(w), if known: fills rel_error and the effectivity indices.
        output_dir: Where to write the table (CSV, JSON, after every level) and fields (XDMF).
        callback: Called as ``callback(record, solution, estimate)`` after every level, on
            every rank; an exception it raises on any rank is raised on every rank
            (:mod:`dwr_signorini.collective`).
        petsc_options: Linear solver options.
        method: Linear algebra of the Newton steps, ``"block"``, ``"schur"`` or ``None`` (the
            default: chosen per level, see :func:`~dwr_signorini.solve`).
        verbose: Print a progress line per level on rank 0, and at the end one line that says
            why the run stopped (``tol``, ``max_levels`` or ``max_cells``).
        ncp_scale: c of the NCP function, for the Newton method and the estimator (see
            :func:`~dwr_signorini.solve`): ``"physical"`` (E / H per macro contact facet) or a
            number (1.0 reproduces the paper's Tables 1-2).
        refinement_rule: ``"edges"`` (all edges of the marked macro cells) or
            ``"longest_edge"`` (each marked cell bisected through its longest edge, with the
            closure conformity needs: less spreading, above all in 3D); see
            :func:`~dwr_signorini.refine.marked_edges`.
        growth: Instead of a fixed ``fraction``, the wanted ratio of macro cells from one level
            to the next (> 1): the fraction of each level follows from it
            (:func:`~dwr_signorini.marking.mark_for_growth`). Not with ``fraction``.

    Returns:
        The :class:`AdaptiveResult` with one :class:`LevelRecord` per level (collective;
        release it with ``destroy()`` or ``with``).

    Raises:
        TypeError, ValueError: Arguments of the wrong type or value, naming the argument
            (checked before the first solve), or an ``output_dir`` that cannot be written.
        ConvergenceError: As :func:`~dwr_signorini.solve`, on any level; the levels before it
            are in ``output_dir`` if given.
        RuntimeError: As :func:`~dwr_signorini.estimate`.
    """
    _validate(
        problem,
        goal,
        refinement,
        fraction,
        strategy,
        max_levels,
        max_cells,
        tol,
        estimator,
        weights,
        method,
        exact,
        callback,
        refinement_rule,
        growth,
        verbose,
        output_dir,
    )
    comm = problem.mesh.comm
    marking = (  # a uniform run records what it was given
        marking_defaults(problem, fraction, growth, strategy)
        if refinement == "adaptive"
        else MarkingRule(strategy or "fixed_fraction", fraction, growth)
    )
    meta = {
        "refinement": refinement,
        "fraction": marking.fraction,
        "strategy": marking.strategy,
        "max_growth": marking.max_growth,
        "estimator": estimator,
        "weights": weights,
        "method": method,
        "ncp_scale": check_ncp_scale(ncp_scale),
        "refinement_rule": refinement_rule,
        "growth": marking.growth,
        "exact": exact,
        "num_processes": comm.size,
    }
    out = None
    if output_dir is not None:
        check_output_dir(output_dir, comm)
        out = OutputDirectory(output_dir, comm, name=refinement)

    result = AdaptiveResult(levels=[], meta=meta, comm=comm)
    previous: Solution | None = None
    previous_rec = None
    sol: Solution | None = None
    est: Estimate | None = None
    macro_parent = None
    current = problem
    try:
        for level in range(max_levels):
            t_start = time.perf_counter()
            with timed("discretize"):
                disc = discretize(current)
            with timed("transfer"):
                guess = (
                    None
                    if previous is None
                    else transfer_solution(previous, disc, previous_rec, macro_parent)
                )
            if previous is not None:
                # PETSc destruction is collective: free the last level's solver and
                # reconstruction on all ranks here, as soon as the warm start no longer needs them.
                previous.destroy()
                previous_rec.destroy()
            t_setup = time.perf_counter() - t_start

            tic = time.perf_counter()
            sol = est = None
            sol = solve(
                disc,
                petsc_options=petsc_options,
                initial_guess=guess,
                method=method,
                ncp_scale=ncp_scale,
            )
            t_solve = time.perf_counter() - tic
            est = estimate(
                sol, goal, estimator=estimator, weights=weights, petsc_options=petsc_options
            )
            # Converged: the interval for J at most 2 tol wide.
            J_low, J_high = est.interval
            result.converged = tol is not None and J_high - J_low <= 2 * tol
            result.stopped_by = "tol" if result.converged else "max_levels"
            stop = result.converged or level == max_levels - 1
            marked = np.zeros(0, dtype=np.int32)
            tic = time.perf_counter()
            if not stop:
                marked, next_problem, macro_parent = refine_level(
                    disc, current, est, refinement, marking, refinement_rule
                )
                result.next_cells = fine_cells(next_problem)
                if max_cells is not None and result.next_cells > max_cells:
                    stop, result.stopped_by = True, "max_cells"
            times = {"setup": t_setup, "solve": t_solve, "refine": time.perf_counter() - tic}
            record = _record(level, disc, sol, est, marked, times, exact)
            record.time["total"] = time.perf_counter() - t_start
            result.levels.append(record)
            if out is not None:
                with timed("output"):  # the fields first: a level in the table has its fields
                    fields = [sol.u, est.indicators, est.dual.y]
                    out.write_fields(level, fields, [*sol.multipliers, *est.dual.multipliers])
                    out.append(record.as_dict(), meta)
            if verbose:
                _progress(comm, record)
            if callback is not None:
                call_collectively(comm, "callback", callback, record, sol, est)
            result.solution, result.estimate, result.problem = sol, est, current
            if stop:
                break
            previous, previous_rec, current = sol, est.reconstructor, next_problem
    except Exception:
        # Every rank raises (the package's errors are collective, dwr_signorini.collective):
        # release this level's and the last level's PETSc objects and options on all ranks.
        for obj in (est, sol, previous_rec, previous):
            if obj is not None:
                obj.destroy()
        raise
    if verbose and comm.rank == 0:
        print(_stop_line(result, tol, max_levels, max_cells), flush=True)
    return result


def _record(
    level: int,
    disc: Any,
    sol: Solution,
    est: Estimate,
    marked: np.ndarray,
    times: dict[str, float],
    exact: float | None,
) -> LevelRecord:
    """The table row of a finished level (``times``: setup, solve, refine)."""
    sizes = ("num_cells", "num_macro_cells", "num_contact_elements", "num_dofs")
    values = ("J_h", "J_best", "eta_p", "eta", "contact_term", "active_set_remainder",
              "weights", "weights_fallback", "resolved")
    J_low, J_high = est.interval
    record = LevelRecord(
        level=level,
        **{name: getattr(disc, name) for name in sizes},
        **{name: getattr(est, name) for name in values},
        estimate=est.value,
        J_low=J_low,
        J_high=J_high,
        num_active=sol.num_active,
        no_contact=sol.num_active == 0,
        num_stick=sol.num_stick,
        num_slip=sol.num_slip,
        method=sol.method,
        newton_iterations=sol.newton_iterations,
        num_marked=disc.comm.allreduce(len(marked), op=MPI.SUM),
        time={
            "setup": times["setup"],
            "solve": times["solve"],
            "dual": est.timings["dual"],
            "estimate": est.timings["estimate"],
            "refine": times["refine"],
        },
    )
    if exact is not None:
        err = exact - est.J_h
        record.rel_error = abs(err) / abs(exact) if exact != 0 else abs(err)
        record.ieff_p = err / est.eta_p if est.eta_p != 0 else math.inf
        if est.eta is not None:
            record.ieff = err / est.eta if est.eta != 0 else math.inf
    return record


def _stop_line(
    result: AdaptiveResult, tol: float | None, max_levels: int, max_cells: int | None
) -> str:
    """The one line that says why a run stopped (tol, max_levels or max_cells)."""
    last = result.levels[-1]
    n = f"{len(result.levels)} level" + ("s" if len(result.levels) != 1 else "")
    width = last.J_high - last.J_low
    if result.converged:
        return f"converged after {n}: J_high - J_low = {width:.3e} <= 2 tol = {2 * tol:.3e}"
    if result.stopped_by == "max_cells":
        limit = (
            f"max_cells = {max_cells} reached (the next level would have "
            f"{result.next_cells} cells)"
        )
    else:
        limit = f"max_levels = {max_levels} reached"
    if tol is None:
        return f"stopped after {n}: {limit}; no tol given, so no convergence test"
    return (
        f"not converged: J_high - J_low = {width:.3e} > 2 tol = {2 * tol:.3e} after {n}: "
        f"{limit}"
    )
