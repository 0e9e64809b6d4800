"""The sparse Jacobi approximation N diag(K)^-1 N^T of the Schur complement N K^-1 N^T.

Both Krylov paths precondition with it: the CG on S_AA of ``method="schur"`` with a Krylov
solver of K (:class:`~dwr_signorini.linalg.schur.KrylovSchurComplement`) and the GMRES on the
saddle-point system of ``method="krylov"`` (:mod:`~dwr_signorini.linalg.krylov`). It is
computed once per mesh and factored for each active set with the inactive rows and columns the
identity; null pivots there mean dependent active constraints (:func:`check_independent`).
"""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np

from ..algebra import ContactAlgebra
from .mumps import null_pivots

__all__ = ["DEPENDENT", "check_independent", "factor_on_active", "jacobi_schur_approximation"]

#: What a singular Schur complement on the active rows means.
DEPENDENT = "active contact constraints are linearly dependent"


def jacobi_schur_approximation(algebra: ContactAlgebra) -> PETSc.Mat:
    """N diag(K)^-1 N^T, the sparse approximation of the Schur complement N K^-1 N^T.

    Args:
        algebra: The pieces of the mesh.

    Returns:
        A new sparse matrix on the multiplier rows (the caller destroys it).
    """
    inv_diag = algebra.K.getDiagonal()
    inv_diag.reciprocal()
    scaled = algebra.NT.copy()
    scaled.diagonalScale(L=inv_diag)
    try:
        return algebra.N.matMult(scaled)
    finally:
        inv_diag.destroy()
        scaled.destroy()


def factor_on_active(
    ksp: PETSc.KSP,
    S_hat: PETSc.Mat,
    active: np.ndarray,
    old: PETSc.Mat | None,
    operator: PETSc.Mat | None = None,
) -> PETSc.Mat:
    """``S_hat`` with the inactive rows and columns the identity, factored by ``ksp``'s PC.

    Args:
        ksp: The solver whose preconditioner factors the matrix (e.g. MUMPS's LDL^T).
        S_hat: The sparse Schur approximation (:func:`jacobi_schur_approximation`).
        active: The active rows (owned).
        old: The matrix of the last active set, destroyed here (None: none).
        operator: The operator of ``ksp`` (None: the new matrix itself).

    Returns:
        The new matrix (the caller keeps it while ``ksp`` uses it). Check
        :func:`check_independent` of ``ksp`` for dependent rows.
    """
    if old is not None:
        old.destroy()
    P = S_hat.copy()
    lo = S_hat.getOwnershipRange()[0]
    P.zeroRowsColumns((lo + np.flatnonzero(~active)).astype(PETSc.IntType), diag=1.0)
    ksp.setOperators(P if operator is None else operator, P)
    ksp.setUp()
    return P


def check_independent(ksp: PETSc.KSP) -> None:
    """LinAlgError if the factors of :func:`factor_on_active` by ``ksp`` have null pivots.

    (N diag(K)^-1 N^T)_AA has the rank of S_AA (both are N_A B N_A^T with B symmetric positive
    definite on the free dofs): null pivots mean dependent active constraints, for which a
    Krylov solve would return one of many multipliers.

    Raises:
        numpy.linalg.LinAlgError: MUMPS found null pivots.
    """
    if null_pivots(ksp) > 0:
        raise np.linalg.LinAlgError(
            f"N diag(K)^-1 N^T, and so N K^-1 N^T, is singular on the active rows: {DEPENDENT}"
        )
