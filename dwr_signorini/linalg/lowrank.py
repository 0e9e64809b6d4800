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

that is 2r solves with the old factors once (Z), and one solve and a dense 2r x 2r solve per
right-hand side. The capacitance matrix S^-1 + U^T Z is equilibrated (its entries range from
those of S^-1 to those of the inverse on the multiplier rows); singular or ill-conditioned after
that (a singular A_new, e.g. linearly dependent active constraints), it is refused, so that the
caller factors A_new and its checks apply.
"""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np

__all__ = ["WoodburyUpdate"]

#: Largest condition number of the capacitance matrix that is accepted.
MAX_CAPACITANCE_CONDITION = 1e14


class WoodburyUpdate:
    """Solves with A_new = A_old + U S U^T through the factors of A_old (module docstring).

    Args:
        ksp: The solver holding the factors of ``A_old`` (its operator).
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
        r = len(rows)
        D = A_new.copy()
        D.axpy(-1.0, A_old, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        lo, hi = D.getOwnershipRange()
        self.U: list[PETSc.Vec] = []
        for row in rows:  # E_C
            e = D.createVecRight()
            if lo <= row < hi:
                e.setValue(int(row), 1.0)
            e.assemble()
            self.U.append(e)
        for e in self.U[:r]:  # D E_C
            column = D.createVecLeft()
            D.mult(e, column)
            self.U.append(column)
        D.destroy()
        self.Z = []
        for u in self.U:
            z = u.duplicate()
            ksp.solve(u, z)
            if ksp.getConvergedReason() < 0:
                z.destroy()
                self.destroy()
                raise np.linalg.LinAlgError("a solve with the old factors failed")
            self.Z.append(z)
        # D_CC[a, b] = e_a . (D e_b); the capacitance S^-1 + U^T Z
        D_CC = np.array([[self.U[a].dot(self.U[r + b]) for b in range(r)] for a in range(r)])
        S_inv = np.block([[np.zeros((r, r)), np.eye(r)], [np.eye(r), D_CC]])
        UtZ = np.array([[u.dot(z) for z in self.Z] for u in self.U])
        capacitance = S_inv + UtZ  # symmetric; its entries span many orders of magnitude
        self.scale = 1.0 / np.sqrt(np.max(np.abs(capacitance), axis=1))
        self.capacitance = self.scale[:, None] * capacitance * self.scale[None, :]
        condition = np.linalg.cond(self.capacitance)
        if not np.isfinite(condition) or condition > MAX_CAPACITANCE_CONDITION:
            self.destroy()
            raise np.linalg.LinAlgError(
                f"the capacitance matrix of the low-rank update has condition {condition:.1e}"
            )

    def solve(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve A_new x = b: one solve with the old factors and a dense 2r x 2r solve."""
        self.ksp.solve(b, x)
        if self.ksp.getConvergedReason() < 0:
            raise np.linalg.LinAlgError("a solve with the old factors failed")
        t = np.array([u.dot(x) for u in self.U])
        s = self.scale * np.linalg.solve(self.capacitance, self.scale * t)
        for coefficient, z in zip(s, self.Z, strict=True):
            x.axpy(-coefficient, z)

    @property
    def solves_per_update(self) -> int:
        """Solves with the old factors that building the update took (2r)."""
        return len(self.U)

    def destroy(self) -> None:
        """Destroy the vectors (collective)."""
        for vec in [*getattr(self, "U", []), *getattr(self, "Z", [])]:
            vec.destroy()
        self.U, self.Z = [], []
