"""The settings of a solve, of an estimate and of a run's stopping, each validated where made.

:class:`SolverOptions` are what :func:`~dwr_signorini.solve` takes besides the problem and the
initial guess, :class:`EstimateOptions` what :func:`~dwr_signorini.estimate` takes besides the
solution and the goal, and :class:`StopRule` when :func:`~dwr_signorini.solve_adaptive` stops
(its marking is a :class:`~dwr_signorini.marking.MarkingRule`). The entry points build them from
their keyword arguments, so a mistake is reported before any work, naming the argument; a run
builds them once and hands them to every level or load step.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .algebra import check_ncp_scale
from .linalg import METHODS

__all__ = ["ESTIMATORS", "WEIGHTS", "EstimateOptions", "SolverOptions", "StopRule"]

#: The ``estimator`` choices of :func:`~dwr_signorini.estimate` and ``solve_adaptive``:
#: ``"eta"`` (primal and dual residual, eq. 15) and ``"eta_p"`` (primal residual, eq. 13).
ESTIMATORS = ("eta", "eta_p")
#: The ``weights`` choices of :func:`~dwr_signorini.estimate` and ``solve_adaptive``: ``"auto"``
#: (the patch weights, and the hierarchical P2 ones on a level whose contact set is not
#: resolved), the paper's patch-wise reconstructions, P2 solutions by a factorisation, or the
#: same P2 solutions by FGMRES with the Newton factorisation as coarse level.
WEIGHTS = ("auto", "patch", "higher_order", "hierarchical", "local")


def _check_petsc_options(petsc_options: Any) -> None:
    if petsc_options is not None and not isinstance(petsc_options, dict):
        raise TypeError(
            "petsc_options must be a dict of PETSc options such as {'pc_type': 'lu'}, got "
            f"{type(petsc_options).__name__}"
        )


@dataclass(frozen=True)
class SolverOptions:
    """The options of the semi-smooth Newton method (:func:`~dwr_signorini.solve`).

    Attributes:
        petsc_options: Options of the linear solver, merged on top of
            :func:`~dwr_signorini.linalg.default_petsc_options`, under
            ``petsc_options_prefix``. They win over the command line for the same key; the
            command line wins over the defaults. They stay in PETSc's options database until
            :meth:`~dwr_signorini.Solution.destroy`.
        method: Linear solver of the Newton steps, one of
            :data:`~dwr_signorini.linalg.METHODS`, or ``None`` (chosen per solve; see
            :func:`~dwr_signorini.solve`).
        ncp_scale: c of the NCP function (20), the same for the Newton method, the dual
            problem and the estimator (:mod:`dwr_signorini.residuals`): ``"physical"``
            (c_n,i = E / H_i on macro contact facet i, invariant under a change of units) or a
            number c > 0 (c_n,i = c; the paper's c = 1 reproduces its Tables 1-2); stored as
            a float.
        max_iterations: Most Newton steps before giving up.
        rtol: Tolerance at convergence on the equilibrium residual, relative to the size of
            its terms (max of ``||K|| ||u||``, ``||N^T lam||``, ``||f||``: a backward error,
            which does not grow with lambda/mu or mesh grading), and on the NCP residual (20),
            entry by entry relative to ``|M lam|_i + c_n,i (M_i max|u| + |g_i|)``.
        petsc_options_prefix: Base options prefix of the solve (default: a new unique
            ``dwr_signorini_<n>_``); inner solvers use sub-prefixes
            (:mod:`dwr_signorini.linalg.options`), so e.g. ``-<prefix>ksp_view`` on the
            command line takes effect.
        form_compiler_options: Passed to ``dolfinx.fem.form`` for the forms of the Newton
            system (as dolfinx's ``LinearProblem`` takes them).
        jit_options: Passed to ``dolfinx.fem.form`` likewise.

    Raises:
        TypeError, ValueError: An option of the wrong type or value, naming it.
    """

    petsc_options: dict[str, Any] | None = None
    method: str | None = None
    ncp_scale: str | float = "physical"
    max_iterations: int = 50
    rtol: float = 1e-8
    petsc_options_prefix: str | None = None
    form_compiler_options: dict[str, Any] | None = None
    jit_options: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        it = self.max_iterations
        if isinstance(it, bool) or not isinstance(it, int) or it < 1:
            raise ValueError(f"max_iterations must be a positive integer, got {it!r}")
        object.__setattr__(self, "ncp_scale", check_ncp_scale(self.ncp_scale))
        rtol = self.rtol
        if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 < rtol < np.inf:
            raise ValueError(f"rtol must be a finite number > 0, got {rtol!r}")
        if self.method is not None and self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS} or None, got {self.method!r}")
        for name, value in (
            ("form_compiler_options", self.form_compiler_options),
            ("jit_options", self.jit_options),
        ):
            if value is not None and not isinstance(value, dict):
                raise TypeError(f"{name} must be a dict, got {type(value).__name__}")
        _check_petsc_options(self.petsc_options)
        prefix = self.petsc_options_prefix
        if prefix is not None and (
            not isinstance(prefix, str) or not prefix or not prefix.endswith("_")
        ):
            raise ValueError(
                "petsc_options_prefix must be a non-empty string ending with '_' (e.g. "
                f"'contact_') or None, got {prefix!r}"
            )

    @property
    def compile_options(self) -> dict[str, Any]:
        """The keyword arguments of ``dolfinx.fem.form`` for the Newton system's forms."""
        return {
            "form_compiler_options": self.form_compiler_options,
            "jit_options": self.jit_options,
        }


@dataclass(frozen=True)
class EstimateOptions:
    """The options of the error estimate (:func:`~dwr_signorini.estimate`).

    Attributes:
        estimator: One of :data:`ESTIMATORS`: ``"eta"`` (primal and dual residual, (15)) or
            ``"eta_p"`` (primal residual, (13)). eta_p is reported in both cases.
        weights: One of :data:`WEIGHTS` (see :func:`~dwr_signorini.estimate`).
        petsc_options: Linear solver options for the higher-order solves, which use the
            primal's kind of Newton system (block, or Schur complement with these options for
            K, e.g. :func:`~dwr_signorini.linalg.iterative_petsc_options`), under the options
            prefix ``<prefix of the solve>p2_``.
        quadrature_degree: Quadrature degree of the non-polynomial residual integrals (data);
            polynomial ones are integrated exactly (:mod:`dwr_signorini.quadrature`). The
            default, ``"problem"``, is the degree the solver integrated the load and gap with
            (the problem's ``quadrature_degree``, 8 unless set), so that the residual vanishes
            on discrete test functions (Galerkin orthogonality). ``None`` lets UFL estimate
            every degree, which is very expensive for non-polynomial data. On example 5.1
            degrees 4, 6, 8 and UFL's estimate give the same Ieff to 6 digits.

    Raises:
        TypeError, ValueError: An option of the wrong type or value, naming it.
    """

    estimator: str = "eta"
    weights: str = "auto"
    petsc_options: dict[str, Any] | None = None
    quadrature_degree: int | str | None = "problem"

    def __post_init__(self) -> None:
        if self.estimator not in ESTIMATORS:
            raise ValueError(f"estimator must be one of {ESTIMATORS}, got {self.estimator!r}")
        if self.weights not in WEIGHTS:
            raise ValueError(f"weights must be one of {WEIGHTS}, got {self.weights!r}")
        _check_petsc_options(self.petsc_options)
        degree = self.quadrature_degree
        if isinstance(degree, str) and degree == "problem":
            return
        if degree is not None and (
            isinstance(degree, bool) or not isinstance(degree, int) or not 0 <= degree <= 30
        ):
            raise ValueError(
                "quadrature_degree must be an integer in [0, 30] or None, or 'problem' (the "
                f"default), got {degree!r}"
            )

    def degree(self, problem: Any) -> int | None:
        """The quadrature degree for a solution of ``problem`` (``"problem"`` resolved)."""
        if isinstance(self.quadrature_degree, str):
            return problem.quadrature_degree
        return self.quadrature_degree


@dataclass(frozen=True)
class StopRule:
    """When an adaptive run stops: after ``max_levels``, above ``max_cells``, or at ``tol``.

    Attributes:
        max_levels: Number of levels (solves) at most.
        max_cells: Stop before a level whose fine mesh would exceed this many cells, or None.
        tol: Stop when the interval for J is at most ``2 tol`` wide, J_high - J_low <= 2 tol
            (:attr:`~dwr_signorini.Estimate.interval`, which contains the active-set
            remainder R_A of Proposition 4, large while the contact set is not resolved), or
            None (no convergence test).

    Raises:
        ValueError: A limit of the wrong type or value, naming it.
    """

    max_levels: int = 8
    max_cells: int | None = None
    tol: float | None = None

    def __post_init__(self) -> None:
        max_levels, max_cells, tol = self.max_levels, self.max_cells, self.tol
        if isinstance(max_levels, bool) or not isinstance(max_levels, int) or max_levels < 1:
            raise ValueError(f"max_levels must be an integer >= 1, got {max_levels!r}")
        if max_cells is not None and (
            isinstance(max_cells, bool) or not isinstance(max_cells, int) or max_cells < 1
        ):
            raise ValueError(f"max_cells must be a positive integer or None, got {max_cells!r}")
        if tol is not None and (not isinstance(tol, (int, float)) or not tol > 0):
            raise ValueError(f"tol must be a positive number or None, got {tol!r}")

    def converged(self, interval: tuple[float, float]) -> bool:
        """Whether the interval ``(J_low, J_high)`` for J is at most ``2 tol`` wide."""
        J_low, J_high = interval
        return self.tol is not None and J_high - J_low <= 2 * self.tol

    def too_many_cells(self, next_cells: int) -> bool:
        """Whether a next level of ``next_cells`` fine cells would exceed ``max_cells``."""
        return self.max_cells is not None and next_cells > self.max_cells

    def explain(self, num_levels: int, width: float, stopped_by: str, next_cells: int) -> str:
        """The one line that says why a run stopped (``tol``, ``max_levels`` or ``max_cells``).

        Args:
            num_levels: The levels the run solved.
            width: J_high - J_low on the last level.
            stopped_by: ``"tol"``, ``"max_levels"`` or ``"max_cells"``.
            next_cells: The fine cells the level after the last would have had.

        Returns:
            The line, without a newline.
        """
        n = f"{num_levels} level" + ("s" if num_levels != 1 else "")
        if stopped_by == "tol":
            return (
                f"converged after {n}: J_high - J_low = {width:.3e} <= 2 tol = "
                f"{2 * self.tol:.3e}"
            )
        if stopped_by == "max_cells":
            limit = (
                f"max_cells = {self.max_cells} reached (the next level would have "
                f"{next_cells} cells)"
            )
        else:
            limit = f"max_levels = {self.max_levels} reached"
        if self.tol is None:
            return f"stopped after {n}: {limit}; no tol given, so no convergence test"
        return (
            f"not converged: J_high - J_low = {width:.3e} > 2 tol = {2 * self.tol:.3e} after "
            f"{n}: {limit}"
        )

