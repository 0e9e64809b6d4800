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
as the intervals hold. This switch is global (every contact facet takes the richer law).

Per region (``model_regions=True``, models [frictionless, Coulomb(mu)]; Rademacher, Numer.
Math. 2019) a level runs Coulomb on a set R of macro contact facets and frictionless elsewhere,
the law Coulomb(mu chi_R) of (M4) (:mod:`dwr_signorini.model_regions`), and is not solved again:
where (M2) fails, the facets outside R with the largest model indicators |eta_M,i| (the summands
of (M1) per macro contact facet) join R for the next level,

    R <- R + {i not in R : |eta_M,i| >= t},                                         (M5)

t the threshold of the run's marking rule (:func:`~dwr_signorini.marking.threshold`: Doerfler's
fewest facets holding ``fraction`` of sum |eta_M,i|, or the ``fraction`` of facets with the
largest ones; the same code as the marking of cells). The first level runs frictionless (R
empty); R is carried to the refined facets by their parents; where R holds every facet the level
runs Coulomb itself (B_M = 0). The run stops by (M3). The facets of R still have the tangential
rows of the Newton matrix: a facet outside R has lambda_t = 0 through mu = 0 there, not fewer
unknowns; what R saves is the stick/slip sets where friction is left out.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import Any

import numpy as np

from .collective import on_root
from .driver import LevelSettings
from .estimator import Estimate
from .goal import Goal
from .io import write_json
from .laws import Coulomb
from .marking import TIE_TOLERANCE, MarkingRule, threshold
from .model_error import check_richer, law_phrase
from .model_regions import RegionMap, RegionMu, flag_function, model_label, num_rich
from .newton import Solution
from .problem import SignoriniProblem
from .spaces import Discretization

__all__ = [
    "ModelChoice", "check_models", "check_regions", "explain", "model_bound", "write_model_map",
]

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


def check_regions(models: tuple[SignoriniProblem, ...], regions: Any) -> bool:
    """Check ``model_regions`` of ``solve_adaptive``: a bool; True needs [frictionless, Coulomb].

    Args:
        models: The checked models (:func:`check_models`).
        regions: ``model_regions``.

    Returns:
        ``regions``.
    """
    if not isinstance(regions, bool):
        raise TypeError(f"model_regions must be True or False, got {regions!r}")
    if not regions:
        return False
    laws = [m.law for m in models]
    if (
        len(laws) != 2 or laws[0].name != "frictionless" or not isinstance(laws[1], Coulomb)
        or isinstance(laws[1].data, dict)
    ):
        raise ValueError(
            "model_regions needs models=[frictionless, Coulomb(mu)] with mu a number or a "
            f"callable of x, got {[repr(law) for law in laws]}"
        )
    return True


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
        index: The model in force (per region: 1 where R holds every facet, else 0).
        regions: Whether the model is chosen per contact facet ((M4), (M5)).
        marking: The run's marking rule; per region it marks the facets of (M5).
        region: Per region: R of the last level with the facets that join it, or None.
        maps: Per region: the model map of every level (:meth:`RegionMap.as_dict`).
    """

    models: tuple[SignoriniProblem, ...]
    tol: float
    share: float = 0.5
    index: int = 0
    regions: bool = False
    marking: MarkingRule | None = None
    region: RegionMap | None = None
    maps: list[dict[str, Any]] = field(default_factory=list)

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
        """``problem`` (a level's) with the law and material of the model in force.

        Args:
            problem: A level's problem.

        Returns:
            ``problem`` itself if it has them, else its data with them.
        """
        model = self.models[self.index]
        if problem.law is model.law and problem.material_law == model.material_law:
            return problem
        return problem.with_mesh(problem.mesh, problem.facet_tags, problem.cell_tags,
                                 law=model.law, material=model.material_law)

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
        if self.regions:
            return self._solve_region_level(base, disc, guess, goal, say, level)
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


    def _solve_region_level(
        self,
        base: LevelSettings,
        disc: Discretization,
        guess: tuple[Any, ...] | None,
        goal: Goal,
        say: Callable[[str], None],
        level: int,
    ) -> tuple[Solution, Estimate, float, Discretization]:
        """:meth:`solve_level` per region: the level runs Coulomb(mu chi_R) once, (M5) for R."""
        chi = flag_function(disc, np.zeros(disc.Q.dofmap.index_map.size_local))
        if self.region is not None:
            chi = self.region.indicator(disc)
        disc = disc.for_problem(self._regional(disc.problem, chi))
        num = len(disc.problem.law.components(disc.mesh.topology.dim))
        guess = None if guess is None else tuple(guess[: 1 + num])
        sol, est, seconds = self.settings(base).solve_and_estimate(disc, guess, goal)
        ran = RegionMap.gather(disc, chi.x.array[: disc.Q.dofmap.index_map.size_local] != 0)
        self.maps.append(ran.as_dict(level))
        self.region = self._grown(disc, ran, est, say, level)
        return sol, est, seconds, disc

    def _regional(self, problem: SignoriniProblem, chi: Any) -> SignoriniProblem:
        """``problem`` with the law of (M4) on R = {chi = 1}; sets :attr:`index`.

        Frictionless where R is empty, Coulomb(mu) where it holds every facet (the models'
        own laws), else Coulomb(mu chi_R).
        """
        simple, rich = (m.law for m in self.models)
        inside, total = num_rich(chi, problem.mesh.comm)
        self.index = int(inside == total)
        law = simple if inside == 0 else rich if inside == total else Coulomb(
            RegionMu(rich.data, chi)
        )
        return problem.with_mesh(problem.mesh, problem.facet_tags, problem.cell_tags, law=law)

    def _grown(
        self, disc: Discretization, ran: RegionMap, est: Estimate, say: Callable, level: int
    ) -> RegionMap:
        """R for the next level: (M5) where (M2) and (M3) fail, else R as it ran."""
        if self.settled(est) or self.converged(est):
            return ran
        n_q = disc.Q.dofmap.index_map.size_local
        offset = sum(disc.comm.allgather(n_q)[: disc.comm.rank])  # ran is in rank order
        inside = ran.rich[offset : offset + n_q]
        values = np.where(inside, 0.0, np.abs(est.model.facet_indicators.x.array[:n_q]))
        rule = self.marking or MarkingRule("doerfler", 0.5, None)
        least = threshold(disc.comm, values, rule.strategy, rule.fraction or 0.5)
        joins = (values >= least * (1.0 - TIE_TOLERANCE)) & (values > 0.0)
        grown = RegionMap(ran.facets, np.concatenate(disc.comm.allgather(inside | joins)))
        say(self._switch_line(level, est, f"coulomb on {grown.share:.0%} of Gamma_C"))
        return grown

    def base(self, problem: SignoriniProblem) -> SignoriniProblem:
        """The problem a level refines: per region with the simplest law, else ``problem``.

        Per region R moves to the next level by :attr:`region`, not by the law.

        Args:
            problem: The level's problem.

        Returns:
            The problem to refine.
        """
        if not self.regions or problem.law is self.models[0].law:
            return problem
        law = self.models[0].law
        return problem.with_mesh(problem.mesh, problem.facet_tags, problem.cell_tags, law=law)

    def annotate(self, record: Any) -> None:
        """Set ``record.rich_share``: the share of Gamma_C (by measure) on the richest law.

        Args:
            record: The level's :class:`~dwr_signorini.report.LevelRecord`.
        """
        record.rich_share = self.maps[-1]["share"] if self.regions else float(self.last)

    def _switch_line(self, level: int, est: Estimate, then: str | None = None) -> str:
        """The line that says why a level runs a richer model: again (``then`` None) or next."""
        rich = model_label(self.models[self.index + 1])
        low, high = est.model_error_interval
        return (
            f"level {level:2d}  J in [{est.interval[0]: .6e}, {est.interval[1]: .6e}]; model "
            f"error of {law_phrase(model_label(self.models[self.index]), rich)}: "
            f"{est.model_error: .3e} in [{low: .3e}, {high: .3e}], above {self.share:g} tol = "
            f"{self.share * self.tol:.3e}: "
            + (f"solved again with {rich}" if then is None else f"next level {then}")
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
    name = model_label(choice.models[choice.index])
    if choice.regions:
        name = f"coulomb on {choice.maps[-1]['share']:.0%} of Gamma_C"
    return f"; model {name}, |model error| <= {model_bound(est):.3e}"


def write_model_map(reporter: Any, maps: list[dict[str, Any]]) -> None:
    """Write a per-region run's model map to its output directory: JSON and PNG (collective).

    Args:
        reporter: The run's :class:`~dwr_signorini.report.Reporter` (nothing without an
            ``output_dir``).
        maps: :attr:`ModelChoice.maps`.
    """
    if reporter.out is None:
        return
    path = reporter.out.path

    def write() -> None:
        from .viz.models import plot_model_map

        write_json(path / "model_map.json", {"levels": maps})
        plot_model_map(maps, path / "model_map.png")

    on_root(reporter.comm, "model_map", write)
