"""A rigid obstacle that moves between the steps of a frictional load path.

The slip of a frictional step is the tangential displacement of the body relative to the
obstacle. A rigid obstacle translated by t_k between steps k - 1 and k (step k's obstacle is
step k - 1's moved, :meth:`~dwr_signorini.obstacles.Obstacle.translation_from`) moves every
one of its points by t_k, so the slip increment of step k is

    (u - u_old - t_k) . e_l,    e_l the tangents of the contact frame
    (:meth:`~dwr_signorini.spaces.Discretization.contact_frame`),

the tangential offsets g_l = B_l (u_old + t_k) (:meth:`~dwr_signorini.spaces.Discretization.
slip_origin`). Moving the obstacle by t_k or the body by -t_k (its prescribed displacements)
then gives the same tractions: a change of frame. t_k is data, a constant offset: the Newton
matrix, the dual problem and the history's goal
(:func:`~dwr_signorini.path_history.history_goal`, the derivative in u_old) are unchanged,
and the estimator's residuals take the same offsets.

Where the obstacle changes between frictional steps in any other way, the slip relative to it
is not defined and :func:`path_translations` refuses the path, except where the change leaves
the slip unaffected by construction:

- a number gap changed: a flat obstacle at distance g along the body's normal n, whose contact
  frame is n itself, moved along n (no tangential part);
- the same object (gap, callable or obstacle) at both steps: no motion.

A force-controlled obstacle moves by its unknown displacement delta d within a step, from
delta_0 (0 in a single solve and on a path's first step, else the previous step's converged
delta): its motion in step k is t_k + (delta_k - delta_(k-1)) d, t_k the translation of its
given position, and the slip offsets g_l = B_l (u_old + t_k + (delta - delta_0) d) depend
on the unknown delta (:meth:`~dwr_signorini.fields.MeshFields.obstacle_motion`, the bordered
Newton step of :mod:`~dwr_signorini.force`). A frictional path refuses a force-controlled
obstacle whose direction d changes from step to step, or that is under a given force at one
step and given by its position at the next (its position there would not include the
previous step's delta). Contact pairs carry their relative motion in u and are unaffected.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .obstacles import Obstacle
from .problem import SignoriniProblem
from .validation import is_real

__all__ = ["path_translations", "step_translation"]

#: The translation of the obstacle of each rigid contact tag between two steps.
Translation = dict[int, np.ndarray]


def path_translations(problems: Sequence[SignoriniProblem]) -> list[Translation | None]:
    """Each step's obstacle translation from the step before (None: none moved).

    Args:
        problems: The steps of a load path (validated: one mesh, the same tags and law).

    Returns:
        One entry per step: None for the first step, for a frictionless law (no slip) and
        where no obstacle moved tangentially; else ``{rigid contact tag: t_k}``.

    Raises:
        ValueError: A frictional step whose obstacle is not the previous step's translated
            (module docstring), naming the step and the contact tag.
    """
    out: list[Translation | None] = [None] * len(problems)
    if not problems[0].law.frictional:
        return out
    for k, problem in enumerate(problems):
        if k > 0:
            out[k] = step_translation(problems[k - 1], problem, k)
    return out


def step_translation(
    previous: SignoriniProblem, current: SignoriniProblem, step: int
) -> Translation | None:
    """The translation of the obstacle of each rigid contact tag from ``previous``.

    Args:
        previous: Step k - 1's problem.
        current: Step k's problem (the same contact tags).
        step: k, for the error message.

    Returns:
        ``{tag: t}`` over the rigid contact tags, or None where every t is zero.

    Raises:
        ValueError: The obstacle of a tag is not the previous one translated.
    """
    _check_forced(previous, current, step)
    dim = current.mesh.geometry.dim
    moves = {}
    for tag in current.rigid_tags:
        old, new = _gap_of(previous, tag), _gap_of(current, tag)
        t = _translation(old, new)
        if t is None:
            raise ValueError(
                f"solve_path: step {step}'s gap on contact tag {tag} ({new!r}) is not step "
                f"{step - 1}'s ({old!r}) translated, so the slip of a frictional step cannot "
                "be measured relative to the obstacle: give every step the same obstacle, or "
                "one moved rigidly (the same kind, size and orientation at a moved point, "
                "Obstacle.translation_from), or hold the obstacle and move the body"
            )
        moves[tag] = np.zeros(dim) if t.size == 0 else t[:dim]
    if not any(np.any(t != 0.0) for t in moves.values()):
        return None
    return moves


def _check_forced(previous: SignoriniProblem, current: SignoriniProblem, step: int) -> None:
    """Refuse a force-controlled obstacle whose motion across steps is not delta along one d.

    Raises:
        ValueError: Step k - 1's obstacle is under a given force and step k's is not, or
            their directions of approach differ (module docstring).
    """
    old, new = previous.force_obstacle, current.force_obstacle
    if old is None:
        return
    if new is None or not np.allclose(old.direction, new.direction, rtol=0.0, atol=1e-12):
        raise ValueError(
            f"solve_path: step {step - 1}'s obstacle {old!r} is under a given force and step "
            f"{step}'s ({new!r}) is not, or has another direction of approach: with friction "
            "the slip is measured from the obstacle's position at the previous step, which "
            "its displacement along its direction then does not give; keep the obstacle under "
            "a (possibly other) force along the same direction on the following steps"
        )


def _gap_of(problem: SignoriniProblem, tag: int) -> Any:
    """The gap of contact tag ``tag`` (a number, a callable or an obstacle)."""
    gap = problem.gap
    return gap[tag] if isinstance(gap, Mapping) else gap


def _translation(old: Any, new: Any) -> np.ndarray | None:
    """The translation from gap ``old`` to ``new``; empty for none; None if not a translate."""
    if new is old or (is_real(old) and is_real(new)):
        return np.zeros(0)
    if isinstance(old, Obstacle) and isinstance(new, Obstacle):
        return new.translation_from(old)
    return None
