"""Quasi-static load paths: a sequence of problems on one body, each step carrying the slip history.

Friction depends on the path: a frictional law's tangential condition is written for the slip
increment of a load step, u_t - u_t^old (:class:`~dwr_signorini.laws.Coulomb`), where u^old is
the displacement at the end of the previous step. :func:`solve_path` solves the steps in order;
step k starts from step k - 1's solution (warm start) and measures its slip from it
(:meth:`~dwr_signorini.spaces.Discretization.set_u_old`), and each step's quantity of interest is
estimated with its interval (:attr:`~dwr_signorini.Estimate.interval`). The estimate of a step
is that of the step's discrete problem for the given u^old: the error that u^old itself carries
from the earlier steps is not part of it (the history is data of the step).

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

from mpi4py import MPI

import numpy as np

from .adapt import (
    AdaptiveResult,
    LevelRecord,
    _progress,
    _record,
    _refine,
    _validate,
    marking_defaults,
)
from .collective import call_collectively
from .estimator import Estimate, estimate
from .goal import Goal
from .io import OutputDirectory, check_output_dir
from .newton import Solution, solve
from .problem import SignoriniProblem
from .spaces import Discretization, discretize
from .timing import timed
from .transfer import transfer_solution

__all__ = ["PathResult", "StepRecord", "solve_path"]


@dataclass
class StepRecord(LevelRecord):
    """One row of a load path's table: a :class:`~dwr_signorini.adapt.LevelRecord` of the step.

    Attributes:
        step: The load step, from 0 (``level`` is the refinement level of its mesh).
    """

    step: int = 0


@dataclass
class PathResult(AdaptiveResult):
    """The steps of a load path, and the last step's solution and estimate.

    As :class:`~dwr_signorini.adapt.AdaptiveResult`; release it with :meth:`destroy` or use it
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

    On the same macro mesh the multipliers' layout is the same (copied) and u is u^old; on a
    refined mesh the solution is transferred as between adaptive levels.
    """
    old = previous.disc
    same = old.macro_mesh is disc.macro_mesh and old.Q.dofmap.index_map.size_local == (
        disc.Q.dofmap.index_map.size_local
    )
    if not disc.comm.allreduce(same, op=MPI.LAND):
        return transfer_solution(previous, disc)
    lams = []
    for f in previous.multipliers:
        g = type(f)(disc.Q, name=f.name)
        g.x.array[:] = f.x.array
        lams.append(g)
    u0 = type(previous.u)(disc.V, name="u")
    u0.x.array[:] = disc.u_old.x.array
    return (u0, *lams)


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
) -> PathResult:
    """Solve a quasi-static load path step by step, each step from the last (module docstring).

    Args:
        problems: One :class:`~dwr_signorini.SignoriniProblem` per load step, on the same macro
            mesh with the same tags and contact law; their data (prescribed displacements,
            loads, gaps) change from step to step.
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
        callback: Called as ``callback(record, solution, estimate)`` after every step, on every
            rank (errors raised on every rank).
        petsc_options: The linear solver's options (as :func:`~dwr_signorini.solve`).
        method: The Newton steps' linear algebra (as :func:`~dwr_signorini.solve`).
        ncp_scale: c of the NCP function (as :func:`~dwr_signorini.solve`).
        verbose: Print a progress line per step on rank 0.
        initial_guess: The first step's initial iterate, ``(u0, lam0, ...)`` on its
            discretisation's spaces (as :func:`~dwr_signorini.solve`); e.g. for a body that
            only contact and friction hold in place, whose first Newton step needs the contact
            active (a floating body's stiffness matrix is singular).

    Returns:
        The :class:`PathResult`, one :class:`StepRecord` per step (collective; release it
        with ``destroy()`` or ``with``).

    Raises:
        TypeError, ValueError: Bad arguments, naming them (before the first solve).
        ConvergenceError: As :func:`~dwr_signorini.solve`, on any step.
    """
    problems = _check_problems(problems)
    goals = _goals(goal, len(problems))
    _validate(problems[0], goals[0], "adaptive" if adaptive else "uniform", fraction,
              "fixed_fraction", len(problems), None, None, estimator, weights, method, None,
              callback, "edges", growth, verbose, output_dir)
    if not isinstance(adaptive, bool):
        raise TypeError(f"adaptive must be True or False, got {adaptive!r}")
    comm = problems[0].mesh.comm
    if adaptive:
        fraction, growth = marking_defaults(problems[0], fraction, growth)
    meta = {"steps": len(problems), "adaptive": adaptive, "estimator": estimator,
            "weights": weights, "fraction": fraction, "growth": growth,
            "num_processes": comm.size, "law": repr(problems[0].law)}
    out = None
    if output_dir is not None:
        check_output_dir(output_dir, comm)
        out = OutputDirectory(output_dir, comm, name="path")
    result = PathResult(levels=[], meta=meta, comm=comm)
    state = _PathState(first_guess=initial_guess)
    try:
        for k, problem in enumerate(problems):
            record = _step(k, problem, goals[k], state, adaptive and k < len(problems) - 1,
                           estimator, weights, fraction, growth, petsc_options, method,
                           ncp_scale)
            result.levels.append(record)
            sol, est = state.solution, state.estimate
            if out is not None:
                with timed("output"):
                    out.write_fields(k, [sol.u, est.indicators, est.dual.y],
                                     [*sol.multipliers, *est.dual.multipliers])
                    out.append(record.as_dict(), meta)
            if verbose:
                _progress(comm, record, f"step {k:3d}  level {record.level:2d}")
            if callback is not None:
                call_collectively(comm, "callback", callback, record, sol, est)
            result.solution, result.estimate, result.problem = sol, est, state.current
    except Exception:
        state.destroy()
        raise
    return result


@dataclass
class _PathState:
    """What a step hands to the next: its solution, estimate, and the refined problems."""

    solution: Solution | None = field(default=None, repr=False)
    estimate: Estimate | None = field(default=None, repr=False)
    current: SignoriniProblem | None = None
    level: int = 0
    macro_parent: Any = None
    first_guess: tuple[Any, ...] | None = None

    def destroy(self) -> None:
        for obj in (self.estimate, self.solution):
            if obj is not None:
                obj.destroy()


def _step(
    k: int, problem: SignoriniProblem, goal: Goal, state: _PathState, refine: bool,
    estimator: str, weights: str, fraction: float | None, growth: float | None,
    petsc_options: dict[str, Any] | None, method: str | None, ncp_scale: str | float,
) -> StepRecord:
    """Solve and estimate load step ``k`` from the state of step k - 1; refine after it."""
    t_start = time.perf_counter()
    current = problem if state.current is None else _on_mesh(problem, state.current)
    with timed("discretize"):
        disc = discretize(current)
    previous = state.solution
    with timed("transfer"):
        disc.set_u_old(None if previous is None else previous.u)
        guess = state.first_guess if previous is None else _warm_start(previous, disc)
    state.destroy()
    t_setup = time.perf_counter() - t_start
    tic = time.perf_counter()
    sol = state.solution = solve(disc, petsc_options=petsc_options, initial_guess=guess,
                                 method=method, ncp_scale=ncp_scale)
    t_solve = time.perf_counter() - tic
    est = state.estimate = estimate(sol, goal, estimator=estimator, weights=weights,
                                    petsc_options=petsc_options)
    tic = time.perf_counter()
    marked = np.zeros(0, dtype=np.int32)
    level, state.current = state.level, current
    if refine:
        marked, state.current, state.macro_parent = _refine(
            disc, current, est, "adaptive", "fixed_fraction", fraction, growth, "edges")
        state.level += 1
    record = _record(level, disc, sol, est, marked,
                     {"setup": t_setup, "solve": t_solve, "refine": time.perf_counter() - tic},
                     None)
    step = StepRecord(**record.as_dict(), step=k)
    step.time["total"] = time.perf_counter() - t_start
    return step


def _on_mesh(problem: SignoriniProblem, current: SignoriniProblem) -> SignoriniProblem:
    """Step ``problem``'s data on the (refined) macro mesh of ``current``."""
    if problem.mesh is current.mesh:
        return problem
    return problem.with_mesh(current.mesh, current.facet_tags, current.cell_tags)
