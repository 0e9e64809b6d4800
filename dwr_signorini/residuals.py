r"""The residuals of Section 3 with a scale-consistent NCP: rho, rho*, C and the indicator chi_h.

**The NCP with a scale c.** For any c > 0 (a number, or a positive function on Gamma_C, here
piecewise constant c_i on the macro contact facets), the contact conditions
lambda >= 0, u_n - g <= 0, lambda (u_n - g) = 0 are equivalent to

    lambda - max(0, lambda + c (u_n - g)) = 0.

The package uses one c everywhere (``ncp_scale`` of :func:`~dwr_signorini.solve`, the ``c_n`` of
:mod:`dwr_signorini.algebra`): ``"physical"``, c_i = E / H_i, by default, so that
lambda + c (u_n - g) is a force per area in any units; c = 1 is the paper's choice.

**The forms.** With w = (u, lambda), phi = (v, mu),

    C(w)(mu)      = (mu, lambda - max(0, lambda + c (u_n - g)))_GC,
    rho(w)(phi)   = l(v) - a(u, v) - (lambda, v_n)_GC - C(w)(mu),

so w solves the problem iff rho(w)(phi) = 0 for all phi. The error identities (13) and (15)
are those of the Lagrangian L(w, z) = J(w) + rho(w)(z) and hold for every c > 0, provided the
dual problem is the linearisation of the same rho at w_h. Its derivative, with the pointwise
indicator chi_h = [lambda_h + c (u_h,n - g) > 0], is

    C'(w_h)(dv, dmu)(mu) = (mu, (1 - chi_h) dmu - c chi_h dv_n)_GC,

so the dual problem (11)-(12) reads, for z = (y, xi),

    a(v, y) - b_h(xi, v) = J'_u(v),        (mu, y_n)_GC + c_h(xi, mu) = J'_lambda(mu),
    b_h(xi, v) = (c chi_h xi, v_n)_GC,     c_h(xi, mu) = ((1 - chi_h) xi, mu)_GC:

the form b carries c, the form c does not. The dual residual (Proposition 8) is

    rho*(w_h, z_h)(phi) = J'(w_h)(phi) - a(v, y_h) + b_h(xi_h, v) - (mu, y_h,n)_GC
                          - c_h(xi_h, mu).

**The discrete dual.** The transposed Newton matrix (:mod:`dwr_signorini.dual`) has the rows
of N, not of c N, in its active block: its solution xi^(1) is that of c = 1 in b_h. Since chi
of the discrete dual is the active set A of whole macro facets and c is constant on each,
xi = xi^(1) / c on A and xi = xi^(1) off A (:func:`~dwr_signorini.dual.solve_dual` returns
xi). Then C(w_h)(xi_H) is independent of c where the discrete and pointwise contact sets
agree; where the obstacle penetrates an inactive facet pointwise (unresolved contact),
-C(w_h)(xi_H) = (xi_H, c (u_h,n - g))_GC there, which needs the physical c to be of the right
size.

**The active-set remainder.** The identity (13) holds up to R_J and (Proposition 4, with c)

    R_A = (xi, (chi - chi_h) [lambda_h + c (u_h,n - g)])_GC,

chi the indicator of the exact contact set. R_A vanishes once the discrete pointwise contact set
chi_h is the exact one (Remark 7). :func:`active_set_remainder` evaluates it with w and xi
replaced by their reconstructions (the weights' A w_h and A z_h): a computable indicator of how
far the contact set is from resolved. It is not a bound: it sees only the part of the contact set
on which the reconstruction and chi_h disagree; a contact zone that neither resolves (smaller than
a macro facet, and not seen by the reconstruction either) is not detected by it, and only the
contact term C(w_h)(xi_H) of the estimate can see it.

**Friction** (:mod:`dwr_signorini.laws`). A frictional law adds a multiplier lambda_t (the
tangential traction, along t) with the NCP lambda_t - P_t(lambda_t + c u_t) = 0, P_t the
projection onto [-s, s] (Tresca). With w = (u, lambda_n, lambda_t), phi = (v, mu_n, mu_t) the
forms gain, component by component, the same terms as the normal one:

    rho(w)(phi) = l(v) - a(u, v) - (lambda_n, v_n) - (lambda_t, v_t)
                  - C_n(w)(mu_n) - C_t(w)(mu_t),
    C_t(w)(mu)  = (mu, lambda_t - P_t(lambda_t + c u_t))_GC,
    C_t'(w_h)(dv, dmu)(mu) = (mu, (1 - chi_t) dmu - c chi_t dv_t)_GC,
    chi_t = [|lambda_t + c u_t| < s],

chi_t the pointwise stick indicator. The Lagrangian L(w, z) = J(w) + rho(w)(z) is the same
functional of a longer w, so the identities (13) and (15) hold as they are, and the estimators
read

    eta_p = rho(w_h)(A z_h - z_h) - C_n(w_h)(xi_n) - C_t(w_h)(xi_t),
    eta   = 1/2 rho(w_h)(A z_h - z_h) + 1/2 rho*(w_h, z_h)(A w_h - w_h) - C_n(w_h)(xi_n)
            - C_t(w_h)(xi_t),

with the dual residual rho* gaining b_t(xi_t, v) = (c chi_t xi_t, v_t), -(mu_t, y_t) and
c_t(xi_t, mu) = ((1 - chi_t) xi_t, mu): the added terms are the tangential part of the primal
residual, (lambda_t, v_t), the tangential contact term -C_t(w_h)(xi_t), which measures where
the discrete traction violates Tresca's law pointwise (the discrete law holds per macro facet),
and the tangential parts of rho*. The dual problem is the transposed Newton matrix with the stick
rows in the constrained block (:mod:`dwr_signorini.dual`). The remainder R_A gains
-(xi_t^+, P_t(x_h) - P_t(x^+) - P_t'(x^+) (x_h - x^+)) with x = lambda_t + c u_t: the
remainder of P_t's expansion at the reconstruction, which for P_n = max(0, .) is the normal R_A
below. :func:`primal_residual`, :func:`dual_residual`, :func:`contact_term` and
:func:`active_set_remainder` sum over the law's components and do not branch on the law.

In 3D lambda_t has two components in the tangent basis and P_t projects onto the disc of
radius s; its derivative J = P_t' is a 2 x 2 matrix (alpha (I - q q^T) where the facet slips),
and the forms above hold with chi_t replaced by J: b_t(xi_t, v) = (c xi_t, J v_t),
c_t(xi_t, mu) = (xi_t, (I - J) mu) and the remainder's P_t'(x^+) (x_h - x^+) a matrix-vector
product (:meth:`~dwr_signorini.laws.ContactLaw.ncp_arguments` gives each component's row of J).
"""

from __future__ import annotations

from typing import Any

import ufl

from .dual import DualSolution
from .goal import GoalForms

__all__ = [
    "active_indicator",
    "active_set_remainder",
    "contact_term",
    "contact_violation",
    "dual_residual",
    "ncp_argument",
    "ncp_terms",
    "primal_residual",
]


def ncp_argument(u: Any, lam: Any, gap: Any, n: Any, c: Any) -> Any:
    """Lambda + c (u_n - g), whose sign decides contact in the NCP function (eq. 8, scaled)."""
    return lam + c * (ufl.dot(u, n) - gap)


def active_indicator(u: Any, lam: Any, gap: Any, n: Any, c: Any) -> Any:
    """The pointwise chi_h = [lambda_h + c (u_h,n - g) > 0] (Proposition 8)."""
    return ufl.conditional(ufl.gt(ncp_argument(u, lam, gap, n, c), 0.0), 1.0, 0.0)


def contact_violation(
    u: Any, lam: Any, mu: Any, gap: Any, n: Any, ds_c: ufl.Measure, c: Any
) -> ufl.Form:
    """C(w)(mu) = (mu, lambda - max(0, lambda + c (u_n - g)))_GC (Section 2, after eq. 8)."""
    return mu * (lam - ufl.max_value(0.0, ncp_argument(u, lam, gap, n, c))) * ds_c


def _tuple(mu: Any) -> tuple:
    """A weight per component of the law: a tuple, or one weight (the normal one)."""
    return tuple(mu) if isinstance(mu, (tuple, list)) else (mu,)


def ncp_terms(sol: Any, u: Any, lams: Any, c: Any) -> list:
    """Each component's (x_k, P_k(x_k), P_k'(x_k)) at (u, lams) (:mod:`~dwr_signorini.laws`)."""
    disc = sol.disc
    m, fields = disc.m, disc.fields
    u_old = disc.slip_origin()
    return disc.problem.law.ncp_arguments(
        disc.relative(u), _tuple(lams), fields.gap(m.x), m.n, c, fields, u_old,
        frame=disc.contact_frame(),
    )


def contact_term(sol: Any, mus: Any, c: Any) -> ufl.Form:
    """C(w_h)(mu) of every component of the law: sum_k (mu_k, lambda_k - P_k(x_k))_GC.

    Without friction this is :func:`contact_violation` (the paper's C(w_h)(mu), Section 2).
    """
    m = sol.disc.m
    form = None
    for (_, P, _), lam, mu in zip(
        ncp_terms(sol, sol.u, sol.multipliers, c), sol.multipliers, _tuple(mus), strict=True
    ):
        term = mu * (lam - P) * m.ds_contact
        form = term if form is None else form + term
    return form


def primal_residual(sol: Any, v: Any, mu: Any, c: Any) -> ufl.Form:
    """rho(w_h)(v, mu) = l(v) - a(u_h, v) - sum_k (lambda_k, v . e_k)_GC - C(w_h)(mu).

    Proposition 4; the directions e_k are n, and t with friction.

    Args:
        sol: The :class:`~dwr_signorini.Solution`.
        v: The displacement weight.
        mu: The multiplier weight, or a tuple of them (one per component of the law).
        c: The scale of the NCP (a function on the multiplier space, or a number).
    """
    disc = sol.disc
    m = disc.m
    components = disc.problem.law.components(m.mesh.topology.dim)
    form = disc.load_form(v) - disc.fields.elastic_form(sol.u, v, m.dx)
    v_rel = disc.relative(v)
    for e, lam in zip(disc.directions(components), sol.multipliers, strict=True):
        form -= lam * ufl.dot(v_rel, e) * m.ds_contact
    return form - contact_term(sol, mu, c)


def dual_residual(
    sol: Any, goal: GoalForms | None, z: DualSolution, v: Any, mu: Any, c: Any
) -> ufl.Form:
    """rho*(w_h, z_h)(v, mu) of Proposition 8, with b_h carrying c (see the module docstring).

    ``J'(w_h)(v, mu) - a(v, y_h) + sum_k [b_k(xi_k, v) - (mu_k, y_h . e_k) - c_k(xi_k, mu_k)]``
    with ``b_k(xi, v) = int c chi_k xi v . e_k``, ``c_k(xi, mu) = int (1 - chi_k) xi mu`` and
    chi_k = P_k' at w_h (the pointwise chi_h of the paper for the normal component, the stick
    indicator for the tangential one). With an obstacle under a given force the dual has the
    entry zeta of its displacement, and the force balance w^T lam = F adds ``-zeta w(mu)``
    (:meth:`~dwr_signorini.spaces.Discretization.force_balance`). Where a projection acts on
    several components (Tresca's ball in 3D) its derivative J is a matrix, chi_k = J_kk, and
    b_k, c_k gain
    ``int c xi_k J_kj v . e_j`` and ``-int xi_k J_kj mu_j`` for j != k. With ``goal`` None
    the form without its J' term (the part that does not depend on the goal).
    """
    disc = sol.disc
    m = disc.m
    components = disc.problem.law.components(m.mesh.topology.dim)
    terms = ncp_terms(sol, sol.u, sol.multipliers, c)
    mus = _tuple(mu)
    directions = disc.directions(components)
    v_rel, y_rel = disc.relative(v), disc.relative(z.y)
    form = -disc.fields.elastic_form(v, z.y, m.dx)
    for k, ((_, _, J_k), xi, mu_k) in enumerate(zip(terms, z.multipliers, mus, strict=True)):
        # b_k(xi, v) = (c xi_k, sum_l J_kl v . e_l), c_k(xi, mu) = (xi_k, mu_k - sum_l J_kl mu_l)
        chi = J_k[k]
        form += c * xi * chi * ufl.dot(v_rel, directions[k]) * m.ds_contact
        form -= mu_k * ufl.dot(y_rel, directions[k]) * m.ds_contact
        form -= xi * (1.0 - chi) * mu_k * m.ds_contact
        for j, (J_kj, e_j, mu_j) in enumerate(zip(J_k, directions, mus, strict=True)):
            if j != k and _nonzero(J_kj):  # the coupling of a projection onto a ball
                form += (c * xi * J_kj * ufl.dot(v_rel, e_j) + xi * J_kj * mu_j) * m.ds_contact
    if z.zeta is not None:  # the force balance's column of the bordered dual (dwr_signorini.force)
        form -= z.zeta * disc.force_balance(mus)
    dJ = None if goal is None else goal.directional(v, *mus)
    return form if dJ is None else dJ + form


def active_set_remainder(
    sol: Any, u_plus: Any, lam_plus: Any, xi_plus: Any, c: Any
) -> ufl.Form:
    """R_A of Proposition 4 with w and xi replaced by reconstructions (module docstring).

    ``(xi^+, (chi(w^+) - chi_h) [lambda_h + c (u_h,n - g)])_GC`` with
    ``chi(w^+) = [lambda^+ + c (u^+_n - g) > 0]`` for the normal component. With P = max(0, .)
    this is ``-(xi^+, P(x_h) - P(x^+) - P'(x^+) (x_h - x^+))``, the remainder of the NCP
    function's expansion at w^+, which is the form used for the other components of the law.

    Args:
        sol: The :class:`~dwr_signorini.Solution`.
        u_plus: The reconstructed displacement.
        lam_plus: The reconstructed multiplier, or one per component (a tuple).
        xi_plus: The reconstructed dual multiplier, or one per component (a tuple).
        c: The scale of the NCP.
    """
    disc = sol.disc
    m = disc.m
    components = disc.problem.law.components(m.mesh.topology.dim)
    gap = disc.normal_gap(components, disc.fields.gap(m.x))
    n = disc.directions(components)[0]  # the normal of the contact frame
    u_h = disc.relative(sol.u)
    arg_h = ncp_argument(u_h, sol.lam, gap, n, c)
    chi_h = active_indicator(u_h, sol.lam, gap, n, c)
    lam_plus, xi_plus = _tuple(lam_plus), _tuple(xi_plus)
    chi_plus = active_indicator(disc.relative(u_plus), lam_plus[0], gap, n, c)
    form = xi_plus[0] * (chi_plus - chi_h) * arg_h * m.ds_contact
    if len(xi_plus) == 1:
        return form
    terms_h = ncp_terms(sol, sol.u, sol.multipliers, c)
    terms_plus = ncp_terms(sol, u_plus, lam_plus, c)
    for k in range(1, len(xi_plus)):
        (_, P_h, _), (_, P_p, J_p) = terms_h[k], terms_plus[k]
        expansion = P_h - P_p
        for j, J_kj in enumerate(J_p):
            if _nonzero(J_kj):
                expansion -= J_kj * (terms_h[j][0] - terms_plus[j][0])
        form -= xi_plus[k] * expansion * m.ds_contact
    return form


def _nonzero(entry: Any) -> bool:
    """Whether an entry of a derivative row is not the number 0 (an uncoupled pair)."""
    return not (isinstance(entry, float) and entry == 0.0)
