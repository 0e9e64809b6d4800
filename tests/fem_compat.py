"""The dolfinx 0.9 / 0.11 wrappers only the tests use (the package's are in dwr_signorini.compat).

As there, every wrapper detects the feature it needs, never a version string:

* ``fem.petsc.LinearProblem`` requires ``petsc_options_prefix`` (0.11): :func:`linear_problem`.
* ``fem.petsc.create_vector(L)`` takes function spaces (0.11), and the ``*_block`` / ``*_nest``
  assemblers are gone (0.11: ``assemble_matrix(forms, kind=...)``): :func:`create_vector`,
  :func:`assemble_matrix_block`.
* ``geometry.bb_tree(mesh, dim, entities)``: ``entities`` is keyword-only (0.11):
  :func:`bb_tree`; ``PointOwnershipData.dest_cells`` etc. are properties (0.11) instead of
  methods: :func:`ownership_field`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from dolfinx import fem
from dolfinx import mesh as dmesh

from dwr_signorini.compat import parameter_names

__all__ = [
    "assemble_matrix_block",
    "bb_tree",
    "create_vector",
    "linear_problem",
    "ownership_field",
]


def bb_tree(
    msh: dmesh.Mesh,
    dim: int,
    entities: npt.NDArray[np.int32] | None = None,
    padding: float = 0.0,
) -> Any:
    """``dolfinx.geometry.bb_tree(msh, dim, entities, padding)``.

    What differs: ``entities`` and ``padding`` are keyword-only in 0.11 (positional in 0.9); the
    names are the same, so they are passed by name.
    """
    from dolfinx import geometry

    return geometry.bb_tree(msh, dim, entities=entities, padding=padding)


def ownership_field(data: Any, name: str) -> np.ndarray:
    """A field of ``PointOwnershipData``, e.g. of ``fem.create_interpolation_data``.

    ``name`` is ``src_owner``, ``dest_owner``, ``dest_points`` or ``dest_cells``. What differs:
    methods in 0.9, properties in 0.11.
    """
    value = getattr(data, name)
    return value() if callable(value) else value



_prefix_counter = itertools.count()


def linear_problem(
    a: Any,
    L: Any,
    bcs: Sequence[Any] | None = None,
    petsc_options: Mapping[str, Any] | None = None,
    petsc_options_prefix: str | None = None,
    **kwargs: Any,
) -> Any:
    """``dolfinx.fem.petsc.LinearProblem`` on both versions.

    What differs: 0.11 requires the keyword ``petsc_options_prefix`` (and makes ``bcs`` keyword-
    only); 0.9 has no such parameter and sets the options under an internal prefix. Without a
    prefix, a unique one (``dwr_signorini_lp<n>_``) is used on 0.11 and it is ignored on 0.9.
    ``solve()`` returns the solution Function on both.
    """
    from dolfinx.fem import petsc as fem_petsc

    kwargs = dict(kwargs, bcs=list(bcs or []), petsc_options=dict(petsc_options or {}))
    if "petsc_options_prefix" in parameter_names(fem_petsc.LinearProblem):
        if petsc_options_prefix is None:
            petsc_options_prefix = f"dwr_signorini_lp{next(_prefix_counter)}_"
        kwargs["petsc_options_prefix"] = petsc_options_prefix
    return fem_petsc.LinearProblem(a, L, **kwargs)


def create_vector(L: fem.Form) -> Any:
    """A PETSc vector (ghosted) for the compiled linear form ``L``.

    What differs: ``fem.petsc.create_vector`` takes the form in 0.9 and its function space(s) in
    0.11.
    """
    from dolfinx.fem import petsc as fem_petsc

    if parameter_names(fem_petsc.create_vector)[:1] == ["V"]:
        return fem_petsc.create_vector(L.function_spaces[0])
    return fem_petsc.create_vector(L)


def assemble_matrix_block(a: Sequence[Sequence[fem.Form]], bcs: Sequence[Any] = ()) -> Any:
    """One monolithic PETSc matrix (AIJ) of a block of compiled bilinear forms, assembled.

    What differs: 0.9 has ``fem.petsc.assemble_matrix_block``; 0.11 removed the ``*_block`` and
    ``*_nest`` functions: ``assemble_matrix(a, bcs, kind=None)`` on a list of lists gives the
    monolithic matrix (``kind=PETSc.Mat.Type.NEST`` a nest).
    """
    from dolfinx.fem import petsc as fem_petsc

    if hasattr(fem_petsc, "assemble_matrix_block"):
        A = fem_petsc.assemble_matrix_block(a, bcs=list(bcs))
    else:
        A = fem_petsc.assemble_matrix(a, bcs=list(bcs))
    A.assemble()
    return A
