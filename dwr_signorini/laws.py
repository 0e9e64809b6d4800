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

    def bound_expr(self, fields: Any, x: Any) -> Any:
        """The threshold data as UFL on the mesh of ``x`` and its ``fields`` (None without one)."""
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
        self, u: Any, lams: Any, gap: Any, n: Any, c: Any, fields: Any, u_old: Any = None
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
            fields: The :class:`~dwr_signorini.fields.MeshFields` of the mesh (the threshold).
            u_old: The displacement of the previous load step, or None (zero).

        Returns:
            One tuple per component, normal first.
        """
        tdim = len(n)
        comps = self.components(tdim)
        data = self.bound_expr(fields, extract_x(n)) if len(comps) > 1 else None
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


# The friction laws live in dwr_signorini.friction; they are part of this module's namespace.
from .friction import (  # noqa: E402
    Coulomb,
    CoulombCone,
    Tangential,
    TangentialBall,
    Tresca,
    tangent_basis,
)
