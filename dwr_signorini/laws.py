"""Contact laws: the NCP functions of the contact conditions and their generalised derivatives.

A law is a list of *components*, one per multiplier on the macro contact facets: the normal
contact force lambda_n for every law, and the tangential traction lambda_t of a frictional law
(a scalar in 2D, along the tangent t = (-n_2, n_1); in 3D its two coordinates in the tangent
basis (t_1, t_2) of :func:`tangent_basis`). Component k has a direction e_k (n or t),
an offset g_k (the gap g for the normal, 0 for the tangential) and a projection P_k onto the
set of admissible forces, and its condition is the NCP (paper eq. 8, with the scale c of
:mod:`~dwr_signorini.residuals`)

    C_k(w)(mu) = (mu, lambda_k - P_k(lambda_k + c (u . e_k - g_k)))_GC = 0,

    normal (Signorini):   P_n(x) = max(0, x),         P_n'(x) = [x > 0]       (active / inactive)
    tangential (Tresca):  P_t(x) = max(-s, min(s, x)), P_t'(x) = [abs(x) < s]  (stick / slip)

Both projections are piecewise linear with slopes 0 and 1, so each component splits its facets
into *constrained* ones (slope 1: the contact condition fixes the displacement, (u . e_k)_i = g_k,i;
active, stick) and *free* ones (slope 0: it fixes the force, lambda_k,i = P_k(x_i), which is 0 on
inactive facets and s sign(x_i) on slipping ones). The semi-smooth Newton step, the dual problem
(the transposed Newton matrix), the residuals and the estimator only see that split and the
value on the free facets (:meth:`Component.newton_set`), and the UFL forms of P_k and P_k'
(:meth:`Component.projection`, :meth:`Component.derivative`): they do not branch on the law.

Tresca's law is the classical given-threshold friction law (Duvaut and Lions): ``|lambda_t| <= s``
on all of Gamma_C, u_t = 0 where ``|lambda_t| < s`` and ``lambda_t = s u_t / |u_t|`` where the
body slips.
The threshold does not depend on the normal force, so a facet that separates still carries
lambda_t = +-s where it moves tangentially: the law is a model of friction with a known normal
pressure, and Coulomb's law (threshold mu lambda_n) is the one for friction that follows contact.
What makes Tresca's law the first frictional law to build on is that the discrete problem is
convex: it minimises the energy plus ``sum_i s_i |(T u)_i|`` under (N u)_i <= g_i, with a unique
solution, whose dual is a bound-constrained quadratic programme in (lambda_n, lambda_t) (the
tests solve it by another method for an independent check). A threshold s chi on the contact
set alone would couple the tangential condition to the normal one through the set, a
quasi-variational inequality whose discrete problem need not have a unique solution (tried: the
semi-smooth Newton method cycled on facets at the edge of the contact zone). The normal and
tangential conditions do not couple in the Newton matrix, which stays symmetric, and every
linear solver of the frictionless problem serves (:mod:`dwr_signorini.linalg`).

**3D.** The tangential traction is a vector of the tangent plane and Tresca's law projects it
onto the disc of radius s: P(x) = x min(1, s / |x|) acts on both tangential components at once
(a *condition* on two components, :meth:`ContactLaw.conditions`, :class:`TangentialBall`). Its
generalised derivative is I inside the disc (stick: both rows constrained, as in 2D) and
alpha (I - q q^T), alpha = s / |x| < 1, q = x / |x|, outside (slip). The semi-smooth Newton method
uses this exact derivative (not the Hueber-Stadler-Wohlmuth fixed point on the slip direction):
the slipping facets' rows are then those of a smooth Newton method, converging quadratically
(measured on the oblique patch test: NCP residuals 1e-2, 9e-5, 1e-8, 5e-16), and the dual
problem is the transposed linearisation that the error identity needs. The price is that a
slipping facet's rows, (I - J) M lambda - c J (B u), couple the two tangential rows and are not
the transpose of the columns B^T: the Newton matrix is not symmetric and is factored by LU
(:mod:`dwr_signorini.linalg.coupled`, :class:`Coupling`). In the facet's rotated basis (q, p) the
step reads lambda_q = s and (B u)_p = (1 - alpha) / (alpha c) M lambda_p, a symmetric form
with a compliant diagonal; the LU path is the one Coulomb's law needs anyway.

**Coulomb's law** (:class:`Coulomb`) has the threshold mu max(0, x_n), x_n the normal NCP
argument: one projection onto the Coulomb cone acts on all components of a facet
(:class:`CoulombCone`), and on a facet in contact that slips the tangential rows depend on x_n
(the derivative mu d, d = sign(x_t) or x_t / ``|x_t|``). Such a facet is a :class:`Coupling`
whose normal row is constrained (active) and whose tangential rows couple to the normal
column; the Newton matrix is not symmetric in 2D either. Its tangential arguments hold the slip
increment of a load step, x_t = lambda_t + c (u - u_old) . t (:func:`~dwr_signorini.solve_path`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from ufl.domain import extract_unique_domain

__all__ = [
    "Component",
    "ContactLaw",
    "Coulomb",
    "CoulombCone",
    "Coupling",
    "Frictionless",
    "Normal",
    "Tangential",
    "TangentialBall",
    "Tresca",
    "multiplier_names",
    "tangent_basis",
]

#: Relative round-off level of the parts of the set test: (B u - g)_i below it times
#: M_i max|u| + |g_i|, and (M lam)_i below it times max_j |(M lam)_j|, count as zero.
ROUNDOFF = 1e-10

#: The threshold of Tresca's law: a number, a callable x -> UFL scalar, or one per contact tag.
ThresholdData = float | Callable[[Any], Any] | Mapping[int, Any]


class Component:
    """One multiplier of a contact law and its NCP (module docstring).

    Attributes:
        name: ``"normal"`` or ``"tangential"``.
    """

    name = ""

    def direction(self, n: Any) -> Any:
        """e_k, the direction of the displacement this multiplier acts on (UFL vector)."""
        raise NotImplementedError

    def offset(self, gap: Any) -> Any:
        """g_k, what (u . e_k) is compared with (the gap for the normal, else 0)."""
        return 0.0

    def projection(self, x: Any, bound: Any) -> Any:
        """P_k(x) in UFL; ``bound`` is the law's threshold (UFL) or None."""
        raise NotImplementedError

    def derivative(self, x: Any, bound: Any) -> Any:
        """P_k'(x) in UFL (1 on the constrained part, 0 on the free part)."""
        raise NotImplementedError

    def ncp(self, Mlam: np.ndarray, x: np.ndarray, bound: np.ndarray | None) -> np.ndarray:
        """The algebraic NCP function (20): (M lam)_i - P_k(x_i), x = M lam + c (B u - g)."""
        raise NotImplementedError

    def newton_set(
        self, Mlam: np.ndarray, residual: np.ndarray, c: np.ndarray, M: np.ndarray,
        g: np.ndarray, u_max: float, force_size: float, bound: np.ndarray | None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The set test of this component's rows (eq. 21 and its tangential analogue).

        Args:
            Mlam: (M lam)_i on the owned rows.
            residual: (B u - g)_i, the displacement part (N u - g for the normal).
            c: c_i of the NCP.
            M: M_i (sizes of the macro contact facets).
            g: g_i (the assembled offset).
            u_max: ``max |u|`` over all ranks.
            force_size: ``max_j |(M lam)_j|`` over all ranks.
            bound: (M s)_i, the integrated threshold, or None.

        Returns:
            ``(constrained, free, ncp, size)``: the rows the Newton step constrains, the value
            of lambda on the free rows, ``|C_k|`` of eq. (20) and the size it is relative to.
        """
        raise NotImplementedError


def _cleaned(
    Mlam: np.ndarray, residual: np.ndarray, c: np.ndarray, M: np.ndarray, g: np.ndarray,
    u_max: float, force_size: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The set test's argument x = M lam + c (B u - g), three ways.

    Returns:
        x with each part zero below its round-off level, x as it is, and the size of its parts.
    """
    gap_size = M * u_max + np.abs(g)
    size = np.abs(Mlam) + c * gap_size
    clean = np.where(np.abs(Mlam) > ROUNDOFF * force_size, Mlam, 0.0) + c * (
        np.where(np.abs(residual) > ROUNDOFF * gap_size, residual, 0.0)
    )
    return clean, Mlam + c * residual, size


class Normal(Component):
    """Signorini's condition: P_n(x) = max(0, x); constrained = active (eq. 21)."""

    name = "normal"

    def direction(self, n: Any) -> Any:
        """See the base class."""
        return n

    def offset(self, gap: Any) -> Any:
        """See the base class."""
        return gap

    def projection(self, x: Any, bound: Any) -> Any:
        """See the base class."""
        return ufl.max_value(0.0, x)

    def derivative(self, x: Any, bound: Any) -> Any:
        """See the base class."""
        return ufl.conditional(ufl.gt(x, 0.0), 1.0, 0.0)

    def ncp(self, Mlam, x, bound):  # noqa: D102  (see Component)
        return Mlam - np.maximum(0.0, x)

    def newton_set(self, Mlam, residual, c, M, g, u_max, force_size, bound):  # noqa: D102  (see Component)
        clean, test, size = _cleaned(Mlam, residual, c, M, g, u_max, force_size)
        return clean > 0.0, np.zeros_like(Mlam), np.abs(self.ncp(Mlam, test, bound)), size


class Tangential(Component):
    """Tresca's condition in 2D: P_t(x) = max(-s, min(s, x)); constrained = stick.

    In 3D a tangential component is one coordinate of lambda_t in the facet's tangent basis
    (:func:`tangent_basis`); its projection is the ball's (:class:`TangentialBall`), so the
    scalar projection below is the 2D one.

    Args:
        axis: None in 2D (t = (-n_2, n_1)); 0 or 1 in 3D (t_1 or t_2 of :func:`tangent_basis`).
    """

    name = "tangential"

    def __init__(self, axis: int | None = None) -> None:
        self.axis = axis

    def direction(self, n: Any) -> Any:
        """See the base class."""
        if self.axis is None:
            return ufl.as_vector((-n[1], n[0]))
        return tangent_basis(n)[self.axis]

    def projection(self, x: Any, bound: Any) -> Any:
        """See the base class."""
        return ufl.max_value(-bound, ufl.min_value(bound, x))

    def derivative(self, x: Any, bound: Any) -> Any:
        """See the base class."""
        return ufl.conditional(ufl.lt(abs(x), bound), 1.0, 0.0)

    def ncp(self, Mlam, x, bound):  # noqa: D102  (see Component)
        return Mlam - np.clip(x, -bound, bound)

    def newton_set(self, Mlam, residual, c, M, g, u_max, force_size, bound):  # noqa: D102  (see Component)
        clean, test, size = _cleaned(Mlam, residual, c, M, g, u_max, force_size)
        stick = np.abs(clean) < bound
        free = np.where(stick, 0.0, np.sign(clean) * bound / M)
        return stick, free, np.abs(self.ncp(Mlam, test, bound)), size + bound


@dataclass
class Coupling:
    """Rows whose Newton step is a general linearisation of the NCP (module docstring).

    For facet f of the group's components k (rows ``rows[f, k]``) the step solves

        sum_l [(delta_kl - J_kl) M_f lam_l - c_f J_kl (B u)_l] = r_k - c_f sum_l J_kl g_l,

    J = P'(x) the generalised derivative of the group's projection at the iterate x and
    r = P(x) - J x (eq. 20 linearised; the offsets g are those of the system that solves the
    step, so that a P2 system of the same step uses its own). A row of a coupled facet that
    the step constrains (the normal row of a facet slipping under Coulomb's law, whose row of
    J is that of an active facet) keeps the constrained row's equation; the other rows couple
    to its column.

    Attributes:
        rows: (m, k) owned multiplier rows of the m coupled facets.
        J: (m, k, k) the derivative blocks.
        r: (m, k) P(x) - J x.
    """

    rows: np.ndarray
    J: np.ndarray
    r: np.ndarray

    @staticmethod
    def empty(k: int) -> Coupling:
        """No coupled facet (for a group of k components)."""
        return Coupling(np.zeros((0, k), dtype=np.int64), np.zeros((0, k, k)), np.zeros((0, k)))

    def mask(self, n: int) -> np.ndarray:
        """The coupled rows as a mask of ``n`` owned rows."""
        out = np.zeros(n, dtype=bool)
        out[self.rows.ravel()] = True
        return out

    def restricted(self, keep: np.ndarray) -> Coupling:
        """The coupled facets of the mask ``keep`` (one entry per facet)."""
        return Coupling(self.rows[keep], self.J[keep], self.r[keep])


class TangentialBall:
    """Tresca's condition in 3D: lambda_t in the disc of radius s (module docstring).

    The projection onto the ball B(s) of R^2, P(x) = x min(1, s / |x|), is smooth off the
    sphere |x| = s; its derivative is I where |x| < s (stick: the step constrains
    u_t = 0, both rows constrained) and (s / |x|) (I - q q^T), q = x / |x|, where the facet
    slips. A slipping facet's rows are coupled (:class:`Coupling`): the exact derivative of
    the projection, not a fixed-point on the slip direction, so that the Newton method
    converges locally quadratically and the dual problem is the transposed linearisation the
    error identity needs. The Newton matrix is then not symmetric (its rows have
    (s / |x|)(I - q q^T) c B, its columns B^T), and is factored by LU.
    """

    size = 2

    def projection(self, xs: Any, bound: Any) -> list:
        """P(x) in UFL, one entry per component."""
        norm = ufl.sqrt(xs[0] ** 2 + xs[1] ** 2)
        factor = ufl.conditional(ufl.gt(norm, bound), bound / ufl.max_value(norm, bound), 1.0)
        return [factor * x for x in xs]

    def derivative(self, xs: Any, bound: Any) -> list:
        """P'(x) in UFL, a 2 x 2 list of rows."""
        norm = ufl.sqrt(xs[0] ** 2 + xs[1] ** 2)
        slip = ufl.gt(norm, bound)
        safe = ufl.max_value(norm, bound)
        factor = ufl.conditional(slip, bound / safe, 1.0)
        curvature = ufl.conditional(slip, bound / safe**3, 0.0)
        return [
            [factor * (1.0 if i == j else 0.0) - curvature * xs[i] * xs[j] for j in range(2)]
            for i in range(2)
        ]

    @staticmethod
    def project(x: np.ndarray, bound: np.ndarray) -> np.ndarray:
        """P(x) on the rows: x of shape (2, m), bound (m,)."""
        norm = np.hypot(x[0], x[1])
        return x * np.minimum(1.0, np.divide(bound, norm, out=np.ones_like(norm), where=norm > 0))

    def ncp(self, Mlam: np.ndarray, x: np.ndarray, bound: np.ndarray) -> np.ndarray:
        """(M lam) - P(x), shape (2, m)."""
        return Mlam - self.project(x, bound)

    def newton_set(
        self, Mlam: np.ndarray, residual: np.ndarray, c: np.ndarray, M: np.ndarray,
        g: np.ndarray, u_max: float, force_size: float, bound: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """The set test of the pair of rows (as :meth:`Component.newton_set`, arrays (2, m)).

        Returns:
            ``(constrained, free, ncp, size, (slip, J, r))``: the stick facets' rows are
            constrained, no row is free, and the slipping facets (mask ``slip``) carry their
            derivative blocks J (m_slip, 2, 2) and right-hand sides r (m_slip, 2).
        """
        parts = [_cleaned(Mlam[k], residual[k], c, M, g[k], u_max, force_size) for k in range(2)]
        clean = np.array([p[0] for p in parts])
        test = np.array([p[1] for p in parts])
        size = np.array([p[2] for p in parts])
        norm = np.hypot(clean[0], clean[1])
        stick = norm < bound
        slip = ~stick
        q = clean[:, slip] / norm[slip]
        alpha = bound[slip] / norm[slip]
        J = alpha[:, None, None] * (np.eye(2)[None] - np.einsum("im,jm->mij", q, q))
        r = (bound[slip] * q).T  # P(x) - J x, as J x = 0
        constrained = np.array([stick, stick])
        ncp = np.abs(self.ncp(Mlam, test, bound))
        return constrained, np.zeros_like(Mlam), ncp, size + bound, (slip, J, r)


class CoulombCone:
    """Coulomb's law on a facet: the normal condition and the tangential one in a cone.

    The projection of Coulomb's NCP acts on all components of a facet, x = (x_n, x_t):
    P_n(x) = max(0, x_n) (Signorini) and P_t(x) = the projection of x_t onto the interval
    [-s, s] (2D) or the disc of radius s (3D), s = mu max(0, x_n) (module docstring of
    :class:`Coulomb`). Where the facet is active and slips, P_t depends on x_n through s:
    dP_t / dx_n = mu d, with d = sign(x_t) (2D) or q = x_t / ``|x_t|`` (3D), and the facet is a
    :class:`Coupling`: its normal row is constrained (active), its tangential rows are
    lambda_t = mu d lambda_n linearised (2D) or the ball's rows with the column mu q (3D).
    Active and sticking: every row constrained; inactive: every row free (lambda = 0).

    Args:
        tangential: The tangential projection: :class:`Tangential` (2D) or
            :class:`TangentialBall` (3D).
    """

    def __init__(self, tangential: Tangential | TangentialBall) -> None:
        self.tangential = tangential
        self.size = 1 + getattr(tangential, "size", 1)

    def _threshold(self, x_n: Any, mu: Any) -> Any:
        return mu * ufl.max_value(0.0, x_n)

    def projection(self, xs: Any, mu: Any) -> list:
        """P(x) in UFL, one entry per component (normal first); ``mu`` the coefficient."""
        s = self._threshold(xs[0], mu)
        xt = list(xs[1:])
        if self.size == 2:
            tangential = [self.tangential.projection(xt[0], s)]
        else:
            tangential = self.tangential.projection(xt, s)
        return [Normal().projection(xs[0], None), *tangential]

    def derivative(self, xs: Any, mu: Any) -> list:
        """P'(x) in UFL, a list of rows (normal first)."""
        s = self._threshold(xs[0], mu)
        active = ufl.conditional(ufl.gt(xs[0], 0.0), 1.0, 0.0)
        xt = list(xs[1:])
        if self.size == 2:
            stick = self.tangential.derivative(xt[0], s)
            rows = [[stick]]
            direction = [(1.0 - stick) * ufl.sign(xt[0])]
        else:
            rows = self.tangential.derivative(xt, s)
            norm = ufl.sqrt(xt[0] ** 2 + xt[1] ** 2)
            slip = ufl.conditional(ufl.gt(norm, s), 1.0, 0.0)
            direction = [slip * x / ufl.max_value(norm, ufl.max_value(s, 1e-300)) for x in xt]
        normal_row = [active] + [0.0] * (self.size - 1)
        return [normal_row] + [
            [mu * active * d, *row] for d, row in zip(direction, rows, strict=True)
        ]

    def _project(self, x: np.ndarray, s: np.ndarray) -> np.ndarray:
        """P_t on the rows: x of shape (k - 1, m), the thresholds s (m,)."""
        if self.size == 2:
            return np.clip(x, -s, s)
        return TangentialBall.project(x, s)

    def ncp(self, Mlam: np.ndarray, x: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """(M lam) - P(x) on the rows, shape (k, m), with the facet coefficients mu_i."""
        s = mu * np.maximum(0.0, x[0])
        return np.concatenate(
            [[Mlam[0] - np.maximum(0.0, x[0])], Mlam[1:] - self._project(x[1:], s)]
        )

    def newton_set(
        self, Mlam: np.ndarray, residual: np.ndarray, c: np.ndarray, M: np.ndarray,
        g: np.ndarray, u_max: float, force_size: float, bound: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """The set test of a facet's rows (as :meth:`TangentialBall.newton_set`, arrays (k, m)).

        ``bound`` is the friction coefficient mu_i of each facet (its facet mean).

        Returns:
            ``(constrained, free, ncp, size, (slip, J, r))``: active rows and sticking
            facets' tangential rows constrained, no free value other than 0, and the active
            slipping facets (mask ``slip``) with their derivative blocks J (m_slip, k, k) and
            r = P(x) - J x = 0 (P is positively homogeneous).
        """
        k = self.size
        parts = [_cleaned(Mlam[i], residual[i], c, M, g[i], u_max, force_size) for i in range(k)]
        clean = np.array([p[0] for p in parts])
        test = np.array([p[1] for p in parts])
        size = np.array([p[2] for p in parts])
        mu = bound
        active = clean[0] > 0.0
        s = mu * np.maximum(clean[0], 0.0)
        xt = clean[1:]
        norm = np.abs(xt[0]) if k == 2 else np.hypot(xt[0], xt[1])
        stick = active & (norm < s)
        slip = active & ~stick
        m = int(slip.sum())
        J = np.zeros((m, k, k))
        J[:, 0, 0] = 1.0
        d = xt[:, slip] / np.where(norm[slip] > 0, norm[slip], 1.0)
        J[:, 1:, 0] = (mu[slip] * d).T
        if k == 3:
            alpha = s[slip] / np.where(norm[slip] > 0, norm[slip], 1.0)
            J[:, 1:, 1:] = alpha[:, None, None] * (
                np.eye(2)[None] - np.einsum("im,jm->mij", d, d)
            )
        constrained = np.array([active] + [stick] * (k - 1))
        ncp = np.abs(self.ncp(Mlam, test, mu))
        size = size.copy()
        size[1:] += mu * size[0]
        return constrained, np.zeros_like(Mlam), ncp, size, (slip, J, np.zeros((m, k)))


class ContactLaw:
    """A contact law: its components and the threshold data (module docstring).

    Attributes:
        name: A short name for tables.
        frictional: Whether the law has a tangential component.
    """

    name = ""
    frictional = False

    def components(self, tdim: int) -> tuple[Component, ...]:
        """The law's multipliers on a mesh of dimension ``tdim`` (normal first)."""
        raise NotImplementedError

    def bound_expr(self, problem: Any, x: Any) -> Any:
        """The threshold data as a UFL expression on the mesh of ``x`` (None without one)."""
        return None

    def bound(self, data: Any, x_normal: Any) -> Any:
        """The tangential threshold in UFL from the data and the normal NCP argument x_n."""
        return None

    def row_bound(
        self, data: np.ndarray | None, active: np.ndarray, M: np.ndarray
    ) -> np.ndarray | None:
        """The threshold data of the tangential conditions on the rows, None without one.

        Args:
            data: The integrated threshold data, (M s)_i (Tresca) or (M mu)_i (Coulomb).
            active: The active rows of the normal component.
            M: M_i, the sizes of the macro contact facets.

        Returns:
            What the law's tangential condition takes as ``bound``: (M s)_i (Tresca), mu_i
            (Coulomb), or None.
        """
        return None

    def conditions(self, tdim: int) -> list[tuple[tuple[int, ...], Any]]:
        """The law's conditions: the components each projection acts on, and the projection.

        Default: one condition per component (its own scalar projection).
        """
        return [((k,), comp) for k, comp in enumerate(self.components(tdim))]

    def symmetric(self, tdim: int) -> bool:
        """Whether the law's Newton matrices are symmetric (no :class:`Coupling` rows)."""
        return all(len(idx) == 1 for idx, _ in self.conditions(tdim))

    def ncp_arguments(
        self, u: Any, lams: Any, gap: Any, n: Any, c: Any, problem: Any, u_old: Any = None
    ) -> list:
        """Each component's UFL (x_k, P_k(x), J_k), x_k = lambda_k + c (u . e_k - g_k).

        J_k is row k of the derivative P'(x) of the law's projections: a tuple with an entry
        per component (the number 0.0 where P_k does not depend on x_l). With ``u_old`` (the
        displacement at the end of the previous load step) a tangential component's argument
        holds the slip increment, x_k = lambda_k + c (u - u_old) . e_k.

        Args:
            u: The displacement.
            lams: The multipliers, one per component (normal first).
            gap: The gap g (UFL).
            n: The outward unit normal.
            c: The scale of the NCP.
            problem: The problem (for the threshold data).
            u_old: The displacement of the previous load step, or None (zero).

        Returns:
            One tuple per component, normal first.
        """
        tdim = len(n)
        comps = self.components(tdim)
        data = self.bound_expr(problem, extract_x(n)) if len(comps) > 1 else None
        xs = [
            lam + c * (ufl.dot(u, comp.direction(n)) - comp.offset(gap))
            - (0.0 if u_old is None or k == 0 else c * ufl.dot(u_old, comp.direction(n)))
            for k, (comp, lam) in enumerate(zip(comps, lams, strict=True))
        ]
        P: list[Any] = [None] * len(comps)
        J: list[list[Any]] = [[0.0] * len(comps) for _ in comps]
        for idx, cond in self.conditions(tdim):
            bound = None if idx == (0,) else self.bound(data, xs[0])
            if len(idx) == 1:
                k = idx[0]
                P[k], J[k][k] = cond.projection(xs[k], bound), cond.derivative(xs[k], bound)
                continue
            group = [xs[k] for k in idx]
            for a, (p, row) in enumerate(
                zip(cond.projection(group, bound), cond.derivative(group, bound), strict=True)
            ):
                P[idx[a]] = p
                for b, entry in enumerate(row):
                    J[idx[a]][idx[b]] = entry
        return [(x, p, tuple(row)) for x, p, row in zip(xs, P, J, strict=True)]

    def check(self, problem: Any) -> ContactLaw:
        """Validate the law's data against ``problem``; returns the law (ValueError else)."""
        return self


class Frictionless(ContactLaw):
    """Frictionless contact (Signorini): the normal contact force alone, lambda_t = 0."""

    name = "frictionless"

    def components(self, tdim: int) -> tuple[Component, ...]:
        """See the base class."""
        return (Normal(),)

    def __repr__(self) -> str:
        """The law as it is constructed."""
        return "Frictionless()"


class _Friction(ContactLaw):
    """What the frictional laws share: the components and the data given per contact tag.

    Attributes:
        data: The law's data (Tresca's s, Coulomb's mu), validated.
    """

    frictional = True
    #: The data's name in messages, e.g. ``"Tresca(s)"``.
    label = ""

    def components(self, tdim: int) -> tuple[Component, ...]:
        """See the base class: in 3D the two coordinates of lambda_t in the tangent basis."""
        if tdim == 2:
            return (Normal(), Tangential())
        return (Normal(), Tangential(0), Tangential(1))

    def check(self, problem: Any) -> _Friction:
        """Tags of data given per tag are the contact tags; a callable returns a scalar."""
        label, data = self.label, self.data
        values = data.items() if isinstance(data, Mapping) else [(None, data)]
        if isinstance(data, Mapping):
            keys = set(data)
            extra = keys - set(problem.contact_tags)
            if extra:
                raise ValueError(
                    f"friction={label}: {self.symbol} has tag(s) {sorted(extra)} that are not "
                    f"contact tags {problem.contact_tags}"
                )
            missing = set(problem.contact_tags) - keys
            if missing:
                raise ValueError(
                    f"friction={label}: {self.symbol} is given per contact tag but misses the "
                    f"contact tag(s) {sorted(missing)}"
                )
        for tag, value in values:
            if callable(value):
                name = label if tag is None else f"{label}[{tag}]"
                problem._check_callable(value, name, ())
        return self

    @property
    def symbol(self) -> str:
        """The data's symbol (``s``, ``mu``)."""
        return self.label[self.label.index("(") + 1 : -1]

    def bound_expr(self, problem: Any, x: Any) -> Any:
        """The data as UFL on the mesh of ``x`` (per tag by contact-tag indicators)."""
        return problem.contact_expr(self.data, x, self.label)

    def bound(self, data: Any, x_normal: Any) -> Any:
        """The data as the tangential condition takes it (s; mu for Coulomb's cone)."""
        return data

    def __repr__(self) -> str:
        """The law as it is constructed."""
        return f"{type(self).__name__}({self.data!r})"


class Tresca(_Friction):
    """Tresca friction with slip threshold s > 0 (module docstring).

    Args:
        s: The slip threshold (a force per area): a number, a callable x -> UFL scalar, or
            ``{contact tag: number | callable}``.

    Raises:
        TypeError, ValueError: ``s`` of the wrong type, or a number that is not finite and > 0.
    """

    name = "tresca"
    label = "Tresca(s)"

    def __init__(self, s: ThresholdData) -> None:
        self.s = self.data = _check_threshold(s, self.label)

    def conditions(self, tdim: int) -> list[tuple[tuple[int, ...], Any]]:
        """See the base class: in 3D the ball projection acts on both tangential rows."""
        if tdim == 2:
            return super().conditions(tdim)
        return [((0,), Normal()), ((1, 2), TangentialBall())]

    def row_bound(
        self, data: np.ndarray | None, active: np.ndarray, M: np.ndarray
    ) -> np.ndarray | None:
        """The integrated threshold (M s)_i on every row."""
        return data


class Coulomb(_Friction):
    """Coulomb friction with friction coefficient mu >= 0: slip threshold mu lambda_n.

    The NCP of the tangential traction (with the slip increment of a load step,
    u_t - u_t^old; :func:`~dwr_signorini.path.solve_path` carries u^old from step to step,
    a single solve has u^old = 0)

        lambda_t - P_B(mu max(0, x_n))(lambda_t + c (u_t - u_t^old)) = 0,
        x_n = lambda_n + c (u_n - g),

    with P_B(s) the projection onto [-s, s] (2D) or the disc of radius s (3D). The normal and
    tangential conditions form one projection onto the Coulomb cone (:class:`CoulombCone`):
    where a facet is active and slips, its tangential rows depend on x_n, so the Newton matrix
    couples the normal and tangential blocks and is not symmetric (LU,
    :mod:`dwr_signorini.linalg.coupled`); the dual problem is its transpose. The threshold
    follows contact, so the discrete problem is a quasi-variational inequality: unique for
    mu small enough (the classical bound of Necas, Jarusek and Haslinger in the continuum,
    mu < sqrt(3 - 4 nu) / (2 - 2 nu) for the discrete problems of Haslinger's analysis),
    possibly not above. mu = 0 gives lambda_t = 0: the frictionless problem.

    Args:
        mu: The friction coefficient: a number >= 0, a callable x -> UFL scalar, or
            ``{contact tag: number | callable}``.

    Raises:
        TypeError, ValueError: ``mu`` of the wrong type, or a number that is not finite and
            >= 0.
    """

    name = "coulomb"
    label = "Coulomb(mu)"

    def __init__(self, mu: ThresholdData) -> None:
        self.mu = self.data = _check_threshold(mu, self.label, zero=True)

    def conditions(self, tdim: int) -> list[tuple[tuple[int, ...], Any]]:
        """See the base class: one projection onto the Coulomb cone on all components."""
        tangential = Tangential() if tdim == 2 else TangentialBall()
        return [(tuple(range(tdim)), CoulombCone(tangential))]

    def row_bound(
        self, data: np.ndarray | None, active: np.ndarray, M: np.ndarray
    ) -> np.ndarray | None:
        """The facet mean of mu, (M mu)_i / M_i."""
        return data / M


def tangent_basis(n: Any) -> tuple[Any, Any]:
    """An orthonormal basis (t_1, t_2) of the plane normal to the unit vector n (3D, UFL).

    t_1 is the unit projection of e_1 onto that plane (of e_2 where ``|n_1| >= 0.9``, so that the
    projection is not short) and t_2 = n x t_1; (t_1, t_2, n) is right-handed. On a flat face
    the basis is constant; the switch between e_1 and e_2 is a jump of the basis where the
    normal crosses ``|n_1| = 0.9``, so a contact zone should not straddle it (a face with normal
    +-e_1 and one with ``|n_1| < 0.9`` are each fine).

    Args:
        n: The unit normal (a UFL vector of length 3).

    Returns:
        (t_1, t_2) as UFL vectors.
    """
    use_e1 = ufl.lt(abs(n[0]), 0.9)
    a = ufl.as_vector((ufl.conditional(use_e1, 1.0, 0.0), ufl.conditional(use_e1, 0.0, 1.0), 0.0))
    t1 = a - ufl.dot(a, n) * n
    t1 = t1 / ufl.sqrt(ufl.dot(t1, t1))
    return t1, ufl.cross(n, t1)


def multiplier_names(components: tuple, name: str) -> list[str]:
    """The names of the functions of the law's multipliers: name, name_t or name_t1, name_t2."""
    out = [name]
    for comp in components[1:]:
        axis = getattr(comp, "axis", None)
        out.append(f"{name}_t" if axis is None else f"{name}_t{axis + 1}")
    return out


def extract_x(n: Any) -> Any:
    """The spatial coordinate of the mesh of the UFL expression ``n``."""
    return ufl.SpatialCoordinate(extract_unique_domain(n))


def _check_threshold(s: Any, name: str, zero: bool = False) -> Any:
    """A law's data validated: a number > 0 (>= 0 with ``zero``), a callable, or a dict.

    The dict holds the data per contact tag; ``name`` (as ``"Tresca(s)"``) names the data in
    the messages.
    """
    symbol = name[name.index("(") + 1 : name.index(")")]
    what = "friction coefficient" if zero else "slip threshold"
    if isinstance(s, Mapping):
        if not s:
            raise ValueError(f"{name}: {symbol} is an empty dict; give a {what} per contact tag")
        out = {}
        for k, v in s.items():
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
                raise TypeError(
                    f"{name}: the keys of {symbol} must be integer contact tags, got {k!r}"
                )
            out[int(k)] = _check_threshold(v, f"{name}[{k}]", zero)
        return out
    if callable(s):
        return s
    if isinstance(s, bool) or not isinstance(s, (int, float, np.integer, np.floating)):
        raise TypeError(
            f"{name}: {symbol} must be a number, a callable x -> UFL scalar or a dict per "
            f"contact tag, got {type(s).__name__}"
        )
    if zero and not (math.isfinite(float(s)) and float(s) >= 0.0):
        raise ValueError(
            f"{name}: the {what} {symbol} must be a finite number >= 0, got {s!r}"
        )
    if not zero and not (math.isfinite(float(s)) and float(s) > 0.0):
        raise ValueError(
            f"{name}: the {what} {symbol} must be a finite number > 0 ({symbol} -> 0 is "
            f"frictionless: use friction=None), got {s!r}"
        )
    return float(s)


def check_law(law: Any, problem: Any) -> ContactLaw:
    """``friction`` of :class:`~dwr_signorini.SignoriniProblem` validated (None: frictionless)."""
    if law is None:
        return Frictionless()
    if not isinstance(law, ContactLaw):
        raise TypeError(
            "friction must be None, ds.Frictionless(), ds.Tresca(s) or ds.Coulomb(mu), got "
            f"{type(law).__name__}"
        )
    return law.check(problem)
