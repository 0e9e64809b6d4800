"""Finite strain along a load path: load factors t in steps, halved where Newton fails.

:func:`solve_path` applies the loads t l and prescribed values t u_D of a finite-strain problem
(:mod:`~dwr_signorini.finite_strain`) over increasing factors, each step from the last converged
state, and records what each requested factor took (:class:`FiniteStrainStep`). A path may start
from an earlier path's state (a body pressed, then slid). :func:`dwr_signorini.solve_path` with
``load_factors`` comes here (:func:`path_entry`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI

import numpy as np

from .finite_strain import (
    FiniteStrainSolution,
    FiniteStrainSystem,
    check_options,
    newton,
    refuse,
    solution_from,
)
from .lifetime import Releasable
from .semismooth import ConvergenceError

__all__ = ["MAX_CUTS", "FiniteStrainPath", "FiniteStrainStep", "path_entry", "solve_path"]

#: The most halvings of one load step of :func:`solve_path` before it gives up.
MAX_CUTS = 6


@dataclass
class FiniteStrainStep:
    """What one requested load factor of :func:`solve_path` took.

    Attributes:
        factor: The requested load factor t.
        newton_iterations: Newton steps of every solve towards it, failed ones included.
        cuts: The load factors whose step failed and was halved on the way (in order).
        steps: The load factors solved on the way, the intermediate ones included.
        seconds: Wall time of the step (all its solves), on rank 0's clock.
    """

    factor: float
    newton_iterations: int
    cuts: list[float]
    steps: list[float]
    seconds: float


@dataclass
class FiniteStrainPath(Releasable):
    """The states of :func:`solve_path` on a finite-strain problem.

    Attributes:
        solutions: One :class:`FiniteStrainSolution` per requested load factor.
        factors: The requested load factors.
        cuts: The load factors at which a step failed and was halved (in order).
        steps: Every load factor solved, the intermediate ones of halved steps included.
        records: One :class:`FiniteStrainStep` per requested load factor.
    """

    solutions: list[FiniteStrainSolution]
    factors: list[float]
    cuts: list[float] = field(default_factory=list)
    steps: list[float] = field(default_factory=list)
    records: list[FiniteStrainStep] = field(default_factory=list)

    def destroy(self) -> None:
        """Release the Newton system (collective)."""
        if self.solutions:
            self.solutions[0].system.destroy()


Callback = Callable[[FiniteStrainStep, FiniteStrainSolution, None], None]


def solve_path(problem: Any, load_factors: Any, options: Any, max_cuts: int = MAX_CUTS,
               start: FiniteStrainSolution | None = None, callback: Callback | None = None
               ) -> FiniteStrainPath:
    """Solve a finite-strain problem over increasing load factors t (loads t l, t u_D).

    Each step starts from the last converged state; a step whose Newton method fails
    (:class:`~dwr_signorini.ConvergenceError`) is halved and retried from that state, at most
    ``max_cuts`` times per requested factor; the factors where a step was cut are reported.

    From a ``start`` state (a solution of an earlier path on the same macro mesh, e.g. a body
    pressed, then slid) the prescribed values move from the start's values u_D0 on Gamma_D to
    the problem's: u_D0 + t (u_D - u_D0); the loads are t l, so the problem must have none.

    Args:
        problem: The finite-strain problem.
        load_factors: Increasing factors in (0, inf).
        options: The :class:`~dwr_signorini.settings.SolverOptions` (checked).
        max_cuts: The most halvings per requested factor.
        start: The initial state, or None (zero).
        callback: Called as ``callback(step, solution, None)`` after each requested factor
            (a :class:`FiniteStrainStep`; no estimate at finite strain yet).

    Raises:
        TypeError: ``start`` not a :class:`FiniteStrainSolution`.
        ValueError: Load factors not increasing in (0, inf); ``start`` on another mesh, or
            with a problem that has loads.
        ConvergenceError: A step still failing after ``max_cuts`` halvings.
    """
    from .spaces import discretize

    factors = [float(t) for t in load_factors]
    if not factors or any(b <= a for a, b in zip([0.0, *factors], factors, strict=False)):
        raise ValueError(f"load_factors must increase from above 0, got {load_factors!r}")
    if start is not None and not isinstance(start, FiniteStrainSolution):
        raise TypeError(f"start must be a FiniteStrainSolution, got {type(start).__name__}")
    disc = discretize(problem) if start is None else start.disc.for_problem(problem)
    system = FiniteStrainSystem(disc, options.ncp_scale)
    try:
        if start is not None:
            _start_from(system, start)
        return _path(system, factors, options, max_cuts, callback)
    except BaseException:
        system.destroy()
        raise


def _start_from(system: FiniteStrainSystem, start: FiniteStrainSolution) -> None:
    """The system's state and prescribed values at t = 0 from a solution (``solve_path``)."""
    system.set_load(1.0)
    loads = system._owned("load")
    if system.disc.comm.allreduce(bool(np.any(loads != 0.0)), op=MPI.LOR):
        raise ValueError(
            "solve_path from an initial state takes a problem without body force or tractions "
            "(its loads t l would start from zero, not from the state's loads)"
        )
    system.u.x.array[:] = start.u.x.array
    system.lam.x.array[:] = start.lam.x.array
    system.u_D0[:] = start.u.x.array


def _path(system: FiniteStrainSystem, factors: list[float], options: Any, max_cuts: int,
          callback: Callback | None) -> FiniteStrainPath:
    """The steps of :func:`solve_path` (module docstring), halving failed ones."""
    path = FiniteStrainPath([], factors)
    done = 0.0
    for target in factors:
        tic = time.perf_counter()
        record = FiniteStrainStep(target, 0, [], [], 0.0)
        cuts, h = 0, target - done
        while done < target:
            t = min(target, done + h / 2 ** cuts)
            saved = system.u.x.array.copy(), system.lam.x.array.copy()
            try:
                history = newton(system, t, options.max_iterations, options.rtol)
            except ConvergenceError as error:
                record.newton_iterations += max(len(error.history) - 1, 0)
                system.u.x.array[:], system.lam.x.array[:] = saved
                cuts += 1
                record.cuts.append(t)
                if cuts > max_cuts:
                    raise
                continue
            record.newton_iterations += len(history) - 1
            record.steps.append(t)
            done = t
        record.seconds = system.disc.comm.bcast(time.perf_counter() - tic, root=0)
        path.cuts += record.cuts
        path.steps += record.steps
        path.records.append(record)
        path.solutions.append(solution_from(system, history, target))
        if callback is not None:
            callback(record, path.solutions[-1], None)
    return path


def path_entry(problem: Any, goal: Any, load_factors: Any, ncp_scale: Any, petsc_options: Any,
               method: Any, adaptive: bool, initial_guess: Any = None,
               callback: Callback | None = None) -> FiniteStrainPath:
    """:func:`dwr_signorini.solve_path` with ``load_factors``: checks, then :func:`solve_path`.

    ``initial_guess`` is its ``start``.

    Raises:
        ValueError: ``problems`` not one finite-strain problem, no ``load_factors``, a goal
            (estimate each state with :func:`~dwr_signorini.estimate` instead) or ``adaptive``.
    """
    from .settings import SolverOptions

    if not getattr(problem, "finite_strain", False) or load_factors is None:
        raise ValueError(
            "solve_path(problem, None, load_factors=[...]) takes one finite-strain problem "
            "(a hyperelastic material) and its load factors; a linear path is a sequence of "
            "problems without load_factors"
        )
    if goal is not None or adaptive:
        refuse("solve_path with a goal or adaptive=True")
    options = check_options(SolverOptions(petsc_options, method, ncp_scale))
    return solve_path(problem, load_factors, options, start=initial_guess, callback=callback)
