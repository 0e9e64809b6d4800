"""Signorini's problem: data of the contact problem (1)-(3) of the paper, validated once.

A :class:`SignoriniProblem` holds the *macro* mesh T_H the user passes, its facet tags and the
material, loads and gap. Nothing is discretised here: :mod:`dwr_signorini.spaces` builds the fine
mesh T_h and the spaces, and the UFL expressions of this module are evaluated on it. The checks
of the data (each error naming its argument) are in :mod:`dwr_signorini.problem_data`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from ufl.domain import extract_unique_domain

from . import compat
from .laws import ContactLaw, check_law
from .obstacles import Obstacle
from .problem_data import (
    DirichletData,
    GapData,
    MaterialData,
    ProblemDataChecks,
    VectorData,
    _is_real,
    _is_tag,
    _nonzero_literal,
    _tags,
)
from .quadrature import DATA_QUADRATURE_DEGREE

__all__ = ["MODELS", "SignoriniProblem", "lame_parameters", "stress"]

MODELS = ("plane_strain", "plane_stress", "3d")



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


#: Per-mesh data of a problem: cell tags of a refined mesh and indicators of contact tags.
_MeshData = dict[str, Any]


class SignoriniProblem(ProblemDataChecks):
    """Signorini's problem (eq. 1-3): an elastic body on a rigid obstacle, with or without friction.

    The contact is frictionless (the paper's problem) or follows Tresca's or Coulomb's law
    (``friction``).

    Args:
        mesh: The macro mesh T_H (simplices for adaptivity; quadrilaterals/hexahedra for uniform
            runs). The displacement lives on its uniform refinement T_h, the contact force on its
            contact facets (P0, so H = 2h).
        facet_tags: Facet tags of ``mesh``.
        contact: Tag, or tags, of the possible contact boundary Gamma_C.
        dirichlet: Gamma_D: tags clamped (u = 0), or ``{tag: value}`` with ``value`` a number
            (every component equals it, e.g. ``0.0``), a tuple of ``gdim`` numbers or ``None``
            (``None`` = that component free: ``(0.0, None)`` is a roller / symmetry plane
            ``u_x = 0``), or a callable ``x -> UFL vector`` (every component, from x). Where two
            conditions prescribe the same component at a vertex, the later tag wins.
        E: Young's modulus, > 0: a number, a callable ``x -> UFL scalar`` (checked > 0 at the
            quadrature points), or ``{cell tag: number}`` with ``cell_tags``.
        nu: Poisson's ratio, in (-1, 0.5): as ``E``.
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
            (the distance along the outward normal), or ``{contact tag: any of these}``.
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

    Raises:
        ValueError: For any inconsistent or non-physical input, naming the argument.
        TypeError: For arguments of the wrong type.
    """

    def __init__(
        self,
        mesh: dmesh.Mesh,
        facet_tags: dmesh.MeshTags,
        contact: int | Iterable[int],
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
    ) -> None:
        if not isinstance(mesh, dmesh.Mesh):
            raise TypeError(f"mesh must be a dolfinx.mesh.Mesh, got {type(mesh).__name__}")
        if not isinstance(facet_tags, dmesh.MeshTags):
            raise TypeError(
                f"facet_tags must be dolfinx.mesh.MeshTags, got {type(facet_tags).__name__}"
            )
        tdim = mesh.topology.dim
        cpp_topology = getattr(mesh.topology, "_cpp_object", None)
        if cpp_topology is not None and facet_tags.topology is not cpp_topology:
            raise ValueError(
                "facet_tags belong to another mesh: create them on `mesh` "
                "(dolfinx.mesh.meshtags(mesh, ...)) or read them together with it (gmshio)"
            )
        if facet_tags.dim != tdim - 1:
            raise ValueError(
                f"facet_tags has dimension {facet_tags.dim}, but the facets of this mesh have "
                f"dimension {tdim - 1}: pass the facet tags, not cell tags"
            )
        mesh.topology.create_entities(tdim - 1)
        num_facets = mesh.topology.index_map(tdim - 1)
        if (
            num_facets is not None
            and len(facet_tags.indices)
            and int(facet_tags.indices.max()) >= (num_facets.size_local + num_facets.num_ghosts)
        ):
            raise ValueError(
                "facet_tags index facets that `mesh` does not have: another mesh's tags?"
            )
        if mesh.topology.index_map(tdim).size_global == 0:
            raise ValueError("mesh has no cells: pass the macro mesh T_H of the body")
        if tdim not in (2, 3) or mesh.geometry.dim != tdim:
            raise ValueError("mesh must be a 2D mesh in the plane or a 3D volume mesh")
        if compat.geometry_cmap(mesh).degree != 1:
            raise ValueError(
                "only meshes with affine/multilinear geometry (degree 1) are supported"
            )

        if model is None:
            model = "plane_strain" if tdim == 2 else "3d"
        if model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {model!r}")
        if (model == "3d") != (tdim == 3):
            raise ValueError(
                f"model={model!r} does not fit a {tdim}D mesh: use "
                + ("'plane_strain' or 'plane_stress'" if tdim == 2 else "'3d'")
            )
        if isinstance(quadrature_degree, bool) or not isinstance(quadrature_degree, int):
            raise TypeError(
                f"quadrature_degree must be an integer, got {type(quadrature_degree).__name__}"
            )
        if not 0 <= quadrature_degree <= 30:
            raise ValueError(
                f"quadrature_degree must be in [0, 30], got {quadrature_degree}"
            )
        self.quadrature_degree = int(quadrature_degree)
        self.mesh = mesh
        self.facet_tags = facet_tags
        self.model = model
        self._mesh_data: dict[int, _MeshData] = {}
        #: Registrations of each fine mesh not yet unregistered (see unregister_mesh).
        self._mesh_users: dict[int, int] = {}
        self.cell_tags = self._check_cell_tags(cell_tags, E, nu)
        self.E = self._check_material(E, "E")
        self.nu = self._check_material(nu, "nu")

        contact_tags = _tags(contact, "contact")
        if not contact_tags:
            raise ValueError("contact must name at least one facet tag")
        if len(set(contact_tags)) != len(contact_tags):
            raise ValueError(f"contact names a tag twice: {contact_tags}")
        self.contact_tags = contact_tags
        self.contact: int | tuple[int, ...] = (
            contact_tags[0] if len(contact_tags) == 1 else contact_tags
        )
        self.dirichlet_values = self._check_dirichlet(dirichlet)
        self.dirichlet = tuple(self.dirichlet_values)
        if traction is not None and not isinstance(traction, Mapping):
            raise TypeError(
                "traction must be a dict {facet tag: load}, e.g. {2: (0.0, -1.0)}, got "
                f"{type(traction).__name__}"
            )
        traction = dict(traction or {})
        for tag in traction:
            if not _is_tag(tag):
                raise TypeError(f"traction keys must be integer facet tags, got {tag!r}")
            if tag in contact_tags:
                raise ValueError(
                    f"traction tag {tag} is also a contact tag; tractions act on Gamma_N (and on "
                    "the free components of a dirichlet face), the contact force is the unknown "
                    "lambda"
                )
        self.body_force = self._check_vector(body_force, "body_force")
        self.traction = {
            int(k): self._check_vector(v, f"traction[{k}]") for k, v in traction.items()
        }
        for tag, load in self.traction.items():
            self._check_traction_on_dirichlet(tag, load)
        self.gap = self._check_gap(gap)
        self.boundary_projection = self._check_projection(boundary_projection)
        self._check_tags()
        self.law = check_law(friction, self)
        self.friction = self.law if self.law.frictional else None
        self.miss_gap  # noqa: B018  (collective: computed once, here)

    # -- validation ---------------------------------------------------------------------------
    def _check_traction_on_dirichlet(self, tag: int, load: Any) -> None:
        """A traction on a dirichlet face acts on its free components only.

        ``dirichlet={4: (d, None)}, traction={4: (0.0, -p)}`` shears the face with a
        displacement and presses it with a force; a nonzero traction on a prescribed
        component would be lost silently (its equations are replaced by the prescribed value).
        """
        if tag not in self.dirichlet_values:
            return
        value = self.dirichlet_values[tag]
        if callable(value):
            raise ValueError(
                f"traction tag {tag} is a dirichlet tag with a callable value, which prescribes "
                f"every component: drop traction[{tag}], or prescribe dirichlet[{tag}] as a "
                "tuple with None on the components the traction acts on"
            )
        if callable(load):
            raise ValueError(
                f"traction[{tag}] is a callable on dirichlet face {tag}: on a face with "
                "prescribed components give the traction as a tuple of numbers (0.0 on the "
                "prescribed ones)"
            )
        clash = [i for i, (c, t) in enumerate(zip(value, load, strict=True))
                 if c is not None and t != 0.0]
        if clash:
            raise ValueError(
                f"traction[{tag}] has nonzero component(s) {clash} that dirichlet[{tag}] "
                f"prescribes ({value!r}): a traction acts on the free (None) components of a "
                "dirichlet face only; set those traction components to 0.0"
            )

    def _data(self, domain_mesh: Any) -> _MeshData:
        """The registered data of a mesh (by its C++ object or Python mesh), or ``{}``."""
        cpp = getattr(domain_mesh, "_cpp_object", domain_mesh)
        if cpp is getattr(self.mesh, "_cpp_object", self.mesh) and not self._mesh_data.get(
            id(cpp)
        ):
            self.register_mesh(self.mesh, cell_tags=self.cell_tags)
        return self._mesh_data.get(id(cpp), {})

    def register_mesh(
        self,
        msh: dmesh.Mesh,
        cell_tags: dmesh.MeshTags | None = None,
        contact_indicators: Mapping[int, Any] | None = None,
    ) -> None:
        """Let the data of this problem be evaluated on ``msh`` (a refinement of T_H).

        :class:`~dwr_signorini.spaces.Discretization` registers T_h with its cell tags (carried
        from T_H through the parent cells) and, for a gap per contact tag, the indicator of each
        contact tag (functions of Lambda_H, 1 on that tag's macro facets).
        """
        key = id(msh._cpp_object)
        data = self._mesh_data.setdefault(key, {"mesh": msh})
        if cell_tags is not None:
            data["cell_tags"] = cell_tags
        if contact_indicators is not None:
            data["contact_indicators"] = dict(contact_indicators)
        if msh is not self.mesh:
            self._mesh_users[key] = self._mesh_users.get(key, 0) + 1

    def unregister_mesh(self, msh: dmesh.Mesh) -> None:
        """One registration of ``msh`` (not T_H) fewer; its data go with the last one.

        Each discretisation registers its T_h once and unregisters it when it is gone (two may
        share T_h: :meth:`~dwr_signorini.spaces.Discretization.for_problem`). A problem solved
        many times would otherwise hold every fine mesh it was discretised on.
        """
        key = id(msh._cpp_object)
        if msh is self.mesh or key not in self._mesh_users:
            return
        self._mesh_users[key] -= 1
        if self._mesh_users[key] == 0:
            del self._mesh_users[key]
            self._mesh_data.pop(key, None)

    def registered_cell_tags(self, msh: dmesh.Mesh) -> dmesh.MeshTags | None:
        """The cell tags of ``msh`` if registered (``self.cell_tags`` on T_H), else ``None``."""
        return self._data(msh).get("cell_tags", self.cell_tags if msh is self.mesh else None)

    def _domain_data(self, x: Any) -> _MeshData:
        return self._data(extract_unique_domain(x).ufl_cargo())

    def material(self, x: Any) -> tuple[Any, Any]:
        """``(E, nu)`` as UFL scalars on the mesh of ``x`` (numbers stay floats)."""
        return self._material(self.E, "E", x), self._material(self.nu, "nu", x)

    def _material(self, value: MaterialData, name: str, x: Any) -> Any:
        if callable(value):
            return self.call_user(name, value, x)
        if not isinstance(value, Mapping):
            return value
        data = self._domain_data(x)
        key = f"field_{name}"
        if key not in data:
            tags = data.get("cell_tags")
            if tags is None:
                raise ValueError(
                    f"{name} is given per cell tag, but this mesh has no registered cell tags "
                    "(build forms on the meshes of ds.discretize / ds.solve)"
                )
            msh = data["mesh"]
            space = fem.functionspace(msh, ("DG", 0))
            field = fem.Function(space, name=name)
            num = msh.topology.index_map(msh.topology.dim).size_local
            lookup = dict(value)
            keep = (tags.indices < num) & np.isin(tags.values, list(lookup))
            cells = tags.indices[keep]
            field.x.array[space.dofmap.list[cells, 0]] = [lookup[int(t)] for t in tags.values[keep]]
            field.x.scatter_forward()
            data[key] = field
        return data[key]

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

    def sigma(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Stress sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I (Hooke's law).

        For numbers E, nu the Lame parameters enter as dolfinx Constants on the mesh of ``u``,
        so forms for different materials share their compiled code (no new JIT compilation per
        E, nu); callables enter as UFL expressions of x, per-cell-tag values as DG0 functions.
        """
        if self.homogeneous_material:
            return stress(u, self.E, self.nu, self.model, constants=True)
        E, nu = self.material(ufl.SpatialCoordinate(extract_unique_domain(u)))
        return stress(u, E, nu, self.model)

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
            return _nonzero_literal(ufl.as_vector(self.call_user(where, value, x)), x)
        data = np.zeros(self.mesh.geometry.dim) if value is None else np.asarray(value, float)
        return fem.Constant(extract_unique_domain(x), data)

    @property
    def miss_gap(self) -> float:
        """The gap where an obstacle's ray misses it (:mod:`dwr_signorini.obstacles`).

        Twice the diameter of the bounding box of T_H plus the largest obstacle size and the
        largest distance from the box's center to an obstacle's reference point: larger than
        any gap a point of the body can close. Computed (collectively) in the constructor.
        """
        if not hasattr(self, "_miss"):
            x = self.mesh.geometry.x
            comm = self.mesh.comm
            lo, hi = np.min(x, axis=0, initial=np.inf), np.max(x, axis=0, initial=-np.inf)
            comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
            comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
            diameter = float(np.linalg.norm(hi - lo))
            extra = 0.0
            gaps = self.gap.values() if isinstance(self.gap, Mapping) else [self.gap]
            gdim = self.mesh.geometry.dim
            for g in gaps:
                if isinstance(g, Obstacle):
                    p = np.zeros(3)
                    p[:gdim] = g.reference_point[:gdim]
                    extra = max(extra, g.size + float(np.linalg.norm(p - 0.5 * (lo + hi))))
            self._miss = 2.0 * (diameter + extra) + 1.0e-300
        return self._miss

    def _gap_value(self, gap: Any, x: Any, n: Any) -> Any:
        """One gap's value at ``x`` (local: calls the user's callable or a Graph's psi)."""
        if isinstance(gap, Obstacle):
            n = ufl.FacetNormal(extract_unique_domain(x)) if n is None else n
            return gap.gap(x, n, self.miss_gap)
        if callable(gap):
            return ufl.as_ufl(gap(x))
        return gap

    def gap_expr(self, x: ufl.SpatialCoordinate, n: Any = None) -> ufl.core.expr.Expr:
        """The gap g as UFL on the mesh of ``x`` (constants as a dolfinx Constant, see vector).

        A gap per contact tag is the sum of each tag's gap times the indicator of its macro
        facets (a function of Lambda_H, registered by the discretisation), so it needs the
        entity maps of :meth:`~dwr_signorini.spaces.Discretization.form`.

        Args:
            x: The spatial coordinate of the mesh of the form.
            n: The outward unit normal; obstacles need it, and ``None`` takes the
                ``ufl.FacetNormal`` of that mesh (the same as ``m.n``), so the expression is
                for facet integrals over Gamma_C.

        Returns:
            The gap, a UFL scalar expression.

        Raises:
            ValueError: If the gap is given per contact tag and ``x`` is not the coordinate of a
                discretisation's mesh (no contact-tag indicators registered for it).
        """
        return self.contact_expr(self.gap, x, "gap", lambda g: self._gap_value(g, x, n))

    def contact_expr(
        self, data: Any, x: Any, name: str, value: Callable[[Any], Any] | None = None
    ) -> ufl.core.expr.Expr:
        """Data on Gamma_C (the gap, a friction threshold) as UFL on the mesh of ``x``.

        Data per contact tag is the sum of each tag's value times the indicator of its macro
        facets (a function of Lambda_H, registered by the discretisation), so it needs the
        entity maps of :meth:`~dwr_signorini.spaces.Discretization.form`.

        Args:
            data: A number, a callable x -> UFL scalar, or ``{contact tag: ...}``.
            x: The spatial coordinate of the mesh of the form.
            name: The argument's name, for errors.
            value: One value's expression (default: a callable is called with ``x``).

        Raises:
            ValueError: Per-tag data and ``x`` not the coordinate of a discretisation's mesh.
        """
        if value is None:
            value = lambda d: d(x) if callable(d) else d  # noqa: E731
        if isinstance(data, Mapping):
            values = {t: self.call_user(f"{name}[{t}]", value, d) for t, d in data.items()}
            distinct = {id(d) for d in data.values()}
            if len(distinct) == 1:
                return self._as_expr(next(iter(values.values())), x)
            indicators = self._domain_data(x).get("contact_indicators")
            if indicators is None:
                raise ValueError(
                    f"{name} is given per contact tag: its expression needs the contact-tag "
                    "indicators of a discretisation (use the measures of ds.discretize)"
                )
            total = sum(indicators[t] * ufl.as_ufl(values[t]) for t in self.contact_tags)
            return total
        return self._as_expr(self.call_user(name, value, data), x)

    @staticmethod
    def _as_expr(value: Any, x: Any) -> Any:
        if _is_real(value):
            return fem.Constant(extract_unique_domain(x), float(value))
        return _nonzero_literal(ufl.as_ufl(value), x)

    def with_mesh(
        self,
        mesh: dmesh.Mesh,
        facet_tags: dmesh.MeshTags,
        cell_tags: dmesh.MeshTags | None = None,
    ) -> SignoriniProblem:
        """The same problem on another (refined) macro mesh.

        Args:
            mesh: The new macro mesh.
            facet_tags: Its facet tags.
            cell_tags: Its cell tags; by default those registered for ``mesh`` (T_h of a
                discretisation of this problem, see :meth:`register_mesh`).

        Returns:
            A new :class:`SignoriniProblem` with this problem's data on ``mesh``.

        Raises:
            ValueError: As the constructor, if the tags do not fit the new mesh.
        """
        if cell_tags is None:
            cell_tags = self._data(mesh).get("cell_tags")
        return SignoriniProblem(
            mesh,
            facet_tags,
            self.contact_tags if len(self.contact_tags) > 1 else self.contact_tags[0],
            self.dirichlet_values,
            self.E,
            self.nu,
            self.model,
            self.body_force,
            self.traction,
            self.gap,
            cell_tags=cell_tags,
            boundary_projection=self.boundary_projection or None,
            friction=self.law,
            quadrature_degree=self.quadrature_degree,
        )
