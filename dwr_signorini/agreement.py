"""Input that must be the same on every rank, compared across ranks once, collectively.

Under MPI every rank passes its own copy of the problem data and loop settings. Data that differ
between ranks (a different ``E``, gap or goal per rank, a different contact tag, friction law or
``max_levels``) do not fail by themselves: the ranks assemble different forms into one matrix
(a mixed answer), or one rank's loop runs a collective the others never reach (a hang). Each
argument is therefore reduced to a *fingerprint* (a SHA-256 of a canonical text) and the
fingerprints are compared in one ``allgather``:

* numbers, strings, tags, ``None``, sequences, arrays and dicts: their canonical text (floats
  exactly, via ``repr``);
* objects of the package (obstacles, contact laws, contact pairs): their class and attributes;
* a callable of the spatial coordinate ``x -> UFL`` (``E``, ``nu``, ``gap``, loads, prescribed
  values, friction thresholds, a :class:`~dwr_signorini.obstacles.Graph`'s ``psi``): its values
  at a few points of the mesh's bounding box, the same points on every rank (UFL evaluates the
  expression there without the mesh); a callable of points (``boundary_projection``): the
  points it returns for those points. A callable that raises is not compared: the checks of the
  data raise its error afterwards, on every rank, naming the rank it came from. Nor is one whose
  expression holds a discrete function (a threshold ``mu * sol.lam``): its values need the mesh,
  and UFL's evaluation of such an expression at a point takes time exponential in its depth.

A mismatch raises the same :class:`ValueError` on every rank, naming each argument that differs
and how the ranks split, e.g.::

    SignoriniProblem: E differs between ranks (rank 0 | rank 1): every rank must pass the same
    data

A goal is compared through its form's signature (:func:`check_form_on_ranks`): UFL's signature
renumbers meshes and coefficients, so it is the same on every rank for the same goal.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections.abc import Callable, Mapping
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from ufl.algorithms import extract_coefficients

from .collective import shadow

__all__ = [
    "check_form_on_ranks",
    "check_options_on_ranks",
    "check_same_on_ranks",
    "fingerprint",
    "probe_points",
]

#: The text of a callable that raised: not compared (the checks of the data raise its error on
#: every rank, naming the rank it was raised on, :mod:`dwr_signorini.collective`).
RAISED = "callable raising"

#: Where in the bounding box (fractions of its sides) callables are evaluated: the centre and
#: points off every symmetry plane of the box.
_FRACTIONS = np.array(
    [
        [0.5, 0.5, 0.5],
        [0.13, 0.71, 0.37],
        [0.83, 0.29, 0.61],
        [0.41, 0.97, 0.07],
        [0.02, 0.05, 0.93],
    ]
)


def probe_points(mesh: Any) -> np.ndarray:
    """A few points of the bounding box of ``mesh``, the same on every rank (collective).

    Args:
        mesh: A dolfinx mesh.

    Returns:
        An array of shape (k, gdim).
    """
    gdim = mesh.geometry.dim
    x = mesh.geometry.x[:, :gdim]
    lo, hi = np.min(x, axis=0, initial=np.inf), np.max(x, axis=0, initial=-np.inf)
    mesh.comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    mesh.comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    return lo + _FRACTIONS[:, :gdim] * (hi - lo)


def _number(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else str(value)


def _ufl_values(function: Callable[..., Any], x: Any, points: np.ndarray) -> str:
    """The values of the UFL expression ``function(x)`` at ``points``, as text."""
    expr = function(x)
    expr = ufl.as_vector(expr) if isinstance(expr, (list, tuple)) else ufl.as_ufl(expr)
    if extract_coefficients(expr):  # a discrete function's values need its mesh: not compared
        return "of discrete functions"
    shape = ufl.shape(expr)
    components = [expr] if not shape else [expr[i] for i in range(shape[0])]
    return repr(
        [[_number(c(tuple(float(p) for p in point))) for c in components] for point in points]
    )


def _point_values(function: Callable[..., Any], points: np.ndarray) -> str:
    """The values of ``function`` on the (3, k) array of ``points`` (a boundary projection)."""
    padded = np.zeros((3, points.shape[0]))
    padded[: points.shape[1]] = points.T
    return repr([_number(v) for v in np.asarray(function(padded), dtype=float).ravel()])


def _callable_text(function: Callable[..., Any], x: Any, points: np.ndarray, numeric: bool) -> str:
    try:
        values = _point_values(function, points) if numeric else _ufl_values(function, x, points)
    except Exception as err:  # the data checks raise the cause on every rank
        return f"{RAISED} {type(err).__name__}"
    return f"callable {values}"


def _text(value: Any, x: Any, points: np.ndarray, numeric: bool = False, depth: int = 0) -> str:
    """The canonical text of ``value`` (module docstring); nested at most 8 deep."""
    if depth > 8:
        return type(value).__name__
    depth += 1
    if value is None or isinstance(value, (bool, str)):
        return repr(value)
    if isinstance(value, (int, np.integer)):
        return repr(int(value))
    if isinstance(value, (float, np.floating)):
        return _number(value)
    if isinstance(value, np.ndarray):
        return repr([_number(v) for v in value.astype(float).ravel()]) + repr(value.shape)
    if isinstance(value, Mapping):
        items = [  # in the order given: dirichlet's later tag wins
            (_text(k, x, points, False, depth), _text(v, x, points, numeric, depth))
            for k, v in value.items()
        ]
        return "{" + ", ".join(f"{k}: {v}" for k, v in items) + "}"
    if isinstance(value, (list, tuple)):
        return "(" + ", ".join(_text(v, x, points, numeric, depth) for v in value) + ")"
    module = type(value).__module__ or ""
    if module.startswith(__package__ or "dwr_signorini") and hasattr(value, "__dict__"):
        attributes = {k: v for k, v in vars(value).items() if not k.startswith("_")}
        return f"{type(value).__name__}{_text(attributes, x, points, False, depth)}"
    if callable(value):
        return _callable_text(value, x, points, numeric)
    return type(value).__name__  # an object without canonical text: its type only


def fingerprint(value: Any, x: Any, points: np.ndarray, numeric: bool = False) -> str:
    """A SHA-256 of the canonical text of ``value`` (local; module docstring).

    Args:
        value: The argument as the user gave it.
        x: The spatial coordinate (``ufl.SpatialCoordinate``) callables of x are called with.
        points: Where callables are evaluated, shape (k, gdim), the same on every rank.
        numeric: Callables take arrays of points (shape (3, n)) instead of ``x``.

    Returns:
        The hex digest, or :data:`RAISED` if a callable in ``value`` raised.
    """
    try:
        text = _text(value, x, points, numeric)
    except Exception:  # data the checks refuse (on every rank, with its cause): not compared
        return RAISED
    return RAISED if RAISED in text else hashlib.sha256(text.encode()).hexdigest()


def _split(hashes: list[str]) -> str:
    """How the ranks split by their fingerprints: ``"ranks 0, 2 | rank 1"``."""
    groups: dict[str, list[int]] = {}
    for rank, h in enumerate(hashes):
        groups.setdefault(h, []).append(rank)
    parts = [
        ("rank " if len(ranks) == 1 else "ranks ") + ", ".join(map(str, ranks))
        for ranks in groups.values()
    ]
    return " | ".join(parts)


def _compare(comm: MPI.Comm, where: str, digests: dict[str, str]) -> None:
    """Raise on every rank if any of ``digests`` (argument -> fingerprint) differs (collective)."""
    if comm.size == 1:
        return
    gathered = shadow(comm).allgather(digests)
    if any(list(g) != list(gathered[0]) for g in gathered):
        split = _split([repr(list(g)) for g in gathered])
        raise ValueError(
            f"{where}: the arguments given differ between ranks ({split}): every rank must "
            "pass the same data"
        )
    names = list(gathered[0])
    differ = [
        f"{name} ({_split([g[name] for g in gathered])})"
        for name in names
        if len({g[name] for g in gathered}) > 1 and all(g[name] != RAISED for g in gathered)
    ]
    if differ:
        raise ValueError(
            f"{where}: {', '.join(differ)} "
            + ("differs" if len(differ) == 1 else "differ")
            + " between ranks: every rank must pass the same data"
        )


def check_same_on_ranks(
    mesh: Any,
    where: str,
    arguments: Mapping[str, Any],
    numeric: tuple[str, ...] = (),
) -> None:
    """Check that every rank of ``mesh.comm`` passed the same ``arguments`` (collective).

    One ``Allreduce`` pair for the probe points and one ``allgather`` of the fingerprints;
    nothing on one rank (serial runs return at once).

    Args:
        mesh: The mesh whose ranks must agree (its coordinate and bounding box evaluate
            callables).
        where: The function or class the arguments are of, for the message.
        arguments: ``{argument name: value as given}``.
        numeric: Names of arguments whose callables take arrays of points
            (``boundary_projection``) instead of the spatial coordinate.

    Raises:
        ValueError: On every rank, naming each argument that differs and the ranks.
    """
    if mesh.comm.size == 1:
        return
    points = probe_points(mesh)
    x = ufl.SpatialCoordinate(mesh)
    digests = {
        name: fingerprint(value, x, points, name in numeric) for name, value in arguments.items()
    }
    _compare(mesh.comm, where, digests)


def check_form_on_ranks(comm: MPI.Comm, where: str, name: str, form: ufl.Form) -> None:
    """Check that ``form`` (a goal's J) is the same on every rank, by its UFL signature.

    Collective (one ``allgather``). The signature holds the form's structure and literal
    numbers, not the values of its constants and coefficients.

    Args:
        comm: The communicator whose ranks must agree.
        where: The function the form is given to, for the message.
        name: The argument the form comes from (``"goal"``).
        form: The form.

    Raises:
        ValueError: On every rank, naming ``name`` and the ranks, if the forms differ.
    """
    if comm.size == 1:
        return
    try:
        signature = form.signature()
    except Exception as err:  # a form UFL cannot sign (on two meshes): the checks name it next
        signature = f"no signature: {type(err).__name__}"
    _compare(comm, where, {name: signature})


def check_options_on_ranks(mesh: Any, where: str, options: Any, **more: Any) -> None:
    """:func:`check_same_on_ranks` for the fields of an options dataclass (and ``more``).

    Collective.

    Args:
        mesh: The mesh whose ranks must agree.
        where: The function the options are of (``"solve"``, ``"estimate"``).
        options: A dataclass (:class:`~dwr_signorini.settings.SolverOptions`, ...): each field
            is compared as the argument of its name.
        more: Further arguments by name.

    Raises:
        ValueError: On every rank, naming each field or argument that differs and the ranks.
    """
    fields = {f.name: getattr(options, f.name) for f in dataclasses.fields(options)}
    check_same_on_ranks(mesh, where, {**fields, **more})
