"""Linear algebra of the Newton steps and of the dual problem.

* :mod:`~dwr_signorini.linalg.options`: defaults, prefixes, options that live with a solver;
* :mod:`~dwr_signorini.linalg.mumps`: MUMPS diagnostics (INFOG, null pivots), inverse entries;
* :mod:`~dwr_signorini.linalg.nullspace`: rigid body modes for algebraic multigrid;
* :mod:`~dwr_signorini.linalg.base`: what every Newton system shares, its errors;
* :mod:`~dwr_signorini.linalg.factor`: a factored Newton matrix kept for later steps, when its
  reuse pays (:class:`~dwr_signorini.linalg.factor.ReusePolicy`);
* :mod:`~dwr_signorini.linalg.jacobi`: the sparse Jacobi approximation of the Schur complement;
* :mod:`~dwr_signorini.linalg.block`: the block Newton matrix by LDL^T (``method="block"``);
* :mod:`~dwr_signorini.linalg.schur`: elimination of u, dense or Krylov S_AA (``method="schur"``);
* :mod:`~dwr_signorini.linalg.krylov`: the step as one saddle-point system by GMRES with one
  multigrid cycle per iteration (``method="krylov"``);
* :mod:`~dwr_signorini.linalg.memory`: what a factorisation would take and what is available;
* :mod:`~dwr_signorini.linalg.coupled`: the nonsymmetric block matrix by LU (``method="block"``
  for a law with coupled rows: Tresca friction in 3D, Coulomb friction).
"""

from .base import LinearSolveError, NewtonLinearSystem
from .block import NewtonSystem
from .coupled import CoupledNewtonSystem
from .factor import ReusePolicy
from .krylov import KrylovNewtonSystem
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
METHODS = ("block", "schur", "krylov")

#: The Newton system of each method.
SYSTEMS: dict[str, type[NewtonLinearSystem]] = {
    "block": NewtonSystem,
    "schur": SchurNewtonSystem,
    "krylov": KrylovNewtonSystem,
}


def system_class(method: str, symmetric: bool = True) -> type[NewtonLinearSystem]:
    """The Newton system of ``method`` for a law whose Newton matrices are (not) symmetric.

    Raises:
        ValueError: ``method="schur"`` for a law with coupled rows (its elimination of u needs
            the symmetric S = N K^-1 N^T on constrained rows).
    """
    if symmetric:
        return SYSTEMS[method]
    if method in ("schur", "krylov"):
        raise ValueError(
            f"method={method!r} solves symmetric Newton matrices; the Newton matrix of Tresca "
            "friction in 3D and of Coulomb friction is not symmetric on slipping facets: use "
            "method='block' (LU)"
        )
    return CoupledNewtonSystem


#: The rule of :func:`choose_method`: the dense Schur path in 3D from this many DoFs ...
AUTO_SCHUR_MIN_DOFS = 100_000
#: ... with at most this many multipliers (S costs 8 n_lam^2 bytes and n_lam columns of K^-1).
AUTO_SCHUR_MAX_MULTIPLIERS = 1000
#: ... and in 2D, from a zero initial guess, from this many DoFs.
AUTO_SCHUR_COLD_MIN_DOFS = 20_000
#: In 3D (symmetric laws) the Krylov path from this many DoFs.
AUTO_KRYLOV_MIN_DOFS = 200_000


def choose_method(
    tdim: int, num_dofs: int, num_multipliers: int, *, cold_start: bool = False,
    symmetric: bool = True, fits: bool = True,
) -> str:
    """The linear solver of the Newton steps when the user gives neither method nor options.

    Args:
        tdim: The topological dimension of the mesh.
        num_dofs: The number of displacement DoFs (global).
        num_multipliers: The number of contact multipliers (global).
        cold_start: Whether the Newton method starts from zero (no initial guess).
        symmetric: Whether the law's Newton matrices are symmetric (else only ``"block"``
            serves, :func:`system_class`).
        fits: Whether a factorisation of K fits in memory.

    Returns:
        ``"schur"``, ``"block"`` or ``"krylov"``.

    ``"schur"`` (K factored once, S = N K^-1 N^T dense) for 3D problems of at least
    :data:`AUTO_SCHUR_MIN_DOFS` DoFs with at most :data:`AUTO_SCHUR_MAX_MULTIPLIERS`
    multipliers, ``"block"`` otherwise. Measured (docs, Performance): on a uniform 3D level of
    216k DoFs and 512 multipliers the Schur path took 0.64 of the block path's time on 1 rank
    and 0.61 on 2; on an adaptive 3D level with 1,510 multipliers computing S alone took
    42.9 s. In 2D a warm-started level takes 1 Newton step, one factorisation either way, and
    the block path, the reference, stays. A 2D solve from a zero initial guess
    (``cold_start``) of at least :data:`AUTO_SCHUR_COLD_MIN_DOFS` DoFs takes the Schur path:
    its first active set is that of the strictly negative gaps, so it takes 2 or more Newton
    steps, each a factorisation of the block matrix when many facets change, where the Schur
    path factors K once (example 5.1 from zero, 49k-786k triangles: 2 steps, the Schur path
    0.1-0.4 of a level's time faster, ``benchmarks/peers.py``).

    A 3D problem with a symmetric law takes ``"krylov"`` (:mod:`~dwr_signorini.linalg.krylov`,
    memory linear in the mesh) from :data:`AUTO_KRYLOV_MIN_DOFS` DoFs on, and wherever a
    factorisation would not fit in memory (``fits=False``,
    :func:`~dwr_signorini.linalg.memory.factorization_fits`). Measured (``bench_levels.py
    --weights patch``, 1 rank, uniform levels): example 5.3 at 29.5k DoFs 1.2 s factored against
    1.8 s by ``"krylov"``, at 216k DoFs 35.2 s against 16.9 s; the indentation at 56k DoFs 3.7 s
    against 2.4 s.
    """
    if not symmetric:
        return "block"
    if not fits or (tdim == 3 and num_dofs >= AUTO_KRYLOV_MIN_DOFS):
        return "krylov"
    few = num_multipliers <= AUTO_SCHUR_MAX_MULTIPLIERS
    if tdim == 3 and num_dofs >= AUTO_SCHUR_MIN_DOFS and few:
        return "schur"
    if tdim == 2 and cold_start and num_dofs >= AUTO_SCHUR_COLD_MIN_DOFS and few:
        return "schur"
    return "block"

__all__ = [
    "AUTO_KRYLOV_MIN_DOFS",
    "AUTO_SCHUR_COLD_MIN_DOFS",
    "AUTO_SCHUR_MAX_MULTIPLIERS",
    "AUTO_SCHUR_MIN_DOFS",
    "LOOSE_RTOL",
    "METHODS",
    "SCHUR_KRYLOV_OPTIONS",
    "SCHUR_MAX_MULTIPLIERS",
    "SYSTEMS",
    "CoupledNewtonSystem",
    "DenseSchurComplement",
    "KrylovNewtonSystem",
    "KrylovSchurComplement",
    "LinearSolveError",
    "NewtonLinearSystem",
    "NewtonSystem",
    "OptionsScope",
    "ReusePolicy",
    "SchurNewtonSystem",
    "choose_method",
    "default_petsc_options",
    "fieldsplit_petsc_options",
    "iterative_petsc_options",
    "mumps_failure",
    "mumps_inverse_entries",
    "null_pivots",
    "system_class",
]
