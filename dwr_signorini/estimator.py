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

import time
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .dual import DualSolution, solve_dual
from .goal import Goal, GoalForms, localize
from .hierarchical import hierarchical_solutions
from .lifetime import Releasable
from .newton import Solution
from .quadrature import DATA_QUADRATURE_DEGREE, with_quadrature_degrees
from .reconstruction import Reconstructor
from .residuals import (
    active_set_remainder,
    contact_violation,
    dual_residual,
    primal_residual,
)
from .timing import timed

__all__ = [
    "ESTIMATORS",
    "WEIGHTS",
    "Estimate",
    "contact_violation",
    "dual_residual",
    "estimate",
    "primal_residual",
]

#: The ``estimator`` choices of :func:`estimate` and ``solve_adaptive``: ``"eta"`` (primal and
#: dual residual, eq. 15) and ``"eta_p"`` (primal residual, eq. 13).
ESTIMATORS = ("eta", "eta_p")
#: The ``weights`` choices of :func:`estimate` and ``solve_adaptive``: the paper's patch-wise
#: reconstructions, P2 solutions by a factorisation, or the same P2 solutions by FGMRES with the
#: Newton factorisation as coarse level.
WEIGHTS = ("patch", "higher_order", "hierarchical")


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
        weights: "patch", "higher_order" or "hierarchical".
        indicators: DG0 function on T_h of signed cell indicators; their sum is the estimate.
        dual: z_h = (y_h, xi_H).
        goal_is_linear: Whether J is linear in (u, lambda) (then R_J vanishes).
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

    def destroy(self) -> None:
        """Release the PETSc objects of the reconstruction (collective; idempotent)."""
        if self.reconstructor is not None:
            self.reconstructor.destroy()


    @property
    def value(self) -> float:
        """The estimate of J(w) - J(w_h) of the chosen estimator."""
        return self.eta if self.estimator == "eta" else self.eta_p


def ncp_scale_function(sol: Solution) -> fem.Function:
    """The c of the NCP function the solution was computed with, as a function on Lambda_H."""
    return sol.multiplier_function(sol.system.c_n, "c")


def _assemble_indicators(
    disc: Any, forms: list[ufl.Form], DG0: fem.FunctionSpace, degree: int | None
) -> list[np.ndarray]:
    """Cell indicators of each scalar form: its integrands times a DG0 test function (Section 4).

    One assembly per form: a fused one would pack the coefficients of all forms for every cell
    at once, a larger array than any single form's, for no gain in time.
    """
    with timed("indicators"):
        q = ufl.TestFunction(DG0)
        out = []
        for form in forms:
            vec = fem_petsc.assemble_vector(
                disc.form(localize(with_quadrature_degrees(form, degree), q))
            )
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            out.append(vec.array.copy())
            vec.destroy()
    return out


def _higher_order_solutions(
    sol: Solution, goal: GoalForms, rec: Reconstructor, primal: bool, petsc_options: Any
) -> tuple[DualSolution, tuple[fem.Function, fem.Function] | None]:
    """Dual (and primal) solved in P2 on T_h with Lambda_H and the final active set."""
    # The same kind of linear solver as the primal problem's (block or Schur complement), with
    # the options prefix <primal prefix>p2_.
    with timed("higher-order solve"):
        system2 = type(sol.system)(
            sol.disc,
            petsc_options,
            V=rec.V2h,
            prefix=sol.system.prefix + "p2_",
            ncp_scale=sol.ncp_scale,
        )
    try:
        with timed("higher-order solve"):
            system2.solve_active(sol.active)
            z2 = solve_dual(system2, goal)
        w2 = None
        if primal:
            u2 = fem.Function(rec.V2h, name="u2")
            u_arr, lam_arr = system2.split(system2.x)
            u2.x.array[: system2.n_u] = u_arr
            u2.x.scatter_forward()
            w2 = (u2, sol.multiplier_function(lam_arr, "lambda2"))
    finally:
        system2.destroy()
    return z2, w2


def estimate(
    sol: Solution,
    goal: Goal,
    estimator: str = "eta",
    weights: str = "patch",
    petsc_options: dict[str, Any] | None = None,
    quadrature_degree: int | None = DATA_QUADRATURE_DEGREE,
) -> Estimate:
    """Estimate J(w) - J(w_h) by eta_p or eta (Section 4).

    Args:
        sol: The discrete solution (its last Newton factorisation serves the dual solve).
        goal: ``goal(u, lam, m) -> ufl.Form``.
        estimator: ``"eta"`` (primal and dual residual, (15)) or ``"eta_p"`` (primal residual,
            (13)). eta_p is reported in both cases.
        weights: ``"patch"`` (the paper's patch-wise reconstructions) or ``"higher_order"`` (dual,
            and for eta the primal, solved in P2 with Lambda_H and the final active set).
        petsc_options: Linear solver options for the higher-order solves, which use the
            primal's kind of Newton system (block, or Schur complement with these options for
            K, e.g. :func:`~dwr_signorini.newton.iterative_petsc_options`), under the
            options prefix ``<prefix of the solve>p2_``.
        quadrature_degree: Quadrature degree of the non-polynomial residual integrals (data);
            polynomial ones are integrated exactly (:mod:`dwr_signorini.quadrature`). The
            default is the degree the solver integrates the load and gap with, so that the
            residual vanishes on discrete test functions (Galerkin orthogonality). ``None``
            lets UFL estimate every degree, which is very expensive for non-polynomial data.
            On example 5.1 degrees 4, 6, 8 and UFL's estimate give the same Ieff to 6 digits.

    Returns:
        The :class:`Estimate` (collective; release it with ``destroy()`` or ``with``).

    Raises:
        TypeError: If ``sol`` is not a :class:`~dwr_signorini.Solution`, or ``goal`` is not
            callable or does not return a UFL form.
        ValueError: For an unknown ``estimator`` or ``weights``, or a goal that is not a scalar
            form on the solution's mesh or uses ``lam`` outside ``m.ds_contact``.
        RuntimeError: If the dual solution (or a P2 solution of the weights) is not finite, or
            the iterative P2 solve of ``weights="hierarchical"`` does not converge.
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    if weights not in WEIGHTS:
        raise ValueError(f"weights must be one of {WEIGHTS}, got {weights!r}")
    if not isinstance(sol, Solution):
        raise TypeError(
            f"estimate() takes the Solution returned by solve(), got {type(sol).__name__}"
        )
    disc = sol.disc
    comm: MPI.Comm = disc.comm
    goal_forms = GoalForms(goal, sol.u, sol.lam, disc)
    tic = time.perf_counter()
    z = solve_dual(sol.system, goal_forms)
    t_dual = time.perf_counter() - tic
    want_eta = estimator == "eta"
    with timed("reconstruct"):
        rec = Reconstructor(disc)
    w2 = None
    if weights == "patch":
        with timed("reconstruct"):
            w_y = rec.patch_weight(z.y)
            xi_plus = rec.patch_linear_multiplier(z.xi)
    else:
        if weights == "hierarchical":
            z2, w2 = hierarchical_solutions(sol, goal_forms, z, rec.V2h, want_eta)
        else:
            z2, w2 = _higher_order_solutions(sol, goal_forms, rec, want_eta, petsc_options)
        with timed("reconstruct"):
            w_y = rec.weight(z2.y, z.y)
            xi_plus = rec.patch_linear_multiplier(z2.xi)
    w_xi = xi_plus - z.xi

    gap, m = disc.problem.gap_expr(disc.m.x), disc.m
    c = ncp_scale_function(sol)
    rho_form = primal_residual(sol, w_y, w_xi, c)
    c_form = contact_violation(sol.u, sol.lam, z.xi, gap, m.n, m.ds_contact, c)

    with timed("reconstruct"):
        if w2 is None:
            w_u = rec.patch_weight(sol.u)
            u_plus = sol.u + w_u  # i_2h^(2) u_h
            lam_plus = rec.patch_linear_multiplier(sol.lam)
        else:
            u_plus = w2[0]
            w_u = rec.weight(u_plus, sol.u) if want_eta else None
            lam_plus = rec.patch_linear_multiplier(w2[1])
    forms = [rho_form, c_form, active_set_remainder(sol, u_plus, lam_plus, xi_plus, c)]
    if want_eta:
        w_lam = lam_plus - sol.lam
        forms.append(dual_residual(sol, goal_forms, z, w_u, w_lam, c))
    DG0 = fem.functionspace(disc.mesh, ("DG", 0))
    ind_rho, ind_c, ind_a, *rest = _assemble_indicators(disc, forms, DG0, quadrature_degree)
    ind_star = rest[0] if want_eta else None

    def total(a: np.ndarray) -> float:
        return comm.allreduce(float(a.sum()), op=MPI.SUM)

    rho, contact = total(ind_rho), total(ind_c)
    rho_star = None if ind_star is None else total(ind_star)
    eta_p = rho - contact
    eta = None if rho_star is None else 0.5 * rho + 0.5 * rho_star - contact

    t_estimate = time.perf_counter() - tic - t_dual
    indicators = fem.Function(DG0, name="indicators")
    n_local = DG0.dofmap.index_map.size_local
    local = ind_rho - ind_c if not want_eta else 0.5 * ind_rho + 0.5 * ind_star - ind_c
    indicators.x.array[:n_local] = local[:n_local]
    indicators.x.scatter_forward()
    return Estimate(
        J_h=goal_forms.value(),
        eta_p=eta_p,
        eta=eta,
        contact_term=contact,
        active_set_remainder=total(ind_a),
        rho=rho,
        rho_star=rho_star,
        estimator=estimator,
        weights=weights,
        indicators=indicators,
        dual=z,
        goal_is_linear=goal_forms.is_linear,
        timings={"dual": t_dual, "estimate": t_estimate},
        reconstructor=rec,
    )
