"""Validation of the data of a problem: each error names its argument.

Pure functions: each ``check_*`` takes what it checks and the context it needs (the macro mesh
T_H, the contact tags, ...) and returns the cleaned value, or raises a ValueError or TypeError
naming the argument. :class:`~dwr_signorini.problem.SignoriniProblem` calls them in its
constructor; the checks of the mesh and its tags are in :mod:`dwr_signorini.mesh_validation`,
except those of contact pairs, which are here with the pairs' other checks (the end of the module).
:func:`call_user` calls a user's callable collectively.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from ufl.domain import extract_unique_domain

from . import compat
from .collective import call_collectively, shadow
from .mesh_validation import check_cells_covered, check_plane_faces_body
from .obstacles import Graph, Obstacle, Plane
from .pairs import ContactPair

__all__ = [
    "MODELS",
    "DirichletData",
    "DirichletValue",
    "GapData",
    "MaterialData",
    "VectorData",
    "call_user",
    "check_callable",
    "check_contact",
    "check_contact_pairs",
    "check_dirichlet",
    "check_gap",
    "check_loads",
    "check_material",
    "check_model",
    "check_pair_bodies",
    "check_pair_gap",
    "check_projection",
    "check_quadrature_degree",
    "check_vector",
]

#: The elastic models: plane strain or plane stress in 2D, 3D elasticity in 3D.
MODELS = ("plane_strain", "plane_stress", "3d")

VectorData = Sequence[float] | Callable[[ufl.SpatialCoordinate], Any] | None
#: A Dirichlet condition as given: a number, a tuple with None = free, or x -> UFL vector.
DirichletData = float | Sequence[float | None] | Callable[[ufl.SpatialCoordinate], Any]
#: A Dirichlet condition as stored: a tuple of gdim (float | None), or x -> UFL vector.
DirichletValue = tuple[float | None, ...] | Callable[[ufl.SpatialCoordinate], Any]
#: E or nu: a number, x -> UFL scalar, or {cell tag: number}.
MaterialData = float | Callable[[ufl.SpatialCoordinate], Any] | Mapping[int, float]
#: A gap: a number, x -> UFL scalar, or an obstacle.
GapData = float | Callable[[ufl.SpatialCoordinate], Any] | Obstacle


def is_real(value: Any) -> bool:
    """Whether ``value`` is a real number (not a bool)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def nonzero_literal(expr: ufl.core.expr.Expr, x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """``expr``, or a Constant with its value if UFL would simplify it away (a literal zero)."""
    if isinstance(expr, ufl.constantvalue.ConstantValue) or (
        isinstance(expr, ufl.classes.ListTensor)
        and all(isinstance(c, ufl.constantvalue.ConstantValue) for c in expr.ufl_operands)
    ):
        shape = ufl.shape(expr)
        data = [float(expr[i]) for i in range(shape[0])] if shape else float(expr)
        return fem.Constant(extract_unique_domain(x), np.asarray(data, dtype=float))
    return expr


def is_tag(value: Any) -> bool:
    """Whether ``value`` is an integer tag (not a bool)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _tags(value: Any, name: str) -> tuple[int, ...]:
    """A tag or an iterable of tags as a tuple of ints (TypeError naming ``name``)."""
    if is_tag(value):
        return (int(value),)
    try:
        tags = tuple(value)
    except TypeError:
        tags = (value,)
    if any(not is_tag(t) for t in tags):
        raise TypeError(f"{name} must be an integer facet tag or a sequence of them, got {value!r}")
    return tuple(int(t) for t in tags)


def _macro_cell_measure(msh: dmesh.Mesh) -> tuple[Any, ufl.Measure]:
    """A quadrature space of degree DATA_QUADRATURE_DEGREE on ``msh`` (for checks of data)."""
    import basix.ufl

    from .quadrature import DATA_QUADRATURE_DEGREE

    element = basix.ufl.quadrature_element(msh.basix_cell(), degree=DATA_QUADRATURE_DEGREE)
    return fem.functionspace(msh, element), DATA_QUADRATURE_DEGREE


def check_dirichlet(
    dirichlet: Any, mesh: dmesh.Mesh, contact_tags: tuple[int, ...]
) -> dict[int, DirichletValue]:
    """``{tag: tuple of gdim (float | None) | callable}`` from the argument ``dirichlet``.

    Args:
        dirichlet: The argument as given.
        mesh: The macro mesh T_H.
        contact_tags: The contact tags (a face is either prescribed or in possible contact).

    Returns:
        The conditions, in the order given.
    """
    gdim = mesh.geometry.dim
    if isinstance(dirichlet, Mapping):
        items = list(dirichlet.items())
        for tag, _ in items:
            if not is_tag(tag):
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
        if tag in contact_tags:
            raise ValueError(
                f"tag {tag} is used both as contact and as dirichlet boundary; "
                "a facet is either prescribed or in possible contact"
            )
        if callable(value):
            check_callable(value, name, (gdim,), mesh)
            out[tag] = value
            continue
        if is_real(value):
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
            if c is not None and not is_real(c):
                raise TypeError(f"{name}[{i}] must be a number or None, got {c!r}")
            if c is not None and not math.isfinite(c):
                raise ValueError(f"{name}[{i}] must be finite, got {c!r}")
        if all(c is None for c in value):
            raise ValueError(f"{name} prescribes no component (all None)")
        out[tag] = tuple(None if c is None else float(c) for c in value)
    return out


def check_material(
    value: Any, name: str, mesh: dmesh.Mesh, cell_tags: dmesh.MeshTags | None
) -> MaterialData:
    """A number, callable or ``{cell tag: number}`` for E or nu, with its range checked.

    Args:
        value: The argument as given.
        name: ``"E"`` or ``"nu"`` (or an entry of them, ``"E[7]"``), for errors.
        mesh: The macro mesh T_H (a callable is checked at its quadrature points).
        cell_tags: The checked cell tags of ``mesh`` (every cell must carry a tag of a dict).

    Returns:
        The float, the callable, or ``{int tag: float}``.
    """
    low, high = (0.0, math.inf) if name == "E" else (-1.0, 0.5)
    if isinstance(value, Mapping):
        values = {}
        for tag, v in value.items():
            if not is_tag(tag):
                raise TypeError(f"{name} keys must be integer cell tags, got {tag!r}")
            values[int(tag)] = check_material(v, f"{name}[{tag}]", mesh, cell_tags)
            if callable(values[int(tag)]):
                raise TypeError(f"{name}[{tag}] must be a number")
        check_cells_covered(values, name, mesh, cell_tags)
        return values
    if callable(value):
        check_callable(value, name, (), mesh)
        _check_range_at_quadrature(value, name, low, high, mesh)
        return value
    if not is_real(value):
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


def _check_range_at_quadrature(
    value: Callable[..., Any], name: str, low: float, high: float, mesh: dmesh.Mesh
) -> None:
    """``low < value(x) < high`` at the degree-8 quadrature points of the mesh (collective)."""
    expr = ufl.as_ufl(call_user(mesh, name, value, ufl.SpatialCoordinate(mesh)))
    if extract_unique_domain(expr) is None:  # a constant, e.g. 0.6 + 0 * x[0] = 0.6
        vals = np.array([float(expr)])
    else:
        space, _ = _macro_cell_measure(mesh)
        f = fem.Function(space)
        f.interpolate(fem.Expression(expr, compat.interpolation_points(space.element)))
        vals = f.x.array
    comm = shadow(mesh.comm)
    lo = comm.allreduce(float(np.min(vals, initial=np.inf)), op=MPI.MIN)
    hi = comm.allreduce(float(np.max(vals, initial=-np.inf)), op=MPI.MAX)
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= low or hi >= high:
        what = "> 0" if name == "E" else "in (-1, 0.5)"
        raise ValueError(
            f"{name}(x) must be {what} at every quadrature point of the mesh, but it "
            f"ranges over [{lo:.6g}, {hi:.6g}]"
        )


def check_gap(
    gap: Any, mesh: dmesh.Mesh, facet_tags: dmesh.MeshTags, contact_tags: tuple[int, ...]
) -> Any:
    """The gap g: a float, a callable, an obstacle, or ``{contact tag: any of these}``.

    Args:
        gap: The argument as given.
        mesh: The macro mesh T_H.
        facet_tags: Its facet tags (a plane must face a contact facet).
        contact_tags: The contact tags (the keys of a gap per tag).

    Returns:
        The gap with floats as floats and tags as ints.
    """
    if isinstance(gap, Mapping):
        keys = set(gap)
        if any(not is_tag(k) for k in keys):
            raise TypeError(f"gap keys must be integer contact tags, got {sorted(keys)}")
        missing = set(contact_tags) - keys
        if missing:
            raise ValueError(
                f"gap is given per contact tag but misses the contact tag(s) "
                f"{sorted(missing)}: give a gap for each of {contact_tags}"
            )
        extra = keys - set(contact_tags)
        if extra:
            raise ValueError(f"gap has tag(s) {sorted(extra)} that are not contact tags")
        return {
            int(k): _check_gap_value(v, f"gap[{k}]", mesh, facet_tags, contact_tags)
            for k, v in gap.items()
        }
    return _check_gap_value(gap, "gap", mesh, facet_tags, contact_tags)


def _check_gap_value(
    gap: Any, name: str, mesh: dmesh.Mesh, facet_tags: dmesh.MeshTags,
    contact_tags: tuple[int, ...],
) -> Any:
    gdim = mesh.geometry.dim
    if isinstance(gap, Obstacle):
        dim = gap.dim
        if dim is not None and dim != gdim:
            raise ValueError(
                f"{name}: a {dim}D obstacle ({gap!r}) on a {gdim}D mesh: give it "
                f"{gdim} coordinates"
            )
        if isinstance(gap, Plane):
            tag = name[len("gap["):-1] if name.startswith("gap[") else None
            tags = contact_tags if tag is None else (int(tag),)
            check_plane_faces_body(gap, name, mesh, facet_tags, tags)
        if isinstance(gap, Graph):
            if not -gdim <= gap.axis < gdim:
                raise ValueError(f"{name}: Graph axis {gap.axis} out of range for {gdim}D")
            check_callable(gap.psi, f"{name} (Graph psi)", (), mesh)
        return gap
    if callable(gap):
        check_callable(gap, name, (), mesh)
        return gap
    if is_real(gap):
        if not math.isfinite(gap):
            raise ValueError(f"{name} must be finite, got {gap!r}")
        return float(gap)
    raise TypeError(
        f"{name} must be a float, a callable x -> UFL scalar or an obstacle "
        f"(ds.obstacles.Plane, Sphere, Cylinder, Graph), got {gap!r}"
    )


def check_projection(projection: Any) -> dict[int, Callable[..., Any]]:
    """``boundary_projection``: ``{facet tag: callable}`` (empty for ``None``)."""
    if projection is None:
        return {}
    if not isinstance(projection, Mapping):
        raise TypeError(
            "boundary_projection must be a dict {facet tag: callable (3, n) array -> "
            f"points}}, got {type(projection).__name__}"
        )
    for tag, f in projection.items():
        if not is_tag(tag):
            raise TypeError(f"boundary_projection keys must be facet tags, got {tag!r}")
        if not callable(f):
            raise TypeError(f"boundary_projection[{tag}] must be callable, got {f!r}")
    return {int(k): v for k, v in projection.items()}


def check_vector(value: VectorData, name: str, mesh: dmesh.Mesh) -> VectorData:
    """A load: ``None``, ``gdim`` finite numbers (a tuple of floats), or x -> UFL vector."""
    gdim = mesh.geometry.dim
    if value is None:
        return value
    if callable(value):
        check_callable(value, name, (gdim,), mesh)
        return value
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise TypeError(
            f"{name} must be a sequence of floats or a callable, got {value!r}"
        ) from err
    if arr.shape != (gdim,):
        raise ValueError(f"{name} must have {gdim} components, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return tuple(float(a) for a in arr)


def check_callable(
    value: Callable[..., Any], name: str, shape: tuple[int, ...], mesh: dmesh.Mesh
) -> None:
    """Call ``value`` with the SpatialCoordinate of ``mesh`` once: a UFL expression of ``shape``?

    Args:
        value: The user's callable.
        name: Its argument's name, for errors.
        shape: The shape it must return (``()`` a scalar, ``(gdim,)`` a vector).
        mesh: The mesh whose coordinate it is called with (collectively).
    """
    what = "scalar" if not shape else f"vector with {shape[0]} components"
    try:
        expr = call_user(mesh, name, value, ufl.SpatialCoordinate(mesh))
        expr = ufl.as_vector(expr) if isinstance(expr, (list, tuple)) else ufl.as_ufl(expr)
    except Exception as err:
        raise TypeError(
            f"{name} must be a callable x -> UFL {what} (x a ufl.SpatialCoordinate; use "
            f"ufl functions such as ufl.sin, not numpy), but calling it failed: {err}"
        ) from err
    if ufl.shape(expr) != shape:
        raise ValueError(f"{name} must return a UFL {what}, got shape {ufl.shape(expr)}")


def call_user(mesh: dmesh.Mesh, where: str, function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)``, the user's, evaluated collectively on the processes of ``mesh``.

    An exception on any rank raises a :class:`~dwr_signorini.collective.CollectiveError`
    naming ``where`` on every rank (:func:`~dwr_signorini.collective.call_collectively`).
    """
    return call_collectively(mesh.comm, where, function, *args)


def check_model(model: Any, tdim: int) -> str:
    """The elastic model on a mesh of dimension ``tdim`` (``None``: plane strain or 3D)."""
    if model is None:
        model = "plane_strain" if tdim == 2 else "3d"
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    if (model == "3d") != (tdim == 3):
        raise ValueError(
            f"model={model!r} does not fit a {tdim}D mesh: use "
            + ("'plane_strain' or 'plane_stress'" if tdim == 2 else "'3d'")
        )
    return model


def check_quadrature_degree(degree: Any) -> int:
    """``quadrature_degree``: an integer in [0, 30]."""
    if isinstance(degree, bool) or not isinstance(degree, int):
        raise TypeError(f"quadrature_degree must be an integer, got {type(degree).__name__}")
    if not 0 <= degree <= 30:
        raise ValueError(f"quadrature_degree must be in [0, 30], got {degree}")
    return int(degree)


def check_contact(contact: Any) -> tuple[int, ...]:
    """The contact tags: one tag or several distinct ones."""
    contact_tags = _tags(contact, "contact")
    if not contact_tags:
        raise ValueError("contact must name at least one facet tag")
    if len(set(contact_tags)) != len(contact_tags):
        raise ValueError(f"contact names a tag twice: {contact_tags}")
    return contact_tags


def check_loads(
    body_force: Any,
    traction: Any,
    mesh: dmesh.Mesh,
    contact_tags: tuple[int, ...],
    dirichlet: Mapping[int, DirichletValue],
) -> tuple[VectorData, dict[int, VectorData]]:
    """The body force and the tractions ``{facet tag: load}`` (none on a contact face).

    Args:
        body_force: The argument as given.
        traction: The argument as given.
        mesh: The macro mesh T_H.
        contact_tags: The contact tags.
        dirichlet: The checked Dirichlet conditions (a traction acts on their free components).

    Returns:
        The body force and the tractions, checked as :func:`check_vector`.
    """
    if traction is not None and not isinstance(traction, Mapping):
        raise TypeError(
            "traction must be a dict {facet tag: load}, e.g. {2: (0.0, -1.0)}, got "
            f"{type(traction).__name__}"
        )
    traction = dict(traction or {})
    for tag in traction:
        if not is_tag(tag):
            raise TypeError(f"traction keys must be integer facet tags, got {tag!r}")
        if tag in contact_tags:
            raise ValueError(
                f"traction tag {tag} is also a contact tag; tractions act on Gamma_N (and on "
                "the free components of a dirichlet face), the contact force is the unknown "
                "lambda"
            )
    body_force = check_vector(body_force, "body_force", mesh)
    loads = {int(k): check_vector(v, f"traction[{k}]", mesh) for k, v in traction.items()}
    for tag, load in loads.items():
        if tag in dirichlet:
            _check_traction_on_dirichlet(tag, load, dirichlet[tag])
    return body_force, loads


def _check_traction_on_dirichlet(tag: int, load: Any, value: DirichletValue) -> None:
    """A traction on a dirichlet face acts on its free components only.

    ``dirichlet={4: (d, None)}, traction={4: (0.0, -p)}`` shears the face with a
    displacement and presses it with a force; a nonzero traction on a prescribed
    component would be lost silently (its equations are replaced by the prescribed value).
    """
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


# -- contact pairs ---------------------------------------------------------------------------
def check_contact_pairs(contact: Any) -> tuple[list[Any], tuple[ContactPair, ...]]:
    """``contact`` split into its tags (pairs by their slave tag) and its pairs.

    Args:
        contact: A tag, a :class:`ContactPair`, or a sequence of them.

    Returns:
        The contact entries with each pair replaced by its slave tag (in the order given), and
        the pairs.

    Raises:
        ValueError: A master tag that is also a contact tag or a slave tag of another pair.
    """
    entries = [contact] if isinstance(contact, ContactPair) else contact
    if isinstance(entries, (str, bytes)) or not isinstance(entries, Iterable):
        return contact, ()
    entries = list(entries)
    pairs = tuple(e for e in entries if isinstance(e, ContactPair))
    tags = [e.slave if isinstance(e, ContactPair) else e for e in entries]
    slaves = {p.slave for p in pairs}
    for p in pairs:
        if p.master in tags or p.master in slaves:
            raise ValueError(
                f"ContactPair(slave={p.slave}, master={p.master}): the master tag {p.master} "
                "is also a contact (slave) tag; a facet is on one side of the contact only"
            )
    return tags, pairs


def check_pair_gap(gap: Any, pairs: tuple[ContactPair, ...], rigid_tags: tuple[int, ...]) -> Any:
    """The ``gap`` of a problem with pairs: it is the rigid contact tags' gap only.

    Raises:
        ValueError: A gap given for a pair's slave tag, or a gap other than the default 0
            without rigid contact tags.
    """
    slaves = sorted(p.slave for p in pairs)
    if isinstance(gap, Mapping):
        named = sorted(set(gap) & set(slaves))
        if named:
            raise ValueError(
                f"gap is given for the ContactPair slave tag(s) {named}: the gap of a pair is "
                "the distance to the master surface along the slave normal, measured from the "
                "meshes; give gap for the rigid-obstacle contact tags only"
            )
        return gap
    if not rigid_tags:
        if isinstance(gap, (int, float)) and not isinstance(gap, bool) and gap == 0.0:
            return gap
        raise ValueError(
            "gap applies to rigid-obstacle contact tags, and every contact tag here is the "
            f"slave side of a ContactPair ({slaves}): the gap of a pair is measured from the "
            "meshes; leave gap at its default"
        )
    return gap


def check_pair_bodies(
    mesh: dmesh.Mesh, facet_tags: dmesh.MeshTags, pairs: tuple[ContactPair, ...]
) -> None:
    """The slave and master facets of each pair share no vertex (two bodies, collective).

    Counted on the vertices' owners (a vertex of the slave facets on one rank and of the master
    facets on another counts), so the answer does not depend on the partition.

    Raises:
        ValueError: A pair whose sides touch in the mesh (one body, or glued bodies).
    """
    if not pairs:
        return
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, 0)
    f2v = mesh.topology.connectivity(fdim, 0)
    vertices = mesh.topology.index_map(0)

    def marks(tag: int) -> np.ndarray:
        """1 on the owned vertices of the facets of ``tag`` on any rank, else 0."""
        vec = la.vector(vertices, 1)
        facets = facet_tags.find(tag)
        if len(facets):
            vec.array[np.unique(np.concatenate([f2v.links(f) for f in facets]))] = 1.0
        vec.scatter_reverse(la.InsertMode.add)
        return vec.array[: vertices.size_local] > 0.0

    for p in pairs:
        shared = int(np.count_nonzero(marks(p.slave) & marks(p.master)))
        shared = mesh.comm.allreduce(shared, op=MPI.SUM)
        if shared:
            raise ValueError(
                f"ContactPair(slave={p.slave}, master={p.master}): {shared} vertices lie on "
                "both sides; the two sides must belong to two bodies that share no vertex "
                "(mesh them as separate volumes, e.g. gmsh surfaces without a common curve)"
            )
