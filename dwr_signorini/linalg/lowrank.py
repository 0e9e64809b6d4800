"""Solves with the factors of a matrix after a few of its rows and columns changed (Woodbury).

Two symmetric Newton matrices of the block path (:mod:`~dwr_signorini.linalg.block`) differ only
in the rows and columns of the multipliers whose activity changed. With C those r rows and
D = A_new - A_old (nonzero only in the rows C and the columns C),

    D = U S U^T,   U = [E_C, D E_C] (n x 2r),   S = [[-D_CC, I], [I, 0]],

where E_C holds the unit vectors of C (check: U S U^T = -E_C D_CC E_C^T + E_C E_C^T D +
D E_C E_C^T, which is D on the rows and columns C). The Sherman-Morrison-Woodbury formula then
solves A_new x = b with the factors of A_old:

    x = y - Z (S^-1 + U^T Z)^-1 U^T y,   y = A_old^-1 b,   Z = A_old^-1 U,
    S^-1 = [[0, I], [I, D_CC]],

that is one solve of 2r right-hand sides with the old factors once (Z), and one solve and a
dense 2r x 2r solve per right-hand side.

The columns of U and Z belonging to a row c depend only on c: the column D e_c of A_s's change is
that of the row's own new activity (a multiplier row of A_s is N's row or M's diagonal entry), so
:class:`FactorColumns` keeps them per row for as long as the factors last. A later Newton step
against the same factors, whose changes mostly repeat the earlier ones, solves only for its new
rows. D e_c is read from the rows c of A_new and A_old (A_s is symmetric), not multiplied out.

The capacitance matrix S^-1 + U^T Z is equilibrated (its entries range from those of S^-1 to
those of the inverse on the multiplier rows); singular or ill-conditioned after that (a
singular A_new, e.g. linearly dependent active constraints), it is refused, so that the caller
factors A_new and its checks apply.
"""

from __future__ import annotations

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

__all__ = ["FactorColumns", "RowUpdate", "WoodburyUpdate"]

#: Largest condition number of the capacitance matrix that is accepted.
MAX_CAPACITANCE_CONDITION = 1e14


class FactorColumns:
    """Per changed row c: D e_c, A_old^-1 e_c and A_old^-1 D e_c (module docstring).

    Args:
        ksp: The solver holding the factors of ``A_old`` (a factorisation).
        A_old: The factored (symmetric) matrix.
    """

    def __init__(self, ksp: PETSc.KSP, A_old: PETSc.Mat) -> None:
        self.ksp, self.A_old = ksp, A_old
        self.comm: MPI.Comm = A_old.getComm().tompi4py()
        self.lo, self.hi = A_old.getOwnershipRange()
        n_local = self.hi - self.lo
        self.index: dict[int, int] = {}
        self.d = np.zeros((n_local, 0))
        self.z_e = np.zeros((n_local, 0))
        self.z_d = np.zeros((n_local, 0))

    def missing(self, rows: np.ndarray) -> np.ndarray:
        """The rows (global, the same on every rank) whose columns are not kept yet."""
        return np.array([r for r in rows if int(r) not in self.index], dtype=np.int64)

    def add(self, A_new: PETSc.Mat, rows: np.ndarray) -> None:
        """Compute and keep the columns of ``rows`` (not kept yet; collective).

        One solve of 2k right-hand sides with the old factors, k = ``len(rows)``.
        """
        k = len(rows)
        if k == 0:
            return
        d = self._changed_columns(A_new, rows)
        n_local, n = self.hi - self.lo, A_new.getSize()[0]
        rhs, sol = (
            PETSc.Mat().createDense(((n_local, n), (None, 2 * k)), comm=A_new.getComm())
            for _ in range(2)
        )
        for block in (rhs, sol):
            block.setUp()
            block.assemble()
        values = rhs.getDenseArray()
        mine = (rows >= self.lo) & (rows < self.hi)
        values[rows[mine] - self.lo, np.flatnonzero(mine)] = 1.0
        values[:, k:] = d
        rhs.assemble()
        self.ksp.getPC().getFactorMatrix().matSolve(rhs, sol)
        z = sol.getDenseArray()
        for j, row in enumerate(rows):
            self.index[int(row)] = self.d.shape[1] + j
        self.d = np.hstack([self.d, d])
        self.z_e = np.hstack([self.z_e, z[:, :k]])
        self.z_d = np.hstack([self.z_d, z[:, k:]])
        rhs.destroy()
        sol.destroy()

    def _changed_columns(self, A_new: PETSc.Mat, rows: np.ndarray) -> np.ndarray:
        """D e_c = (A_new - A_old) e_c for each row c of ``rows``, owned entries (collective).

        By symmetry the column is the row, which the owner of c reads and every rank receives.
        """
        entries = []
        for j in np.flatnonzero((rows >= self.lo) & (rows < self.hi)):
            cols, new = A_new.getRow(int(rows[j]))
            cols_old, old = self.A_old.getRow(int(rows[j]))
            if not np.array_equal(cols, cols_old):
                raise ValueError("A_new and A_old must share their sparsity pattern")
            change = new - old
            keep = change != 0.0
            entries.append((j, cols[keep], change[keep]))
        d = np.zeros((self.hi - self.lo, len(rows)))
        for part in self.comm.allgather(entries):
            for j, cols, change in part:
                mine = (cols >= self.lo) & (cols < self.hi)
                d[cols[mine] - self.lo, j] = change[mine]
        return d

    def destroy(self) -> None:
        """Drop the kept columns (numpy arrays: nothing collective)."""
        self.index = {}
        self.d = self.z_e = self.z_d = np.zeros((0, 0))


class WoodburyUpdate:
    """Solves with A_new = A_old + U S U^T through the factors of A_old (module docstring).

    U = [E_C, D E_C] and Z = A_old^-1 U come from ``columns``, which computes those of the rows it
    does not keep yet (one multi-right-hand-side solve, ``MatMatSolve``).

    Args:
        columns: The kept columns of the factors of ``A_old``.
        A_new: The matrix to solve with (same layout and pattern as ``A_old``).
        rows: Global indices of the changed rows, the same on every rank.

    Raises:
        numpy.linalg.LinAlgError: The capacitance matrix is singular or ill-conditioned.
    """

    def __init__(self, columns: FactorColumns, A_new: PETSc.Mat, rows: np.ndarray) -> None:
        columns.add(A_new, columns.missing(rows))
        self.ksp, self.comm = columns.ksp, columns.comm
        r = len(rows)
        at = [columns.index[int(row)] for row in rows]
        self.d = columns.d[:, at]
        self.Z = np.hstack([columns.z_e[:, at], columns.z_d[:, at]])
        mine = (rows >= columns.lo) & (rows < columns.hi)
        self._local = rows[mine] - columns.lo  # owned changed rows, local indices
        self._position = np.flatnonzero(mine)  # their positions in ``rows``
        # U^T Z and D_CC = E_C^T D E_C, one reduction
        local = np.zeros((2 * r + r, 2 * r))
        local[self._position] = self.Z[self._local]
        local[r : 2 * r] = self.d.T @ self.Z
        local[2 * r + self._position, :r] = self.d[self._local]
        total = self.comm.allreduce(local)
        UtZ, D_CC = total[: 2 * r], total[2 * r :, :r]
        S_inv = np.block([[np.zeros((r, r)), np.eye(r)], [np.eye(r), D_CC]])
        capacitance = S_inv + UtZ  # symmetric; its entries span many orders of magnitude
        self.scale = 1.0 / np.sqrt(np.max(np.abs(capacitance), axis=1))
        self.capacitance = self.scale[:, None] * capacitance * self.scale[None, :]
        condition = np.linalg.cond(self.capacitance)
        if not np.isfinite(condition) or condition > MAX_CAPACITANCE_CONDITION:
            raise np.linalg.LinAlgError(
                f"the capacitance matrix of the low-rank update has condition {condition:.1e}"
            )

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve A_new x = b: one solve with the old factors and a dense 2r x 2r solve."""
        self.ksp.solve(b, x)
        if self.ksp.getConvergedReason() < 0:
            raise np.linalg.LinAlgError("a solve with the old factors failed")
        r = self.d.shape[1]
        local = np.zeros(2 * r)
        y = x.array_r
        local[self._position] = y[self._local]
        local[r:] = self.d.T @ y
        t = self.comm.allreduce(local)
        s = self.scale * np.linalg.solve(self.capacitance, self.scale * t)
        x.array_w[:] -= self.Z @ s

    def destroy(self) -> None:
        """Release the blocks (numpy arrays: nothing collective)."""
        self.d = self.Z = np.zeros((0, 0))


class RowUpdate:
    """Solves with A_new through the factors of A_old where they differ in a few rows only.

    The nonsymmetric Newton matrices of the coupled path (:mod:`~dwr_signorini.linalg.coupled`)
    of two steps differ in the multiplier rows C of the facets whose sets or derivative blocks
    changed: A_new = A_old + E_C E_C^T D, D = A_new - A_old. The Sherman-Morrison-Woodbury
    formula with U = E_C (n x r) and V^T = E_C^T D gives

        x = y - Z (I + (D Z)_C)^-1 (D y)_C,   y = A_old^-1 b,   Z = A_old^-1 E_C,

    one solve of r right-hand sides with the old factors (Z, ``MatMatSolve``), two products
    with A_new and A_old for (D Z)_C, and per solve one solve and an r x r dense solve.

    Args:
        ksp: The solver holding the factors of ``A_old``.
        A_old: The factored matrix.
        A_new: The matrix to solve with (the same layout and sparsity pattern).
        rows: Global indices of the changed rows, the same on every rank.

    Raises:
        numpy.linalg.LinAlgError: The capacitance matrix is singular or ill-conditioned.
    """

    def __init__(
        self, ksp: PETSc.KSP, A_old: PETSc.Mat, A_new: PETSc.Mat, rows: np.ndarray
    ) -> None:
        self.ksp, self.A_old, self.A_new = ksp, A_old, A_new
        self.comm: MPI.Comm = A_old.getComm().tompi4py()
        lo, hi = A_old.getOwnershipRange()
        n_local, n, r = hi - lo, A_old.getSize()[0], len(rows)
        mine = (rows >= lo) & (rows < hi)
        self._local, self._position = rows[mine] - lo, np.flatnonzero(mine)
        rhs, Z = (PETSc.Mat().createDense(((n_local, n), (None, r)), comm=A_old.getComm())
                  for _ in range(2))
        for block in (rhs, Z):
            block.setUp()
            block.assemble()
        rhs.getDenseArray()[self._local, self._position] = 1.0
        rhs.assemble()
        ksp.getPC().getFactorMatrix().matSolve(rhs, Z)
        DZ = A_new.matMult(Z)
        AZ = A_old.matMult(Z)
        local = np.zeros((r, r))
        local[self._position] = DZ.getDenseArray()[self._local] - AZ.getDenseArray()[self._local]
        self.capacitance = np.eye(r) + self.comm.allreduce(local)
        self.Z = Z.getDenseArray().copy()
        for mat in (rhs, Z, DZ, AZ):
            mat.destroy()
        condition = np.linalg.cond(self.capacitance)
        if not np.isfinite(condition) or condition > MAX_CAPACITANCE_CONDITION:
            raise np.linalg.LinAlgError(
                f"the capacitance matrix of the row update has condition {condition:.1e}"
            )
        self._work = A_old.createVecLeft()

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve A_new x = b: one solve with the old factors and an r x r dense solve."""
        self.ksp.solve(b, x)
        if self.ksp.getConvergedReason() < 0:
            raise np.linalg.LinAlgError("a solve with the old factors failed")
        self.A_new.mult(x, self._work)
        local = np.zeros(self.capacitance.shape[0])
        local[self._position] = self._work.array_r[self._local]
        self.A_old.mult(x, self._work)
        local[self._position] -= self._work.array_r[self._local]
        s = np.linalg.solve(self.capacitance, self.comm.allreduce(local))
        x.array_w[:] -= self.Z @ s

    def destroy(self) -> None:
        """Release the work vector (collective) and the blocks."""
        self._work.destroy()
        self.Z = np.zeros((0, 0))
