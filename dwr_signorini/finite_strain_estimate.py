r"""The goal's error at finite strain: the dual problem, eta_p, eta and the interval.

With w = (u, lambda), phi = (v, mu) and the residual R of :mod:`~dwr_signorini.finite_strain`,
the Lagrangian is L(w, z) = J(w) + rho(w)(z) with

    rho(w)(v, mu) = t l(v) - int P(F(u)) : grad v dx + int lam grad d(x + u) . v ds
                    - C(w)(mu),
    C(w)(mu)      = int mu (lam - max(0, lam - c d(x + u))) ds,

C the paper's contact-violation term with the gap of the deformed configuration (the linear
path's lam + c (u_n - g) is lam - c d(x + u) to first order; c the scale of the NCP per macro
facet, the one of the Newton method). rho(w_h)(v_h, mu_h) = -C(w_h)(mu_h) on the discrete
space, since the discrete NCP holds per macro facet, the pointwise one need not.

**The dual problem** is the transposed Newton matrix of the final active set A *at the converged
(u_h, lambda_H)*: the Newton loop's last matrix belongs to the iterate before the converged one,
so it is assembled once more at w_h (:meth:`~dwr_signorini.finite_strain.FiniteStrainSystem.
newton_matrix`) and solved by MUMPS's transposed solve with its factors (``KSP.solveTranspose``):
one factorisation of the size of a Newton step. With the Newton matrix N = D F'(w_h), D the row
scaling of the step (-1/c_i on the active rows, 1 on the others), the dual solution of
F'(w_h)^T z = J'(w_h) is z = D N^-T J'(w_h): y_h as solved, xi = -xi^(N) / c on A. Then for a
parameter p of the data, F(w_h(p), p) = 0 gives the adjoint identity dJ/dp = -z . dF/dp.

**The estimates** (paper, (13) and (15)) with the patch weights (the paper's reconstructions of
:mod:`~dwr_signorini.reconstruction`, as ``weights="patch"`` of the linear path):

    eta_p = rho(w_h)(A z_h - z_h) - C(w_h)(xi_H),
    eta   = 1/2 rho(w_h)(A z_h - z_h) + 1/2 rho*(w_h, z_h)(A w_h - w_h) - C(w_h)(xi_H),

rho*(w_h, z_h)(phi) = L'_w(w_h, z_h)(phi) by UFL's derivative (the material's tangent, the
curvature of d, the pointwise indicator chi_h = [lam_h - c d(x + u_h) > 0] from max's
derivative). The P2 weights of the linear path would need the P2 primal problem, here a
nonlinear one; they are not offered (``weights`` "patch" or "auto", which is "patch").

**The remainder.** The identity (15) holds up to R^(3) = 1/2 int_0^1 L'''(x_h + s e)(e, e, e)
s (s - 1) ds, x = (w, z), e = x - x_h (Becker and Rannacher), and R_A (Proposition 4). For the
linear model L''' = 0; at finite strain the material law and the obstacle's curvature make it
nonzero. It is estimated by the midpoint value L''' ~ L'''(x_h) and the weights in place of e:

    R3 ~ -1/12 [L'''(w_h, z_h)(e_w, e_w, e_w) + 3 rho''(w_h)(e_z)(e_w, e_w)],

e_w = (A w_h - w_h), e_z = (A z_h - z_h) (UFL's third derivatives; the max of the NCP counts
with chi_h fixed: its kinks are R_A's part). R3 is an estimate, not a bound, as |eta - eta_p|
and R_A of :mod:`~dwr_signorini.interval` are: the interval (*) there is widened by |R3| on
both sides (:attr:`FiniteStrainEstimate.interval`).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from ufl.algorithms import expand_derivatives

from .dual import DualSolution
from .estimate_parts import IndicatorForm
from .estimator import Estimate, _assemble_indicators, goal_magnitude
from .finite_strain import (
    FiniteStrainSolution,
    FiniteStrainSystem,
    cell_degree,
    refuse,
    residual_forms,
    signed_distance,
)
from .goal import Goal, GoalForms
from .interval import contact_set_resolved, roundoff_bound
from .quadrature import with_quadrature_degrees
from .reconstruction import Reconstructor
from .settings import EstimateOptions

__all__ = [
    "FiniteStrainEstimate", "check_options", "contact_facet_indicators", "estimate", "solve_dual",
]


@dataclass
class FiniteStrainEstimate(Estimate):
    """An :class:`~dwr_signorini.Estimate` at finite strain (module docstring).

    Attributes:
        nonlinear_remainder: The estimate R3 of the remainder of the identity (15), which
            widens :attr:`interval` by its magnitude on both sides.
        contact_indicators: DG0 on the macro contact facets (Lambda_H): the Gamma_C part of the
            estimate per facet (the multiplier weights' terms, the contact-violation term and
            the goal's Gamma_C integrals), contained in ``indicators`` too, through the cell
            beside each facet.
    """

    nonlinear_remainder: float = 0.0
    contact_indicators: fem.Function | None = field(default=None, repr=False)

    @property
    def interval(self) -> tuple[float, float]:
        """The linear path's interval (*) widened by ``|nonlinear_remainder|`` on both sides."""
        low, high = Estimate.interval.fget(self)
        r = abs(self.nonlinear_remainder)
        return low - r, high + r


@contextlib.contextmanager
def _state_of(sol: FiniteStrainSolution) -> Iterator[FiniteStrainSystem]:
    """The solution's Newton system at the solution's (u, lam, t); its own state restored after.

    The states of a load path share one system
    (:func:`~dwr_signorini.finite_strain_path.solve_path`).
    """
    system = sol.system
    saved = system.u.x.array.copy(), system.lam.x.array.copy(), float(system.t.value)
    system.u.x.array[:] = sol.u.x.array
    system.lam.x.array[:] = sol.lam.x.array
    system.t.value = sol.load_factor
    try:
        yield system
    finally:
        system.u.x.array[:], system.lam.x.array[:] = saved[0], saved[1]
        system.t.value = saved[2]


def _dual_rhs(system: FiniteStrainSystem, goal: GoalForms, out: PETSc.Vec) -> None:
    """[J'_u(w_h); J'_lambda(w_h)] into ``out`` (owned rows, zero on Gamma_D)."""
    degree = system.disc.problem.quadrature_degree
    parts = [np.zeros(system.n_u), np.zeros(system.n_q)]
    for k, (present, form) in enumerate(((goal.has_u, goal.dJ_u), (goal.has_lam, goal.dJ_lam))):
        if present:
            b = fem_petsc.assemble_vector(system.disc.form(with_quadrature_degrees(form, degree)))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            if k == 0:
                fem_petsc.set_bc(b, system.disc.bcs)
            parts[k][:] = b.array_r[: len(parts[k])]
            b.destroy()
    out.array_w[:] = np.concatenate(parts)


def solve_dual(sol: FiniteStrainSolution, goal: GoalForms) -> DualSolution:
    """z_h = (y_h, xi_H): F'(w_h)^T z_h = J'(w_h) by the transposed Newton matrix at w_h.

    Args:
        sol: The finite-strain solution (its system alive).
        goal: J's forms at w_h (on ``sol.u``, ``sol.lam``).

    Returns:
        The dual solution, xi scaled to the NCP's c (module docstring).

    Raises:
        RuntimeError: The dual solution is not finite.
    """
    with _state_of(sol) as system:
        matrix = system.newton_matrix(sol.active)
        rhs, z = matrix.createVecLeft(), matrix.createVecRight()
        try:
            _dual_rhs(system, goal, rhs)
            system.ksp.solveTranspose(rhs, z)
            values = z.array_r.copy()
        finally:
            rhs.destroy()
            z.destroy()
    disc = sol.disc
    y = fem.Function(disc.V, name="y")
    y.x.array[: system.n_u] = values[: system.n_u]
    y.x.scatter_forward()
    xi = fem.Function(disc.Q, name="xi")
    xi_n = values[system.n_u:]
    xi.x.array[: system.n_q] = np.where(sol.active, -xi_n / system.c, xi_n)
    xi.x.scatter_forward()
    finite = bool(np.all(np.isfinite(values)))
    if not disc.comm.allreduce(finite, op=MPI.LAND):
        raise RuntimeError("NaN or Inf in the finite-strain dual solution")
    return DualSolution(y, xi)


class _Forms:
    """The UFL pieces of the module docstring at w_h = (u_h, lambda_H) of one solution."""

    def __init__(self, sol: FiniteStrainSolution, goal: GoalForms) -> None:
        disc = sol.disc
        problem = disc.problem
        self.sol, self.goal = sol, goal
        # the weights are P2: two degrees more than the Newton system's cell rule (R3 is cubic
        # in them); Gamma_C's rule is the Newton system's, so that rho vanishes on P1 weights
        self.dx = disc.m.dx(metadata={"quadrature_degree": cell_degree(disc) + 2})
        self.dsc = disc.m.ds_contact(metadata={"quadrature_degree": problem.quadrature_degree})
        self.t = fem.Constant(disc.mesh, float(sol.load_factor))
        self.c = fem.Function(disc.Q, name="c")
        self.c.x.array[: sol.system.n_q] = sol.system.c
        self.c.x.scatter_forward()
        self.v = ufl.TestFunction(disc.V)
        internal, load, contact, self.d = residual_forms(
            disc, sol.u, sol.lam, self.t, self.v, self.dx, self.dsc)
        self.R = internal - load + contact

    def distance(self, u: Any) -> Any:
        """d(x + u) of the problem's obstacle."""
        disc = self.sol.disc
        return signed_distance(self.sol.system.obstacle, disc.m.x + u)

    def ncp_argument(self, lam: Any, d: Any) -> Any:
        """The NCP argument lam - c d, whose sign decides contact pointwise."""
        return lam - self.c * d

    def contact(self, mu: Any) -> ufl.Form:
        """C(w_h)(mu)."""
        lam = self.sol.lam
        return mu * (lam - ufl.max_value(0.0, self.ncp_argument(lam, self.d))) * self.dsc

    def rho(self, v: Any, mu: Any) -> ufl.Form:
        """rho(w_h)(v, mu) = -R(w_h)[v] - C(w_h)(mu)."""
        return -ufl.replace(self.R, {self.v: v}) - self.contact(mu)

    def lagrangian(self, z: DualSolution) -> ufl.Form:
        """L(w, z_h) = J(w) + rho(w)(z_h) as a form in (u_h, lambda_H)."""
        return self.goal.J + self.rho(z.y, z.xi)

    def gateaux(self, form: ufl.Form, w_u: Any, w_lam: Any, order: int = 1) -> ufl.Form:
        """The ``order``-th derivative of ``form`` at w_h in the direction (w_u, w_lam).

        The direction enters through placeholder functions, replaced after the derivatives are
        expanded: w_lam = lambda^+ - lambda_H holds lambda_H, which a repeated derivative must
        not differentiate.
        """
        sol = self.sol
        du, dlam = fem.Function(sol.disc.V), fem.Function(sol.disc.Q)
        for _ in range(order):
            form = ufl.derivative(form, sol.u, du) + ufl.derivative(form, sol.lam, dlam)
        return ufl.replace(expand_derivatives(form), {du: w_u, dlam: w_lam})

    def active_set_remainder(self, u_plus: Any, lam_plus: Any, xi_plus: Any) -> ufl.Form:
        """R_A = (xi^+, (chi^+ - chi_h) [lam_h - c d(x + u_h)]) (Proposition 4)."""
        arg_h = self.ncp_argument(self.sol.lam, self.d)
        arg_plus = self.ncp_argument(lam_plus, self.distance(u_plus))

        def chi(arg: Any) -> Any:
            return ufl.conditional(ufl.gt(arg, 0.0), 1.0, 0.0)

        return xi_plus * (chi(arg_plus) - chi(arg_h)) * arg_h * self.dsc

    def third_order(self, z: DualSolution, e_u: Any, e_lam: Any, e_y: Any, e_xi: Any
                    ) -> ufl.Form:
        """R3 ~ -1/12 [L'''(e_w, e_w, e_w) + 3 rho''(e_z)(e_w, e_w)] (module docstring)."""
        third = self.gateaux(self.lagrangian(z), e_u, e_lam, order=3)
        second = self.gateaux(self.rho(e_y, e_xi), e_u, e_lam, order=2)
        return -1.0 / 12.0 * (third + 3.0 * second)


def _contact_part(form: ufl.Form, contact_tags: tuple[int, ...]) -> ufl.Form | None:
    """The integrals of ``form`` over Gamma_C (derivatives expanded), or None."""
    kept = []
    for itg in expand_derivatives(form).integrals():
        ids = itg.subdomain_id()
        ids = ids if isinstance(ids, tuple) else (ids,)
        if itg.integral_type() == "exterior_facet" and all(i in contact_tags for i in ids):
            kept.append(itg)
    return ufl.Form(kept) if kept else None


@dataclass
class _Weights:
    """The patch weights: e_z = (w_y, w_xi), e_w = (w_u, w_lam) and the reconstructions."""

    w_y: fem.Function
    w_xi: Any
    xi_plus: fem.Function
    w_u: fem.Function
    w_lam: Any
    lam_plus: fem.Function


def _patch_weights(sol: FiniteStrainSolution, z: DualSolution, rec: Reconstructor) -> _Weights:
    """i_2h^(2) v - v of y_h and u_h, i_2H^(1) of xi_H and lambda_H (the paper's, Section 4)."""
    xi_plus = rec.patch_linear_multiplier(z.xi)
    lam_plus = rec.patch_linear_multiplier(sol.lam)
    return _Weights(rec.patch_weight(z.y), xi_plus - z.xi, xi_plus, rec.patch_weight(sol.u),
                    lam_plus - sol.lam, lam_plus)


def _check(sol: FiniteStrainSolution, options: EstimateOptions, model_error: Any) -> None:
    """Refuse what the finite-strain estimate does not take (clear ValueErrors)."""
    if getattr(sol.system, "ksp", None) is None:
        raise ValueError(
            "sol has been destroyed (its Newton system released): estimate a finite-strain "
            "solution before releasing it"
        )
    check_options(options, model_error)


def check_options(options: EstimateOptions, model_error: Any = None) -> None:
    """Refuse the estimate's options that it does not take at finite strain.

    Also :func:`~dwr_signorini.solve_adaptive`'s check before its first solve.

    Args:
        options: The estimate's options.
        model_error: The richer problem of a model error, or None.

    Raises:
        ValueError: Weights other than ``"patch"`` or ``"auto"``, or a model error.
    """
    if options.weights not in ("auto", "patch"):
        refuse(f"estimate(weights={options.weights!r})",
               "the P2 weights need the P2 primal problem, a nonlinear one at finite strain; "
               "weights='patch' (or 'auto', which takes it) is offered")
    if model_error is not None:
        refuse("estimate(model_error=...)", "the model error of small strain is estimated at "
               "the small-strain solution (ds.estimate(sol, goal, model_error=problem with a "
               "hyperelastic material), sol of the linear problem)")


def estimate(sol: FiniteStrainSolution, goal: Goal, options: EstimateOptions,
             model_error: Any = None) -> FiniteStrainEstimate:
    """:func:`dwr_signorini.estimate` of a finite-strain solution (module docstring).

    Args:
        sol: A :class:`~dwr_signorini.finite_strain.FiniteStrainSolution` (of
            :func:`~dwr_signorini.solve` or a state of :func:`~dwr_signorini.solve_path`).
        goal: ``goal(u, lam, m) -> ufl.Form``.
        options: The estimate's options (``weights`` "auto" or "patch").
        model_error: Must be None (not taken at finite strain).

    Returns:
        The :class:`FiniteStrainEstimate` (collective; release it with ``destroy()``).

    Raises:
        ValueError: A destroyed solution, P2 weights or a model error asked for.
        RuntimeError: A dual solution that is not finite.
    """
    _check(sol, options, model_error)
    disc = sol.disc
    goal_forms = GoalForms(goal, sol.u, sol.lam, disc)
    tic = time.perf_counter()
    z = solve_dual(sol, goal_forms)
    t_dual = time.perf_counter() - tic
    rec = Reconstructor(disc)
    try:
        return _estimate(sol, goal_forms, z, rec, options, (tic, t_dual))
    except BaseException:
        rec.destroy()
        raise


def _estimate(sol: FiniteStrainSolution, goal_forms: GoalForms, z: DualSolution,
              rec: Reconstructor, options: EstimateOptions, times: tuple[float, float]
              ) -> FiniteStrainEstimate:
    """The estimate's terms, indicators and interval from the dual solution."""
    disc = sol.disc
    forms = _Forms(sol, goal_forms)
    w = _patch_weights(sol, z, rec)
    want_eta = options.estimator == "eta"
    terms = {
        "rho": forms.rho(w.w_y, w.w_xi),
        "contact": forms.contact(z.xi),
        "remainder": forms.active_set_remainder(sol.u + w.w_u, w.lam_plus, w.xi_plus),
        "third": forms.third_order(z, w.w_u, w.w_lam, w.w_y, w.w_xi),
    }
    if want_eta:
        dJ = goal_forms.directional(w.w_u, w.w_lam)
        star = forms.gateaux(forms.rho(z.y, z.xi), w.w_u, w.w_lam)
        terms["rho_star"] = star if dJ is None else dJ + star
    terms = {k: expand_derivatives(f) for k, f in terms.items()}
    degree = options.degree(disc.problem)
    DG0 = fem.functionspace(disc.mesh, ("DG", 0))
    local = dict(zip(terms, _assemble_indicators(disc, list(terms.values()), DG0, degree),
                     strict=True))
    total = {k: disc.comm.allreduce(float(v.sum()), op=MPI.SUM) for k, v in local.items()}
    weights = ({"rho": 0.5, "rho_star": 0.5, "contact": -1.0} if want_eta
               else {"rho": 1.0, "contact": -1.0})
    indicators = fem.Function(DG0, name="indicators")
    n_local = DG0.dofmap.index_map.size_local
    indicators.x.array[:n_local] = sum(a * local[k][:n_local] for k, a in weights.items())
    indicators.x.scatter_forward()
    estimate_form = sum(a * terms[k] for k, a in weights.items())
    eta_p = total["rho"] - total["contact"]
    eta = 0.5 * total["rho"] + 0.5 * total["rho_star"] - total["contact"] if want_eta else None
    J_h = goal_forms.value()
    q = roundoff_bound(goal_magnitude(goal_forms, disc.problem.quadrature_degree),
                       disc.num_dofs, disc.mesh.topology.dim)
    value = eta if want_eta else eta_p
    tic, t_dual = times
    return FiniteStrainEstimate(
        J_h=J_h, eta_p=eta_p, eta=eta, contact_term=total["contact"],
        active_set_remainder=total["remainder"], rho=total["rho"],
        rho_star=total.get("rho_star"), estimator=options.estimator, weights="patch",
        indicators=indicators, dual=z, goal_is_linear=goal_forms.is_linear,
        timings={"dual": t_dual, "estimate": time.perf_counter() - tic - t_dual},
        reconstructor=rec,
        resolved=contact_set_resolved(value, total["remainder"], total["contact"], q),
        roundoff=q, nonlinear_remainder=total["third"],
        contact_indicators=contact_facet_indicators(disc, estimate_form, degree),
    )


def contact_facet_indicators(disc: Any, form: ufl.Form, degree: int | None) -> fem.Function:
    """The Gamma_C integrals of ``form`` per macro contact facet (a function on Lambda_H).

    Args:
        disc: The discretisation.
        form: A scalar form.
        degree: The quadrature degree of its non-polynomial integrals (None: UFL's).

    Returns:
        One value per macro contact facet (zero where ``form`` has no Gamma_C integral).
    """
    out = fem.Function(disc.Q, name="contact indicators")
    part = _contact_part(form, disc.problem.contact_tags)
    if part is None:
        return out
    n = disc.Q.dofmap.index_map.size_local
    out.x.array[:n] = IndicatorForm(disc, part, disc.Q, degree).assemble()[:n]
    out.x.scatter_forward()
    return out
