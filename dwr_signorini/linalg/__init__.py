"""Linear algebra of the Newton steps and of the dual problem.

* :mod:`~dwr_signorini.linalg.options`: defaults, prefixes, options that live with a solver;
* :mod:`~dwr_signorini.linalg.mumps`: MUMPS diagnostics (INFOG, null pivots), inverse entries;
* :mod:`~dwr_signorini.linalg.nullspace`: rigid body modes for algebraic multigrid;
* :mod:`~dwr_signorini.linalg.base`: what every Newton system shares;
* :mod:`~dwr_signorini.linalg.block`: the block Newton matrix by LDL^T (``method="block"``);
* :mod:`~dwr_signorini.linalg.schur`: elimination of u, dense or Krylov S_AA (``method="schur"``).
"""

from .base import NewtonLinearSystem
from .block import LinearSolveError, NewtonSystem
from .mumps import mumps_failure, mumps_inverse_entries, null_pivots
from .options import (
    LOOSE_RTOL,
    SCHUR_KRYLOV_OPTIONS,
    OptionsScope,
    default_petsc_options,
    fieldsplit_petsc_options,
    iterative_petsc_options,
)
from .schur import (
    SCHUR_MAX_MULTIPLIERS,
    DenseSchurComplement,
    KrylovSchurComplement,
    SchurNewtonSystem,
)

#: Linear solvers of the Newton steps, the ``method`` of :func:`dwr_signorini.solve`.
METHODS = ("block", "schur")

#: The Newton system of each method.
SYSTEMS: dict[str, type[NewtonLinearSystem]] = {"block": NewtonSystem, "schur": SchurNewtonSystem}

__all__ = [
    "LOOSE_RTOL",
    "METHODS",
    "SCHUR_KRYLOV_OPTIONS",
    "SCHUR_MAX_MULTIPLIERS",
    "SYSTEMS",
    "DenseSchurComplement",
    "KrylovSchurComplement",
    "LinearSolveError",
    "NewtonLinearSystem",
    "NewtonSystem",
    "OptionsScope",
    "SchurNewtonSystem",
    "default_petsc_options",
    "fieldsplit_petsc_options",
    "iterative_petsc_options",
    "mumps_failure",
    "mumps_inverse_entries",
    "null_pivots",
]
