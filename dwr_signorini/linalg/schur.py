"""The Newton step by elimination of u (``method="schur"``): S = N K^-1 N^T on the active rows.

A Newton step K u + N^T lam = f, (N u)_A = g_A, lam_I = 0 is, after eliminating
u = K^-1 (f - N_A^T lam_A),

    S_AA lam_A = (N K^-1 f)_A - g_A,    u = K^-1 (f - N_A^T lam_A),    lam_I = 0,

with S = N K^-1 N^T symmetric positive definite on the active rows when Gamma_D clamps the body.
The solver of K (``petsc_options``) is set up once per mesh and decides how S_AA is solved:

* a direct solver (``ksp_type="preonly"``, ``pc_type`` ``"lu"`` or ``"cholesky"``; the default
  is MUMPS's LDL^T): :class:`DenseSchurComplement`, S computed once per mesh from the factors of
  K, a step costs a dense Cholesky factorisation of S_AA and one solve with the factors of K;
* a Krylov solver (e.g. :func:`~dwr_signorini.linalg.options.iterative_petsc_options`: CG with
  GAMG and the rigid body modes): :class:`KrylovSchurComplement`, CG on S_AA applied matrix-free
  (one K solve per iteration), preconditioned by the factored sparse N_A diag(K)^-1 N_A^T;
  nothing of the size of S is stored, so this is the path for large 3D meshes.

The transposed Newton matrix (the dual problem, K symmetric) reads, with eta_A = -xi_A,

    K y + N_A^T eta_A = j_u,    (N y)_A = j_lam,A,    xi_I = (j_lam,I - (N y)_I) / M_I,

the same saddle-point problem with other data: two solves with K and one with S_AA.

The Schur complements are built from the algebra and the solver of K they are given (by
composition): they hold no reference to the system that owns them.
"""

from __future__ import annotations

import logging
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.linalg
import scipy.sparse

from ..algebra import ContactAlgebra
from ..lifetime import destroy_attributes
from ..timing import timed
from .base import LinearSolveError, NewtonLinearSystem, owned_rows
from .jacobi import DEPENDENT, check_independent, factor_on_active, jacobi_schur_approximation
from .mumps import (
    inverse_entries_available,
    mumps_factor,
    mumps_failure,
    mumps_inverse_entries,
    null_pivots,
    set_up,
)
from .nullspace import rigid_body_modes
from .options import LOOSE_RTOL, SCHUR_KRYLOV_OPTIONS, OptionsScope

__all__ = [
    "SCHUR_MAX_MULTIPLIERS",
    "DenseSchurComplement",
    "KrylovSchurComplement",
    "SchurNewtonSystem",
]

logger = logging.getLogger(__name__)

#: Most multipliers (global) for ``method="schur"`` with a direct solver: its dense N K^-1 N^T
#: takes 8 n_lam^2 bytes on rank 0 (3.2 GB at this size), the Cholesky factor of S_AA as much.
SCHUR_MAX_MULTIPLIERS = 20000

#: Entries of one block of right-hand sides N^T[:, block] (dense, global) when computing S: bounds
#: the memory of the multi-RHS solves (MUMPS may gather dense right-hand sides on one rank).
SCHUR_BLOCK_ENTRIES = 2**24

#: A Cholesky pivot of S_AA below this times its diagonal entry means dependent active rows.
_PIVOT_RTOL = 1e-12


def solve_with(ksp: PETSc.KSP, b: PETSc.Vec, x: PETSc.Vec) -> None:
    """Solve with ``ksp`` (factors, or a set-up Krylov solver); LinearSolveError if it fails."""
    ksp.solve(b, x)
    reason = ksp.getConvergedReason()
    if reason < 0:
        raise LinearSolveError(f"the solve with K failed (KSP reason {reason})")


class DenseSchurComplement:
    """S = N K^-1 N^T dense on rank 0, from the factors of K; S_AA by dense Cholesky.

    S is computed once per mesh (8 n_lam^2 bytes on rank 0). N only touches the displacement
    dofs C on Gamma_C, so S = N_C (K^-1)_CC N_C^T: with MUMPS, the block (K^-1)_CC comes from
    MUMPS's entries of the inverse (:func:`~dwr_signorini.linalg.mumps.mumps_inverse_entries`);
    with another direct solver, or if PETSc's function for those entries is missing (then with a
    logged warning), from solves with blocks of columns of N^T as right-hand sides. Rank 0 runs
    the dense algebra and scatters the result, so that all ranks use the same numbers.

    Args:
        algebra: The pieces of the mesh (N, N^T, sizes).
        ksp: The set-up direct solver of K.
    """

    def __init__(self, algebra: ContactAlgebra, ksp: PETSc.KSP) -> None:
        self.algebra, self.ksp = algebra, ksp
        self.comm: MPI.Comm = algebra.comm
        self.n = self.comm.allreduce(algebra.n_lam, op=MPI.SUM)
        self._offsets = np.cumsum(self.comm.allgather(algebra.n_lam))[:-1]
        self._factor: tuple[np.ndarray, Any] | None = None
        self.S = self._compute()

    def _compute(self) -> np.ndarray | None:
        """S on rank 0 (None elsewhere): from entries of K^-1 with MUMPS, else by solves."""
        if mumps_factor(self.ksp) is None:
            return self.compute_by_solves()
        if not inverse_entries_available():
            logger.warning(
                "PETSc's MatMumpsGetInverseTranspose was not found: S = N K^-1 N^T is computed "
                "by multi-right-hand-side solves instead of MUMPS's entries of the inverse"
            )
            return self.compute_by_solves()
        return self.compute_from_inverse_entries()

    def compute_from_inverse_entries(self) -> np.ndarray | None:
        """S = N_C (K^-1)_CC N_C^T on rank 0 (None elsewhere), C the columns of N."""
        comm = self.comm
        owned = owned_rows(self.algebra.N)
        touched = np.unique(owned.indices[owned.data != 0])
        C = np.unique(np.concatenate(comm.allgather(touched))).astype(PETSc.IntType)
        rows = comm.gather(owned, root=0)
        N_C = scipy.sparse.vstack(rows).tocsc()[:, C] if comm.rank == 0 else None
        S = np.zeros((self.n, self.n)) if comm.rank == 0 else None
        # (K^-1)_CC a block of columns at a time: S += (N_C (K^-1)_{C,block}) N_C[:, block]^T.
        width = max(1, SCHUR_BLOCK_ENTRIES // max(1, len(C)))
        for start in range(0, len(C), width):
            block = mumps_inverse_entries(self.ksp, C, C[start : start + width])
            if comm.rank == 0:
                S += (N_C @ block) @ N_C[:, start : start + width].T.toarray()
        return None if S is None else 0.5 * (S + S.T)

    def compute_by_solves(self) -> np.ndarray | None:
        """S on rank 0 (None elsewhere), a block of columns at a time.

        The columns X = K^-1 N^T[:, block] come from one multi-RHS solve, and S[:, block] =
        (N^T)^T X is summed over the ranks' owned rows of N^T.
        """
        comm, n, alg = self.comm, self.n, self.algebra
        NT = owned_rows(alg.NT)
        width = max(1, min(n, SCHUR_BLOCK_ENTRIES // alg.K.getSize()[0]))
        S = np.empty((n, n)) if comm.rank == 0 else None
        B = X = None
        try:
            for start in range(0, n, width):
                stop = min(n, start + width)
                if B is None or B.getSize()[1] != stop - start:
                    for mat in (B, X):
                        if mat is not None:
                            mat.destroy()
                    B = PETSc.Mat().createDense(((alg.n_u, None), (None, stop - start)), comm=comm)
                    B.setUp()
                    X = B.duplicate()
                B.getDenseArray()[:] = NT[:, start:stop].toarray()
                B.assemble()
                self.ksp.matSolve(B, X)
                block = np.ascontiguousarray(NT.T @ X.getDenseArray())
                total = np.empty_like(block) if comm.rank == 0 else None
                comm.Reduce(block, total, op=MPI.SUM, root=0)
                if comm.rank == 0:
                    S[:, start:stop] = total
        finally:
            for mat in (B, X):
                if mat is not None:
                    mat.destroy()
        if comm.rank == 0:
            S = 0.5 * (S + S.T)  # symmetric up to the round-off of the solves
        return S

    def _gather(self, owned: np.ndarray) -> np.ndarray | None:
        """The global multiplier vector on rank 0 from every rank's owned rows."""
        parts = self.comm.gather(owned, root=0)
        return np.concatenate(parts) if parts is not None else None

    def set_active(self, active: np.ndarray) -> None:
        """Cholesky factor of S_AA on rank 0; LinAlgError on every rank if S_AA is singular."""
        mask = self._gather(active)
        error = None
        if self.comm.rank == 0:
            index = np.flatnonzero(mask)
            S_AA = self.S[np.ix_(index, index)]
            factor = None
            try:
                if index.size:
                    factor = scipy.linalg.cho_factor(S_AA)
                    # Pivots relative to the diagonal: a scale-invariant test for dependent rows.
                    if np.any(np.diag(factor[0]) ** 2 <= _PIVOT_RTOL * S_AA.diagonal()):
                        raise np.linalg.LinAlgError
            except np.linalg.LinAlgError:
                error = f"N K^-1 N^T is singular on the active rows: {DEPENDENT}"
            self._factor = (index, factor)
        error = self.comm.bcast(error, root=0)
        if error is not None:
            raise np.linalg.LinAlgError(error)

    def solve(self, r: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """The owned l with S_AA l_A = r_A, l_I = 0 (``guess`` is not needed)."""
        r_all = self._gather(r)
        parts = None
        if self.comm.rank == 0:
            index, factor = self._factor
            full = np.zeros(self.n)
            if index.size:
                full[index] = scipy.linalg.cho_solve(factor, r_all[index])
            parts = np.split(full, self._offsets)
        return self.comm.scatter(parts, root=0)

    def set_loose(self, loose: bool) -> bool:
        """Direct solves are exact: never loose."""
        return False

    def destroy(self) -> None:
        """Nothing of PETSc's to destroy (numpy only)."""
        self.S = self._factor = None


class _MaskedSchurOperator:
    """Context of the python matrix P_A N K^-1 N^T P_A + P_I on the multiplier rows."""

    def __init__(self, algebra: ContactAlgebra, ksp: PETSc.KSP) -> None:
        self.algebra, self.ksp = algebra, ksp
        self.mask = np.zeros(algebra.n_lam)
        self._lam = algebra.N.createVecLeft()
        self._w, self._v = algebra.K.createVecRight(), algebra.K.createVecRight()

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """The product y = P_A N K^-1 N^T P_A x + P_I x: one solve with K."""
        alg = self.algebra
        self._lam.array_w[:] = self.mask * x.array_r
        alg.NT.mult(self._lam, self._w)
        solve_with(self.ksp, self._w, self._v)
        alg.N.mult(self._v, y)
        y.array_w[:] = self.mask * y.array_r + (1.0 - self.mask) * x.array_r

    def destroy(self, mat: PETSc.Mat) -> None:
        """Destroy the work vectors with the python matrix."""
        for vec in (self._lam, self._w, self._v):
            vec.destroy()


class KrylovSchurComplement:
    """CG on S_AA = (N K^-1 N^T)_AA, matrix-free, preconditioned by (N diag(K)^-1 N^T)_AA.

    The operator is a PETSc python matrix on the multiplier rows: P_A S P_A + P_I with P_A, P_I
    the projections on the active and inactive rows, so that one CG solves S_AA l_A = r_A,
    l_I = r_I = 0 with the distributed layout of the multipliers. Each application costs one
    solve with K by the given Krylov solver. The preconditioner is the sparse
    N diag(K)^-1 N^T (computed once per mesh) with the inactive rows and columns replaced by the
    identity, factored by MUMPS's LDL^T for each active set; its options stay in the database
    for the life of this object, so every new factorisation reads them (null pivot detection,
    ICNTL(24), included). The CG's options have the prefix ``<prefix>schur_`` (pass e.g.
    ``schur_ksp_rtol`` in ``petsc_options``); defaults in
    :data:`~dwr_signorini.linalg.options.SCHUR_KRYLOV_OPTIONS`.

    Args:
        algebra: The pieces of the mesh.
        ksp: The set-up Krylov solver of K.
        prefix: The options prefix of the CG on S_AA.
    """

    def __init__(self, algebra: ContactAlgebra, ksp: PETSc.KSP, prefix: str) -> None:
        self._scope: OptionsScope | None = None
        try:  # on a failure (a rejected schur_ option), what exists is destroyed
            self._set_up(algebra, ksp, prefix)
        except BaseException:
            self.destroy()
            raise

    def _set_up(self, algebra: ContactAlgebra, ksp: PETSc.KSP, prefix: str) -> None:
        """The preconditioner's S_hat, the python matrix S, the CG and its options."""
        self.ksp_K = ksp
        comm = algebra.comm
        self.S_hat = jacobi_schur_approximation(algebra)
        self.P: PETSc.Mat | None = None
        n = algebra.n_lam
        self._operator = _MaskedSchurOperator(algebra, ksp)
        self.S = PETSc.Mat().createPython(((n, None), (n, None)), self._operator, comm=comm)
        self.S.setUp()
        self._y = self.S.createVecLeft()
        self._scope = OptionsScope(prefix, SCHUR_KRYLOV_OPTIONS)
        self.ksp = PETSc.KSP().create(comm)
        self._scope.apply(self.ksp)
        self.iterations = 0
        self._rtol = (ksp.getTolerances()[0], self.ksp.getTolerances()[0])

    def set_loose(self, loose: bool) -> bool:
        """Loose relative tolerances of the K solves and the CG on S_AA, or those of the options.

        Loose means at least :data:`~dwr_signorini.linalg.options.LOOSE_RTOL`.

        Returns:
            ``loose``.
        """
        solvers = (self.ksp_K, self.ksp)
        for ksp, tight, floor in zip(solvers, self._rtol, LOOSE_RTOL, strict=True):
            ksp.setTolerances(rtol=max(tight, floor) if loose else tight)
        return loose

    def set_active(self, active: np.ndarray) -> None:
        """Build and factor the preconditioner of S_AA for ``active`` (owned rows).

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots in (N diag(K)^-1 N^T)_AA, which
                has the rank of S_AA (both are N_A B N_A^T with B symmetric positive definite on
                the free dofs): dependent active constraints, for which CG would return one of
                many multipliers.
        """
        self._operator.mask = active.astype(float)
        self.P = factor_on_active(self.ksp, self.S_hat, active, self.P, operator=self.S)
        check_independent(self.ksp)

    def solve(self, r: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """The owned l with S_AA l_A = r_A, l_I = 0, by CG from ``guess`` (None: zero)."""
        mask = self._operator.mask
        self._y.array_w[:] = mask * r
        out = self.S.createVecRight()
        if guess is not None:
            out.array_w[:] = mask * guess
        self.ksp.setInitialGuessNonzero(guess is not None)
        try:
            self.ksp.solve(self._y, out)
            reason = self.ksp.getConvergedReason()
            self.iterations += self.ksp.getIterationNumber()
            if reason < 0:
                raise LinearSolveError(f"CG on S_AA did not converge (KSP reason {reason})")
            return out.array_r.copy()
        finally:
            out.destroy()

    def destroy(self) -> None:
        """Destroy the PETSc objects and remove the options (collective)."""
        destroy_attributes(self, ("ksp", "S", "P", "S_hat", "_y"))
        if self._scope is not None:
            self._scope.destroy()


class SchurNewtonSystem(NewtonLinearSystem):
    """The Newton steps by elimination of u: K set up once per mesh, S = N K^-1 N^T.

    Args:
        disc, petsc_options, V, kwargs: See
            :class:`~dwr_signorini.linalg.base.NewtonLinearSystem`; ``petsc_options`` are for
            K (a direct solver by default, or e.g.
            :func:`~dwr_signorini.linalg.options.iterative_petsc_options`).

    Attributes:
        schur: The :class:`DenseSchurComplement` or :class:`KrylovSchurComplement`.
        direct: Whether K is factored.

    Raises:
        ValueError: ``petsc_options`` give ``ksp_type="preonly"`` without a factorisation, or
            there are more than :data:`SCHUR_MAX_MULTIPLIERS` multipliers for the dense S.
        LinearSolveError: K could not be factored (the body is not held in place).
    """

    _petsc_objects = (
        "schur",  # first: its solves use the solver of K
        *NewtonLinearSystem._petsc_objects,
        "_u",
        "_u_f",
        "_rhs_u",
        "_lam_vec",
        "_near_nullspace",
    )

    @property
    def n_lam_global(self) -> int:
        """Global number of multiplier rows (every component of the contact law's)."""
        return self.N.getSize()[0]

    def _setup(self) -> None:
        """Check and set up the solver of K, compute K^-1 f and the Schur complement."""
        ksp_type, pc_type = self.ksp.getType(), self.ksp.getPC().getType()
        if ksp_type == "preonly" and pc_type not in ("lu", "cholesky"):
            raise ValueError(
                "method='schur' solves with K: with ksp_type 'preonly' petsc_options need "
                f"pc_type 'lu' or 'cholesky' (got {pc_type!r}); for a Krylov solver of K use "
                "e.g. iterative_petsc_options()"
            )
        self.direct = ksp_type == "preonly"
        n_lam = self.n_lam_global
        if self.direct and n_lam > SCHUR_MAX_MULTIPLIERS:
            raise ValueError(
                f"method='schur' with a direct solver stores the dense {n_lam} x {n_lam} matrix "
                f"N K^-1 N^T ({8e-9 * n_lam**2:.1f} GB), more than SCHUR_MAX_MULTIPLIERS = "
                f"{SCHUR_MAX_MULTIPLIERS} multipliers allow; use method='block' or a Krylov "
                "solver of K (iterative_petsc_options())"
            )
        self._u, self._u_f, self._rhs_u = (self.K.createVecRight() for _ in range(3))
        self._lam_vec = self.N.createVecLeft()
        if not self.direct:
            self._near_nullspace = rigid_body_modes(self.V, self.n_u)
            self.K.setNearNullSpace(self._near_nullspace)
        with timed("factorize"):
            error: Exception | None = None
            try:
                set_up(self.ksp, self.K)
                solve_with(self.ksp, self.f, self._u_f)
            except (PETSc.Error, LinearSolveError) as err:
                error = err
            if error is not None or null_pivots(self.ksp) > 0:
                cause = mumps_failure(self.ksp) or (
                    "K is singular (the body is not held in place, check dirichlet)"
                )
                raise LinearSolveError(
                    f"the factorisation (or preconditioner) of the stiffness matrix K failed: "
                    f"{cause}"
                ) from error
            self.schur: DenseSchurComplement | KrylovSchurComplement = (
                DenseSchurComplement(self.algebra, self.ksp)
                if self.direct
                else KrylovSchurComplement(self.algebra, self.ksp, self.prefix + "schur_")
            )

    def _saddle(
        self, a: PETSc.Vec, b: np.ndarray, w: PETSc.Vec, guess: np.ndarray | None = None
    ) -> np.ndarray:
        """Solve K u + N_A^T l_A = a, (N u)_A = b_A, l_I = 0 for the last set-up active set.

        Args:
            a: Right-hand side of the displacement rows.
            b: Owned right-hand sides of the multiplier rows (only the active ones count).
            w: K^-1 a (it may be ``self._u``, which is overwritten).
            guess: Owned initial guess of l for a Krylov solve of S_AA (None: zero).

        Returns:
            The owned l; u is left in ``self._u``.
        """
        self.N.mult(w, self._lam_vec)
        l_owned = self.schur.solve(self._lam_vec.array - b, guess)  # S_AA l_A = (N K^-1 a - b)_A
        self._lam_vec.array_w[:] = l_owned
        self.NT.mult(self._lam_vec, self._rhs_u)
        self._rhs_u.aypx(-1.0, a)  # a - N_A^T l_A
        solve_with(self.ksp, self._rhs_u, self._u)
        return l_owned

    def set_loose(self, loose: bool) -> bool:
        """Loose tolerances of the Krylov solves (:class:`KrylovSchurComplement`) or full ones.

        Returns:
            Whether the following Newton steps are solved loosely (never with a direct solver).
        """
        return self.schur.set_loose(loose)

    def solve_active(
        self, active: np.ndarray, free: np.ndarray | None = None, couplings: Any = None
    ) -> None:
        """One Newton step: lam_A from S_AA, then u with the solver of K, into :attr:`x`.

        With free values (friction) the load is f - B_I^T free_I, and lam_I = free_I.
        """
        self._check_uncoupled(couplings)
        with timed("newton solve"):
            self.schur.set_active(active)
            guess = np.where(active, self.split(self.x)[1], 0.0) if self.solved else None
            self.active = active.copy()
            force = self._set_free(active, free)
            if force is None:
                lam = self._saddle(self.f, self.g.array, self._u_f, guess)
            else:
                force.aypx(-1.0, self.f)  # f - B_I^T free_I
                solve_with(self.ksp, force, self._u)
                lam = self._saddle(force, self.g.array, self._u, guess) + self.free
                force.destroy()
            self.write(self.x, self._u.array_r, lam)
        self.solved = True

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """A^T z = rhs by eliminating y (:meth:`.NewtonLinearSystem.solve_transpose`)."""
        self.check_solved()
        j_u, j_lam = self.split(rhs)
        self._rhs_u.array_w[:] = j_u
        j = self._rhs_u.copy()
        try:
            solve_with(self.ksp, j, self._u)
            eta = self._saddle(j, j_lam, self._u)
        except (LinearSolveError, PETSc.Error) as err:
            raise RuntimeError(f"the dual solve failed: {err}") from err
        finally:
            j.destroy()
        self._write_dual(z, self._u, eta, j_lam)

