"""Validation of the data of a problem: each error names its argument.

The checks of the boundary conditions, materials, gaps, projections, loads and tags, as a base
class of :class:`~dwr_signorini.problem.SignoriniProblem` (they read and set its attributes), and
the small helpers they share with it.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from ufl.domain import extract_unique_domain

from . import compat
from .collective import call_collectively, shadow
from .obstacles import Graph, Obstacle, Plane

__all__ = ["DirichletData", "DirichletValue", "GapData", "MaterialData", "ProblemDataChecks",
           "VectorData"]

VectorData = Sequence[float] | Callable[[ufl.SpatialCoordinate], Any] | None
#: A Dirichlet condition as given: a number, a tuple with None = free, or x -> UFL vector.
DirichletData = float | Sequence[float | None] | Callable[[ufl.SpatialCoordinate], Any]
#: A Dirichlet condition as stored: a tuple of gdim (float | None), or x -> UFL vector.
DirichletValue = tuple[float | None, ...] | Callable[[ufl.SpatialCoordinate], Any]
#: E or nu: a number, x -> UFL scalar, or {cell tag: number}.
MaterialData = float | Callable[[ufl.SpatialCoordinate], Any] | Mapping[int, float]
#: A gap: a number, x -> UFL scalar, or an obstacle.
GapData = float | Callable[[ufl.SpatialCoordinate], Any] | Obstacle


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


def _is_tag(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _tags(value: Any, name: str) -> tuple[int, ...]:
    """A tag or an iterable of tags as a tuple of ints (TypeError naming ``name``)."""
    if _is_tag(value):
        return (int(value),)
    try:
        tags = tuple(value)
    except TypeError:
        tags = (value,)
    if any(not _is_tag(t) for t in tags):
        raise TypeError(f"{name} must be an integer facet tag or a sequence of them, got {value!r}")
    return tuple(int(t) for t in tags)


def _macro_cell_measure(msh: dmesh.Mesh) -> tuple[Any, ufl.Measure]:
    """A quadrature space of degree DATA_QUADRATURE_DEGREE on ``msh`` (for checks of data)."""
    import basix.ufl

    from .quadrature import DATA_QUADRATURE_DEGREE

    element = basix.ufl.quadrature_element(msh.basix_cell(), degree=DATA_QUADRATURE_DEGREE)
    return fem.functionspace(msh, element), DATA_QUADRATURE_DEGREE


class ProblemDataChecks:
    """The checks of a problem's data (the base of :class:`~dwr_signorini.SignoriniProblem`)."""

    def _check_dirichlet(self, dirichlet: Any) -> dict[int, DirichletValue]:
        """``{tag: tuple of gdim (float | None) | callable}`` from the argument ``dirichlet``."""
        gdim = self.mesh.geometry.dim
        if isinstance(dirichlet, Mapping):
            items = list(dirichlet.items())
            for tag, _ in items:
                if not _is_tag(tag):
                    raise TypeError(f"dirichlet keys must be integer facet tags, got {tag!r}")
        else:
            items = [(t, 0.0) for t in _tags(dirichlet, "dirichlet")]
        if not items:
            raise ValueError(
                "dirichlet must name at least one facet tag: without a clamped boundary "
                "Gamma_D the body can move rigidly and the problem is not well posed"
            )
        out: dict[int, DirichletValue] = {}
        for tag, value in items:
            tag = int(tag)
            name = f"dirichlet[{tag}]"
            if tag in self.contact_tags:
                raise ValueError(
                    f"tag {tag} is used both as contact and as dirichlet boundary; "
                    "a facet is either prescribed or in possible contact"
                )
            if callable(value):
                self._check_callable(value, name, (gdim,))
                out[tag] = value
                continue
            if _is_real(value):
                value = (value,) * gdim
            if not isinstance(value, (tuple, list)):
                raise TypeError(
                    f"{name} must be a number, a tuple of {gdim} numbers or None (None = that "
                    f"component free), or a callable x -> UFL vector, got {value!r}"
                )
            if len(value) != gdim:
                raise ValueError(
                    f"{name} must have {gdim} components (one per coordinate, None = free), "
                    f"got {len(value)}: {value!r}"
                )
            for i, c in enumerate(value):
                if c is not None and not _is_real(c):
                    raise TypeError(f"{name}[{i}] must be a number or None, got {c!r}")
                if c is not None and not math.isfinite(c):
                    raise ValueError(f"{name}[{i}] must be finite, got {c!r}")
            if all(c is None for c in value):
                raise ValueError(f"{name} prescribes no component (all None)")
            out[tag] = tuple(None if c is None else float(c) for c in value)
        return out

    @property
    def homogeneous_dirichlet(self) -> bool:
        """Whether every Dirichlet condition prescribes zero (no lifting needed)."""
        return all(
            not callable(v) and all(c in (None, 0.0) for c in v)
            for v in self.dirichlet_values.values()
        )

    def _check_cell_tags(
        self, cell_tags: dmesh.MeshTags | None, E: Any, nu: Any
    ) -> dmesh.MeshTags | None:
        per_tag = [name for name, v in (("E", E), ("nu", nu)) if isinstance(v, Mapping)]
        if cell_tags is None:
            if per_tag:
                raise ValueError(
                    f"{per_tag[0]} is given per cell tag, so cell_tags (the MeshTags of the "
                    "cells of `mesh`, e.g. from ds.read_mesh) are needed"
                )
            return None
        if not isinstance(cell_tags, dmesh.MeshTags):
            raise TypeError(f"cell_tags must be dolfinx.mesh.MeshTags, got {cell_tags!r}")
        tdim = self.mesh.topology.dim
        if cell_tags.dim != tdim:
            raise ValueError(
                f"cell_tags has dimension {cell_tags.dim}, the cells of the mesh {tdim}"
            )
        cpp_topology = getattr(self.mesh.topology, "_cpp_object", None)
        if cpp_topology is not None and cell_tags.topology is not cpp_topology:
            raise ValueError("cell_tags belong to another mesh: pass the tags of `mesh`")
        return cell_tags

    def _check_material(self, value: Any, name: str) -> MaterialData:
        """A number, callable or ``{cell tag: number}`` for E or nu, with its range checked."""
        low, high = (0.0, math.inf) if name == "E" else (-1.0, 0.5)
        if isinstance(value, Mapping):
            values = {}
            for tag, v in value.items():
                if not _is_tag(tag):
                    raise TypeError(f"{name} keys must be integer cell tags, got {tag!r}")
                values[int(tag)] = self._check_material(v, f"{name}[{tag}]")
                if callable(values[int(tag)]):
                    raise TypeError(f"{name}[{tag}] must be a number")
            self._check_cells_covered(values, name)
            return values
        if callable(value):
            self._check_callable(value, name, ())
            self._check_range_at_quadrature(value, name, low, high)
            return value
        if not _is_real(value):
            raise TypeError(
                f"{name} must be a real number, a callable x -> UFL scalar or a dict "
                f"{{cell tag: number}}, got {value!r}"
            )
        if name.startswith("E") and (not math.isfinite(value) or value <= 0):
            raise ValueError(
                f"{name} (Young's modulus) must be a finite number > 0, got {value!r}: pass the "
                "stiffness of the material (any consistent units, e.g. E=210e9 in Pa)"
            )
        if name.startswith("nu") and not -1.0 < value < 0.5:
            raise ValueError(
                f"{name} (Poisson's ratio) must lie in the open interval (-1, 0.5), got {value!r}"
                + (
                    ": nu = 0.5 is incompressible, which a displacement formulation cannot "
                    "represent; use nu <= 0.499 (P1 elements lock as nu -> 0.5)"
                    if value == 0.5
                    else ""
                )
            )
        return float(value)

    def _check_cells_covered(self, values: Mapping[int, float], name: str) -> None:
        """Every owned cell carries a tag of ``values`` (collective)."""
        tags = self.cell_tags
        num = self.mesh.topology.index_map(self.mesh.topology.dim).size_local
        covered = np.zeros(num, dtype=bool)
        keep = np.isin(tags.values, list(values)) & (tags.indices < num)
        covered[tags.indices[keep]] = True
        comm = shadow(self.mesh.comm)
        missing = comm.allreduce(int((~covered).sum()), op=MPI.SUM)
        if missing:
            present = sorted(set(comm.allreduce(list(map(int, np.unique(tags.values))))))
            raise ValueError(
                f"{name} is given for cell tags {sorted(values)}, but {missing} cells carry none "
                f"of them (cell tags present: {present})"
            )

    def _check_range_at_quadrature(
        self, value: Callable[..., Any], name: str, low: float, high: float
    ) -> None:
        """``low < value(x) < high`` at the degree-8 quadrature points of the mesh (collective)."""
        expr = ufl.as_ufl(self.call_user(name, value, ufl.SpatialCoordinate(self.mesh)))
        if extract_unique_domain(expr) is None:  # a constant, e.g. 0.6 + 0 * x[0] = 0.6
            vals = np.array([float(expr)])
        else:
            space, _ = _macro_cell_measure(self.mesh)
            f = fem.Function(space)
            f.interpolate(fem.Expression(expr, compat.interpolation_points(space.element)))
            vals = f.x.array
        comm = shadow(self.mesh.comm)
        lo = comm.allreduce(float(np.min(vals, initial=np.inf)), op=MPI.MIN)
        hi = comm.allreduce(float(np.max(vals, initial=-np.inf)), op=MPI.MAX)
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= low or hi >= high:
            what = "> 0" if name == "E" else "in (-1, 0.5)"
            raise ValueError(
                f"{name}(x) must be {what} at every quadrature point of the mesh, but it "
                f"ranges over [{lo:.6g}, {hi:.6g}]"
            )

    def _check_gap(self, gap: Any) -> Any:
        if isinstance(gap, Mapping):
            keys = set(gap)
            if any(not _is_tag(k) for k in keys):
                raise TypeError(f"gap keys must be integer contact tags, got {sorted(keys)}")
            missing = set(self.contact_tags) - keys
            if missing:
                raise ValueError(
                    f"gap is given per contact tag but misses the contact tag(s) "
                    f"{sorted(missing)}: give a gap for each of {self.contact_tags}"
                )
            extra = keys - set(self.contact_tags)
            if extra:
                raise ValueError(f"gap has tag(s) {sorted(extra)} that are not contact tags")
            return {int(k): self._check_gap_value(v, f"gap[{k}]") for k, v in gap.items()}
        return self._check_gap_value(gap, "gap")

    def _check_gap_value(self, gap: Any, name: str) -> Any:
        gdim = self.mesh.geometry.dim
        if isinstance(gap, Obstacle):
            dim = gap.dim
            if dim is not None and dim != gdim:
                raise ValueError(
                    f"{name}: a {dim}D obstacle ({gap!r}) on a {gdim}D mesh: give it "
                    f"{gdim} coordinates"
                )
            if isinstance(gap, Plane):
                self._check_plane_faces_body(gap, name)
            if isinstance(gap, Graph):
                if not -gdim <= gap.axis < gdim:
                    raise ValueError(f"{name}: Graph axis {gap.axis} out of range for {gdim}D")
                self._check_callable(gap.psi, f"{name} (Graph psi)", ())
            return gap
        if callable(gap):
            self._check_callable(gap, name, ())
            return gap
        if _is_real(gap):
            if not math.isfinite(gap):
                raise ValueError(f"{name} must be finite, got {gap!r}")
            return float(gap)
        raise TypeError(
            f"{name} must be a float, a callable x -> UFL scalar or an obstacle "
            f"(ds.obstacles.Plane, Sphere, Cylinder, Graph), got {gap!r}"
        )

    def _check_plane_faces_body(self, plane: Plane, name: str) -> None:
        """Some contact facet faces ``plane`` (its outward normal . the plane's normal > 0).

        A plane whose normal points into the body lies behind every contact facet: no facet can
        touch it and J would come out in [0, 0] without a word. Collective.
        """
        tag = name[len("gap["):-1] if name.startswith("gap[") else None
        tags = self.contact_tags if tag is None else (int(tag),)
        normals = self._outward_facet_normals(tags)
        facing = int(np.sum(normals @ plane.normal > 1e-12))
        comm = shadow(self.mesh.comm)
        facing, count = comm.allreduce(np.array([facing, len(normals)]), op=MPI.SUM)
        if count and not facing:  # (no contact facet at all: _check_tags names the tag)
            found = comm.allgather(np.unique(np.round(normals, 6), axis=0).tolist())
            seen = sorted({tuple(v) for part in found for v in part})
            raise ValueError(
                f"{name}: {plane!r} lies behind the body: no contact facet faces it (the "
                f"outward normals of contact tag(s) {list(tags)} are {seen[:4]}, and the "
                "normal of a Plane points into the obstacle, away from the body); flip the "
                "normal, e.g. Plane(point, normal="
                f"{tuple(float(-c) + 0.0 for c in plane.normal)})"
            )

    def _outward_facet_normals(self, tags: Sequence[int]) -> np.ndarray:
        """Outward unit normals (rows) of the owned facets of T_H with the facet tags ``tags``."""
        msh = self.mesh
        tdim, gdim = msh.topology.dim, msh.geometry.dim
        fdim = tdim - 1
        msh.topology.create_connectivity(fdim, tdim)
        num = msh.topology.index_map(fdim).size_local
        facets = np.unique(np.concatenate([self.facet_tags.find(t) for t in tags]))
        facets = facets[facets < num].astype(np.int32)
        if facets.size == 0:
            return np.zeros((0, gdim))
        x = msh.geometry.x[:, :gdim]
        fx = x[dmesh.entities_to_geometry(msh, fdim, facets)]
        if tdim == 2:
            t = fx[:, 1] - fx[:, 0]
            n = np.stack([t[:, 1], -t[:, 0]], axis=1)
        else:
            n = np.cross(fx[:, 1] - fx[:, 0], fx[:, 2] - fx[:, 0])
        f_to_c = msh.topology.connectivity(fdim, tdim)
        cells = np.array([f_to_c.links(f)[0] for f in facets], dtype=np.int32)
        centroids = x[dmesh.entities_to_geometry(msh, tdim, cells)].mean(axis=1)
        sign = np.sign(np.sum(n * (fx.mean(axis=1) - centroids), axis=1))
        n *= sign[:, None]
        return n / np.linalg.norm(n, axis=1)[:, None]

    def _check_projection(self, projection: Any) -> dict[int, Callable[..., Any]]:
        if projection is None:
            return {}
        if not isinstance(projection, Mapping):
            raise TypeError(
                "boundary_projection must be a dict {facet tag: callable (3, n) array -> "
                f"points}}, got {type(projection).__name__}"
            )
        for tag, f in projection.items():
            if not _is_tag(tag):
                raise TypeError(f"boundary_projection keys must be facet tags, got {tag!r}")
            if not callable(f):
                raise TypeError(f"boundary_projection[{tag}] must be callable, got {f!r}")
        return {int(k): v for k, v in projection.items()}

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
            expr = self.call_user(name, value, ufl.SpatialCoordinate(self.mesh))
            expr = ufl.as_vector(expr) if isinstance(expr, (list, tuple)) else ufl.as_ufl(expr)
        except Exception as err:
            raise TypeError(
                f"{name} must be a callable x -> UFL {what} (x a ufl.SpatialCoordinate; use "
                f"ufl functions such as ufl.sin, not numpy), but calling it failed: {err}"
            ) from err
        if ufl.shape(expr) != shape:
            raise ValueError(f"{name} must return a UFL {what}, got shape {ufl.shape(expr)}")

    def call_user(self, where: str, function: Callable[..., Any], *args: Any) -> Any:
        """``function(*args)``, the user's, evaluated collectively on the mesh's communicator.

        An exception on any rank raises a :class:`~dwr_signorini.collective.CollectiveError`
        naming ``where`` on every rank (:func:`~dwr_signorini.collective.call_collectively`).
        """
        return call_collectively(self.mesh.comm, where, function, *args)

    def _check_tags(self) -> None:
        """Every tag used marks a boundary facet somewhere, contact tags no common facet."""
        msh, tags = self.mesh, self.facet_tags
        fdim = msh.topology.dim - 1
        msh.topology.create_connectivity(fdim, fdim + 1)
        boundary = dmesh.exterior_facet_indices(msh.topology)
        comm = shadow(msh.comm)
        for name, tag in (
            [("contact", t) for t in self.contact_tags]
            + [("dirichlet", t) for t in self.dirichlet]
            + [("traction", t) for t in self.traction]
            + [("boundary_projection", t) for t in self.boundary_projection]
        ):
            facets = tags.find(tag)
            count = comm.allreduce(int(np.isin(facets, boundary).sum()), op=MPI.SUM)
            if count == 0:
                present = sorted(set(comm.allreduce(list(map(int, np.unique(tags.values))))))
                raise ValueError(
                    f"{name} tag {tag} marks no boundary facet of the mesh (tags present: "
                    f"{present}); pass the tag that facet_tags give that boundary"
                )
        if len(self.contact_tags) > 1:
            facets = np.concatenate([np.unique(tags.find(t)) for t in self.contact_tags])
            shared = comm.allreduce(int(len(facets) - len(np.unique(facets))), op=MPI.SUM)
            if shared:
                raise ValueError(
                    f"contact tags {self.contact_tags} overlap: {shared} facets carry two of "
                    "them; each contact facet must belong to one contact tag"
                )

    # -- data on other meshes (refinements) ---------------------------------------------------
