"""Signorini's problem: data of the contact problem (1)-(3) of the paper, validated once.

A :class:`SignoriniProblem` holds the *macro* mesh T_H the user passes, its facet tags and the
material, loads and gap, and nothing else: it is frozen after its constructor has checked the
data (:mod:`dwr_signorini.validation`, :mod:`dwr_signorini.mesh_validation`). Nothing is
discretised here: :mod:`dwr_signorini.spaces` builds the fine mesh T_h and the spaces, and the
data on a mesh as UFL are the :class:`~dwr_signorini.fields.MeshFields` the discretisation owns.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any, NoReturn

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from ufl.domain import extract_unique_domain

from .agreement import check_same_on_ranks
from .fields import MeshFields, lame_parameters, stress
from .laws import ContactLaw, check_law
from .materials import Material, check_material_law
from .mesh_validation import check_cell_tags, check_mesh, check_projection_fits, check_tags
from .obstacles import Obstacle
from .pairs import ContactPair
from .quadrature import DATA_QUADRATURE_DEGREE
from .validation import (
    MODELS,
    DirichletData,
    GapData,
    MaterialData,
    VectorData,
    call_user,
    check_contact,
    check_contact_pairs,
    check_dirichlet,
    check_gap,
    check_loads,
    check_material,
    check_model,
    check_pair_bodies,
    check_pair_gap,
    check_projection,
    check_quadrature_degree,
    nonzero_literal,
)

__all__ = ["MODELS", "SignoriniProblem", "lame_parameters", "stress"]


class SignoriniProblem:
    """Signorini's problem (eq. 1-3): an elastic body on a rigid obstacle, with or without friction.

    The contact is frictionless (the paper's problem) or follows Tresca's or Coulomb's law
    (``friction``).

    Args:
        mesh: The macro mesh T_H (simplices for adaptivity; quadrilaterals/hexahedra for uniform
            runs). The displacement lives on its uniform refinement T_h, the contact force on its
            contact facets (P0, so H = 2h).
        facet_tags: Facet tags of ``mesh``.
        contact: Tag, or tags, of the possible contact boundary Gamma_C with the rigid
            obstacle, and :class:`~dwr_signorini.pairs.ContactPair` ``(slave=, master=)``
            entries: facets of one body that may touch facets of another body of the mesh
            (Gamma_C is then the slave side; a list may mix pairs and tags).
        dirichlet: Gamma_D: tags clamped (u = 0), or ``{tag: value}`` with ``value`` a number
            (every component equals it, e.g. ``0.0``), a tuple of ``gdim`` numbers or ``None``
            (``None`` = that component free: ``(0.0, None)`` is a roller / symmetry plane
            ``u_x = 0``), or a callable ``x -> UFL vector`` (every component, from x). Where two
            conditions prescribe the same component at a vertex, the later tag wins.
        E: Young's modulus, > 0: a number, a callable ``x -> UFL scalar`` (checked > 0 at the
            quadrature points), or ``{cell tag: number}`` with ``cell_tags``.
        nu: Poisson's ratio, in (-1, 0.5): as ``E``.
        material: The material law (:mod:`dwr_signorini.materials`): ``None`` or
            ``ds.LinearElastic()`` (the default, small strain), or a finite-strain law
            (``ds.NeoHookean()``, ``ds.SaintVenantKirchhoff()``, ``ds.Hyperelastic(psi)``,
            with the Lame parameters from ``E``, ``nu``): then the contact with the rigid
            obstacle is measured in the deformed configuration
            (:mod:`dwr_signorini.finite_strain`).
        model: ``"plane_strain"`` or ``"plane_stress"`` in 2D, ``"3d"`` in 3D; ``None`` picks
            plane strain in 2D and ``"3d"`` in 3D.
        body_force: Volume load f: ``None``, a constant sequence, or a callable ``x -> UFL vector``.
        traction: Surface loads b on Gamma_N: ``{tag: sequence | callable x -> UFL vector}``.
            A dirichlet face may carry a traction on the components it leaves free
            (``dirichlet={4: (d, None)}, traction={4: (0.0, -p)}``: shear it with a
            displacement, press it with a force), given as numbers, 0.0 on the prescribed
            components; contact faces carry none.
        gap: The gap g of the linearised contact condition u_n <= g on Gamma_C (eq. 2): a finite
            float, a callable ``x -> UFL scalar``, an obstacle of :mod:`dwr_signorini.obstacles`
            (the distance along the outward normal), or ``{contact tag: any of these}``; for
            the rigid contact tags only (a pair's gap is measured from the meshes).
        cell_tags: Cell tags of ``mesh``, needed when ``E`` or ``nu`` is a dict.
        boundary_projection: ``{facet tag: callable}``: the callable maps points (an array of
            shape (3, n)) onto the true (curved) surface of that boundary; after each refinement
            of T_H the vertices on those facets are moved onto it
            (:func:`dwr_signorini.refine.refine_marked`).
        friction: The contact law (:mod:`dwr_signorini.laws`): ``None`` or
            ``ds.Frictionless()`` (the default, Signorini's problem), ``ds.Tresca(s)`` (the slip
            threshold s) or ``ds.Coulomb(mu)`` (the threshold mu lambda_n; a sequence of such
            problems is a load path for :func:`~dwr_signorini.solve_path`).
        quadrature_degree: Degree of the quadrature rule for non-polynomial data (body force,
            tractions, gap, the friction bound, ``E`` and ``nu`` given as functions of x) in
            the Newton system, and by default in the residuals of the estimators
            (:func:`~dwr_signorini.estimate`), so that they vanish on discrete test functions.
            Polynomial integrands are integrated exactly whatever it is
            (:mod:`dwr_signorini.quadrature`). The default, 8 (16 points per triangle),
            integrates smooth data far below the discretisation error of P1; lower degrees
            cost fewer evaluations of the data.

    The problem is data: validated once (:mod:`dwr_signorini.validation`), then frozen (setting
    an attribute raises; :meth:`with_mesh` makes the same problem on another mesh). Its data on
    a mesh as UFL are the :class:`~dwr_signorini.fields.MeshFields` of a discretisation
    (``disc.fields``).

    Raises:
        ValueError: For any inconsistent or non-physical input, naming the argument.
        TypeError: For arguments of the wrong type.
    """

    def __init__(
        self,
        mesh: dmesh.Mesh,
        facet_tags: dmesh.MeshTags,
        contact: int | ContactPair | Iterable[int | ContactPair],
        dirichlet: Iterable[int] | Mapping[int, DirichletData] = (),
        E: MaterialData = 1.0,
        nu: MaterialData = 0.3,
        model: str | None = None,
        body_force: VectorData = None,
        traction: Mapping[int, VectorData] | None = None,
        gap: GapData | Mapping[int, GapData] = 0.0,
        cell_tags: dmesh.MeshTags | None = None,
        boundary_projection: Mapping[int, Callable[[np.ndarray], np.ndarray]] | None = None,
        friction: ContactLaw | None = None,
        quadrature_degree: int = DATA_QUADRATURE_DEGREE,
        material: Material | None = None,
    ) -> None:
        check_mesh(mesh, facet_tags)
        check_same_on_ranks(
            mesh,
            "SignoriniProblem",
            {
                "contact": contact, "dirichlet": dirichlet, "E": E, "nu": nu, "model": model,
                "body_force": body_force, "traction": traction, "gap": gap,
                "cell_tags": cell_tags is None, "boundary_projection": boundary_projection,
                "friction": friction, "quadrature_degree": quadrature_degree,
                "material": repr(material),
            },
            numeric=("boundary_projection",),
        )
        self.mesh = mesh
        self.facet_tags = facet_tags
        self.model = check_model(model, mesh.topology.dim)
        self.quadrature_degree = check_quadrature_degree(quadrature_degree)
        self.cell_tags = check_cell_tags(cell_tags, mesh, E, nu)
        self.E = check_material(E, "E", mesh, self.cell_tags)
        self.nu = check_material(nu, "nu", mesh, self.cell_tags)
        tags, self.pairs = check_contact_pairs(contact)
        self.contact_tags = check_contact(tags)
        self.contact: int | tuple[int, ...] = (
            self.contact_tags[0] if len(self.contact_tags) == 1 else self.contact_tags
        )
        self.master_tags = tuple(p.master for p in self.pairs)
        slaves = {p.slave for p in self.pairs}
        self.rigid_tags = tuple(t for t in self.contact_tags if t not in slaves)
        sides = self.contact_tags + self.master_tags
        self.dirichlet_values = check_dirichlet(dirichlet, mesh, sides)
        self.dirichlet = tuple(self.dirichlet_values)
        self.body_force, self.traction = check_loads(
            body_force, traction, mesh, sides, self.dirichlet_values
        )
        self.gap = check_pair_gap(gap, self.pairs, self.rigid_tags) if self.pairs else gap
        self.gap = check_gap(self.gap, mesh, facet_tags, self.rigid_tags or self.contact_tags)
        self.force_obstacle = _force_obstacle(self.gap, bool(self.pairs))
        self.boundary_projection = check_projection(boundary_projection)
        used = (
            [("contact", t) for t in self.contact_tags]
            + [("ContactPair master", t) for t in self.master_tags]
            + [("dirichlet", t) for t in self.dirichlet]
            + [("traction", t) for t in self.traction]
            + [("boundary_projection", t) for t in self.boundary_projection]
        )
        check_tags(mesh, facet_tags, used, sides)
        check_projection_fits(mesh, facet_tags, self.boundary_projection)
        check_pair_bodies(mesh, facet_tags, self.pairs)
        self.law = check_law(friction, self)
        self.friction = self.law if self.law.frictional else None
        self.material_law = check_material_law(material, self)
        self._miss = _miss_gap(mesh, self.gap)  # collective: computed once, here
        self._frozen = True

    def __setattr__(self, name: str, value: Any) -> None:
        """Set an attribute in the constructor; afterwards the problem is frozen."""
        if getattr(self, "_frozen", False):
            _frozen_error(name)
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> NoReturn:
        """The problem is frozen: no attribute can be deleted."""
        _frozen_error(name)

    @property
    def contact_entries(self) -> int | tuple[Any, ...]:
        """``contact`` as given: the tags, with each pair's slave tag replaced by the pair."""
        by_slave = {p.slave: p for p in self.pairs}
        entries = tuple(by_slave.get(t, t) for t in self.contact_tags)
        return entries[0] if len(entries) == 1 and not self.pairs else entries

    @property
    def homogeneous_dirichlet(self) -> bool:
        """Whether every Dirichlet condition prescribes zero (no lifting needed)."""
        return all(
            not callable(v) and all(c in (None, 0.0) for c in v)
            for v in self.dirichlet_values.values()
        )

    @property
    def finite_strain(self) -> bool:
        """Whether the material law is a finite-strain (hyperelastic) one."""
        return self.material_law.finite_strain

    @property
    def homogeneous_material(self) -> bool:
        """Whether E and nu are numbers."""
        return isinstance(self.E, float) and isinstance(self.nu, float)

    # -- material law (linear elasticity) ----------------------------------------------------
    @property
    def lame(self) -> tuple[float, float]:
        """Lame parameters (mu, lambda) of the model (plane stress uses the reduced lambda)."""
        if not self.homogeneous_material:
            raise ValueError("lame: E and nu vary in space; use material(x) / sigma(u)")
        return lame_parameters(self.E, self.nu, self.model)

    def epsilon(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Linearised strain eps(u) = sym(grad u)."""
        return ufl.sym(ufl.grad(u))

    def _fields(self, expr: Any) -> MeshFields:
        """The data on the mesh of ``expr``: with T_H's cell tags on T_H, without elsewhere.

        The fields of a discretisation's meshes (with the cell tags of T_h and the contact-tag
        indicators) are its own, ``disc.fields`` and ``disc.macro_fields``.
        """
        cargo = extract_unique_domain(expr).ufl_cargo()
        if getattr(cargo, "_cpp_object", cargo) is getattr(self.mesh, "_cpp_object", self.mesh):
            return MeshFields(self, self.mesh, self.cell_tags)
        return MeshFields(self, cargo)

    def material(self, x: Any) -> tuple[Any, Any]:
        """``(E, nu)`` as UFL scalars on the mesh of ``x`` (numbers stay floats).

        Per-cell-tag data on a mesh other than T_H raise a ValueError: use ``m.sigma(u)`` (the
        goal measures) or the fields of a discretisation (``disc.fields.material(x)``).
        """
        return self._fields(x).material(x)

    def sigma(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Stress sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I (Hooke's law).

        As :meth:`~dwr_signorini.fields.MeshFields.sigma` on the mesh of ``u``; per-cell-tag
        data on a mesh other than T_H raise a ValueError (use ``m.sigma(u)`` or
        ``disc.fields.sigma(u)``).
        """
        if self.homogeneous_material:
            return stress(u, self.E, self.nu, self.model, constants=True)
        return self._fields(u).sigma(u)

    def elastic_form(self, u: Any, v: Any, dx: ufl.Measure) -> ufl.Form:
        """a(u, v) = (sigma(u), eps(v)) (Section 2)."""
        return ufl.inner(self.sigma(u), self.epsilon(v)) * dx

    def load_form(
        self, v: Any, m: Any, f: Any | None = None, dx: ufl.Measure | None = None
    ) -> ufl.Form:
        """<l, v> = (f, v) + (b, v)_GN on the measures ``m`` of a mesh (Section 2).

        Args:
            v: Test function (or weight).
            m: Measures of the mesh.
            f: The body force as a UFL expression on that mesh, if not built from the data
                (e.g. its values at quadrature points).
            dx: The cell measure to integrate ``f`` with (default ``m.dx``).
        """
        f = self.vector(self.body_force, m.x) if f is None else f
        form = ufl.inner(f, v) * (m.dx if dx is None else dx)
        for tag, t in self.traction.items():
            form += ufl.inner(self.vector(t, m.x, f"traction[{tag}]"), v) * m.ds(tag)
        return form

    def vector(
        self, value: VectorData, x: ufl.SpatialCoordinate, where: str = "body_force"
    ) -> ufl.core.expr.Expr:
        """A load as a UFL vector on the mesh of ``x``; ``None`` is the zero vector.

        ``where`` names the load in the error of a callable that raises (on any rank).

        Constant data (``None``, a sequence, a callable returning literal numbers) become a
        :class:`dolfinx.fem.Constant`: UFL simplifies a literal zero away, and
        ``inner(0, v) * dx`` would lose its test function and could not be assembled.
        """
        if callable(value):
            return nonzero_literal(ufl.as_vector(call_user(self.mesh, where, value, x)), x)
        data = np.zeros(self.mesh.geometry.dim) if value is None else np.asarray(value, float)
        return fem.Constant(extract_unique_domain(x), data)

    @property
    def miss_gap(self) -> float:
        """The gap where an obstacle's ray misses it (:mod:`dwr_signorini.obstacles`).

        Twice the diameter of the bounding box of T_H plus the largest obstacle size and the
        largest distance from the box's center to an obstacle's reference point: larger than
        any gap a point of the body can close. Computed (collectively) in the constructor.
        """
        return self._miss

    def gap_expr(self, x: ufl.SpatialCoordinate, n: Any = None) -> ufl.core.expr.Expr:
        """The gap g as UFL on the mesh of ``x`` (constants as a dolfinx Constant, see vector).

        As :meth:`~dwr_signorini.fields.MeshFields.gap`. A gap that differs between contact
        tags needs the indicators of the tags' macro facets, which a discretisation holds: use
        its fields, ``disc.fields.gap(m.x)``.

        Args:
            x: The spatial coordinate of the mesh of the form.
            n: The outward unit normal; obstacles need it, and ``None`` takes the
                ``ufl.FacetNormal`` of that mesh (the same as ``m.n``), so the expression is
                for facet integrals over Gamma_C.

        Returns:
            The gap, a UFL scalar expression.

        Raises:
            ValueError: If the gap differs between contact tags (use ``disc.fields.gap``).
        """
        return self._fields(x).gap(x, n)

    def with_mesh(
        self,
        mesh: dmesh.Mesh,
        facet_tags: dmesh.MeshTags,
        cell_tags: dmesh.MeshTags | None = None,
        law: Any = None,
        material: Any = None,
    ) -> SignoriniProblem:
        """The same problem on another (refined) macro mesh.

        Args:
            mesh: The new macro mesh.
            facet_tags: Its facet tags.
            cell_tags: Its cell tags, needed when E or nu is given per cell tag (those of a
                discretisation's T_h are ``disc.cell_tags``).
            law: Another contact law for the new problem (``None``: this problem's), e.g. the
                richer law of a model error estimate.
            material: Another material law (``None``: this problem's), e.g. the hyperelastic
                law of a model error estimate.

        Returns:
            A new :class:`SignoriniProblem` with this problem's data on ``mesh``.

        Raises:
            ValueError: As the constructor, if the tags do not fit the new mesh.
        """
        return SignoriniProblem(
            mesh,
            facet_tags,
            self.contact_entries,
            self.dirichlet_values,
            self.E,
            self.nu,
            self.model,
            self.body_force,
            self.traction,
            self.gap,
            cell_tags=cell_tags,
            boundary_projection=self.boundary_projection or None,
            friction=self.law if law is None else law,
            quadrature_degree=self.quadrature_degree,
            material=self.material_law if material is None else material,
        )


def _force_obstacle(gap: Any, pairs: bool) -> Obstacle | None:
    """The obstacle of ``gap`` under a given force (force control), or None.

    Raises:
        ValueError: A force-controlled obstacle in a gap per contact tag or beside contact
            pairs (one obstacle, the only contact, is supported).
    """
    given = list(gap.values()) if isinstance(gap, Mapping) else [gap]
    forced = [g for g in given if isinstance(g, Obstacle) and g.force is not None]
    if not forced:
        return None
    if isinstance(gap, Mapping) or pairs:
        raise ValueError(
            "an obstacle with force= must be the problem's only gap (gap=obstacle), not one of "
            "a gap per contact tag or beside contact pairs"
        )
    return forced[0]


def _frozen_error(name: str) -> NoReturn:
    raise AttributeError(
        f"SignoriniProblem is frozen after validation: {name!r} cannot be changed; build a new "
        "problem (ds.SignoriniProblem(...), or problem.with_mesh(...) on another mesh)"
    )


def _miss_gap(mesh: dmesh.Mesh, gap: Any) -> float:
    """The problem's ``miss_gap`` for the macro mesh ``mesh`` and the checked ``gap``."""
    x = mesh.geometry.x
    comm = mesh.comm
    lo, hi = np.min(x, axis=0, initial=np.inf), np.max(x, axis=0, initial=-np.inf)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    diameter = float(np.linalg.norm(hi - lo))
    extra = 0.0
    gaps = gap.values() if isinstance(gap, Mapping) else [gap]
    gdim = mesh.geometry.dim
    for g in gaps:
        if isinstance(g, Obstacle):
            p = np.zeros(3)
            p[:gdim] = g.reference_point[:gdim]
            extra = max(extra, g.size + float(np.linalg.norm(p - 0.5 * (lo + hi))))
    return 2.0 * (diameter + extra) + 1.0e-300
