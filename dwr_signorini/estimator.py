"""The error estimators eta_p and eta of Section 4, localised to the cells of T_h.

With w_h = (u_h, lambda_H), z_h = (y_h, xi_H) and the reconstruction operator A,

    eta_p = rho(w_h)(A z_h - z_h) - C(w_h)(xi_H)                                     (from (13))
    eta   = 1/2 rho(w_h)(A z_h - z_h) + 1/2 rho*(w_h, z_h)(A w_h - w_h) - C(w_h)(xi_H)  (from (15))

The residuals rho, rho* and the contact term C, with the scale c of the NCP that the Newton
method used (``Solution.ncp_scale``), are in :mod:`dwr_signorini.residuals`, which derives them.
Every term is a UFL functional; multiplying its integrands by a DG0 test function on T_h gives the
cell indicators (facet terms go to the adjacent cell), whose signed sum is the estimate.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from .agreement import check_options_on_ranks
from .dual import DualSolution, solve_dual
from .estimate_parts import (
    EstimateParts,
    FactoredP2,
    IndicatorForm,
    MasterShare,
)
from .estimate_parts import ncp_scale_function as ncp_scale_function  # re-exported
from .finite_strain import FiniteStrainSolution
from .goal import Goal, GoalForms
from .interval import best_estimate, contact_set_resolved, error_interval, roundoff_bound
from .lifetime import Releasable
from .model_error import ModelError
from .newton import Solution
from .path_model_error import any_model_error, check_model_error
from .quadrature import with_quadrature_degrees
from .reconstruction import Reconstructor
from .settings import EstimateOptions
from .timing import timed
from .weights import nearly_incompressible, p2_kind, second_weights, unresolved_kind

__all__ = ["Estimate", "estimate", "goal_magnitude"]

logger = logging.getLogger(__name__)


def goal_magnitude(goal_forms: GoalForms, degree: int | None) -> float:
    """``int |j|``: the integral of the magnitude of J's integrands at w_h (collective).

    The scale of J_h's round-off (:func:`~dwr_signorini.interval.roundoff_bound`).

    Args:
        goal_forms: J's forms at w_h.
        degree: The quadrature degree of non-polynomial integrands.

    Returns:
        The sum over J's integrals of the integral of the absolute value of the integrand.
    """
    J = goal_forms.J
    form = ufl.Form([itg.reconstruct(integrand=abs(itg.integrand())) for itg in J.integrals()])
    disc = goal_forms.disc
    local = fem.assemble_scalar(disc.form(with_quadrature_degrees(form, degree)))
    return disc.comm.allreduce(float(local), op=MPI.SUM)


@dataclass
class Estimate(Releasable):
    """The estimated error in J and its parts.

    Attributes:
        J_h: J(w_h).
        eta_p: The primal estimator (always computed).
        eta: The primal-dual estimator, or ``None`` when only eta_p was asked for.
        contact_term: C(w_h)(xi_H) (the estimators contain it with a minus sign).
        active_set_remainder: The remainder R_A of Proposition 4 evaluated with
            reconstructions (:func:`~dwr_signorini.residuals.active_set_remainder`): how far
            the contact set is from resolved. Not part of eta_p or eta, and not a bound.
        rho: rho(w_h)(A z_h - z_h).
        rho_star: rho*(w_h, z_h)(A w_h - w_h), or ``None``.
        estimator: Which estimator the indicators belong to ("eta" or "eta_p").
        weights: The weights it was computed with: "patch", "higher_order", "hierarchical"
            or "local". ``weights="auto"`` takes "patch" where the contact set is resolved;
            on a level whose contact set is not (``resolved`` below, with the patch weights)
            "local", the P2 weights on a band around the contact zone
            (:mod:`~dwr_signorini.local_p2`; a contact pair takes the P2 weights of the whole
            mesh); on every level of a nearly incompressible material
            (:func:`nearly_incompressible`, nu >= 0.45) the P2 weights of the whole mesh:
            "hierarchical", but "higher_order" for a law with coupled rows in 3D (Tresca and
            Coulomb friction), where the two-level solver was not faster
            (:func:`~dwr_signorini.weights.p2_kind`).
        indicators: DG0 function on T_h of signed cell indicators; their sum is the estimate.
        dual: z_h = (y_h, xi_H).
        goal_is_linear: Whether J is linear in (u, lambda) (then R_J vanishes).
        resolved: Whether the contact set counts as resolved (``|R_A| + |C| <= |estimate| / 4``
            with the weights first computed,
            :func:`~dwr_signorini.interval.contact_set_resolved`).
        roundoff: The round-off q that J_h and the estimate may carry
            (:func:`~dwr_signorini.interval.roundoff_bound`); it widens the interval.
        weights_fallback: Why ``weights="auto"`` kept the patch weights where it would have
            taken P2 ones (the P2 problem's predicted memory does not fit,
            :func:`~dwr_signorini.weights.p2_weights_fit`), else ``None``.
        model: With ``estimate(..., model_error=richer)``: the estimate of J(richer) -
            J(simpler) at w_h, its interval and indicators
            (:class:`~dwr_signorini.model_error.ModelError`), else ``None``.
    """

    J_h: float
    eta_p: float
    eta: float | None
    contact_term: float
    active_set_remainder: float
    rho: float
    rho_star: float | None
    estimator: str
    weights: str
    indicators: fem.Function = field(repr=False)
    dual: DualSolution = field(repr=False)
    goal_is_linear: bool = False
    timings: dict[str, float] = field(default_factory=dict)
    reconstructor: Reconstructor | None = field(default=None, repr=False)
    resolved: bool = True
    roundoff: float = 0.0
    weights_fallback: str | None = None
    model: ModelError | None = field(default=None, repr=False)
    #: Whether :meth:`destroy` releases the reconstructor: not where it belongs to the parts
    #: that the solution's estimates share (:mod:`~dwr_signorini.estimate_parts`).
    owns_reconstructor: bool = field(default=True, repr=False)

    @property
    def model_error(self) -> float | None:
        """The estimate of J(richer) - J(simpler) at w_h (theory, eq. (M1)), or ``None``."""
        return None if self.model is None else self.model.value

    @property
    def model_error_interval(self) -> tuple[float, float] | None:
        """The interval of J(richer) - J(simpler), or ``None`` (:func:`.model_interval`)."""
        return None if self.model is None else self.model.interval

    def destroy(self) -> None:
        """Release the PETSc objects of the reconstruction (collective; idempotent)."""
        if self.reconstructor is not None and self.owns_reconstructor:
            self.reconstructor.destroy()

    @property
    def value(self) -> float:
        """The estimate of J(w) - J(w_h) of the chosen estimator."""
        return self.eta if self.estimator == "eta" else self.eta_p

    @property
    def interval(self) -> tuple[float, float]:
        """``(J_low, J_high)``: the interval for J(w) of :mod:`~dwr_signorini.interval`.

        J_h + [1/(1 + b), 1/(1 - b)] x the estimate (b = 0.4 where the contact set is
        resolved, 1/2 where not), widened by ``|eta - eta_p| + |R_A|`` on both sides (without the
        first term for ``estimator="eta_p"``).
        """
        eta = self.eta if self.estimator == "eta" else None
        return error_interval(
            self.J_h, eta, self.eta_p, self.active_set_remainder, self.resolved, self.roundoff
        )

    @property
    def J_best(self) -> float:
        """The best estimate of J(w): the interval's centre, J_h corrected by the estimate.

        ``J_h + estimate / (1 - b^2)`` (:func:`~dwr_signorini.interval.best_estimate`); J_h
        itself is often outside :attr:`interval`, which lies on the side the estimate points to.
        """
        return best_estimate(self.J_h, self.value, self.resolved)


def _assemble_indicators(
    disc: Any, forms: list[ufl.Form], DG0: fem.FunctionSpace, degree: int | None
) -> list[np.ndarray]:
    """Cell indicators of each scalar form: its integrands times a DG0 test function (Section 4).

    ``DG0`` is a space on T_h (cell indicators) or on the fine slave facets (facet indicators)
    (:class:`~dwr_signorini.estimate_parts.IndicatorForm`).

    One assembly per form: a fused one would pack the coefficients of all forms for every cell
    at once, a larger array than any single form's, for no gain in time.
    """
    with timed("indicators"):
        return [IndicatorForm(disc, form, DG0, degree).assemble() for form in forms]


def _higher_order_solutions(
    sol: Solution, goal: GoalForms, rec: Reconstructor, primal: bool, petsc_options: Any
) -> tuple[DualSolution, tuple[fem.Function, tuple[fem.Function, ...]] | None]:
    """Dual (and primal) solved in P2 on T_h with Lambda_H and the final active set.

    By one factorisation of the P2 system (:class:`~dwr_signorini.estimate_parts.FactoredP2`),
    released before the return.
    """
    with FactoredP2(sol, rec, petsc_options) as p2:
        return p2.dual(goal), p2.primal if primal else None


@dataclass
class _Inputs:
    """What every kind of weights starts from: w_h, J's forms, z_h, the goal-independent parts.

    ``parts`` (:class:`~dwr_signorini.estimate_parts.EstimateParts`) hold the reconstructor,
    the P2 solvers and the primal weights, made once per solution.
    """

    sol: Solution
    goal_forms: GoalForms
    z: DualSolution
    parts: EstimateParts
    options: EstimateOptions

    @property
    def rec(self) -> Reconstructor:
        """The reconstructor of the solution's parts."""
        return self.parts.rec

    @property
    def want_eta(self) -> bool:
        """Whether eta (and so rho*) is estimated, not eta_p alone."""
        return self.options.estimator == "eta"

    @property
    def petsc_options(self) -> Any:
        """The linear solver options of the higher-order solves."""
        return self.options.petsc_options


def _weights(inp: _Inputs, weights: str) -> tuple[Any, tuple, Any, Any, tuple]:
    """The weights of the estimators: w_y = A y_h - y_h, xi^+, u^+, w_u = A u_h - u_h, lambda^+.

    ``"patch"``: the paper's reconstructions of z_h and w_h; otherwise the P2 solutions of the
    final active set (hierarchical or factored; the multipliers reconstructed patch-wise from
    them). Without eta the P2 primal is not solved and w_h is reconstructed patch-wise. The
    multipliers' reconstructions xi^+ and lambda^+ are tuples, one per component of the law.
    """
    sol, z, rec, want_eta = inp.sol, inp.z, inp.rec, inp.want_eta
    if weights == "patch":
        z2, w2 = z, None
    else:
        z2, w2 = inp.parts.p2_solutions(
            sol, weights, inp.goal_forms, z, want_eta, inp.petsc_options
        )
    with timed("reconstruct"):
        w_y = rec.patch_weight(z.y) if weights == "patch" else rec.weight(z2.y, z.y)
        xi_plus = inp.parts.linear(z2.multipliers)
    u_plus, w_u, lam_plus = inp.parts.primal_weights(sol, weights, want_eta, w2)
    return w_y, xi_plus, u_plus, w_u, lam_plus


@dataclass
class _Terms:
    """The estimators' terms with one kind of weights: totals and cell indicators."""

    weights: str
    rho: float
    rho_star: float | None
    contact: float
    remainder: float
    indicators: np.ndarray

    @property
    def eta_p(self) -> float:
        return self.rho - self.contact

    @property
    def eta(self) -> float | None:
        if self.rho_star is None:
            return None
        return 0.5 * self.rho + 0.5 * self.rho_star - self.contact

    def value(self, estimator: str) -> float:
        return self.eta if estimator == "eta" else self.eta_p


def _terms(
    inp: _Inputs, weights: str, quadrature_degree: int | None, DG0: fem.FunctionSpace
) -> _Terms:
    """rho(w_h)(A z_h - z_h), rho*(w_h, z_h)(A w_h - w_h), C(w_h)(xi_H) and R_A, eq. (13), (15)."""
    sol, z, want_eta = inp.sol, inp.z, inp.want_eta
    disc = sol.disc
    w_y, xi_plus, _, w_u, lam_plus = _weights(inp, weights)
    compiled = inp.parts.residual_forms(sol, weights, want_eta, quadrature_degree)
    with timed("indicators"):
        indicators = compiled.indicators(z, w_y, xi_plus)
    if want_eta:  # the goal's own term of rho*: J'(w_h)(A w_h - w_h, lambda^+ - lambda)
        w_lam = tuple(p - f for p, f in zip(lam_plus, sol.multipliers, strict=True))
        dJ = inp.goal_forms.directional(w_u, *w_lam)
        if dJ is not None:
            (goal_part,) = _assemble_indicators(disc, [dJ], DG0, quadrature_degree)
            with timed("indicators"):
                goal_part += MasterShare(disc, dJ, w_u, DG0, quadrature_degree)()
            indicators[3] += goal_part
    ind_rho, ind_c, ind_a, *rest = indicators
    ind_star = rest[0] if want_eta else None

    def total(a: np.ndarray) -> float:
        return disc.comm.allreduce(float(a.sum()), op=MPI.SUM)

    local = ind_rho - ind_c if ind_star is None else 0.5 * ind_rho + 0.5 * ind_star - ind_c
    return _Terms(
        weights=weights,
        rho=total(ind_rho),
        rho_star=None if ind_star is None else total(ind_star),
        contact=total(ind_c),
        remainder=total(ind_a),
        indicators=local,
    )


def _auto_terms(
    inp: _Inputs,
    estimator: str,
    weights: str,
    quadrature_degree: int | None,
    DG0: fem.FunctionSpace,
    J_h: float,
    roundoff: float,
) -> tuple[_Terms, bool, str | None]:
    """The terms with the weights asked for; ``"auto"`` picks them (see :func:`estimate`).

    Returns:
        The terms, whether the contact set counts as resolved, and why ``"auto"`` kept the
        patch weights where P2 ones did not fit in memory (else ``None``).
    """
    p2 = p2_kind(inp.sol)
    first, fallback = weights, None
    if weights == "auto":
        first = p2 if nearly_incompressible(inp.sol.disc.problem) else "patch"
        if first != "patch":
            fallback = inp.parts.fallback(inp.sol, p2)
            first = "patch" if fallback else first
    terms = _terms(inp, first, quadrature_degree, DG0)
    value = terms.value(estimator)
    resolved = contact_set_resolved(value, terms.remainder, terms.contact, roundoff)
    second = second_weights(terms, estimator, resolved, J_h, roundoff, unresolved_kind(inp.sol))
    if weights == "auto" and first == "patch" and fallback is None and second is not None:
        fallback = inp.parts.fallback(inp.sol, second)
        if fallback is None:
            terms = _terms(inp, second, quadrature_degree, DG0)
    return terms, resolved, fallback


def estimate(
    sol: Solution,
    goal: Goal,
    estimator: str = "eta",
    weights: str = "auto",
    petsc_options: dict[str, Any] | None = None,
    quadrature_degree: int | str | None = "problem",
    *,
    options: EstimateOptions | None = None,
    model_error: Any = None,
) -> Estimate:
    """Estimate J(w) - J(w_h) by eta_p or eta (Section 4), and an interval for J(w).

    Args:
        sol: The discrete solution (its last Newton factorisation serves the dual solve), or
            a finite-strain one (:mod:`~dwr_signorini.finite_strain_estimate`: the dual at
            w_h, the patch weights, the interval widened by the third-order remainder; returns
            its :class:`~dwr_signorini.finite_strain_estimate.FiniteStrainEstimate`).
        goal: ``goal(u, lam, m) -> ufl.Form``.
        estimator: ``"eta"`` (primal and dual residual, (15)) or ``"eta_p"`` (primal residual,
            (13)). eta_p is reported in both cases.
        weights: ``"auto"`` (the default: the patch weights; instead, on a level whose
            contact set is not resolved (see :mod:`~dwr_signorini.interval`), ``"local"`` (the
            P2 weights of the whole mesh for a contact pair); where J_h vanishes to round-off
            while the patch estimate does not, ``"higher_order"``; on every level of a nearly
            incompressible material, :func:`nearly_incompressible`, the hierarchical P2
            weights, or the factored ones, ``"higher_order"``, for a law with coupled rows in
            3D: Tresca and Coulomb friction; but the patch weights where the P2 ones'
            predicted memory does not fit, :func:`~dwr_signorini.weights.p2_weights_fit`, said
            by a log line and ``Estimate.weights_fallback``),
            ``"patch"`` (the paper's patch-wise reconstructions), ``"higher_order"`` (dual,
            and for eta the primal, solved in P2 with Lambda_H and the final active set, by a
            factorisation), ``"hierarchical"`` (the same P2 solutions by a two-level
            iteration on the Newton factors, :mod:`~dwr_signorini.hierarchical`, for every
            law, coupled rows included) or ``"local"`` (the same P2 problems solved on a band
            of cells around the contact zone, the patch reconstructions as their data off it,
            :mod:`~dwr_signorini.local_p2`; one body).
        petsc_options: Linear solver options for the higher-order solves (as
            :class:`~dwr_signorini.settings.EstimateOptions`).
        quadrature_degree: Quadrature degree of the non-polynomial residual integrals: the
            default, ``"problem"``, the problem's ``quadrature_degree``; ``None`` lets UFL
            estimate every degree (as :class:`~dwr_signorini.settings.EstimateOptions`).
        options: ``estimator``, ``weights``, ``petsc_options`` and ``quadrature_degree`` as
            one :class:`~dwr_signorini.settings.EstimateOptions`, instead of the keywords.
        model_error: ``None``, or the same problem with a richer contact law (frictionless <
            Tresca < Coulomb, :mod:`~dwr_signorini.model_error`, theory eq. (M1)) or with a
            hyperelastic material (``material=ds.NeoHookean()``, ...; small strain in place of
            finite strain, :mod:`~dwr_signorini.strain_model_error`, eq. (M6)):
            ``Estimate.model`` then holds the estimate of J(richer) - J(simpler) at ``sol``.
            For the last step of a load path whose earlier steps the path kept
            (``solve_path(..., keep_steps=True)``): the richer path's problems, one per step
            (:mod:`~dwr_signorini.path_model_error`, eq. (M7)).

    Returns:
        The :class:`Estimate` (collective; release it with ``destroy()`` or ``with``);
        ``Estimate.weights`` names the weights it was computed with.

    Raises:
        TypeError: If ``sol`` is not a :class:`~dwr_signorini.Solution` (or a finite-strain
            solution), or ``goal`` is not
            callable or does not return a UFL form.
        ValueError: For an unknown ``estimator`` or ``weights``, or a goal that is not a scalar
            form on the solution's mesh or uses ``lam`` outside ``m.ds_contact``.
        RuntimeError: If the dual solution (or a P2 solution of the weights) is not finite, or
            the iterative P2 solve of ``weights="hierarchical"`` does not converge.
    """
    keywords = EstimateOptions(estimator, weights, petsc_options, quadrature_degree)
    if options is None:
        options = keywords
    elif not isinstance(options, EstimateOptions) or keywords != EstimateOptions():
        raise TypeError(
            "options must be an EstimateOptions, given instead of the estimate's keyword "
            "arguments"
        )
    if isinstance(sol, FiniteStrainSolution):  # the nonlinear residuals
        from .finite_strain_estimate import estimate as finite_strain_estimate

        check_options_on_ranks(sol.disc.mesh, "estimate", options)
        return finite_strain_estimate(sol, goal, options, model_error)
    if not isinstance(sol, Solution):
        raise TypeError(
            f"sol must be the Solution returned by solve(), got {type(sol).__name__}"
        )
    if getattr(sol.system, "ksp", None) is None:
        raise ValueError(
            "sol has been destroyed (Solution.destroy(), or the end of its `with` block): "
            "estimate a Solution before releasing it"
        )
    check_options_on_ranks(sol.disc.mesh, "estimate", options)
    if model_error is not None:
        check_model_error(sol, model_error)
    goal_forms = GoalForms(goal, sol.u, sol.lam, sol.disc, sol.tangential or None)
    tic = time.perf_counter()
    z = solve_dual(sol.system, goal_forms)
    t_dual = time.perf_counter() - tic
    # the goal-independent parts: the solution's own where it keeps them (a load path's
    # history), else made for this estimate and released at its end but the reconstructor
    parts = sol.estimate_parts
    own = parts is None
    if own:
        parts = EstimateParts(sol)
    try:  # on a failure the parts made here are released
        est = _estimate(_Inputs(sol, goal_forms, z, parts, options), tic, t_dual)
        if model_error is not None:
            est.model = _model_error(est, sol, goal, model_error, options)
    except BaseException:
        if own:
            parts.destroy()
        raise
    if own:
        parts.hand_over()
        parts.destroy()
    else:
        est.owns_reconstructor = False
    return est


def _model_error(
    est: Estimate, sol: Solution, goal: Goal, richer: Any, options: EstimateOptions
) -> ModelError:
    """The model error of ``sol``'s law against ``richer``'s, its cell indicators as est's."""
    disc = sol.disc
    DG0 = est.indicators.function_space
    degree = options.degree(disc.problem)
    tic = time.perf_counter()
    out = any_model_error(
        sol, goal, richer,
        lambda form: _assemble_indicators(disc, [form], DG0, degree)[0],
        est.roundoff,
    )
    est.timings["model_error"] = time.perf_counter() - tic
    return out


def _estimate(inp: _Inputs, tic: float, t_dual: float) -> Estimate:
    """The :class:`Estimate` from its inputs (``tic``: the start of :func:`estimate`)."""
    sol, options, disc = inp.sol, inp.options, inp.sol.disc
    DG0 = inp.parts.DG0
    J_h = inp.goal_forms.value()
    q = roundoff_bound(
        goal_magnitude(inp.goal_forms, sol.disc.problem.quadrature_degree),
        disc.num_dofs,
        disc.mesh.topology.dim,
    )
    terms, resolved, fallback = _auto_terms(
        inp, options.estimator, options.weights, options.degree(disc.problem), DG0, J_h, q
    )
    t_estimate = time.perf_counter() - tic - t_dual
    indicators = fem.Function(DG0, name="indicators")
    n_local = DG0.dofmap.index_map.size_local
    indicators.x.array[:n_local] = terms.indicators[:n_local]
    indicators.x.scatter_forward()
    return Estimate(
        J_h=J_h,
        eta_p=terms.eta_p,
        eta=terms.eta,
        contact_term=terms.contact,
        active_set_remainder=terms.remainder,
        rho=terms.rho,
        rho_star=terms.rho_star,
        estimator=options.estimator,
        weights=terms.weights,
        indicators=indicators,
        dual=inp.z,
        goal_is_linear=inp.goal_forms.is_linear,
        timings={"dual": t_dual, "estimate": t_estimate},
        reconstructor=inp.rec,
        resolved=resolved,
        roundoff=q,
        weights_fallback=fallback,
    )
