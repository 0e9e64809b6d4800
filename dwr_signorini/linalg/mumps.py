"""MUMPS through PETSc: why a factorisation failed, null pivots, selected entries of the inverse.

All functions are local (no communication): MUMPS's INFOG is the same on every rank.
"""

from __future__ import annotations

import functools
import logging
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

__all__ = [
    "inverse_entries_available",
    "mumps_factor",
    "mumps_failure",
    "mumps_inverse_entries",
    "null_pivots",
    "set_up",
]

logger = logging.getLogger(__name__)

#: MUMPS's error codes (INFOG(1)) of memory that could not be allocated, and of a workspace
#: that turned out too small (e.g. after delayed pivots), see the MUMPS user guide.
_MUMPS_NO_MEMORY = (-5, -7, -13)
_MUMPS_SMALL_WORKSPACE = (-8, -9, -11, -12, -14, -15, -17, -20)

#: The PETSc function behind :func:`mumps_inverse_entries` (not wrapped by petsc4py 3.22).
_INVERSE_FUNCTION = "MatMumpsGetInverseTranspose"


def mumps_factor(ksp: PETSc.KSP) -> PETSc.Mat | None:
    """The MUMPS factor of ``ksp``'s preconditioner.

    Returns:
        The factor matrix, or None if the preconditioner is no MUMPS factorisation.

    Raises:
        RuntimeError: The preconditioner is a MUMPS factorisation but its factor cannot be
            reached (not set up, or PETSc refused): the callers' checks would be blind.
    """
    pc = ksp.getPC()
    if pc.getType() not in ("lu", "cholesky") or pc.getFactorSolverType() != "mumps":
        return None
    try:
        return pc.getFactorMatrix()
    except PETSc.Error as err:
        raise RuntimeError(
            f"the MUMPS factor of the solver with prefix {ksp.getOptionsPrefix()!r} cannot be "
            "reached (is the solver set up?)"
        ) from err


def mumps_failure(ksp: PETSc.KSP) -> str | None:
    """Why MUMPS failed to factor the operator of ``ksp``, from its INFOG(1).

    Returns:
        The reason, or None if MUMPS did not fail (or is not the solver), or found the matrix
        singular (the callers say what a singular matrix means for them).
    """
    try:
        factor = mumps_factor(ksp)
    except RuntimeError:
        return None  # a failure elsewhere, e.g. in the set-up: the caller reports it
    if factor is None:
        return None
    code, detail = factor.getMumpsInfog(1), factor.getMumpsInfog(2)
    megabytes = factor.getMumpsInfog(17)
    if code >= 0:
        return None
    if code in _MUMPS_NO_MEMORY:
        need = f" (its estimate: {megabytes} MB over all ranks)" if megabytes > 0 else ""
        return (
            f"MUMPS could not allocate the memory of the factorisation{need}, INFOG(1) = {code}: "
            "the direct solver does not fit; for large 3D meshes use method='schur' with "
            "iterative_petsc_options()"
        )
    if code in _MUMPS_SMALL_WORKSPACE:
        return (
            f"MUMPS's workspace was too small (INFOG(1) = {code}, INFOG(2) = {detail}), e.g. "
            f"after delayed pivots, also with ICNTL(14) = {factor.getMumpsIcntl(14)} percent "
            "extra (set_up doubles it up to WORKSPACE_RETRIES times): raise it further with "
            "petsc_options {'mat_mumps_icntl_14': ...}"
        )
    if code == -19:
        return (
            "MUMPS needs more working memory than mat_mumps_icntl_23 allows (INFOG(1) = -19): "
            "raise or drop that option"
        )
    if code in (-6, -10):  # structurally or numerically singular
        return None
    meaning = _MUMPS_MEANINGS.get(code, "an error of MUMPS this package does not expect")
    return f"MUMPS failed with INFOG(1) = {code}, INFOG(2) = {detail}: {meaning}"


#: What the other error codes of MUMPS (INFOG(1), MUMPS 5 user guide, section "Error
#: diagnostics") mean for a Newton step; the rest is named as unexpected.
_MUMPS_MEANINGS = {
    -1: "an error on the rank INFOG(2) (see that rank's INFO(1))",
    -2: "the matrix has an invalid number of entries (an assembly error)",
    -3: "MUMPS was called in the wrong order (a factorisation was not set up before a solve)",
    -16: "the matrix has an invalid size (empty system?)",
    -22: "an array handed to MUMPS is missing (an internal error of the solver's set-up)",
    -44: "the factors needed for the solve are not available",
    -45: "a solve was asked with no right-hand side (NRHS <= 0: an internal error)",
    -51: "an integer overflow in MUMPS's 32-bit indices: the factors are too large",
}


#: Most factorisations :func:`set_up` tries when MUMPS's workspace was too small.
WORKSPACE_RETRIES = 3


def set_up(ksp: PETSc.KSP, A: PETSc.Mat) -> None:
    """``ksp.setOperators(A)`` and ``ksp.setUp()``, with more workspace where MUMPS ran short.

    MUMPS sizes its workspace at the analysis, and pivoting in the numerical factorisation can
    need more than that estimate (INFOG(1) = -8, -9, ...: delayed pivots, as on locally bisected
    3D meshes). Then the factorisation is repeated from the analysis with ICNTL(14), the
    percentage of extra workspace, doubled (at least 100), up to :data:`WORKSPACE_RETRIES`
    times, each with a logged warning. The raised value is put in the options database under
    the solver's prefix for that set-up only (options win over values set on the factor), and
    the previous value is restored after it. Any other failure is left to the caller's checks
    (:func:`mumps_failure`).
    """
    ksp.setOperators(A)
    ksp.setUp()
    for _ in range(WORKSPACE_RETRIES):
        try:
            factor = mumps_factor(ksp)
        except RuntimeError:
            return  # not set up: the caller's solve reports it
        if factor is None or factor.getMumpsInfog(1) not in _MUMPS_SMALL_WORKSPACE:
            return
        extra = max(100, 2 * factor.getMumpsIcntl(14))
        logger.warning(
            "MUMPS's workspace was too small (INFOG(1) = %d, solver prefix %r): factorising "
            "again with ICNTL(14) = %d", factor.getMumpsInfog(1), ksp.getOptionsPrefix(), extra,
        )
        db = PETSc.Options()
        name = (ksp.getOptionsPrefix() or "") + "mat_mumps_icntl_14"
        previous = db.getString(name) if db.hasName(name) else None
        db[name] = extra
        try:
            ksp.getPC().reset()
            ksp.setOperators(A)
            ksp.setUp()
        finally:
            if previous is None:
                db.delValue(name)
            else:
                db[name] = previous


def null_pivots(ksp: PETSc.KSP) -> int:
    """How many null pivots MUMPS found in the factorisation of ``ksp`` (INFOG(28)).

    Counted only with null pivot detection (``mat_mumps_icntl_24=1``, as in
    :func:`~dwr_signorini.linalg.options.default_petsc_options`), which replaces them and goes
    on: a positive count means a singular matrix. 0 for other solvers (they fail instead).

    Raises:
        RuntimeError: The factor of a MUMPS factorisation cannot be reached
            (:func:`mumps_factor`), so null pivots cannot be counted.
    """
    factor = mumps_factor(ksp)
    return 0 if factor is None else factor.getMumpsInfog(28)


@functools.cache
def _petsc_function(name: str) -> Any:
    """A PETSc C function of two object handles that petsc4py does not wrap, or None.

    Looked up in the library petsc4py is linked to; it returns a PetscErrorCode.
    """
    import ctypes

    try:
        function = getattr(ctypes.CDLL(PETSc.__file__), name)
    except (OSError, AttributeError):
        return None
    function.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    function.restype = ctypes.c_int
    return function


def inverse_entries_available() -> bool:
    """Whether :func:`mumps_inverse_entries` can be called (its PETSc symbol was found)."""
    return _petsc_function(_INVERSE_FUNCTION) is not None


def mumps_inverse_entries(
    ksp: PETSc.KSP, rows: np.ndarray, columns: np.ndarray
) -> np.ndarray | None:
    """The dense block (A^-1)[rows, columns] of the symmetric operator A factored by MUMPS.

    MUMPS computes selected entries of the inverse (ICNTL(30)) by solves with sparse right-hand
    sides, pruned to the parts of the factors they touch: much less work than full solves with
    the unit vectors. (PETSc's call returns entries of A^-T, hence "symmetric".)

    Args:
        ksp: A KSP whose preconditioner is a MUMPS factorisation of A.
        rows: Sorted global indices, the same on every rank.
        columns: Global indices, the same on every rank.

    Returns:
        The (len(rows), len(columns)) block on rank 0, None on the other ranks.

    Raises:
        ValueError: ``ksp`` is no MUMPS factorisation.
        RuntimeError: The PETSc function is missing (:func:`inverse_entries_available`), or
            MUMPS failed.
    """
    factor = mumps_factor(ksp)
    if factor is None:
        raise ValueError("mumps_inverse_entries needs a MUMPS factorisation")
    function = _petsc_function(_INVERSE_FUNCTION)
    if function is None:
        raise RuntimeError(f"PETSc's {_INVERSE_FUNCTION} was not found in {PETSc.__file__}")
    comm: MPI.Comm = ksp.getComm().tompi4py()
    n = ksp.getOperators()[0].getSize()[0]
    m = len(rows)
    # Row j of the request is column j of A^-1: MUMPS wants all n of them (the others empty),
    # the whole request on rank 0.
    local = n if comm.rank == 0 else 0
    counts = np.zeros(local, dtype=PETSc.IntType)
    if comm.rank == 0:
        counts[columns] = m
    request = PETSc.Mat().createAIJ(((local, n), (local, n)), nnz=(counts, 0), comm=comm)
    if comm.rank == 0:
        request.setValuesCSR(
            np.concatenate([[0], np.cumsum(counts)]).astype(PETSc.IntType),
            np.tile(rows, len(columns)).astype(PETSc.IntType),
            np.zeros(m * len(columns)),
        )
    request.assemble()
    # The call leaves ICNTL(30) on and the solution centralised (ICNTL(21) = 0): both are
    # restored for the solves that follow.
    distributed = factor.getMumpsIcntl(21)
    try:
        code = function(factor.handle, request.handle)
        if code != 0:
            raise RuntimeError(
                f"MUMPS could not compute entries of the inverse (PETSc error {code}, "
                f"INFOG(1) = {factor.getMumpsInfog(1)})"
            )
        # Rows of the request in increasing column index, each with the entries at ``rows``.
        order = np.argsort(np.argsort(columns))
        block = request.getValuesCSR()[2].reshape(-1, m)[order].T if comm.rank == 0 else None
    finally:
        factor.setMumpsIcntl(30, 0)
        factor.setMumpsIcntl(21, distributed)
        request.destroy()
    return block
