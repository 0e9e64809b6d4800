"""One level (or load step) of a run, as both loops take it: solve, estimate, refine, its row.

:func:`~dwr_signorini.solve_adaptive` (the loop over levels, :mod:`dwr_signorini.adapt`) and
:func:`~dwr_signorini.solve_path` (the loop over load steps, :mod:`dwr_signorini.path`) hold
one :class:`LevelSettings` each, made once from their arguments, and report every level through
one :class:`~dwr_signorini.report.Reporter`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh

from .estimate_parts import SolverBudget, keep_estimate_parts
from .estimator import Estimate, estimate
from .goal import Goal
from .marking import MarkingRule, refine_level
from .newton import Solution, solve
from .problem import SignoriniProblem
from .report import LevelRecord, level_record
from .settings import EstimateOptions, SolverOptions
from .spaces import Discretization

__all__ = ["LevelSettings", "check_simplex"]


def check_simplex(problem: SignoriniProblem, refinement: str) -> None:
    """Check that a run that refines adaptively has a simplex mesh.

    Args:
        problem: The run's first problem.
        refinement: ``"adaptive"`` or ``"uniform"``.

    Raises:
        ValueError: Adaptive refinement of a quadrilateral or hexahedral mesh.
    """
    simplex = problem.mesh.topology.cell_type in (
        dmesh.CellType.triangle,
        dmesh.CellType.tetrahedron,
    )
    if refinement == "adaptive" and not simplex:
        raise ValueError(
            "adaptive refinement needs a simplex mesh (triangles/tetrahedra); "
            "quadrilateral/hexahedral meshes support refinement='uniform' only"
        )


@dataclass(frozen=True)
class LevelSettings:
    """What every level of a run is solved, estimated and refined with.

    Attributes:
        solver: The options of :func:`~dwr_signorini.solve`.
        estimate: The options of :func:`~dwr_signorini.estimate`.
        marking: How the macro cells are marked (adaptive refinement), or None.
        refinement: ``"adaptive"`` or ``"uniform"``.
        refinement_rule: ``"edges"`` or ``"longest_edge"``
            (:func:`~dwr_signorini.refine.marked_edges`).
        exact: The exact J, if known: fills the rows' rel_error and effectivity indices.
        model_error: The problem with a richer contact law whose model error every level
            estimates (:mod:`~dwr_signorini.model_error`), or None.
    """

    solver: SolverOptions
    estimate: EstimateOptions
    marking: MarkingRule | None = None
    refinement: str = "adaptive"
    refinement_rule: str = "edges"
    exact: float | None = None
    model_error: SignoriniProblem | None = None

    def richer(self, problem: SignoriniProblem) -> SignoriniProblem | None:
        """The richer problem of :attr:`model_error` on ``problem``'s macro mesh, or None.

        Args:
            problem: The level's problem.

        Returns:
            :attr:`model_error` itself on its own mesh, else the same data with its law and
            material on ``problem``'s (refined) mesh.
        """
        rich = self.model_error
        if rich is None or rich.mesh is problem.mesh:
            return rich
        return problem.with_mesh(
            problem.mesh, problem.facet_tags, problem.cell_tags, law=rich.law,
            material=rich.material_law,
        )

    def solve_and_estimate(
        self, disc: Discretization, guess: tuple[Any, ...] | None, goal: Goal,
        keep_parts: SolverBudget | None = None,
        earlier: tuple[Solution, ...] | None = None,
        richer: Any = None,
    ) -> tuple[Solution, Estimate, float]:
        """Solve the level from ``guess`` and estimate ``goal`` (collective).

        Args:
            disc: The level's discretisation.
            guess: The initial iterate, or None.
            goal: The quantity of interest.
            keep_parts: Keep the estimate's goal-independent parts with the solution, for
                estimates of other goals at it (:mod:`~dwr_signorini.estimate_parts`), its P2
                solvers within this budget; None: not kept.
            earlier: The earlier steps of a load path the solution lists
                (:attr:`~dwr_signorini.Solution.earlier`), or None.
            richer: The richer model of the estimate's model error, in place of
                :meth:`richer` (e.g. a richer path's problems, eq. (M7)), or None.

        Returns:
            The solution, its estimate and the seconds of the solve. On a failure of the
            estimate the solution is released before the error is raised.
        """
        tic = time.perf_counter()
        sol = solve(disc, initial_guess=guess, options=self.solver)
        t_solve = time.perf_counter() - tic
        if earlier is not None:
            sol.earlier = earlier
        if richer is None:
            richer = self.richer(disc.problem)
        try:
            if keep_parts is not None:
                keep_estimate_parts(sol, keep_parts)
            est = estimate(sol, goal, options=self.estimate, model_error=richer)
        except BaseException:
            sol.destroy()
            raise
        return sol, est, t_solve

    def refine(
        self, disc: Discretization, problem: SignoriniProblem, est: Estimate
    ) -> tuple[np.ndarray, SignoriniProblem, Any]:
        """Mark and refine the level's macro mesh (:func:`~dwr_signorini.marking.refine_level`).

        Args:
            disc: The level's discretisation.
            problem: The level's problem.
            est: Its estimate (the indicators).

        Returns:
            The marked macro cells, the problem on the refined macro mesh and the parent map.
        """
        return refine_level(
            disc, problem, est, self.refinement, self.marking, self.refinement_rule
        )

    def record(
        self,
        level: int,
        disc: Discretization,
        sol: Solution,
        est: Estimate,
        marked: np.ndarray,
        times: dict[str, float],
    ) -> LevelRecord:
        """The level's row (:func:`~dwr_signorini.report.level_record` with :attr:`exact`).

        Args:
            level: The refinement level.
            disc: The level's discretisation.
            sol: Its solution.
            est: Its estimate.
            marked: The macro cells marked on this rank.
            times: Seconds of ``setup``, ``solve`` and ``refine``.

        Returns:
            The row, without the ``total`` time.
        """
        return level_record(level, disc, sol, est, marked, times, self.exact)
