"""Signorini's problem: data of the contact problem (1)-(3) of the paper, validated once.

A :class:`SignoriniProblem` holds the *macro* mesh T_H the user passes, its facet tags and the
material, loads and gap. Nothing is discretised here: :mod:`dwr_signorini.spaces` builds the fine
mesh T_h and the spaces, and the UFL expressions of this module are evaluated on it.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from ufl.domain import extract_unique_domain

from . import compat

__all__ = ["MODELS", "SignoriniProblem", "lame_parameters", "stress"]

MODELS = ("plane_strain", "plane_stress", "3d")

VectorData = Sequence[float] | Callable[[ufl.SpatialCoordinate], Any] | None


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


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _nonzero_literal(expr: ufl.core.expr.Expr, x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """``expr``, or a Constant with its value if UFL would simplify it away (a literal zero)."""
    if isinstance(expr, ufl.constantvalue.ConstantValue) or (
        isinstance(expr, ufl.classes.ListTensor)
        and all(isinstance(c, ufl.constantvalue.ConstantValue) for c in expr.ufl_operands)
    ):
        shape = ufl.shape(expr)
        data = [float(expr[i]) for i in range(shape[0])] if shape else float(expr)
        return fem.Constant(extract_unique_domain(x), np.asarray(data, dtype=float))
    return expr


class SignoriniProblem:
    """Frictionless contact of a linear-elastic body with a rigid obstacle (paper eq. 1-3).

    Args:
        mesh: The macro mesh T_H (simplices for adaptivity; quadrilaterals/hexahedra for uniform
            runs). The displacement lives on its uniform refinement T_h, the contact force on its
            contact facets (P0, so H = 2h).
        facet_tags: Facet tags of ``mesh``.
        contact: Tag of the possible contact boundary Gamma_C.
        dirichlet: Tags of the clamped boundary Gamma_D (u = 0).
        E: Young's modulus, > 0.
        nu: Poisson's ratio, in (-1, 0.5).
        model: ``"plane_strain"`` or ``"plane_stress"`` in 2D, ``"3d"`` in 3D; ``None`` picks
            plane strain in 2D and ``"3d"`` in 3D.
        body_force: Volume load f: ``None``, a constant sequence, or a callable ``x -> UFL vector``.
        traction: Surface loads b on Gamma_N: ``{tag: sequence | callable x -> UFL vector}``.
        gap: The gap g of the linearised contact condition u_n <= g on Gamma_C (eq. 2): a finite
            float or a callable ``x -> UFL scalar``.

    Raises:
        ValueError: For any inconsistent or non-physical input, naming the argument.
        TypeError: For arguments of the wrong type.
    """

    def __init__(
        self,
        mesh: dmesh.Mesh,
        facet_tags: dmesh.MeshTags,
        contact: int,
        dirichlet: Iterable[int] = (),
        E: float = 1.0,
        nu: float = 0.3,
        model: str | None = None,
        body_force: VectorData = None,
        traction: Mapping[int, VectorData] | None = None,
        gap: float | Callable[[ufl.SpatialCoordinate], Any] = 0.0,
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
        for name, value in (("E", E), ("nu", nu)):
            if not _is_real(value):
                raise TypeError(f"{name} must be a real number, got {value!r}")
        if not math.isfinite(E) or E <= 0:
            raise ValueError(
                f"E (Young's modulus) must be a finite number > 0, got {E!r}: pass the "
                "stiffness of the material (any consistent units, e.g. E=210e9 in Pa)"
            )
        if not -1.0 < nu < 0.5:
            raise ValueError(
                f"nu (Poisson's ratio) must lie in the open interval (-1, 0.5), got {nu!r}"
                + (
                    ": nu = 0.5 is incompressible, which a displacement formulation cannot "
                    "represent; use nu <= 0.499 (P1 elements lock as nu -> 0.5)"
                    if nu == 0.5
                    else ""
                )
            )

        if not isinstance(contact, numbers.Integral) or isinstance(contact, bool):
            raise TypeError(f"contact must be an integer facet tag, got {contact!r}")
        if isinstance(dirichlet, numbers.Integral):
            dirichlet = (dirichlet,)
        dirichlet = tuple(dirichlet)
        if any(not isinstance(t, numbers.Integral) or isinstance(t, bool) for t in dirichlet):
            raise TypeError(
                f"dirichlet must be a sequence of integer facet tags, got {dirichlet!r}"
            )
        if not dirichlet:
            raise ValueError(
                "dirichlet must name at least one facet tag: without a clamped boundary "
                "Gamma_D the body can move rigidly and the problem is not well posed"
            )
        if contact in dirichlet:
            raise ValueError(
                f"tag {contact} is used both as contact and as dirichlet boundary; "
                "a facet is either clamped or in possible contact"
            )
        if traction is not None and not isinstance(traction, Mapping):
            raise TypeError(
                "traction must be a dict {facet tag: load}, e.g. {2: (0.0, -1.0)}, got "
                f"{type(traction).__name__}"
            )
        traction = dict(traction or {})
        for tag in traction:
            if not isinstance(tag, numbers.Integral) or isinstance(tag, bool):
                raise TypeError(f"traction keys must be integer facet tags, got {tag!r}")
            if tag == contact or tag in dirichlet:
                raise ValueError(
                    f"traction tag {tag} is also a contact/dirichlet tag; tractions act on Gamma_N"
                )

        if callable(gap):
            pass  # checked below, once self.mesh is set
        elif _is_real(gap):
            if not math.isfinite(gap):
                raise ValueError(f"gap must be finite, got {gap!r}")
            gap = float(gap)
        else:
            raise TypeError(f"gap must be a float or a callable x -> UFL scalar, got {gap!r}")

        self.mesh = mesh
        self.facet_tags = facet_tags
        self.contact = int(contact)
        self.dirichlet = tuple(int(t) for t in dirichlet)
        self.E = float(E)
        self.nu = float(nu)
        self.model = model
        self.body_force = self._check_vector(body_force, "body_force")
        self.traction = {
            int(k): self._check_vector(v, f"traction[{k}]") for k, v in traction.items()
        }
        self.gap = gap
        if callable(gap):
            self._check_callable(gap, "gap", ())

        self._check_tags()

    # -- validation ---------------------------------------------------------------------------
    def _check_vector(self, value: VectorData, name: str) -> VectorData:
        if value is None:
            return value
        if callable(value):
            self._check_callable(value, name, (self.mesh.geometry.dim,))
            return value
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError) as err:
            raise TypeError(
                f"{name} must be a sequence of floats or a callable, got {value!r}"
            ) from err
        if arr.shape != (self.mesh.geometry.dim,):
            raise ValueError(
                f"{name} must have {self.mesh.geometry.dim} components, got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite, got {value!r}")
        return tuple(float(a) for a in arr)

    def _check_callable(self, value: Callable[..., Any], name: str, shape: tuple[int, ...]) -> None:
        """Call ``value`` with the mesh's SpatialCoordinate once: a UFL expression of ``shape``?"""
        what = "scalar" if not shape else f"vector with {shape[0]} components"
        try:
            expr = value(ufl.SpatialCoordinate(self.mesh))
            expr = ufl.as_vector(expr) if isinstance(expr, (list, tuple)) else ufl.as_ufl(expr)
        except Exception as err:
            raise TypeError(
                f"{name} must be a callable x -> UFL {what} (x a ufl.SpatialCoordinate; use "
                f"ufl functions such as ufl.sin, not numpy), but calling it failed: {err}"
            ) from err
        if ufl.shape(expr) != shape:
            raise ValueError(f"{name} must return a UFL {what}, got shape {ufl.shape(expr)}")

    def _check_tags(self) -> None:
        """Every tag used must mark at least one boundary facet somewhere (all ranks)."""
        msh, tags = self.mesh, self.facet_tags
        fdim = msh.topology.dim - 1
        msh.topology.create_connectivity(fdim, fdim + 1)
        boundary = dmesh.exterior_facet_indices(msh.topology)
        comm = msh.comm
        for name, tag in (
            [("contact", self.contact)]
            + [("dirichlet", t) for t in self.dirichlet]
            + [("traction", t) for t in self.traction]
        ):
            facets = tags.find(tag)
            count = comm.allreduce(int(np.isin(facets, boundary).sum()), op=MPI.SUM)
            if count == 0:
                present = sorted(set(comm.allreduce(list(map(int, np.unique(tags.values))))))
                raise ValueError(
                    f"{name} tag {tag} marks no boundary facet of the mesh (tags present: "
                    f"{present}); pass the tag that facet_tags give that boundary"
                )

    # -- material law (linear elasticity) ----------------------------------------------------
    @property
    def lame(self) -> tuple[float, float]:
        """Lame parameters (mu, lambda) of the model (plane stress uses the reduced lambda)."""
        return lame_parameters(self.E, self.nu, self.model)

    def epsilon(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Linearised strain eps(u) = sym(grad u)."""
        return ufl.sym(ufl.grad(u))

    def sigma(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Stress sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I (Hooke's law).

        The Lame parameters enter as dolfinx Constants on the mesh of ``u``, so forms for
        different materials share their compiled code (no new JIT compilation per E, nu).
        """
        return stress(u, self.E, self.nu, self.model, constants=True)

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
            form += ufl.inner(self.vector(t, m.x), v) * m.ds(tag)
        return form

    def vector(self, value: VectorData, x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
        """A load as a UFL vector on the mesh of ``x``; ``None`` is the zero vector.

        Constant data (``None``, a sequence, a callable returning literal numbers) become a
        :class:`dolfinx.fem.Constant`: UFL simplifies a literal zero away, and
        ``inner(0, v) * dx`` would lose its test function and could not be assembled.
        """
        if callable(value):
            return _nonzero_literal(ufl.as_vector(value(x)), x)
        data = np.zeros(self.mesh.geometry.dim) if value is None else np.asarray(value, float)
        return fem.Constant(extract_unique_domain(x), data)

    def gap_expr(self, x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
        """The gap g as UFL on the mesh of ``x`` (constants as a dolfinx Constant, see vector)."""
        if callable(self.gap):
            return _nonzero_literal(ufl.as_ufl(self.gap(x)), x)
        return fem.Constant(extract_unique_domain(x), float(self.gap))

    def with_mesh(self, mesh: dmesh.Mesh, facet_tags: dmesh.MeshTags) -> SignoriniProblem:
        """The same problem on another (refined) macro mesh."""
        return SignoriniProblem(
            mesh,
            facet_tags,
            self.contact,
            self.dirichlet,
            self.E,
            self.nu,
            self.model,
            self.body_force,
            self.traction,
            self.gap,
        )
