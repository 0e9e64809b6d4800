r"""The error a simpler contact law makes in J along a load path (theory, eq. (M7)).

A frictional law is written for the slip increment of a load step (:mod:`~dwr_signorini.path`):
step k of the richer path solves F_k(w^k; u^(k-1)) = 0, its tangential offsets
g_l = B_l u^(k-1) taken from the previous step. The simpler path (frictionless, or Tresca in
place of Coulomb) has the states w_s^0, ..., w_s^K. Linearised at them, the richer path's
states differ by e^k = w_r^k - w_s^k with

    A_k e^k = -F_k(w_s^k*; u_s^(k-1)) - G_k (u_r^(k-1) - u_s^(k-1)),

A_k the richer law's Newton matrix at w_s^k* (the simpler state with the multipliers it lacks
filled, :mod:`~dwr_signorini.model_error`) and G_k its derivative in u_old. With the goals
J_K = J and J_(k-1) = L_k, the sensitivity of step k's J_k to u_old through the dual z_k of
A_k^T z_k = J_k' (:func:`~dwr_signorini.dual.slip_offset_goal`, the history goal of a path),

    J(w_r^K) - J(w_s^K) ~ eta_M = sum_(k=0)^K eta_M,k(J_k),                            (M7)

eta_M,k(J_k) the model error (M1) of step k for the goal J_k, with the richer step's slip
measured from u_s^(k-1): the richer residual of each simpler step weighted by the chain of
duals solved backward from the last step, as the history's error of a path is
(:func:`~dwr_signorini.path_history.history_estimates`). The goals J_k, k < K, are linear in u, so
their (M1) are their Newton steps; the interval is the sum of the steps' intervals of (M1)
(``value +- r`` where the richer sets settle after the step, ``hull(0, 2 value) +- r`` where
not), and the indicators (per cell and per macro contact facet) the sums of the steps'.

The earlier steps of the simpler path are reachable from its last solution where
:func:`~dwr_signorini.solve_path` kept them (``keep_steps=True``:
:attr:`~dwr_signorini.Solution.earlier`); ``richer`` is the richer path's problems, one per
step, on the same mesh.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import ufl
from dolfinx import fem

from .goal import Goal
from .model_error import ModelError, check_richer, model_error

__all__ = ["any_model_error", "check_model_error", "path_model_error"]


def _is_path(richer: Any) -> bool:
    """Whether ``richer`` is a richer path (a sequence of problems) rather than one problem."""
    return isinstance(richer, Sequence) and not isinstance(richer, str)


def check_model_error(sol: Any, richer: Any) -> None:
    """Check ``richer`` of ``estimate(sol, goal, model_error=richer)`` (TypeError, ValueError).

    One problem (:func:`~dwr_signorini.model_error.check_richer`), or the richer path's
    problems for a load step whose earlier steps the path kept (:func:`path_steps`).

    Args:
        sol: The simpler solution.
        richer: The richer problem, or the richer path's problems.
    """
    if _is_path(richer):
        path_steps(sol, richer)
    else:
        check_richer(sol.disc.problem, richer)


def path_steps(sol: Any, richer: Sequence[Any]) -> list[Any]:
    """The simpler path's steps ending at ``sol``, checked against the richer path's problems.

    Args:
        sol: The last step of the simpler path (its earlier steps in ``sol.earlier``).
        richer: One richer problem per step, the first step first.

    Returns:
        The steps' solutions, the first step first.

    Raises:
        TypeError, ValueError: A count or a mesh that does not match, or a step's richer
            problem that is not its problem with a richer contact law.
    """
    steps = [*sol.earlier, sol]
    if len(richer) != len(steps):
        raise ValueError(
            f"model_error: {len(richer)} richer problems for a path of {len(steps)} steps "
            f"reachable from sol ({len(sol.earlier)} earlier steps; solve_path(..., "
            "keep_steps=True) keeps them): give one richer problem per step, the first first"
        )
    for k, (step, rich) in enumerate(zip(steps, richer, strict=True)):
        if step.disc.V is not sol.disc.V:
            raise ValueError(
                f"model_error: step {k} of the path lives on another mesh than its last step: "
                "the model error along a path needs every step on one mesh (adaptive=False)"
            )
        check_richer(step.disc.problem, rich)
        if rich.finite_strain:
            raise ValueError(
                "model_error: along a load path only a richer contact law is estimated, not a "
                "richer material"
            )
    return steps


def path_model_error(
    sol: Any,
    goal: Goal,
    richer: Sequence[Any],
    localize: Callable[[ufl.Form], np.ndarray],
    roundoff: float = 0.0,
) -> ModelError:
    """eta_M of (M7) for the simpler path ending at ``sol`` and the richer path ``richer``.

    Args:
        sol: The last step's :class:`~dwr_signorini.Solution` of the simpler path, its earlier
            steps in ``sol.earlier`` (:func:`~dwr_signorini.solve_path` with
            ``keep_steps=True``).
        goal: The goal of the last step.
        richer: The richer path's problems, one per step (:func:`path_steps`).
        localize: Cell indicators (on T_h, local array) of a scalar form.
        roundoff: The round-off of J (widens the interval).

    Returns:
        The :class:`~dwr_signorini.model_error.ModelError` of the path (collective); its
        ``steps`` the summands of (M7), the first step first.
    """
    steps = path_steps(sol, richer)
    parts: list[ModelError] = []
    for k in reversed(range(len(steps))):  # backward from the last step, as the duals go
        last = k == len(steps) - 1
        part = model_error(steps[k], goal, richer[k], localize, roundoff if last else 0.0,
                           history=True)
        parts.append(part)
        goal = part.history
    parts.reverse()
    return _summed(parts)


def _summed(parts: list[ModelError]) -> ModelError:
    """The path's :class:`ModelError` from its steps' (the first step first)."""
    last = parts[-1]
    value = sum(p.value for p in parts)
    low = sum(p.interval[0] for p in parts)
    high = sum(p.interval[1] for p in parts)
    cells, facets = (_sum_functions([getattr(p, name) for p in parts])
                     for name in ("indicators", "facet_indicators"))
    return ModelError(
        value=value,
        interval=(low, high),
        indicators=cells,
        facet_indicators=facets,
        law=last.law,
        newton_step=sum(p.newton_step for p in parts),
        num_slip=last.num_slip,
        num_changed=sum(p.num_changed for p in parts),
        steps=tuple(p.value for p in parts),
    )


def _sum_functions(functions: list[fem.Function]) -> fem.Function:
    """The sum of functions on one space (a new function, named as the last)."""
    out = fem.Function(functions[-1].function_space, name=functions[-1].name)
    for f in functions:
        out.x.array[:] += f.x.array
    return out


def any_model_error(
    sol: Any,
    goal: Goal,
    richer: Any,
    localize: Callable[[ufl.Form], np.ndarray],
    roundoff: float = 0.0,
) -> ModelError:
    """(M7) where ``richer`` is a richer path, else (M1) or (M6) of one problem.

    Args:
        sol: The simpler solution (the last step of a path for (M7)).
        goal: The goal.
        richer: The richer problem, or the richer path's problems.
        localize: Cell indicators (on T_h, local array) of a scalar form.
        roundoff: The round-off of J.

    Returns:
        The :class:`~dwr_signorini.model_error.ModelError` (collective).
    """
    if _is_path(richer):
        return path_model_error(sol, goal, richer, localize, roundoff)
    return model_error(sol, goal, richer, localize, roundoff)
