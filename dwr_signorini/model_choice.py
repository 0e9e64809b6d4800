r"""Mesh and model adaptivity: each level solves the cheapest law that the goal needs.

``solve_adaptive(problem, goal, tol=tol, models=[simple, ..., rich])`` (the run of
:mod:`dwr_signorini.adapt`) solves every level with the model in force, ``models[k]``
(``k = 0`` on the first level), estimates its discretisation error and the model error
eta_M of (M1) against the next richer model ``models[k + 1]``
(:mod:`dwr_signorini.model_error`), and keeps the model while the bound of the model error is
below a share ``s`` of the tolerance (theory, "Mesh and model adaptivity"):

    stay on models[k]  iff  B_M = max(|M_low|, |M_high|) <= s tol,                 (M2)

[M_low, M_high] the interval of J(models[k + 1]) - J(models[k]). Otherwise the level is solved
again, on the same mesh, with ``models[k + 1]`` (warm-started from the simpler solution) and
tested again; a run never returns to a simpler model. The run stops when

    (J_high - J_low) / 2 + B_M <= tol                                              (M3)

(B_M = 0 on the richest model): J of the next richer model is then within tol of J_best, so far
as the intervals hold. The switch is global (every contact facet takes the richer law): a law
is one per problem here, and a richer law on part of Gamma_C (the per-facet choice of
Rademacher, Numer. Math. 2019) would still assemble the richer law's Newton matrix everywhere.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any

from .driver import LevelSettings
from .estimator import Estimate
from .goal import Goal
from .model_error import check_richer, law_phrase
from .newton import Solution
from .problem import SignoriniProblem
from .spaces import Discretization

__all__ = ["ModelChoice", "check_models", "explain", "model_bound"]

def check_models(problem: Any, models: Any, tol: Any, share: Any) -> tuple[Any, ...]:
    """Check ``models``, ``tol`` and ``model_share`` of ``solve_adaptive`` (TypeError, ValueError).

    Args:
        problem: The run's problem: must be ``models[0]`` (the same object).
        models: Two or more problems, each the one before with a richer law
            (:func:`~dwr_signorini.model_error.check_richer`).
        tol: The run's tolerance (needed: (M2) compares with it).
        share: s of (M2), in (0, 1).

    Returns:
        ``models`` as a tuple.
    """
    if not isinstance(models, Sequence) or isinstance(models, str) or len(models) < 2:
        raise TypeError(
            f"models must be a list of two or more problems [simple, ..., rich], got {models!r}"
        )
    if models[0] is not problem:
        raise ValueError(
            "models: the first model must be the run's problem (solve_adaptive(simple, goal, "
            "models=[simple, ..., rich]))"
        )
    for simple, rich in pairwise(models):
        check_richer(simple, rich)
    if tol is None:
        raise ValueError("models needs tol: the model error is compared with a share of it")
    if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 < share < 1:
        raise ValueError(f"model_share must be a number in (0, 1), got {share!r}")
    return tuple(models)


def model_bound(est: Estimate) -> float:
    """B_M of (M2): the largest |J(richer) - J(simpler)| of the model error's interval (0 if none).

    Args:
        est: The level's estimate.

    Returns:
        ``max(|M_low|, |M_high|)``, or 0 without a model error.
    """
    interval = est.model_error_interval
    if interval is None:
        return 0.0
    return max(abs(interval[0]), abs(interval[1]))


@dataclass
class ModelChoice:
    """The model in force of a run with ``models`` (module docstring, (M2) and (M3)).

    Attributes:
        models: The problems from the simplest to the richest (on the first macro mesh).
        tol: The run's tolerance.
        share: s of (M2).
        index: The model in force.
    """

    models: tuple[SignoriniProblem, ...]
    tol: float
    share: float = 0.5
    index: int = 0

    @property
    def last(self) -> bool:
        """Whether the model in force is the richest."""
        return self.index == len(self.models) - 1

    def settings(self, base: LevelSettings) -> LevelSettings:
        """``base`` estimating the model error against the next richer model (none on the last).

        Args:
            base: The run's settings.

        Returns:
            A copy of ``base`` with its ``model_error``.
        """
        return replace(base, model_error=None if self.last else self.models[self.index + 1])

    def settled(self, est: Estimate) -> bool:
        """(M2): the model in force serves the goal (always on the richest).

        Args:
            est: The level's estimate, with the model error against the next richer model.

        Returns:
            Whether B_M <= share * tol, or the model in force is the richest.
        """
        return self.last or model_bound(est) <= self.share * self.tol

    def converged(self, est: Estimate) -> bool:
        """(M3): half the interval of J plus the model error's bound at most tol.

        Args:
            est: The level's estimate.

        Returns:
            Whether (J_high - J_low) / 2 + B_M <= tol.
        """
        J_low, J_high = est.interval
        return 0.5 * (J_high - J_low) + model_bound(est) <= self.tol

    def on_model(self, problem: SignoriniProblem) -> SignoriniProblem:
        """``problem`` (a level's) with the law of the model in force.

        Args:
            problem: A level's problem.

        Returns:
            ``problem`` itself if it has that law, else its data with that law.
        """
        law = self.models[self.index].law
        if problem.law is law:
            return problem
        return problem.with_mesh(problem.mesh, problem.facet_tags, problem.cell_tags, law=law)

    def solve_level(
        self,
        base: LevelSettings,
        disc: Discretization,
        guess: tuple[Any, ...] | None,
        goal: Goal,
        say: Callable[[str], None],
        level: int,
    ) -> tuple[Solution, Estimate, float, Discretization]:
        """Solve and estimate a level with the model in force, richer ones until (M2) holds.

        Args:
            base: The run's settings.
            disc: The level's discretisation (of the model in force).
            guess: The initial iterate, or None.
            goal: The quantity of interest.
            say: Reports a switch of the model (one line, rank 0).
            level: The level, for that line.

        Returns:
            The solution, its estimate, the seconds of all solves and the discretisation of the
            model that ran (collective).
        """
        seconds = 0.0
        while True:
            sol, est, t_solve = self.settings(base).solve_and_estimate(disc, guess, goal)
            seconds += t_solve
            if self.settled(est):
                return sol, est, seconds, disc
            say(self._switch_line(level, est))
            self.index += 1
            disc = disc.for_problem(self.on_model(disc.problem))
            guess = _copies(sol)
            est.destroy()
            sol.destroy()


    def _switch_line(self, level: int, est: Estimate) -> str:
        """The line that says why a level is solved again with the next richer model."""
        simple, rich = (self.models[self.index + k].law.name for k in (0, 1))
        low, high = est.model_error_interval
        return (
            f"level {level:2d}  J in [{est.interval[0]: .6e}, {est.interval[1]: .6e}]; model "
            f"error of {law_phrase(simple, rich)}: {est.model_error: .3e} in [{low: .3e}, "
            f"{high: .3e}], above {self.share:g} tol = {self.share * self.tol:.3e}: solved "
            f"again with {rich}"
        )


def _copies(sol: Solution) -> tuple[Any, ...]:
    """(u, lam, lam_t...) of ``sol`` as copies (a warm start on the same spaces)."""
    out = [sol.u.copy(), sol.lam.copy()]
    return tuple(out + [f.copy() for f in (sol.tangential or ())])


def explain(choice: ModelChoice | None, est: Estimate) -> str:
    """The model part of a run's closing line: the model that ran last and its B_M.

    Args:
        choice: The run's model choice, or None (a run without ``models``).
        est: The last level's estimate.

    Returns:
        ``"; model <name>, |model error| <= B_M"``, or ``""`` without ``models``.
    """
    if choice is None:
        return ""
    name = choice.models[choice.index].law.name
    return f"; model {name}, |model error| <= {model_bound(est):.3e}"
