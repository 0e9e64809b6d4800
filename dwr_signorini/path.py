"""Quasi-static load paths: a sequence of problems on one body, each step carrying the slip history.

Friction depends on the path: a frictional law's tangential condition is written for the slip
increment of a load step, u_t - u_t^old (:class:`~dwr_signorini.laws.Coulomb`), where u^old is
the displacement at the end of the previous step. :func:`solve_path` solves the steps in order;
step k starts from step k - 1's solution (warm start) and measures its slip from it
(:meth:`~dwr_signorini.spaces.Discretization.set_u_old`), and each step's quantity of interest is
estimated with its interval (:attr:`~dwr_signorini.Estimate.interval`). A rigid obstacle given
translated from one step to the next carries its translation into the slip
(:mod:`~dwr_signorini.obstacle_motion`): moving it or the body gives the same tractions.

**The error the history carries.** The estimate of a step's own residuals is that of its
discrete problem for the given u^old; the error of u^old enters its J to first order as
L(u_old - u_old,h), L the sensitivity of J to u^old
(:func:`~dwr_signorini.path_history.history_goal`, exact for the discrete problem). L is a goal
of the previous step, estimated there with its own dual solution, whose sensitivity is a goal
of the step before, back to the first step
(:func:`~dwr_signorini.path_history.history_estimates`): a backward chain of dual problems, as
a space-time dual would be solved backwards in time. The chain's estimates are added to the
step's estimate and its interval (the intervals summed).

**One backward sweep.** The chain of step k is a sweep back over the k earlier steps, one
estimate (one transposed solve with that step's stored last Newton factors) per step, and its
goals depend on k: the chains of different steps share no solve. So the default,
``history="last"``, estimates the history of the last step only, by one sweep back over the
path after its last solve: n - 1 estimates for n steps, one per step in total; the terms are
those of the chain of the last step, as computed step by step. ``history="every"`` (or True)
runs the chain after every step: k estimates at step k, n (n - 1) / 2 along the path.

A history estimate is one of another goal at the solution that the step's own estimate judged:
each kept step keeps what its own estimate made that does not depend on the goal
(:mod:`~dwr_signorini.estimate_parts`: the reconstructor, the P2 system of the weights with
its factors or two-level set-up, the primal weights, the compiled forms of the indicators),
so a history estimate costs the goal's own work: J and its derivatives, the P1 and P2
transposed solves, the weights of the dual and one assembly of the indicators. Each kept step
holds its P2 factors (``weights="higher_order"``, and ``"auto"`` where it takes them) until the
path ends, beside its Newton factors, where the memory allows
(:class:`~dwr_signorini.estimate_parts.SolverBudget`); where it does not, its history estimate
factors the P2 system again.

**Adaptivity along the path** (``adaptive=True``): after each step the macro mesh is refined
for that step's goal (the marking of :func:`~dwr_signorini.solve_adaptive`), and the next step
lives on the refined mesh. The history is carried by interpolation: u^old, piecewise linear on
the old fine mesh, is piecewise linear on the refined one (refinement is nested), so the
transfer is exact and the slip that the earlier steps accumulated is kept as it was computed;
what changes is only the resolution of the next increments. So a path refined at step k and
the same path on the refined mesh from the start differ by the discretisation error of the
steps before k, not by the transfer.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import fem

from . import finite_strain_path
from .agreement import check_same_on_ranks
from .driver import LevelSettings, check_simplex
from .estimate_parts import SolverBudget, release_estimate_parts
from .estimator import Estimate
from .goal import Goal
from .marking import MarkingRule, marking_defaults
from .model_error import check_richer
from .newton import Solution
from .obstacle_motion import path_translations
from .path_history import add_history, history_estimates, history_goal, history_mode
from .problem import SignoriniProblem
from .report import AdaptiveResult, LevelRecord, Reporter
from .settings import EstimateOptions, SolverOptions
from .spaces import Discretization, discretize
from .timing import timed
from .transfer import carry_obstacle_displacement, transfer_solution

__all__ = ["PathResult", "StepRecord", "history_estimates", "history_goal", "solve_path"]


@dataclass
class StepRecord(LevelRecord):
    """One row of a load path's table: a :class:`~dwr_signorini.LevelRecord` of the step.

    Attributes:
        step: The load step, from 0 (``level`` is the refinement level of its mesh).
        eta_history: The estimated error that the earlier steps carry into this step's goal,
            or None where it is not estimated (``history=False``, adaptive paths, and the steps
            before the last with the default ``history="last"``).

    ``estimate``, ``J_low`` and ``J_high`` include the error the history carries into the
    step's goal (:func:`history_estimates`) when it is estimated; ``eta`` and ``eta_p`` are
    those of the step's own residuals.

    ``time`` has the phases of a level and ``history`` (the backward chain of the history's
    estimates).
    """

    step: int = 0
    eta_history: float | None = None


@dataclass
class PathResult(AdaptiveResult):
    """The steps of a load path, and the last step's solution and estimate.

    As :class:`~dwr_signorini.AdaptiveResult`; release it with :meth:`destroy` or use it
    as a context manager.

    Attributes:
        levels: One :class:`StepRecord` per load step (also :attr:`steps`).
        solution: The last step's :class:`~dwr_signorini.Solution`.
        estimate: The last step's :class:`~dwr_signorini.Estimate`.
        problem: The last step's problem, on its (refined) macro mesh.
        meta: The path's settings (written by :meth:`to_json`).
        comm: The mesh communicator.
    """

    @property
    def steps(self) -> list[StepRecord]:
        """One :class:`StepRecord` per load step."""
        return self.levels  # type: ignore[return-value]


def _check_problems(problems: Any) -> list[SignoriniProblem]:
    """The steps' problems validated: a non-empty sequence on one mesh, the same tags and law."""
    if isinstance(problems, SignoriniProblem) or not isinstance(problems, Sequence):
        raise TypeError(
            "problems must be a sequence (list or tuple) of SignoriniProblem, one per load "
            f"step, got {type(problems).__name__}"
        )
    problems = list(problems)
    if not problems:
        raise ValueError("problems is empty: a load path needs at least one step")
    first = problems[0]
    for k, p in enumerate(problems):
        if not isinstance(p, SignoriniProblem):
            raise TypeError(f"problems[{k}] must be a SignoriniProblem, got {type(p).__name__}")
        if p.mesh is not first.mesh:
            raise ValueError(
                f"problems[{k}] lives on another mesh than problems[0]: the steps of a load "
                "path share one macro mesh (build them on the same mesh object)"
            )
        if p.contact_tags != first.contact_tags or repr(p.law) != repr(first.law):
            raise ValueError(
                f"problems[{k}] has another contact boundary or contact law than problems[0] "
                f"({p.contact_tags}, {p.law!r} against {first.contact_tags}, {first.law!r}): "
                "the data of a load path change per step, its tags and law do not"
            )
    return problems


def _goals(goal: Any, n: int) -> list[Goal]:
    """One goal per step: the same callable, or a sequence of them."""
    if callable(goal):
        return [goal] * n
    if isinstance(goal, Sequence) and len(goal) == n and all(callable(g) for g in goal):
        return list(goal)
    raise TypeError(
        f"goal must be a callable goal(u, lam, m[, lam_t]) -> ufl.Form or a sequence of {n} "
        f"of them (one per load step), got {goal!r}"
    )


def _warm_start(previous: Solution, disc: Discretization) -> tuple[Any, ...]:
    """Step k's initial guess: step k - 1's solution on this step's discretisation.

    On the same mesh (the spaces are shared, :meth:`Discretization.for_problem`) a copy; on a
    refined mesh the solution is transferred as between adaptive levels.
    """
    if previous.disc.V is not disc.V:
        return transfer_solution(previous, disc)
    carry_obstacle_displacement(previous, disc)
    copies = []
    for f in (previous.u, *previous.multipliers):
        g = fem.Function(f.function_space, name=f.name)
        g.x.array[:] = f.x.array
        copies.append(g)
    return tuple(copies)


def solve_path(
    problems: Sequence[SignoriniProblem],
    goal: Goal | Sequence[Goal],
    adaptive: bool = False,
    estimator: str = "eta",
    weights: str = "auto",
    fraction: float | None = None,
    growth: float | None = None,
    output_dir: str | Path | None = None,
    callback: Callable[[StepRecord, Solution, Estimate], None] | None = None,
    petsc_options: dict[str, Any] | None = None,
    method: str | None = None,
    ncp_scale: str | float = "physical",
    verbose: bool = True,
    initial_guess: tuple[Any, ...] | None = None,
    history: bool | str | None = None,
    *,
    load_factors: Sequence[float] | None = None,
    keep_steps: bool = False,
    model_error: Sequence[SignoriniProblem] | None = None,
) -> PathResult:
    """Solve a quasi-static load path step by step, each step from the last (module docstring).

    Args:
        problems: One :class:`~dwr_signorini.SignoriniProblem` per load step, on the same macro
            mesh with the same tags and contact law; their data (prescribed displacements,
            loads, gaps) change from step to step; with friction, a rigid obstacle from step
            to step only by a translation (:mod:`~dwr_signorini.obstacle_motion`).
        goal: The quantity of interest of every step, or one per step.
        adaptive: Refine the macro mesh after each step for that step's goal (the next step
            lives on the refined mesh, the history interpolated; module docstring).
        estimator: ``"eta"`` or ``"eta_p"`` (drives the marking with ``adaptive``).
        weights: The estimate's weights (:func:`~dwr_signorini.estimate`).
        fraction: The marking fraction of ``adaptive`` (as
            :func:`~dwr_signorini.solve_adaptive`; default as there).
        growth: Or the growth of the macro mesh per step (as
            :func:`~dwr_signorini.solve_adaptive`).
        output_dir: Where to write the table (``path.csv``, ``path.json``, after every step)
            and each step's fields.
        callback: Called as ``callback(record, solution, estimate)`` after every step.
        petsc_options: The linear solver's options (as :func:`~dwr_signorini.solve`).
        method: The Newton steps' linear algebra (as :func:`~dwr_signorini.solve`).
        ncp_scale: c of the NCP function (as :func:`~dwr_signorini.solve`).
        verbose: Print a progress line per step on rank 0.
        initial_guess: The first step's initial iterate, ``(u0, lam0, ...)`` on its
            discretisation's spaces (as :func:`~dwr_signorini.solve`); e.g. for a body that
            only contact and friction hold in place, whose first Newton step needs the contact
            active (a floating body's stiffness matrix is singular).
        history: Estimate the error the earlier steps carry into a step's goal
            (:func:`history_estimates`, added to the step's estimate and interval); keeps every
            step's solution (and its factorisation). ``"last"``: into the last step's goal, by
            one backward sweep after the last step (one estimate per earlier step in total);
            ``"every"`` or True: into every step's goal (k more estimates at step k); False:
            not estimated. Default: ``"last"`` on a path on one mesh with a frictional law,
            False with ``adaptive`` (not available there: the earlier steps live on other
            meshes) and for a frictionless law (its steps do not depend on the earlier ones).
        load_factors: For a finite-strain problem (``problems`` one problem with a
            hyperelastic ``material``, ``goal`` None): the increasing load factors t of its
            loads and prescribed displacements; a failed step is halved and retried
            (:func:`dwr_signorini.finite_strain_path.solve_path`, which returns a
            :class:`~dwr_signorini.finite_strain_path.FiniteStrainPath`). There ``callback`` is
            called as ``callback(step, solution, None)`` per factor (a
            :class:`~dwr_signorini.finite_strain_path.FiniteStrainStep`), and ``initial_guess`` may
            be the last solution of an earlier finite-strain path on the same mesh: the path
            starts from it, its prescribed values moving from the state's to the problem's.
        keep_steps: Keep every step's solution: each step's
            :attr:`~dwr_signorini.Solution.earlier` lists the steps before it (in
            ``callback`` and on the result's last solution, which releases them), so that
            ``estimate(sol, goal, model_error=richer_steps)`` estimates the model error along
            the path (:mod:`~dwr_signorini.path_model_error`, eq. (M7)). Not with
            ``adaptive``.
        model_error: The richer path's problems, one per step (the same data with a richer
            contact law, e.g. ``Coulomb(mu)`` in place of frictionless): every step reports the
            model error of its law, eq. (M7) over the steps so far, in its record
            (``model_error``, ``model_error_low``, ``model_error_high``) and progress line.
            Keeps every step (as ``keep_steps``); step k costs k + 1 model error estimates.
            Not with ``adaptive``.

    Returns:
        The :class:`PathResult`, one :class:`StepRecord` per step (collective; release it
        with ``destroy()`` or ``with``).

    Raises:
        TypeError, ValueError: Bad arguments, naming them (before the first solve); a
            frictional step whose obstacle is not the previous step's translated.
        ConvergenceError: As :func:`~dwr_signorini.solve`, on any step.
    """
    if load_factors is not None or getattr(problems, "finite_strain", False):
        return finite_strain_path.path_entry(
            problems, goal, load_factors, ncp_scale, petsc_options, method, adaptive,
            initial_guess, callback,
        )
    problems = _check_problems(problems)
    check_same_on_ranks(
        problems[0].mesh,
        "solve_path",
        {
            "problems": len(problems), "goal": callable(goal), "adaptive": adaptive,
            "estimator": estimator, "weights": weights, "fraction": fraction,
            "growth": growth, "output_dir": None if output_dir is None else str(output_dir),
            "callback": callback is None, "petsc_options": petsc_options, "method": method,
            "ncp_scale": ncp_scale, "initial_guess": initial_guess is None, "history": history,
            "keep_steps": keep_steps, "model_error": model_error is None,
        },
    )
    goals = _goals(goal, len(problems))
    settings = _path_settings(problems[0], adaptive, fraction, growth, estimator, weights,
                              petsc_options, method, ncp_scale)
    history = history_mode(history, adaptive, problems[0].law.frictional)
    _check_keep_steps(keep_steps, adaptive)
    richer = _check_richer_path(model_error, problems, adaptive)
    keep_steps = keep_steps or richer is not None
    translations = path_translations(problems)
    comm = problems[0].mesh.comm
    marking = settings.marking if adaptive else None
    meta = {"steps": len(problems), "adaptive": adaptive, "estimator": estimator,
            "weights": weights, "fraction": settings.marking.fraction,
            "growth": settings.marking.growth,
            "strategy": None if marking is None else marking.strategy,
            "max_growth": None if marking is None else marking.max_growth, "history": history,
            "num_processes": comm.size, "law": repr(problems[0].law)}
    reporter = Reporter(comm, "path", meta, output_dir, callback, verbose, series=True)
    state = _PathState(first_guess=initial_guess, keep=history is not None or keep_steps,
                       parts=history is not None, link=keep_steps, translations=translations,
                       richer=richer)
    return _steps(problems, goals, settings, adaptive, history, state, reporter)


def _check_richer_path(
    model_error: Any, problems: list[SignoriniProblem], adaptive: bool
) -> list[SignoriniProblem] | None:
    """``model_error`` of :func:`solve_path`: a richer problem per step (TypeError, ValueError)."""
    if model_error is None:
        return None
    if isinstance(model_error, SignoriniProblem) or not isinstance(model_error, Sequence):
        raise TypeError(
            "model_error of solve_path must be the richer path's problems, one per step, got "
            f"{type(model_error).__name__}"
        )
    if adaptive:
        raise ValueError(
            "model_error needs every step on one mesh: the steps of an adaptive path live on "
            "different meshes (use adaptive=False)"
        )
    if len(model_error) != len(problems):
        raise ValueError(
            f"model_error: {len(model_error)} richer problems for {len(problems)} steps: give "
            "one per step, the first first"
        )
    for k, (simple, rich) in enumerate(zip(problems, model_error, strict=True)):
        try:
            check_richer(simple, rich)
        except (TypeError, ValueError) as err:
            raise type(err)(f"step {k}: {err}") from None
    return list(model_error)


def _check_keep_steps(keep_steps: Any, adaptive: bool) -> None:
    """``keep_steps`` of :func:`solve_path` validated (TypeError, ValueError)."""
    if not isinstance(keep_steps, bool):
        raise TypeError(f"keep_steps must be True or False, got {keep_steps!r}")
    if keep_steps and adaptive:
        raise ValueError(
            "keep_steps=True needs every step on one mesh: the steps of an adaptive path live "
            "on different meshes (use adaptive=False)"
        )


def _path_settings(
    first: SignoriniProblem, adaptive: Any, fraction: Any, growth: Any, estimator: Any,
    weights: Any, petsc_options: Any, method: Any, ncp_scale: Any,
) -> LevelSettings:
    """The settings of every step of :func:`solve_path` (validated)."""
    if not isinstance(adaptive, bool):
        raise TypeError(f"adaptive must be True or False, got {adaptive!r}")
    check_simplex(first, "adaptive" if adaptive else "uniform")
    marking = (
        marking_defaults(first, fraction, growth)
        if adaptive
        else MarkingRule("fixed_fraction", fraction, growth)  # recorded, not used
    )
    return LevelSettings(
        SolverOptions(petsc_options, method, ncp_scale),
        EstimateOptions(estimator, weights, petsc_options),
        marking,
    )


def _steps(
    problems: list[SignoriniProblem],
    goals: list[Goal],
    settings: LevelSettings,
    adaptive: bool,
    history: str | None,
    state: _PathState,
    reporter: Reporter,
) -> PathResult:
    """The loop of :func:`solve_path` over the load steps."""
    result = PathResult(levels=[], meta=reporter.meta, comm=reporter.comm)
    try:
        with reporter:
            for k, problem in enumerate(problems):
                last = k == len(problems) - 1
                refine = adaptive and not last
                sweep = history == "every" or (history == "last" and last)
                record = _step(k, problem, goals[k], state, refine, settings, sweep)
                result.levels.append(record)
                sol, est = state.solution, state.estimate
                reporter.report(k, record, sol, est, f"step {k:3d}  level {record.level:2d}")
                result.solution, result.estimate, result.problem = sol, est, state.current
    except Exception:
        state.destroy()
        raise
    if state.link and result.solution is not None:  # the kept steps go with the last one
        result.solution.owns_earlier = True
    else:
        for kept in state.kept:  # the last step's solution and estimate go with the result
            kept.destroy()
    for disc in state.discs[:-1]:  # the earlier meshes' master traces
        disc.destroy()
    if result.solution is not None:  # and the last mesh's with the last solution
        result.solution.owns_disc = True
        release_estimate_parts(result.solution, result.estimate)
    return result


@dataclass
class _PathState:
    """What a step hands to the next.

    Its solution and estimate, the discretisation, the earlier steps' solutions (for the
    history's error) and the refined problems.
    """

    solution: Solution | None = field(default=None, repr=False)
    estimate: Estimate | None = field(default=None, repr=False)
    disc: Discretization | None = field(default=None, repr=False)
    kept: list[Solution] = field(default_factory=list, repr=False)
    #: The discretisations made (one per mesh; their master traces are released at the end).
    discs: list[Discretization] = field(default_factory=list, repr=False)
    keep: bool = False
    #: Whether the kept steps keep their estimates' parts (for the history's estimates).
    parts: bool = False
    #: Whether each step's solution lists the kept earlier steps (``keep_steps``).
    link: bool = False
    #: The memory the kept steps' P2 solvers may take (:mod:`~dwr_signorini.estimate_parts`).
    budget: SolverBudget = field(default_factory=SolverBudget, repr=False)
    current: SignoriniProblem | None = None
    level: int = 0
    macro_parent: Any = None
    first_guess: tuple[Any, ...] | None = None
    #: Each step's obstacle translation from the step before (:mod:`.obstacle_motion`).
    translations: list[Any] = field(default_factory=list, repr=False)
    #: The richer path's problems of ``model_error`` (one per step), or None.
    richer: list[SignoriniProblem] | None = field(default=None, repr=False)

    def retire(self) -> None:
        """Release the last step's estimate; its solution too unless the history needs it."""
        if self.estimate is not None:
            self.estimate.destroy()
        if self.solution is not None:
            if self.keep:
                self.kept.append(self.solution)
            else:
                self.solution.destroy()
        self.solution = self.estimate = None

    def destroy(self) -> None:
        for obj in (self.estimate, self.solution, *self.kept, *self.discs):
            if obj is not None:
                obj.destroy()


def _discretization(current: SignoriniProblem, state: _PathState) -> Discretization:
    """The step's discretisation: the last one with the step's data on the same macro mesh."""
    if state.disc is not None and state.disc.macro_mesh is current.mesh:
        return state.disc.for_problem(current)
    state.discs.append(discretize(current))
    return state.discs[-1]


def _step(
    k: int, problem: SignoriniProblem, goal: Goal, state: _PathState, refine: bool,
    settings: LevelSettings,
    sweep: bool = False,
) -> StepRecord:
    """Solve and estimate load step ``k`` from the state of step k - 1; refine after it.

    With ``sweep`` the error its history carries is estimated by the backward chain over the
    kept earlier steps (:func:`history_estimates`).
    """
    t_start = time.perf_counter()
    current = problem if state.current is None else _on_mesh(problem, state.current)
    with timed("discretize"):
        disc = state.disc = _discretization(current, state)
    previous = state.solution
    with timed("transfer"):
        disc.set_u_old(None if previous is None else previous.u, state.translations[k],
                       None if previous is None else previous.obstacle_displacement)
        guess = state.first_guess if previous is None else _warm_start(previous, disc)
    state.retire()
    t_setup = time.perf_counter() - t_start
    sol, est, t_solve = settings.solve_and_estimate(
        disc, guess, goal, keep_parts=state.budget if state.parts else None,
        earlier=tuple(state.kept) if state.link else None,
        richer=None if state.richer is None else state.richer[: k + 1],
    )
    state.solution, state.estimate = sol, est
    tic = time.perf_counter()
    history = history_estimates(state.kept, sol, est, settings.estimate) if sweep else []
    t_history = time.perf_counter() - tic
    tic = time.perf_counter()
    marked = np.zeros(0, dtype=np.int32)
    level, state.current = state.level, current
    if refine:
        marked, state.current, state.macro_parent = settings.refine(disc, current, est)
        state.level += 1
    record = settings.record(level, disc, sol, est, marked,
                             {"setup": t_setup, "solve": t_solve,
                              "refine": time.perf_counter() - tic})
    step = StepRecord(**record.as_dict(), step=k)
    step.time["history"] = t_history
    if sweep:
        add_history(step, history)
    step.time["total"] = time.perf_counter() - t_start
    return step


def _on_mesh(problem: SignoriniProblem, current: SignoriniProblem) -> SignoriniProblem:
    """Step ``problem``'s data on the (refined) macro mesh of ``current``."""
    if problem.mesh is current.mesh:
        return problem
    return problem.with_mesh(current.mesh, current.facet_tags, current.cell_tags)
