"""Hooke's law, and a problem's data on one mesh as UFL: materials, gaps, contact data.

A :class:`MeshFields` evaluates the data of a :class:`~dwr_signorini.problem.SignoriniProblem` on
one mesh. It holds what that evaluation needs beyond the data: the mesh's cell tags, the DG0
fields of a material given per cell tag (made when first used), and the indicators of the
contact tags (functions of Lambda_H, 1 on a tag's macro facets) for data given per contact tag.
A :class:`~dwr_signorini.spaces.Discretization` makes those of T_h (``disc.fields``) and of T_H
(``disc.macro_fields``) and owns them: they live as long as it does.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from ufl.domain import extract_unique_domain

from .obstacles import Obstacle
from .validation import MaterialData, call_user, is_real, nonzero_literal

if TYPE_CHECKING:
    from .problem import SignoriniProblem

__all__ = ["MeshFields", "deformation_gradient", "gap_value", "lame_parameters", "stress"]


def deformation_gradient(u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """The deformation gradient F = I + grad u of a displacement (UFL)."""
    return ufl.Identity(len(u)) + ufl.grad(u)


def lame_parameters(E: float, nu: float, model: str = "plane_strain") -> tuple[float, float]:
    """Lame parameters ``(mu, lambda)`` of Hooke's law (Section 2).

    Args:
        E: Young's modulus.
        nu: Poisson's ratio.
        model: ``"plane_stress"`` gives the reduced ``lambda* = 2 mu lambda / (lambda + 2 mu)
            = E nu / (1 - nu^2)``; ``"plane_strain"`` and ``"3d"`` give
            ``lambda = E nu / ((1 + nu)(1 - 2 nu))``.

    Returns:
        The shear modulus ``mu = E / (2 (1 + nu))`` and the first Lame parameter.
    """
    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    if model == "plane_stress":
        lmbda = 2.0 * mu * lmbda / (lmbda + 2.0 * mu)
    return mu, lmbda


def stress(
    u: ufl.core.expr.Expr,
    E: float,
    nu: float,
    model: str = "plane_strain",
    constants: bool = False,
) -> ufl.core.expr.Expr:
    """Hooke's law ``sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I`` (Section 2).

    Args:
        u: Displacement, a UFL vector expression.
        E: Young's modulus.
        nu: Poisson's ratio.
        model: The model of :func:`lame_parameters`.
        constants: Let ``mu`` and ``lambda`` enter as dolfinx Constants on the mesh of ``u`` (if
            it has one), so that forms for different materials share their compiled code;
            otherwise they enter as float literals.

    Returns:
        The symmetric stress tensor as a UFL expression.
    """
    mu, lmbda = lame_parameters(E, nu, model)
    domain = extract_unique_domain(u) if constants else None
    if domain is not None:
        mu, lmbda = fem.Constant(domain, mu), fem.Constant(domain, lmbda)
    eps = ufl.sym(ufl.grad(u))
    return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(len(u))


def gap_value(gap: Any, x: Any, n: Any, miss: float) -> Any:
    """One gap's value at ``x`` (local: calls the user's callable or a Graph's psi).

    Args:
        gap: A number, a callable x -> UFL scalar, or an obstacle.
        x: The point: a spatial coordinate, or a UFL vector of numbers.
        n: The outward unit normal (an obstacle's gap is measured along it); ``None`` takes the
            ``ufl.FacetNormal`` of the mesh of ``x``.
        miss: The gap where an obstacle's ray misses it (the problem's ``miss_gap``).
    """
    if isinstance(gap, Obstacle):
        n = ufl.FacetNormal(extract_unique_domain(x)) if n is None else n
        return gap.gap(x, n, miss)
    if callable(gap):
        return ufl.as_ufl(gap(x))
    return gap


def _as_expr(value: Any, x: Any) -> Any:
    """A number as a Constant on the mesh of ``x``; UFL as it is (a literal zero a Constant)."""
    if is_real(value):
        return fem.Constant(extract_unique_domain(x), float(value))
    return nonzero_literal(ufl.as_ufl(value), x)


class MeshFields:
    """The data of a problem on one mesh (module docstring).

    Args:
        problem: The problem whose data these are.
        mesh: The mesh (T_h, or the problem's macro mesh T_H).
        cell_tags: The cell tags of ``mesh`` (those of the parent macro cells on T_h), needed
            by a material given per cell tag.
        contact_indicators: ``{contact tag: function of Lambda_H}``, 1 on that tag's macro
            facets, needed by data given per contact tag (with several contact tags).
        pair_gap: With contact pairs, returns the gap of the pairs on this mesh (the
            projected gap of its master trace, :mod:`~dwr_signorini.pairs`).
        pair_frame: With contact pairs, returns the normal of their contact frame on this
            mesh (of the master trace, :attr:`~dwr_signorini.pairs.MasterTrace.frame`).

    Attributes:
        problem: The problem.
        mesh: The mesh.
        cell_tags: Its cell tags, or None.
        contact_indicators: The indicators of the contact tags, or None.
    """

    def __init__(
        self,
        problem: SignoriniProblem,
        mesh: dmesh.Mesh,
        cell_tags: dmesh.MeshTags | None = None,
        contact_indicators: Mapping[int, fem.Function] | None = None,
        pair_gap: Callable[[], fem.Function] | None = None,
        pair_frame: Callable[[], fem.Function] | None = None,
    ) -> None:
        self.problem = problem
        self.pair_gap = pair_gap
        self.pair_frame = pair_frame
        self.mesh = mesh
        self.cell_tags = cell_tags
        self.contact_indicators = (
            None if contact_indicators is None else dict(contact_indicators)
        )
        #: The DG0 fields of E and nu given per cell tag, made when first used.
        self._materials: dict[str, fem.Function] = {}
        #: The rigid displacement delta of a force-controlled obstacle along its direction (a
        #: Constant on this mesh, set by the Newton method; None without force control).
        self.obstacle_displacement = (
            None if problem.force_obstacle is None else fem.Constant(mesh, 0.0)
        )
        #: Where the slip of the solve starts from: the obstacle's displacement delta_0 at the
        #: start of the load step (0 in a single solve; the previous step's along a path).
        self.obstacle_start = (
            None if problem.force_obstacle is None else fem.Constant(mesh, 0.0)
        )

    def call_user(self, where: str, function: Callable[..., Any], *args: Any) -> Any:
        """A user's callable of the problem's data, called collectively (naming ``where``)."""
        return call_user(self.problem.mesh, where, function, *args)

    # -- material law (linear elasticity) ----------------------------------------------------
    def material(self, x: Any) -> tuple[Any, Any]:
        """``(E, nu)`` as UFL scalars on this mesh (numbers stay floats).

        Args:
            x: The spatial coordinate of this mesh.

        Returns:
            E and nu: floats, UFL expressions of ``x``, or DG0 functions (given per cell tag).

        Raises:
            ValueError: A material given per cell tag, and this mesh has no cell tags.
        """
        problem = self.problem
        return self._material(problem.E, "E", x), self._material(problem.nu, "nu", x)

    def _material(self, value: MaterialData, name: str, x: Any) -> Any:
        if callable(value):
            return self.call_user(name, value, x)
        if not isinstance(value, Mapping):
            return value
        if name not in self._materials:
            self._materials[name] = self._cell_field(value, name)
        return self._materials[name]

    def _cell_field(self, value: Mapping[int, float], name: str) -> fem.Function:
        """The DG0 function with the value of each cell's tag (``name`` E or nu)."""
        tags = self.cell_tags
        if tags is None:
            raise ValueError(
                f"{name} is given per cell tag, but this mesh has no cell tags: on a mesh "
                "other than the problem's T_H use m.sigma(u) (the goal measures) or the fields "
                "of a discretisation (disc.fields.sigma(u), disc.fields.material(x))"
            )
        msh = self.mesh
        space = fem.functionspace(msh, ("DG", 0))
        field = fem.Function(space, name=name)
        num = msh.topology.index_map(msh.topology.dim).size_local
        lookup = dict(value)
        keep = (tags.indices < num) & np.isin(tags.values, list(lookup))
        cells = tags.indices[keep]
        field.x.array[space.dofmap.list[cells, 0]] = [lookup[int(t)] for t in tags.values[keep]]
        field.x.scatter_forward()
        return field

    def sigma(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Stress sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I (Hooke's law).

        For numbers E, nu the Lame parameters enter as dolfinx Constants on the mesh of ``u``,
        so forms for different materials share their compiled code (no new JIT compilation per
        E, nu); callables enter as UFL expressions of x, per-cell-tag values as DG0 functions.

        Args:
            u: A displacement on this mesh (UFL vector).

        Returns:
            The stress tensor (UFL).

        Raises:
            ValueError: A material given per cell tag, and this mesh has no cell tags.
        """
        problem = self.problem
        if problem.homogeneous_material:
            return stress(u, problem.E, problem.nu, problem.model, constants=True)
        E, nu = self.material(ufl.SpatialCoordinate(extract_unique_domain(u)))
        return stress(u, E, nu, problem.model)

    def first_piola(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The first Piola-Kirchhoff stress P(F(u)) of the problem's material law.

        P = dpsi/dF at F = I + grad u (a UFL derivative of the strain energy) for a hyperelastic
        law, with mu, lambda from E, nu as given (per cell tag as DG0 fields, as in the Newton
        system); for :class:`~dwr_signorini.LinearElastic` it is Hooke's sigma(u) (:meth:`sigma`):
        at small strain the stress measures coincide.

        Args:
            u: A displacement on this mesh (UFL vector).

        Returns:
            P as a UFL tensor (d x d, not symmetric at finite strain).
        """
        law = self.problem.material_law
        if not law.finite_strain:
            return self.sigma(u)
        E, nu = self.material(ufl.SpatialCoordinate(extract_unique_domain(u)))
        mu, lmbda = lame_parameters(E, nu, self.problem.model)
        return law.first_piola(ufl.variable(deformation_gradient(u)), mu, lmbda)

    def cauchy(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The Cauchy stress sigma = P F^T / det F of the problem's material law.

        For :class:`~dwr_signorini.LinearElastic` it is Hooke's sigma(u) (:meth:`sigma`).

        Args:
            u: A displacement on this mesh (UFL vector).

        Returns:
            The Cauchy stress as a UFL tensor, a field on the reference configuration.
        """
        if not self.problem.material_law.finite_strain:
            return self.sigma(u)
        F = deformation_gradient(u)
        return self.first_piola(u) * F.T / ufl.det(F)

    def elastic_form(self, u: Any, v: Any, dx: ufl.Measure) -> ufl.Form:
        """a(u, v) = (sigma(u), eps(v)) (Section 2) on this mesh."""
        return ufl.inner(self.sigma(u), self.problem.epsilon(v)) * dx

    # -- data on Gamma_C -----------------------------------------------------------------------
    def gap(self, x: ufl.SpatialCoordinate, n: Any = None) -> ufl.core.expr.Expr:
        """The gap g as UFL on this mesh (constants as a dolfinx Constant).

        A gap per contact tag is the sum of each tag's gap times the indicator of its macro
        facets (a function of Lambda_H), so it needs the entity maps of
        :meth:`~dwr_signorini.spaces.Discretization.form`.

        Args:
            x: The spatial coordinate of this mesh.
            n: The outward unit normal; obstacles need it, and ``None`` takes the
                ``ufl.FacetNormal`` of the mesh (the same as ``m.n``), so the expression is
                for facet integrals over Gamma_C.

        Returns:
            The gap, a UFL scalar expression.

        Raises:
            ValueError: A gap that differs between contact tags, and no contact indicators.
        """
        miss = self.problem.miss_gap

        def value(g: Any) -> Any:
            return gap_value(g, self._seen_by(g, x), n, miss)

        if self.problem.pairs and self.pair_gap is None:
            raise ValueError(
                "the gap of a ContactPair is measured on a discretisation's mesh: use its "
                "fields, disc.fields.gap(m.x)"
            )
        return self._rigid_and_pairs(x, value, self.pair_gap)

    def frame_normal(self, x: ufl.SpatialCoordinate, n: Any = None) -> ufl.core.expr.Expr:
        """The normal of the contact frame: the tangential slip is measured normal to it.

        A rigid obstacle's own normal where the body's normal ray enters it
        (:meth:`~dwr_signorini.obstacles.Obstacle.surface_normal`); the body's normal ``n``
        where the gap is a number or a function (no surface to take a normal of); for a
        contact pair the normalised mean of the slave normal and the master's opposite normal
        (``pair_frame``, :mod:`~dwr_signorini.pairs`). So the normal approach of a curved
        surface is not read as slip (``docs/theory.md``, the contact frame).

        Args:
            x: The spatial coordinate of this mesh.
            n: The outward unit normal; ``None`` takes the ``ufl.FacetNormal`` of the mesh.

        Returns:
            A UFL unit vector on Gamma_C.
        """
        n = ufl.FacetNormal(extract_unique_domain(x)) if n is None else n
        miss = self.problem.miss_gap

        def value(g: Any) -> Any:
            return g.surface_normal(self._seen_by(g, x), n, miss) if isinstance(g, Obstacle) else n

        return self._rigid_and_pairs(x, value, self.pair_frame)

    def translation(self, moves: Mapping[int, np.ndarray]) -> ufl.core.expr.Expr:
        """The translation of each rigid contact tag's obstacle as a UFL vector on Gamma_C.

        Args:
            moves: ``{rigid contact tag: t}`` (:mod:`~dwr_signorini.obstacle_motion`).

        Returns:
            t on each tag's facets (a Constant, or a sum weighted by the contact-tag
            indicators), zero on the slave facets of contact pairs.
        """
        constants = {t: fem.Constant(self.mesh, np.asarray(v, dtype=float))
                     for t, v in moves.items()}
        first = next(iter(moves.values()))
        if not self.problem.pairs and all(np.array_equal(v, first) for v in moves.values()):
            return constants[next(iter(moves))]
        return sum(self.contact_indicators[t] * constants[t] for t in moves)

    def obstacle_motion(self) -> ufl.core.expr.Expr | None:
        """The force-controlled obstacle's motion in the step, (delta - delta_0) d, with friction.

        Its part along the contact frame's tangents is a slip of the obstacle: the slip
        increment is (u - u_old - (delta - delta_0) d) . e_l (:mod:`~dwr_signorini.force`),
        delta the unknown :attr:`obstacle_displacement` and delta_0 :attr:`obstacle_start`.

        Returns:
            A UFL vector (the obstacle is the problem's only gap), or None without a
            force-controlled obstacle or without friction (no slip).
        """
        if self.problem.force_obstacle is None or not self.problem.law.frictional:
            return None
        return (self.obstacle_displacement - self.obstacle_start) * self.approach()

    def approach(self) -> ufl.core.expr.Expr:
        """The direction d of approach of the obstacle under a given force (UFL vector).

        Raises:
            ValueError: The problem has no force-controlled obstacle.
        """
        obstacle = self.problem.force_obstacle
        if obstacle is None:
            raise ValueError("the problem has no obstacle under a given force")
        return ufl.as_vector([float(c) for c in obstacle.direction])

    def _rigid_and_pairs(
        self, x: Any, value: Callable[[Any], Any], pairs: Callable[[], Any] | None
    ) -> ufl.core.expr.Expr:
        """``value`` of each rigid contact tag's gap, and ``pairs()`` on the pairs' facets.

        Args:
            x: The spatial coordinate of this mesh.
            value: A gap's (number, callable or obstacle) value on its tags, UFL.
            pairs: The value on the slave facets of the pairs (measured by their master trace).

        Returns:
            A UFL expression on Gamma_C.
        """
        problem = self.problem
        if not problem.pairs:
            return self.contact_expr(problem.gap, x, "gap", value)
        on_pairs = pairs()
        if not problem.rigid_tags:
            return on_pairs
        chi = sum(self.contact_indicators[t] for t in problem.rigid_tags)
        rigid = self.contact_expr(problem.gap, x, "gap", value, problem.rigid_tags)
        return chi * rigid + (1.0 - chi) * on_pairs

    def _seen_by(self, gap: Any, x: Any, delta: Any = None) -> Any:
        """``x`` as the gap ``gap`` sees it: the force-controlled obstacle at its displacement.

        Args:
            gap: One gap of the problem (a number, a callable or an obstacle).
            x: The point (UFL vector).
            delta: The obstacle's displacement (``None``: :attr:`obstacle_displacement`).

        Returns:
            ``gap.moved(x, delta)`` for the force-controlled obstacle, else ``x``.
        """
        if gap is not self.problem.force_obstacle:
            return x
        return gap.moved(x, self.obstacle_displacement if delta is None else delta)

    def gap_rate(
        self, x: ufl.SpatialCoordinate, n: Any, offset: Callable[[Any, Any], Any]
    ) -> ufl.core.expr.Expr:
        """The normal condition's offset per unit displacement of the force-controlled obstacle.

        The offset of the normal condition in the contact frame, ``offset(g, n_c)`` (the
        normal component's :meth:`~dwr_signorini.laws.Component.offset_in`, g (n . n_c)),
        differentiated in delta with both the gap g and the frame normal n_c of the moved
        obstacle, so the bordered Newton step (:mod:`~dwr_signorini.force`) is exact.

        Args:
            x: The spatial coordinate of this mesh.
            n: The outward unit normal.
            offset: ``(g, n_c) -> `` the normal condition's offset (UFL).

        Returns:
            The derivative at the current :attr:`obstacle_displacement`, a UFL scalar.

        Raises:
            ValueError: The problem has no force-controlled obstacle.
        """
        obstacle = self.problem.force_obstacle
        if obstacle is None:
            raise ValueError("the problem has no obstacle under a given force")
        delta = ufl.variable(self.obstacle_displacement)
        y, miss = self._seen_by(obstacle, x, delta), self.problem.miss_gap
        g = gap_value(obstacle, y, n, miss)
        return ufl.diff(offset(g, obstacle.surface_normal(y, n, miss)), delta)

    def contact_expr(
        self,
        data: Any,
        x: Any,
        name: str,
        value: Callable[[Any], Any] | None = None,
        tags: tuple[int, ...] | None = None,
    ) -> ufl.core.expr.Expr:
        """Data on Gamma_C (the gap, a friction threshold) as UFL on this mesh.

        Data per contact tag is the sum of each tag's value times the indicator of its macro
        facets (a function of Lambda_H), so it needs the entity maps of
        :meth:`~dwr_signorini.spaces.Discretization.form`.

        Args:
            data: A number, a callable x -> UFL scalar, or ``{contact tag: ...}``.
            x: The spatial coordinate of this mesh.
            name: The argument's name, for errors.
            value: One value's expression (default: a callable is called with ``x``).
            tags: The contact tags the data is for (default: all).

        Returns:
            The data as a UFL scalar expression.

        Raises:
            ValueError: Per-tag data (differing between tags) and no contact indicators.
        """
        if value is None:
            value = lambda d: d(x) if callable(d) else d  # noqa: E731
        if not isinstance(data, Mapping):
            return _as_expr(self.call_user(name, value, data), x)
        values = {t: self.call_user(f"{name}[{t}]", value, d) for t, d in data.items()}
        distinct = {id(d) for d in data.values()}
        if len(distinct) == 1:
            return _as_expr(next(iter(values.values())), x)
        indicators = self.contact_indicators
        if indicators is None:
            raise ValueError(
                f"{name} is given per contact tag: its expression needs the contact-tag "
                "indicators of a discretisation (use disc.fields, e.g. disc.fields.gap(m.x))"
            )
        tags = self.problem.contact_tags if tags is None else tags
        return sum(indicators[t] * ufl.as_ufl(values[t]) for t in tags)
