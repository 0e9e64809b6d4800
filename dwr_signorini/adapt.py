"""The adaptive loop: solve, estimate, mark, refine (the only loop over levels).

Each level solves Signorini's problem on T_h (warm-started from the previous level), estimates the
error in J with eta or eta_p, sums the indicators over the patches (macro cells), marks them, and
refines the macro mesh T_H with the edges of the marked cells; the next fine mesh is one uniform
refinement of the new macro mesh. A level is solved, estimated and refined by
:class:`~dwr_signorini.driver.LevelSettings` and reported by
:class:`~dwr_signorini.report.Reporter`, as the load steps of :func:`~dwr_signorini.solve_path`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from . import finite_strain, finite_strain_estimate
from .agreement import check_same_on_ranks
from .driver import LevelSettings, check_simplex
from .estimator import Estimate
from .goal import Goal
from .marking import MarkingRule, marking_defaults
from .model_choice import ModelChoice, check_models, check_regions, explain, write_model_map
from .model_error import check_richer
from .model_regions import model_label
from .newton import Solution
from .problem import SignoriniProblem
from .refine import RULES, fine_cells
from .report import AdaptiveResult, LevelRecord, Reporter
from .settings import EstimateOptions, SolverOptions, StopRule
from .spaces import discretize
from .timing import timed
from .transfer import transfer_solution

__all__ = ["solve_adaptive"]

REFINEMENTS = ("adaptive", "uniform")


def _check_problem_and_goal(problem: Any, goal: Any, refinement: Any) -> None:
    """Check ``problem``, ``goal`` and ``refinement`` of :func:`solve_adaptive`."""
    if not isinstance(problem, SignoriniProblem):
        raise TypeError(f"problem must be a SignoriniProblem, got {type(problem).__name__}")
    if not callable(goal):
        raise TypeError(f"goal must be a callable goal(u, lam, m) -> ufl.Form, got {goal!r}")
    if refinement not in REFINEMENTS:
        raise ValueError(f"refinement must be one of {REFINEMENTS}, got {refinement!r}")


def _check_refinement(problem: SignoriniProblem, refinement: str, rule: Any, exact: Any) -> None:
    """Check ``exact`` and ``refinement_rule`` of :func:`solve_adaptive`, and the cell type."""
    if exact is not None and (not isinstance(exact, (int, float)) or not math.isfinite(exact)):
        raise ValueError(f"exact must be a finite number (the exact J) or None, got {exact!r}")
    if rule not in RULES:
        raise ValueError(f"refinement_rule must be one of {RULES}, got {rule!r}")
    check_simplex(problem, refinement)


def _check_finite_strain(
    problem: SignoriniProblem, settings: LevelSettings, models: Any
) -> None:
    """Refuse, before the first solve, what a finite-strain level would refuse (ValueError).

    The solver's ``petsc_options`` and ``method``
    (:func:`~dwr_signorini.finite_strain.check_options`), weights other than the patch ones
    and ``model_error`` (:func:`~dwr_signorini.finite_strain_estimate.check_options`), and
    ``models`` richer than a finite-strain problem (none is: friction is not covered at finite
    strain); the solver's and the estimate's options also where a richer model of ``models``
    is a finite-strain one (small strain first, ``models=[linear, hyperelastic]``).
    """
    if problem.finite_strain and models is not None:
        finite_strain.refuse("solve_adaptive(models=...)", "no model is richer than a "
                             "finite-strain one here (friction is not covered at finite strain)")
    if problem.finite_strain or any(m.finite_strain for m in models or ()):
        finite_strain.check_options(settings.solver)
        finite_strain_estimate.check_options(
            settings.estimate, settings.model_error if problem.finite_strain else None)


def _model_choice(
    problem: SignoriniProblem, model_error: Any, models: Any, tol: Any, share: Any,
    regions: Any = False, marking: MarkingRule | None = None,
) -> ModelChoice | None:
    """Check ``model_error`` or ``models`` of :func:`solve_adaptive`; the run's model choice."""
    if model_error is not None:
        check_richer(problem, model_error)
    if models is None:
        if regions is not False:
            raise ValueError("model_regions needs models=[frictionless, Coulomb(mu)]")
        return None
    if model_error is not None:
        raise ValueError("give models or model_error, not both")
    models = check_models(problem, models, tol, share)
    return ModelChoice(models, tol, share, regions=check_regions(models, regions),
                       marking=marking)


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
    model_error: SignoriniProblem | None = None,
    models: list[SignoriniProblem] | None = None,
    model_share: float = 0.5,
    model_regions: bool = False,
) -> AdaptiveResult:
    """Goal-oriented adaptive (or uniform) refinement for Signorini's problem.

    Args:
        problem: The problem on the initial macro mesh. A finite-strain one (a hyperelastic
            ``material``) is solved on every level at the full load by
            :mod:`~dwr_signorini.finite_strain` (level 0 from zero, the next from the previous
            level's solution) and estimated by :mod:`~dwr_signorini.finite_strain_estimate`
            (patch weights; the interval widened by R3); ``petsc_options``, ``method``,
            ``weights`` other than ``"patch"``/``"auto"``, ``model_error`` and ``models`` are
            refused for it.
        goal: ``goal(u, lam, m) -> ufl.Form``, the quantity of interest J.
        refinement: ``"adaptive"`` (mark and refine, simplices only) or ``"uniform"``.
        fraction: Marking fraction in (0, 1] (of cells, or of indicator mass for Doerfler);
            default :func:`~dwr_signorini.marking.marking_defaults`.
        strategy: ``"fixed_fraction"``, ``"doerfler"`` or ``None`` (the default's).
        max_levels: Number of levels (solves) at most.
        max_cells: Stop before a level whose fine mesh would exceed this many cells.
        tol: Stop when the interval for J is at most ``2 tol`` wide
            (:class:`~dwr_signorini.settings.StopRule`, ``AdaptiveResult.converged``).
        estimator: ``"eta"`` or ``"eta_p"``: drives marking and the stopping test.
        weights: The estimate's weights (see :func:`~dwr_signorini.estimate`).
        exact: The exact J(w), if known: fills rel_error and the effectivity indices.
        output_dir: Where to write the table (CSV, JSON, after every level) and fields (XDMF).
        callback: Called as ``callback(record, solution, estimate)`` after every level, on
            every rank; an exception it raises on any rank is raised on every rank.
        petsc_options: Linear solver options (of the solves and the estimates).
        method: Linear algebra of the Newton steps (``None``: chosen per level, see
            :func:`~dwr_signorini.solve`).
        verbose: Print a progress line per level on rank 0, and at the end one line that says
            why the run stopped (:class:`~dwr_signorini.report.Reporter`).
        ncp_scale: c of the NCP function (as :func:`~dwr_signorini.solve`).
        refinement_rule: ``"edges"`` (all edges of the marked macro cells) or
            ``"longest_edge"`` (:func:`~dwr_signorini.refine.marked_edges`).
        growth: Instead of ``fraction``, the wanted ratio of macro cells from one level to the
            next (> 1, :func:`~dwr_signorini.marking.mark_for_growth`).
        model_error: ``problem`` with a richer contact law (as for
            :func:`~dwr_signorini.estimate`): every level also estimates the change of J from
            the law of ``problem`` to that one (``LevelRecord.model_error`` and its interval);
            it does not drive the refinement.
        models: Mesh and model adaptivity (:mod:`~dwr_signorini.model_choice`): problems from
            the simplest law to the richest, each the one before with a richer law (the same
            mesh and data), ``models[0]`` being ``problem``; needs ``tol``. Each level solves
            the model in force and estimates its model error against the next richer one; where
            the bound of that error exceeds ``model_share * tol`` the level is solved again with
            the richer model, which stays in force (eq. (M2)). The run converges when half the
            interval of J plus the bound of the model error is at most ``tol`` (eq. (M3)).
            ``LevelRecord.model`` names the law that ran. Not with ``model_error``.
        model_share: s of (M2), in (0, 1): the share of ``tol`` a left-out law may change J by.
        model_regions: With ``models=[frictionless, Coulomb(mu)]``: choose the law per macro
            contact facet (eqs. (M4), (M5)): the first level runs frictionless; where (M2)
            fails, the facets with the largest model indicators (by the run's marking rule) run
            Coulomb from the next level on. ``LevelRecord.rich_share`` and
            ``AdaptiveResult.model_map`` say which facets ran which law; with ``output_dir``
            the run writes ``model_map.json`` and ``model_map.png``
            (:func:`dwr_signorini.viz.plot_model_map`).

    Returns:
        The :class:`AdaptiveResult` with one :class:`LevelRecord` per level (collective;
        release it with ``destroy()`` or ``with``).

    Raises:
        TypeError, ValueError: Arguments of the wrong type or value, naming the argument
            (checked before the first solve), or an ``output_dir`` that cannot be written.
        ConvergenceError: As :func:`~dwr_signorini.solve`, on any level (at finite strain
            the message says the Newton method started from the previous level's solution);
            the levels before it are in ``output_dir`` if given.
        RuntimeError: As :func:`~dwr_signorini.estimate`.
    """
    _check_problem_and_goal(problem, goal, refinement)
    check_same_on_ranks(
        problem.mesh,
        "solve_adaptive",
        {
            "refinement": refinement, "fraction": fraction, "strategy": strategy,
            "max_levels": max_levels, "max_cells": max_cells, "tol": tol,
            "estimator": estimator, "weights": weights, "exact": exact,
            "output_dir": None if output_dir is None else str(output_dir),
            "callback": callback is None, "petsc_options": petsc_options, "method": method,
            "ncp_scale": ncp_scale, "refinement_rule": refinement_rule, "growth": growth,
            "models": None if models is None else len(models), "model_share": model_share,
            "model_regions": model_regions,
        },
    )
    marking = (  # a uniform run records what it was given
        marking_defaults(problem, fraction, growth, strategy)
        if refinement == "adaptive"
        else MarkingRule(strategy or "fixed_fraction", fraction, growth)
    )
    stop = StopRule(max_levels, max_cells, tol)
    solver = SolverOptions(petsc_options, method, ncp_scale)
    estimate_options = EstimateOptions(estimator, weights, petsc_options)
    settings = LevelSettings(
        solver, estimate_options, marking, refinement, refinement_rule, exact, model_error
    )
    _check_refinement(problem, refinement, refinement_rule, exact)
    _check_finite_strain(problem, settings, models)
    choice = _model_choice(
        problem, model_error, models, tol, model_share, model_regions, marking
    )
    meta = {"refinement": refinement, "fraction": marking.fraction, "strategy": marking.strategy,
            "max_growth": marking.max_growth, "estimator": estimator, "weights": weights,
            "method": method, "ncp_scale": solver.ncp_scale, "refinement_rule": refinement_rule,
            "growth": marking.growth, "exact": exact, "num_processes": problem.mesh.comm.size,
            "models": None if models is None else [model_label(m) for m in models],
            "model_share": None if models is None else model_share,
            "model_regions": model_regions}
    reporter = Reporter(problem.mesh.comm, refinement, meta, output_dir, callback, verbose)
    return _levels(problem, goal, settings, stop, reporter, choice)


def _levels(
    problem: SignoriniProblem,
    goal: Goal,
    settings: LevelSettings,
    stop: StopRule,
    reporter: Reporter,
    choice: ModelChoice | None = None,
) -> AdaptiveResult:
    """The loop of :func:`solve_adaptive` over the levels, from ``problem``'s macro mesh.

    With ``choice`` each level runs the model it chooses (:meth:`ModelChoice.solve_level`)
    and the run converges by its rule (M3).
    """
    result = AdaptiveResult(levels=[], meta=reporter.meta, comm=reporter.comm)
    previous: Solution | None = None
    previous_rec = sol = est = macro_parent = disc = None
    current = problem
    try:
        with reporter:
            for level in range(stop.max_levels):
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
                    # reconstruction on all ranks, as soon as the warm start no longer needs them.
                    previous.destroy()
                    previous_rec.destroy()
                t_setup = time.perf_counter() - t_start
                sol = est = None
                if choice is None:
                    sol, est, t_solve = settings.solve_and_estimate(disc, guess, goal)
                    result.converged = stop.converged(est.interval)
                else:
                    sol, est, t_solve, disc = choice.solve_level(
                        settings, disc, guess, goal, reporter.say, level
                    )
                    current = choice.base(disc.problem)
                    result.converged = choice.converged(est)
                sol.owns_disc = True  # the level's master traces go with its solution
                result.stopped_by = "tol" if result.converged else "max_levels"
                done = result.converged or level == stop.max_levels - 1
                marked = np.zeros(0, dtype=np.int32)
                tic = time.perf_counter()
                if not done:
                    marked, next_problem, macro_parent = settings.refine(disc, current, est)
                    result.next_cells = fine_cells(next_problem)
                    if stop.too_many_cells(result.next_cells):
                        done, result.stopped_by = True, "max_cells"
                times = {"setup": t_setup, "solve": t_solve, "refine": time.perf_counter() - tic}
                record = settings.record(level, disc, sol, est, marked, times)
                record.time["total"] = time.perf_counter() - t_start
                if choice is not None:
                    choice.annotate(record)
                result.levels.append(record)
                reporter.report(level, record, sol, est)
                result.solution, result.estimate, result.problem = sol, est, current
                if done:
                    break
                previous, previous_rec, current = sol, est.reconstructor, next_problem
            if choice is not None and choice.regions:
                result.model_map = choice.maps
                write_model_map(reporter, choice.maps)
            last = result.levels[-1]
            reporter.say(stop.explain(len(result.levels), last.J_high - last.J_low,
                                      result.stopped_by, result.next_cells)
                         + explain(choice, result.estimate))
    except Exception:
        # Every rank raises (the package's errors are collective, dwr_signorini.collective):
        # release this level's and the last level's PETSc objects and options on all ranks.
        for obj in (est, sol, previous_rec, previous, disc):
            if obj is not None:
                obj.destroy()
        raise
    return result
