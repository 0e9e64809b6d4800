"""The error the earlier steps of a load path carry into a step's goal (a backward chain of duals).

A frictional step measures its slip from the previous step's displacement u^old
(:mod:`~dwr_signorini.path`), so the error of u^old enters the step's J to first order as
L(u_old - u_old,h), L the sensitivity of J to u^old (:func:`history_goal`). L is a goal of the
previous step, estimated there with its own dual solution, whose sensitivity is a goal of the
step before, back to the first step (:func:`history_estimates`). :func:`history_mode` reads
``solve_path(..., history=)``, :func:`add_history` adds the chain's estimates to a step's record.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .dual import slip_offset_goal
from .estimator import Estimate, estimate
from .goal import Goal
from .newton import Solution
from .settings import EstimateOptions

if TYPE_CHECKING:
    from .path import StepRecord

__all__ = ["HISTORY_MODES", "add_history", "history_estimates", "history_goal", "history_mode"]


HISTORY_MODES = ("last", "every")


def history_mode(history: Any, adaptive: bool, frictional: bool) -> str | None:
    """``history`` of :func:`solve_path` as ``"last"``, ``"every"`` or None (not estimated)."""
    if history is None:  # a frictionless law carries no history (no slip offsets)
        return "last" if frictional and not adaptive else None
    if history is True:
        history = "every"
    if history is False:
        return None
    if not isinstance(history, str):
        raise TypeError(
            f"history must be None, True, False, 'last' or 'every', got {history!r}"
        )
    if history not in HISTORY_MODES:
        raise ValueError(f"history must be None, True, False, 'last' or 'every', got {history!r}")
    if adaptive:
        raise ValueError(
            f"history={history!r} needs every step on one mesh: the history's error is not "
            "estimated on an adaptive path (use history=False or adaptive=False)"
        )
    return history


def history_goal(sol: Solution, est: Estimate) -> Goal:
    """The sensitivity of a step's goal to its history, as a goal of the step before.

    Args:
        sol: The step's solution (its discretisation's meshes are the previous step's).
        est: The estimate of the step's goal (its dual solution).

    Returns:
        ``goal(u, lam, m, lam_t) -> ufl.Form``, L(u).

    A step's tangential offsets are g_l = B_l u_old (the slip increment u - u_old,
    :class:`~dwr_signorini.laws.Coulomb`), so the step's J depends on the previous step's
    displacement. With the step's final sets, the derivative of its right-hand side in g_l is
    -1 on a constrained (sticking) row and -c_f J_kl on the rows k of a coupled (slipping)
    facet, so with the dual solution z (A^T z = J', :func:`~dwr_signorini.dual.solve_dual`)

        J(w(u_old + v)) - J(w(u_old)) = L(v) = - sum_l (w_l, v . e_l)_GC,
        w_l = z_l on the constrained rows, c_f sum_k z_k J_kl on the coupled ones,

    (with contact pairs, v is the relative displacement v - P v of :mod:`~dwr_signorini.pairs`,
    and :class:`~dwr_signorini.goal.GoalForms` adds the master trace's part -P^T to L')

    exactly for the discrete problem while the sets hold (w_l is P0 on the macro facets). Its
    error at the previous step, L(u - u_h), is the part of the step's error that the history
    carries (module docstring).
    """
    return slip_offset_goal(sol.system, sol.stacked(est.dual.multipliers))


def history_estimates(
    kept: list[Solution],
    sol: Solution,
    est: Estimate,
    options: EstimateOptions | dict[str, Any],
) -> list[tuple[float, float, float]]:
    """The error that each earlier step carries into this step's goal, by a backward chain.

    Args:
        kept: The earlier steps' solutions, first step first (on the same meshes).
        sol: This step's solution.
        est: Its estimate.
        options: The options of :func:`~dwr_signorini.estimate`: an
            :class:`~dwr_signorini.settings.EstimateOptions` or its keyword arguments.

    Returns:
        One ``(estimate, low, high)`` per earlier step (last first): the estimated error of the
        history goal and its interval's ends relative to the goal's value.

    From the last step back to the first: the history goal of the later step
    (:func:`history_goal`) is estimated at the earlier one (its own residuals, weighted by the
    dual solution of that goal), and that estimate's dual gives the next goal back. Costs one
    estimate per earlier step (with the earlier step's factorisation), each reusing the parts
    of the step's own estimate that the path kept with its solution
    (:mod:`~dwr_signorini.estimate_parts`).
    """
    if not isinstance(options, EstimateOptions):
        options = EstimateOptions(**options)
    out = []
    later_sol, later_est, owned = sol, est, None
    for earlier in reversed(kept):
        e = estimate(earlier, history_goal(later_sol, later_est), options=options)
        if owned is not None:
            owned.destroy()
        low, high = e.interval
        out.append((e.value, low - e.J_h, high - e.J_h))
        later_sol, later_est, owned = earlier, e, e
    if owned is not None:
        owned.destroy()
    return out


def add_history(step: StepRecord, history: list[tuple[float, float, float]]) -> None:
    """The history's estimated error added to the step's estimate and interval."""
    step.eta_history = sum(h[0] for h in history)
    step.estimate += step.eta_history
    step.J_low += sum(h[1] for h in history)
    step.J_high += sum(h[2] for h in history)
    step.J_best += sum(0.5 * (h[1] + h[2]) for h in history)
