"""The friction laws: Tresca's and Coulomb's, their projections and tangent bases.

The idea of a contact law, its components, NCP functions and couplings is
:mod:`dwr_signorini.laws` (whose docstring describes these laws) and its interface
:mod:`dwr_signorini.laws.base`; this module holds the laws with a tangential traction:
:class:`Tangential` (a 2D tangential component, Tresca's interval), :class:`TangentialBall`
(Tresca's disc in 3D), :class:`CoulombCone` (Coulomb's cone, normal and tangential rows
together), the set rule :func:`reversing` they share, the laws :class:`Tresca` and
:class:`Coulomb`, and :func:`tangent_basis`. The public path of each name is
:mod:`dwr_signorini.laws`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import ufl

from ..validation import check_callable
from .base import ROUNDOFF, Component, ContactLaw, set_test_argument
from .frictionless import Normal

__all__ = [
    "Coulomb",
    "CoulombCone",
    "Tangential",
    "TangentialBall",
    "ThresholdData",
    "Tresca",
    "reversing",
    "tangent_basis",
]

#: The threshold of Tresca's law: a number, a callable x -> UFL scalar, or one per contact tag.
ThresholdData = float | Callable[[Any], Any] | Mapping[int, Any]


def reversing(Mlam_t: np.ndarray, xt: np.ndarray, force_size: float) -> np.ndarray:
    """The facets whose slip reverses: the test argument x_t points against lambda_t.

    Args:
        Mlam_t: (k, m) the tangential multipliers times M.
        xt: (k, m) the tangential test argument, round-off cleaned.
        force_size: The round-off scale of M lambda.

    Returns:
        A mask of the m facets.

    A set rule of every friction law (Tresca's and Coulomb's): where x_t . lambda_t < 0 the
    last step's friction force pushed the facet back, and the step holds it (stick) instead
    of letting it slip the other way. At a solution lambda_t = P(x_t) points along x_t, so the
    rule never fires there (:meth:`CoulombCone.transitions` says why it is needed).
    """
    tiny = ROUNDOFF * force_size
    return np.einsum("km,km->m", xt, Mlam_t) < -tiny * np.sum(np.abs(xt), axis=0)


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
        clean, test, size = set_test_argument(Mlam, residual, c, M, g, u_max, force_size)
        stick = (np.abs(clean) < bound) | reversing(Mlam[None], clean[None], force_size)
        free = np.where(stick, 0.0, np.sign(clean) * bound / M)
        return stick, free, np.abs(self.ncp(Mlam, test, bound)), size + bound


class TangentialBall:
    """Tresca's condition in 3D: lambda_t in the disc of radius s (module docstring).

    The projection onto the ball B(s) of R^2, P(x) = x min(1, s / |x|), is smooth off the
    sphere |x| = s; its derivative is I where |x| < s (stick: the step constrains
    u_t = 0, both rows constrained) and (s / |x|) (I - q q^T), q = x / |x|, where the facet
    slips. A slipping facet's rows are coupled (:class:`~dwr_signorini.laws.Coupling`): the
    exact derivative of the projection, not a fixed-point on the slip direction, so that the
    Newton method
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
        clean, test, size = set_test_argument(Mlam, residual, c, M, g, u_max, force_size)
        norm = np.hypot(clean[0], clean[1])
        stick = (norm < bound) | reversing(Mlam, clean, force_size)
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

    Args:
        tangential: The tangential projection: :class:`Tangential` (2D) or
            :class:`TangentialBall` (3D).

    The projection of Coulomb's NCP acts on all components of a facet, x = (x_n, x_t):
    P_n(x) = max(0, x_n) (Signorini) and P_t(x) = the projection of x_t onto the interval
    [-s, s] (2D) or the disc of radius s (3D), s = mu max(0, x_n) (module docstring of
    :class:`Coulomb`). Where the facet is active and slips, P_t depends on x_n through s:
    dP_t / dx_n = mu d, with d = sign(x_t) (2D) or q = x_t / ``|x_t|`` (3D), and the facet is a
    :class:`~dwr_signorini.laws.Coupling`: its normal row is constrained (active), its
    tangential rows are lambda_t = mu d lambda_n linearised (2D) or the ball's rows with the
    column mu q (3D).
    Active and sticking: every row constrained; inactive: every row free (lambda = 0).
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

    @staticmethod
    def transitions(
        Mlam: np.ndarray, xt: np.ndarray, force_size: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The facets entering contact and the facets reversing their slip (two set rules).

        Two transitions of the set test are taken in two steps. A facet that carries no
        normal force at the iterate (lambda_n = 0: it was out of contact in the last step)
        and is in contact by the test enters *without friction*: its normal row is
        constrained and its tangential traction is 0 for one step, so that the next test sees
        the direction in which it slides. A facet in contact whose test argument x_t points
        against its tangential traction (x_t . lambda_t < 0: the last step's friction pushed
        it back) reverses through *stick*. Neither condition holds at a solution of the NCP
        (there lambda_n > 0 where x_n > 0, and lambda_t = P(x_t) points along x_t), so the
        rules leave the solutions, the last Newton matrix and the dual problem as they are;
        they decide the sets of the steps before it.

        Why: the tangential test x_t = lambda_t + c (u_t - u_t^old) weighs the slip with the
        facet-scale stiffness c = E / H, while a step that applies the wrong friction force
        moves the whole contact zone through the body's global compliance, up to L / H times
        more. The slip of such a step overshoots, x_t lands beyond the opposite edge of the
        cone, and the plain rule alternates between slipping one way and the other without
        visiting stick (a 2-cycle, measured on the uniform patch tests at stick ratios 0.5 to
        0.83). From stick, x_t = lambda_t is the trial traction: the facet slips where it
        exceeds mu lambda_n, along the traction, as a return mapping does. From a no-contact
        iterate (lambda = 0, the first step from zero) u_t is the displacement of a free
        body, and neither stick (it can pull the facet off the obstacle where its neighbours
        slip, measured: a 2-cycle of stick and separation at slip ratio 10) nor that slip
        direction is a safe guess: without friction the facet slides where the body pushes it.

        Args:
            Mlam: (k, m) the iterate's multipliers times M (normal first).
            xt: (k - 1, m) the tangential test argument, round-off cleaned.
            force_size: The round-off scale of M lambda (max over all rows).

        Returns:
            ``(entering, reversing)``: masks of the m facets.
        """
        return Mlam[0] <= ROUNDOFF * force_size, reversing(Mlam[1:], xt, force_size)

    def newton_set(
        self, Mlam: np.ndarray, residual: np.ndarray, c: np.ndarray, M: np.ndarray,
        g: np.ndarray, u_max: float, force_size: float, bound: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """The set test of a facet's rows (as :meth:`TangentialBall.newton_set`, arrays (k, m)).

        ``bound`` is the friction coefficient mu_i of each facet (its facet mean). A facet in
        contact sticks where ``|x_t| < mu x_n`` and where it reverses; it enters contact
        without friction (:meth:`transitions`).

        Returns:
            ``(constrained, free, ncp, size, (slip, J, r))``: active rows and sticking
            facets' tangential rows constrained, no free value other than 0, and the active
            slipping facets (mask ``slip``) with their derivative blocks J (m_slip, k, k) and
            r = P(x) - J x = 0 (P is positively homogeneous).
        """
        k = self.size
        clean, test, size = set_test_argument(Mlam, residual, c, M, g, u_max, force_size)
        mu = bound
        active = clean[0] > 0.0
        s = mu * np.maximum(clean[0], 0.0)
        xt = clean[1:]
        norm = np.abs(xt[0]) if k == 2 else np.hypot(xt[0], xt[1])
        entering, reversing = self.transitions(Mlam, xt, force_size)
        stick = active & ~entering & ((norm < s) | reversing)
        slip = active & ~entering & ~stick
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
                check_callable(value, name, (), problem.mesh)
        return self

    @property
    def symbol(self) -> str:
        """The data's symbol (``s``, ``mu``)."""
        return self.label[self.label.index("(") + 1 : -1]

    def bound_expr(self, fields: Any, x: Any) -> Any:
        """The data as UFL on the mesh of ``x`` (per tag by the indicators of its ``fields``)."""
        return fields.contact_expr(self.data, x, self.label)

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

    Args:
        mu: The friction coefficient: a number >= 0, a callable x -> UFL scalar, or
            ``{contact tag: number | callable}``.

    Raises:
        TypeError, ValueError: ``mu`` of the wrong type, or a number that is not finite and
            >= 0.

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

    Args:
        n: The unit normal (a UFL vector of length 3).

    Returns:
        (t_1, t_2) as UFL vectors.

    t_1 is the unit projection of e_1 onto that plane (of e_2 where ``|n_1| >= 0.9``, so that the
    projection is not short) and t_2 = n x t_1; (t_1, t_2, n) is right-handed. On a flat face
    the basis is constant; the switch between e_1 and e_2 is a jump of the basis where the
    normal crosses ``|n_1| = 0.9``, so a contact zone should not straddle it (a face with normal
    +-e_1 and one with ``|n_1| < 0.9`` are each fine).
    """
    use_e1 = ufl.lt(abs(n[0]), 0.9)
    a = ufl.as_vector((ufl.conditional(use_e1, 1.0, 0.0), ufl.conditional(use_e1, 0.0, 1.0), 0.0))
    t1 = a - ufl.dot(a, n) * n
    t1 = t1 / ufl.sqrt(ufl.dot(t1, t1))
    return t1, ufl.cross(n, t1)


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
