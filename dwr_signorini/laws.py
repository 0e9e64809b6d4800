"""Contact laws: the NCP functions of the contact conditions and their generalised derivatives.

A law is a list of *components*, one per multiplier on the macro contact facets: the normal
contact force lambda_n for every law, and the tangential traction lambda_t of a frictional law
(a scalar in 2D, along the tangent t = (-n_2, n_1)). Component k has a direction e_k (n or t),
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
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import ufl
from ufl.domain import extract_unique_domain

__all__ = ["Component", "ContactLaw", "Frictionless", "Normal", "Tangential", "Tresca"]

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
    """Tresca's condition in 2D: P_t(x) = max(-s, min(s, x)); constrained = stick."""

    name = "tangential"

    def direction(self, n: Any) -> Any:
        """See the base class."""
        return ufl.as_vector((-n[1], n[0]))

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

    def row_bound(self, data: np.ndarray | None, active: np.ndarray) -> np.ndarray | None:
        """The tangential threshold on the rows, None without one.

        Args:
            data: The integrated threshold data, (M s)_i.
            active: The active rows of the normal component (a threshold that follows contact,
                as Coulomb's, needs them).

        Returns:
            (M s)_i per tangential row, or None.
        """
        return None

    def ncp_arguments(self, u: Any, lams: Any, gap: Any, n: Any, c: Any, problem: Any) -> list:
        """Each component's UFL (x_k, P_k(x_k), P_k'(x_k)), x_k = lambda_k + c (u . e_k - g_k).

        Args:
            u: The displacement.
            lams: The multipliers, one per component (normal first).
            gap: The gap g (UFL).
            n: The outward unit normal.
            c: The scale of the NCP.
            problem: The problem (for the threshold data).

        Returns:
            One tuple per component, normal first.
        """
        comps = self.components(len(n))
        out = []
        data = self.bound_expr(problem, extract_x(n)) if len(comps) > 1 else None
        bound = None
        for k, (comp, lam) in enumerate(zip(comps, lams, strict=True)):
            x = lam + c * (ufl.dot(u, comp.direction(n)) - comp.offset(gap))
            if k == 1:
                bound = self.bound(data, out[0][0])
            out.append((x, comp.projection(x, bound), comp.derivative(x, bound)))
        return out

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


class Tresca(ContactLaw):
    """Tresca friction with slip threshold s > 0 (module docstring).

    Args:
        s: The slip threshold (a force per area): a number, a callable x -> UFL scalar, or
            ``{contact tag: number | callable}``.

    Raises:
        TypeError, ValueError: ``s`` of the wrong type, or a number that is not finite and > 0.
    """

    name = "tresca"
    frictional = True

    def __init__(self, s: ThresholdData) -> None:
        self.s = _check_threshold(s, "Tresca(s)")

    def __repr__(self) -> str:
        """The law as it is constructed."""
        return f"Tresca({self.s!r})"

    def components(self, tdim: int) -> tuple[Component, ...]:
        """See the base class."""
        if tdim != 2:
            raise NotImplementedError(
                "Tresca friction is implemented for 2D problems (plane strain/stress); in 3D "
                "the tangential traction is a vector in the facet's tangent plane, not yet "
                "supported"
            )
        return (Normal(), Tangential())

    def check(self, problem: Any) -> Tresca:
        """Tags of a per-tag threshold are the contact tags; a callable returns a scalar."""
        if problem.mesh.topology.dim != 2:
            self.components(problem.mesh.topology.dim)
        values = self.s.items() if isinstance(self.s, Mapping) else [(None, self.s)]
        if isinstance(self.s, Mapping):
            keys = set(self.s)
            extra = keys - set(problem.contact_tags)
            if extra:
                raise ValueError(
                    f"friction=Tresca(s): s has tag(s) {sorted(extra)} that are not contact "
                    f"tags {problem.contact_tags}"
                )
            missing = set(problem.contact_tags) - keys
            if missing:
                raise ValueError(
                    f"friction=Tresca(s): s is given per contact tag but misses the contact "
                    f"tag(s) {sorted(missing)}"
                )
        for tag, value in values:
            if callable(value):
                name = "Tresca(s)" if tag is None else f"Tresca(s)[{tag}]"
                problem._check_callable(value, name, ())
        return self

    def bound_expr(self, problem: Any, x: Any) -> Any:
        """The threshold s as UFL on the mesh of ``x`` (per tag by contact-tag indicators)."""
        return problem.contact_expr(self.s, x, "Tresca(s)")

    def bound(self, data: Any, x_normal: Any) -> Any:
        """The threshold s, whatever the normal state."""
        return data

    def row_bound(self, data: np.ndarray | None, active: np.ndarray) -> np.ndarray | None:
        """The integrated threshold (M s)_i on every row."""
        return data


def extract_x(n: Any) -> Any:
    """The spatial coordinate of the mesh of the UFL expression ``n``."""
    return ufl.SpatialCoordinate(extract_unique_domain(n))


def _check_threshold(s: Any, name: str) -> Any:
    """A threshold validated: a finite number > 0, a callable, or a dict of them per tag."""
    if isinstance(s, Mapping):
        if not s:
            raise ValueError(f"{name}: s is an empty dict; give a threshold per contact tag")
        out = {}
        for k, v in s.items():
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
                raise TypeError(f"{name}: the keys of s must be integer contact tags, got {k!r}")
            out[int(k)] = _check_threshold(v, f"{name}[{k}]")
        return out
    if callable(s):
        return s
    if isinstance(s, bool) or not isinstance(s, (int, float, np.integer, np.floating)):
        raise TypeError(
            f"{name}: s must be a number, a callable x -> UFL scalar or a dict per contact tag, "
            f"got {type(s).__name__}"
        )
    if not (math.isfinite(float(s)) and float(s) > 0.0):
        raise ValueError(
            f"{name}: the slip threshold s must be a finite number > 0 (s -> 0 is frictionless: "
            f"use friction=None), got {s!r}"
        )
    return float(s)


def check_law(law: Any, problem: Any) -> ContactLaw:
    """``friction`` of :class:`~dwr_signorini.SignoriniProblem` validated (None: frictionless)."""
    if law is None:
        return Frictionless()
    if not isinstance(law, ContactLaw):
        raise TypeError(
            "friction must be None, ds.Frictionless() or ds.Tresca(s), got "
            f"{type(law).__name__}"
        )
    return law.check(problem)
