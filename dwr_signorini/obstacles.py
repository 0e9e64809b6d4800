r"""Rigid obstacles and the gap they give along the outward normal of the body (eq. 2).

The linearised contact condition of the paper is ``u_n <= g`` on Gamma_C, with ``g`` the
distance from a boundary point ``x`` to the obstacle, measured along the outward unit normal
``n`` of the body at ``x``: ``g(x) = t*`` for the smallest ``t*`` with ``x + t* n`` on the
obstacle's surface (the ray's entry point). ``g`` is negative where ``x`` already lies inside
the obstacle (the entry point of the line through ``x`` lies behind it).

Each obstacle gives that gap as a UFL expression of ``x`` and ``n`` (:meth:`Obstacle.gap`), to
be integrated at the quadrature points of Gamma_C. :class:`Plane`, :class:`Sphere` and
:class:`Cylinder` are exact for their shape (no paraboloid approximation). :class:`Graph` uses the
paper's formula of Section 2.

**Rays that miss.** Where the ray ``x + t n`` (t >= 0) does not meet the obstacle (it points
away or passes beside it), the point cannot come into contact. The gap there is the finite value
``miss`` (an argument of :meth:`Obstacle.gap`; :class:`~dwr_signorini.SignoriniProblem` passes
the diameter of the body's bounding box plus the obstacle's :attr:`Obstacle.size`, plus the
distance between the two), so that assemblies stay finite and the NCP keeps such points
inactive. Gaps that would exceed ``miss`` (grazing rays) are cut at ``miss``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import ufl

__all__ = ["Cylinder", "Graph", "Obstacle", "Plane", "Sphere"]

Expr = Any


def _unit(vector: Sequence[float], name: str) -> np.ndarray:
    arr = np.asarray(vector, dtype=float)
    if arr.ndim != 1 or arr.size not in (2, 3) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite vector of 2 or 3 components, got {vector!r}")
    length = float(np.linalg.norm(arr))
    if length == 0.0:
        raise ValueError(f"{name} must not be the zero vector")
    return arr / length


def _point(point: Sequence[float], name: str) -> np.ndarray:
    arr = np.asarray(point, dtype=float)
    if arr.ndim != 1 or arr.size not in (2, 3) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite point of 2 or 3 coordinates, got {point!r}")
    return arr


def _positive(value: float, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    if not (0.0 < value < np.inf):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


def _same(a: Any, b: Any) -> bool:
    """Whether two radii or unit vectors agree to round-off (relative 1e-12)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(float(np.abs(a).max()), float(np.abs(b).max()))
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= 1e-12 * scale))


def _dot(a: Sequence[Expr], b: Sequence[Expr]) -> Expr:
    return sum(ai * bi for ai, bi in zip(a, b, strict=True))


def _components(v: Expr, dim: int) -> list[Expr]:
    return [v[i] for i in range(dim)]


def _ray_quadric(A: Expr, B: Expr, C: Expr, miss: float) -> Expr:
    """Entry parameter t of the ray into {A t^2 + 2 B t + C <= 0}, or ``miss``.

    The roots are ``t1 <= t2``; the ray meets the (convex) solid iff the discriminant
    ``B^2 - A C`` is >= 0 and ``t2 >= 0``. ``t1 = C / (-B + sqrt(B^2 - A C))`` (no cancellation,
    and right for A -> 0: a ray parallel to a cylinder's axis); ``-B + sqrt(...) = A t2``.
    """
    disc = B * B - A * C
    root = ufl.sqrt(ufl.max_value(disc, 0.0))
    denominator = -B + root
    safe = ufl.conditional(ufl.gt(denominator, 0.0), denominator, 1.0)
    t1 = ufl.max_value(ufl.min_value(C / safe, miss), -miss)
    hit = ufl.And(ufl.ge(disc, 0.0), ufl.gt(denominator, 0.0))
    return ufl.conditional(hit, t1, miss)


class Obstacle:
    """A rigid obstacle: the gap along the body's outward normal (see the module docstring).

    Attributes:
        dim: The space dimension the obstacle is defined in (2 or 3).
        force: The resultant F > 0 it presses the body with along :attr:`direction` (force
            control: its rigid displacement along the direction is then an unknown of the
            discrete problem), or None (the obstacle stays where it is given).
        direction: The unit direction of approach of a force-controlled obstacle, or None.
    """

    dim: int
    force: float | None = None
    direction: np.ndarray | None = None

    def _set_force(self, force: float | None, direction: Sequence[float] | None,
                   default: np.ndarray | None) -> None:
        """Check and set :attr:`force` and :attr:`direction` (``default``: the direction)."""
        name = type(self).__name__
        if force is None:
            if direction is not None:
                raise ValueError(f"{name} direction is the direction of a force: give force=")
            return
        self.force = _positive(force, f"{name} force")
        if direction is None and default is None:
            raise ValueError(
                f"{name} with force= needs direction=, the direction in which it approaches "
                "the body"
            )
        self.direction = _unit(default if direction is None else direction, f"{name} direction")
        if self.direction.size != self.dim:
            raise ValueError(f"{name} direction must have {self.dim} components")

    def moved(self, x: Expr, displacement: Expr) -> Expr:
        """The point ``x`` seen from the obstacle moved by ``displacement`` along its direction.

        A rigid translation by delta d: the gap of the moved obstacle at x is the gap of the
        obstacle at x - delta d.

        Args:
            x: The point (UFL vector).
            displacement: delta, a UFL scalar (a dolfinx Constant).

        Returns:
            x - delta d as a UFL vector.
        """
        d = [float(c) for c in self.direction]
        return ufl.as_vector([x[i] - displacement * d[i] for i in range(self.dim)])

    def _force_repr(self) -> str:
        if self.force is None:
            return ""
        return f", force={self.force}, direction={self.direction.tolist()}"

    @property
    def size(self) -> float:
        """A length of the obstacle (a radius; 0 for unbounded ones), for the ``miss`` value."""
        return 0.0

    @property
    def reference_point(self) -> np.ndarray:
        """A point of the obstacle, for the ``miss`` value.

        Raises:
            NotImplementedError: On the base class; every obstacle defines it.
        """
        raise NotImplementedError

    def translation_from(self, previous: Obstacle) -> np.ndarray | None:
        """The rigid translation t that moves ``previous`` onto this obstacle, or None.

        A load path's frictional step measures the slip relative to the obstacle: where
        step k's obstacle is step k - 1's translated by t, the slip increment is
        u - (u_old + t) (:func:`~dwr_signorini.solve_path`). The translation is that of the
        obstacle's defining point (:attr:`reference_point`: a plane's point, a sphere's
        center, a point of a cylinder's axis), which moves with the obstacle as a material
        point of it: a plane or cylinder given with its point moved along the plane or the
        axis is dragged that way over the body.

        Args:
            previous: The obstacle of the step before.

        Returns:
            t (``dim`` components): zero for the same object; None where this obstacle is
            not ``previous`` translated (another kind, radius, normal or axis, another
            function, another dimension).
        """
        if previous is self:
            return np.zeros(self.dim or 3)
        if type(previous) is not type(self) or previous.dim != self.dim:
            return None
        if not self._same_shape(previous):
            return None
        return self.reference_point - previous.reference_point

    def _same_shape(self, other: Obstacle) -> bool:
        """Whether ``other`` (of this class) has this obstacle's shape and orientation."""
        return False

    def gap(self, x: Expr, n: Expr, miss: float) -> Expr:
        """The distance along ``n`` from ``x`` to the obstacle's surface, as UFL.

        Args:
            x: The boundary point (``ufl.SpatialCoordinate``, or any UFL vector).
            n: The body's outward unit normal at ``x`` (``ufl.FacetNormal``, or a UFL vector).
            miss: The finite value where the ray misses the obstacle.

        Returns:
            The gap, a UFL scalar expression in ``x`` and ``n``.

        Raises:
            NotImplementedError: On the base class; every obstacle defines it.
        """
        raise NotImplementedError

    def surface_normal(self, x: Expr, n: Expr, miss: float) -> Expr:
        """The obstacle's unit normal where the ray ``x + t n`` enters it, as UFL.

        It points into the obstacle (the way the body's outward normal faces it): the normal
        of the contact frame in which the tangential slip against the obstacle is measured
        (:meth:`~dwr_signorini.spaces.Discretization.contact_frame`). Where the ray misses,
        ``n`` itself.

        Args:
            x: The boundary point.
            n: The body's outward unit normal at ``x``.
            miss: The finite gap where the ray misses the obstacle.

        Returns:
            A UFL unit vector.

        Raises:
            NotImplementedError: On the base class; every obstacle defines it.
        """
        raise NotImplementedError

    def _towards(self, point: Expr, x: Expr, n: Expr, miss: float) -> Expr:
        """The unit vector from the ray's entry point to ``point`` (n where the ray misses)."""
        g = self.gap(x, n, miss)
        d = [p - (xi + g * ni) for p, xi, ni in zip(
            point, _components(x, self.dim), _components(n, self.dim), strict=True)]
        length = ufl.sqrt(_dot(d, d))
        safe = ufl.conditional(ufl.gt(length, 0.0), length, 1.0)
        hit = ufl.And(ufl.lt(g, miss), ufl.gt(length, 0.0))
        return ufl.conditional(hit, ufl.as_vector([di / safe for di in d]), n)


class Plane(Obstacle):
    """The rigid half-space ``{y : (y - point) . normal >= 0}`` (the body on the other side).

    Gap: ``t = (point - x) . normal / (n . normal)`` where ``n . normal > 0``, else ``miss``
    (a boundary facing away from the plane cannot touch it).

    Args:
        point: A point of the plane.
        normal: The direction into the obstacle (normalised here).
        force: A resultant F > 0 pressing the obstacle onto the body (force control), or None.
        direction: Its direction of approach (default ``-normal``).

    Raises:
        ValueError: If ``point`` or ``normal`` is not a finite vector of 2 or 3 components,
            ``normal`` is zero, or the two differ in length.
    """

    def __init__(
        self, point: Sequence[float], normal: Sequence[float], force: float | None = None,
        direction: Sequence[float] | None = None,
    ) -> None:
        self.point = _point(point, "Plane point")
        self.normal = _unit(normal, "Plane normal")
        if self.point.size != self.normal.size:
            raise ValueError("Plane point and normal must have the same number of components")
        self.dim = self.point.size
        self._set_force(force, direction, -self.normal)

    @property
    def reference_point(self) -> np.ndarray:  # noqa: D102
        return self.point

    def _same_shape(self, other: Obstacle) -> bool:
        return _same(self.normal, other.normal)

    def gap(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        nu = [float(c) for c in self.normal]
        n_dot = _dot(_components(n, self.dim), nu)
        xs = _components(x, self.dim)
        dist = _dot([float(p) - xi for p, xi in zip(self.point, xs, strict=True)], nu)
        safe = ufl.conditional(ufl.gt(n_dot, 0.0), n_dot, 1.0)
        t = ufl.max_value(ufl.min_value(dist / safe, miss), -miss)
        return ufl.conditional(ufl.gt(n_dot, 0.0), t, miss)

    def surface_normal(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        n_dot = _dot(_components(n, self.dim), [float(c) for c in self.normal])
        normal = ufl.as_vector([float(c) for c in self.normal])
        return ufl.conditional(ufl.gt(n_dot, 0.0), normal, n)

    def __repr__(self) -> str:
        return (
            f"Plane(point={self.point.tolist()}, normal={self.normal.tolist()}"
            f"{self._force_repr()})"
        )


class Sphere(Obstacle):
    """A rigid disc (2D, ``center`` of 2 coordinates) or ball (3D).

    Gap: the entry point of the ray into the ball, exactly (the smaller root of
    ``|x + t n - center|^2 = radius^2``); negative for a point inside the ball.

    Args:
        center: The center, 2 or 3 coordinates.
        radius: The radius, > 0.
        force: A resultant F > 0 pressing the obstacle onto the body (force control), or None.
        direction: Its direction of approach (needed with ``force``).

    Raises:
        ValueError: If ``center`` is not a finite point of 2 or 3 coordinates, or ``radius`` is
            not finite and positive.
        TypeError: If ``radius`` is not a number.
    """

    def __init__(
        self, center: Sequence[float], radius: float, force: float | None = None,
        direction: Sequence[float] | None = None,
    ) -> None:
        self.center = _point(center, "Sphere center")
        self.radius = _positive(radius, "Sphere radius")
        self.dim = self.center.size
        self._set_force(force, direction, None)

    @property
    def size(self) -> float:  # noqa: D102
        return self.radius

    @property
    def reference_point(self) -> np.ndarray:  # noqa: D102
        return self.center

    def _same_shape(self, other: Obstacle) -> bool:
        return _same(self.radius, other.radius)

    def gap(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        d = [xi - float(c) for xi, c in zip(_components(x, self.dim), self.center, strict=True)]
        nn = _components(n, self.dim)
        return _ray_quadric(_dot(nn, nn), _dot(nn, d), _dot(d, d) - self.radius**2, miss)

    def surface_normal(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        return self._towards([float(c) for c in self.center], x, n, miss)

    def __repr__(self) -> str:
        return (
            f"Sphere(center={self.center.tolist()}, radius={self.radius}{self._force_repr()})"
        )


class Cylinder(Obstacle):
    """A rigid infinite circular cylinder in 3D: points at distance <= radius from the axis.

    Gap: the entry point of the ray, exactly (the quadric of the components normal to the axis;
    a ray parallel to the axis misses unless it starts inside).

    Args:
        point: A point of the axis (3 coordinates).
        axis: The axis direction (normalised here).
        radius: The radius, > 0.
        force: A resultant F > 0 pressing the obstacle onto the body (force control), or None.
        direction: Its direction of approach (needed with ``force``).

    Raises:
        ValueError: If ``point`` or ``axis`` is not a finite vector of 3 components, ``axis``
            is zero, or ``radius`` is not finite and positive.
        TypeError: If ``radius`` is not a number.
    """

    def __init__(
        self, point: Sequence[float], axis: Sequence[float], radius: float,
        force: float | None = None, direction: Sequence[float] | None = None,
    ) -> None:
        self.point = _point(point, "Cylinder point")
        self.axis = _unit(axis, "Cylinder axis")
        if self.point.size != 3 or self.axis.size != 3:
            raise ValueError("Cylinder is a 3D obstacle: point and axis need 3 components")
        self.radius = _positive(radius, "Cylinder radius")
        self.dim = 3
        self._set_force(force, direction, None)

    @property
    def size(self) -> float:  # noqa: D102
        return self.radius

    @property
    def reference_point(self) -> np.ndarray:  # noqa: D102
        return self.point

    def _same_shape(self, other: Obstacle) -> bool:
        return _same(self.radius, other.radius) and (
            _same(self.axis, other.axis) or _same(self.axis, -other.axis)
        )

    def gap(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        a = [float(c) for c in self.axis]
        d = [xi - float(p) for xi, p in zip(_components(x, 3), self.point, strict=True)]
        nn = _components(n, 3)
        d_a, n_a = _dot(d, a), _dot(nn, a)
        d_perp = [di - d_a * ai for di, ai in zip(d, a, strict=True)]
        n_perp = [ni - n_a * ai for ni, ai in zip(nn, a, strict=True)]
        A = _dot(n_perp, n_perp)
        return _ray_quadric(A, _dot(n_perp, d_perp), _dot(d_perp, d_perp) - self.radius**2, miss)

    def surface_normal(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        # the point of the axis level with the entry point y: p + ((y - p) . a) a
        a = [float(c) for c in self.axis]
        y = [xi + self.gap(x, n, miss) * ni
             for xi, ni in zip(_components(x, 3), _components(n, 3), strict=True)]
        along = _dot([yi - float(p) for yi, p in zip(y, self.point, strict=True)], a)
        foot = [float(p) + along * ai for p, ai in zip(self.point, a, strict=True)]
        return self._towards(foot, x, n, miss)

    def __repr__(self) -> str:
        return (
            f"Cylinder(point={self.point.tolist()}, axis={self.axis.tolist()}, "
            f"radius={self.radius}{self._force_repr()})"
        )


class Graph(Obstacle):
    r"""The obstacle above a graph: ``{y : y_axis >= psi(y)}``, the body below it.

    Args:
        psi: ``x -> UFL scalar``, the height of the obstacle's surface; it is called with the
            full spatial coordinate and must not depend on ``x[axis]``.
        axis: The vertical direction (default the last coordinate).
        dim: The space dimension (2 or 3), checked against the mesh.

    Raises:
        TypeError: If ``psi`` is not callable or ``axis`` is not an integer.

    The gap is the paper's formula of Section 2: for a contact boundary that is itself a graph
    ``x_axis = phi(x')``, ``g = (psi - phi) (1 + |grad phi|^2)^(-1/2)``. At a boundary point,
    ``phi(x') = x_axis`` and ``(1 + |grad phi|^2)^(-1/2) = n_axis`` (the normal of the graph), so
    ``g = (psi(x) - x_axis) n_axis`` where ``n_axis > 0``, and ``miss`` where the boundary does not
    face the obstacle (``n_axis <= 0``). This is the first-order (in the slopes) approximation
    of the distance along n that the paper uses, exact for a flat psi and phi parallel to it.
    """

    def __init__(
        self, psi: Callable[[Any], Expr], axis: int = -1, dim: int | None = None
    ) -> None:
        if not callable(psi):
            raise TypeError(f"Graph psi must be a callable x -> UFL scalar, got {psi!r}")
        if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)):
            raise TypeError(f"Graph axis must be an integer, got {axis!r}")
        self.psi = psi
        self.axis = int(axis)
        self.dim = dim  # type: ignore[assignment]

    @property
    def reference_point(self) -> np.ndarray:  # noqa: D102
        return np.zeros(self.dim or 3)

    def translation_from(self, previous: Obstacle) -> np.ndarray | None:
        """Zero for the same graph (the same ``psi`` and axis), else None.

        A graph is given by a function, whose translates cannot be recognised: a moving
        graph obstacle is refused along a frictional path (:meth:`Obstacle.translation_from`).

        Args:
            previous: The obstacle of the step before.

        Returns:
            Zeros, or None where ``previous`` is not this graph.
        """
        same = isinstance(previous, Graph) and previous.psi is self.psi and (
            previous.axis == self.axis and previous.dim == self.dim
        )
        return np.zeros(self.dim or 3) if same or previous is self else None

    def gap(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        dim = ufl.shape(x)[0]
        axis = self.axis % dim
        n_axis = n[axis]
        g = (ufl.as_ufl(self.psi(x)) - x[axis]) * n_axis
        g = ufl.max_value(ufl.min_value(g, miss), -miss)
        return ufl.conditional(ufl.gt(n_axis, 0.0), g, miss)

    def surface_normal(self, x: Expr, n: Expr, miss: float) -> Expr:  # noqa: D102
        # the graph's upward normal (e_axis - grad psi) / |.| at x, to first order in the gap
        # as the gap itself (psi does not depend on x[axis])
        dim = ufl.shape(x)[0]
        axis = self.axis % dim
        grad = ufl.grad(ufl.as_ufl(self.psi(x)) + 0.0 * x[axis])
        up = ufl.as_vector([1.0 if i == axis else -grad[i] for i in range(dim)])
        return ufl.conditional(ufl.gt(n[axis], 0.0), up / ufl.sqrt(ufl.dot(up, up)), n)

    def __repr__(self) -> str:
        return f"Graph(psi={self.psi!r}, axis={self.axis})"
