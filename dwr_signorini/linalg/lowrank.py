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
dense 2r x 2r solve per right-hand side. The capacitance matrix S^-1 + U^T Z is equilibrated
(its entries range from those of S^-1 to those of the inverse on the multiplier rows); singular
or ill-conditioned after that (a singular A_new, e.g. linearly dependent active constraints),
it is refused, so that the caller factors A_new and its checks apply.
"""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np

__all__ = ["WoodburyUpdate"]

#: Largest condition number of the capacitance matrix that is accepted.
MAX_CAPACITANCE_CONDITION = 1e14


class WoodburyUpdate:
    """Solves with A_new = A_old + U S U^T through the factors of A_old (module docstring).

    U and Z = A_old^-1 U are dense blocks of 2r columns (the owned rows of each rank); Z comes
    from one multi-right-hand-side solve with the factors (``MatMatSolve``).

    Args:
        ksp: The solver holding the factors of ``A_old`` (its operator; a factorisation).
        A_old: The factored matrix.
        A_new: The matrix to solve with (same layout and pattern).
        rows: Global indices of the changed rows, the same on every rank.

    Raises:
        numpy.linalg.LinAlgError: The capacitance matrix is singular or ill-conditioned.
    """

    def __init__(
        self, ksp: PETSc.KSP, A_old: PETSc.Mat, A_new: PETSc.Mat, rows: np.ndarray
    ) -> None:
        self.ksp = ksp
        self.comm = A_new.getComm().tompi4py()
        r = len(rows)
        D = A_new.copy()
        D.axpy(-1.0, A_old, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        lo, hi = D.getOwnershipRange()
        n_local, n = hi - lo, D.getSize()[0]
        blocks = []
        for _ in range(2):
            block = PETSc.Mat().createDense(((n_local, n), (None, 2 * r)), comm=D.getComm())
            block.setUp()
            block.assemble()
            blocks.append(block)
        U, Z = blocks
        mine = (rows >= lo) & (rows < hi)
        e, column = D.createVecRight(), D.createVecLeft()
        u = U.getDenseArray()
        u[rows[mine] - lo, np.flatnonzero(mine)] = 1.0  # E_C
        for j, row in enumerate(rows):  # D E_C
            e.set(0.0)
            if lo <= row < hi:
                e.setValue(int(row), 1.0)
            e.assemble()
            D.mult(e, column)
            u[:, r + j] = column.array_r
        for obj in (D, e, column):
            obj.destroy()
        U.assemble()
        ksp.getPC().getFactorMatrix().matSolve(U, Z)
        self.U, self.Z = U.getDenseArray().copy(), Z.getDenseArray().copy()
        U.destroy()
        Z.destroy()
        # S^-1 + U^T Z, with D_CC[a, b] = e_a . (D e_b)
        UtU = self.comm.allreduce(self.U.T @ self.U)
        UtZ = self.comm.allreduce(self.U.T @ self.Z)
        D_CC = UtU[:r, r:]
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
        t = self.comm.allreduce(self.U.T @ x.array_r)
        s = self.scale * np.linalg.solve(self.capacitance, self.scale * t)
        x.array_w[:] -= self.Z @ s

    def destroy(self) -> None:
        """Release the blocks (numpy arrays: nothing collective)."""
        self.U = self.Z = np.zeros((0, 0))
