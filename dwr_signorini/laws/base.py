"""The interface of a contact law: its components, their conditions and the coupled rows.

A law (:class:`ContactLaw`) is a list of components (:class:`Component`), one per multiplier,
each with its direction, its offset, its projection P_k and generalised derivative P_k' in UFL,
and its algebraic NCP function and set test on the rows; :meth:`ContactLaw.conditions` groups
components whose projection acts on them together, and the rows such a projection couples are a
:class:`Coupling`. :func:`set_test_argument` is the round-off cleaned argument of every set
test. The laws themselves are :mod:`dwr_signorini.laws.frictionless` and
:mod:`dwr_signorini.laws.friction`; the ideas are in :mod:`dwr_signorini.laws`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from ufl.domain import extract_unique_domain

__all__ = [
    "ROUNDOFF",
    "Component",
    "ContactLaw",
    "Coupling",
    "extract_x",
    "multiplier_names",
    "set_test_argument",
]

#: Relative round-off level of the parts of the set test: (B u - g)_i below it times
#: M_i max|u| + |g_i|, and (M lam)_i below it times max_j |(M lam)_j|, count as zero.
ROUNDOFF = 1e-10



class Component:
    """One multiplier of a contact law and its NCP (:mod:`dwr_signorini.laws`).

    Attributes:
        name: ``"normal"`` or ``"tangential"``.
    """

    name = ""

    def direction(self, n: Any) -> Any:
        """e_k, the direction of the displacement this multiplier acts on (UFL vector)."""
        raise NotImplementedError

    def direction_in(self, n: Any, frame: Any) -> Any:
        """e_k in the contact frame: a tangent of the plane normal to ``frame``.

        ``frame`` is the normal n_c of the contact frame
        (:meth:`~dwr_signorini.spaces.Discretization.contact_frame`), in which the relative
        displacement is split: the obstacle's normal, or the bisector of the two normals of a
        pair; the normal component overrides this with n_c itself.
        """
        return self.direction(frame)

    def offset_in(self, gap: Any, n: Any, frame: Any) -> Any:
        """g_k in the contact frame of normal ``frame`` (``gap`` is measured along ``n``).

        0 for a tangential component; the normal one compares with g (n . n_c), the component
        of the gap vector g n along n_c.
        """
        return self.offset(gap)

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


def set_test_argument(
    Mlam: np.ndarray, residual: np.ndarray, c: np.ndarray, M: np.ndarray, g: np.ndarray,
    u_max: float, force_size: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The set test's argument x = M lam + c (B u - g), three ways.

    Every component's set test (:meth:`Component.newton_set`) takes its argument from here,
    on the rows of one component (arrays (m,)) or of a condition's k components at once
    (``Mlam``, ``residual``, ``g`` of shape (k, m); every operation is elementwise).

    Args:
        Mlam: (M lam)_i on the owned rows.
        residual: (B u - g)_i, the displacement part.
        c: c_i of the NCP, (m,).
        M: M_i (sizes of the macro contact facets), (m,).
        g: g_i (the assembled offset).
        u_max: ``max |u|`` over all ranks.
        force_size: ``max_j |(M lam)_j|`` over all ranks.

    Returns:
        x with each part zero below its round-off level (:data:`ROUNDOFF`), x as it is, and
        the size of its parts.
    """
    gap_size = M * u_max + np.abs(g)
    size = np.abs(Mlam) + c * gap_size
    clean = np.where(np.abs(Mlam) > ROUNDOFF * force_size, Mlam, 0.0) + c * (
        np.where(np.abs(residual) > ROUNDOFF * gap_size, residual, 0.0)
    )
    return clean, Mlam + c * residual, size



@dataclass
class Coupling:
    """Rows whose Newton step is a general linearisation of the NCP (:mod:`dwr_signorini.laws`).

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
    """A contact law: its components and the threshold data (:mod:`dwr_signorini.laws`).

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
        self, u: Any, lams: Any, gap: Any, n: Any, c: Any, fields: Any, u_old: Any = None,
        frame: Any = None,
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
            frame: The normal n_c of the contact frame the components are measured in
                (:meth:`Component.direction_in`, :meth:`Component.offset_in`); None takes
                ``n`` (the paper's condition (2)).

        Returns:
            One tuple per component, normal first.
        """
        tdim = len(n)
        comps = self.components(tdim)
        data = self.bound_expr(fields, extract_x(n)) if len(comps) > 1 else None
        frame = n if frame is None else frame
        es = [comp.direction_in(n, frame) for comp in comps]
        xs = [
            lam + c * (ufl.dot(u, e) - comp.offset_in(gap, n, frame))
            - (0.0 if u_old is None or k == 0 else c * ufl.dot(u_old, e))
            for k, (comp, lam, e) in enumerate(zip(comps, lams, es, strict=True))
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


