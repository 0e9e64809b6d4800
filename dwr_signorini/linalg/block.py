"""The Newton step by the block matrix (``method="block"``, the reference) and its transpose.

Each Newton step solves

    [ K          N^T    ] [u  ]   [ f       ]
    [ -D_A N     D_I M  ] [lam] = [ -D_A g  ]

through the symmetric matrix A_s of the same equations (:meth:`NewtonSystem.newton_matrix`),
factored by MUMPS's LDL^T; the dual problem A^T z = r uses the same factors.
"""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np

from ..timing import timed
from .base import NewtonLinearSystem
from .mumps import mumps_failure, null_pivots, set_up
from .nullspace import rigid_body_modes

__all__ = ["LinearSolveError", "NewtonSystem"]

#: Multigrid preconditioners: for K (``method="schur"``), not for the block Newton matrix.
MULTIGRID = ("gamg", "hypre", "ml", "mg")


class LinearSolveError(RuntimeError):
    """A linear solve of a Newton step failed (the Newton loop adds its history)."""


class NewtonSystem(NewtonLinearSystem):
    """The Newton steps by the block matrix: A_s assembled and factored in every step.

    Args:
        disc, petsc_options, V, kwargs: See
            :class:`~dwr_signorini.linalg.base.NewtonLinearSystem`; ``petsc_options`` are for
            the block matrix (e.g. :func:`~dwr_signorini.linalg.options.fieldsplit_petsc_options`).

    Attributes:
        A0: The block pattern [K, N^T; N, M] (all active sets share it).
        A: Symmetric form of the Newton matrix of the last step (:meth:`newton_matrix`; None
            before the first step).
        direct: Whether the solver is a factorisation.

    Raises:
        ValueError: A multigrid preconditioner, which does not suit the block matrix.
    """

    _petsc_objects = (
        *NewtonLinearSystem._petsc_objects,
        "A0",
        "A",
        "b",
        "is_u",
        "is_lam",
        "_near_nullspace",
    )

    def _setup(self) -> None:
        """Check the PC; the block pattern A0 of the Newton matrices; the field split if any."""
        self.A: PETSc.Mat | None = None
        pc_type = self.ksp.getPC().getType()
        if pc_type in MULTIGRID:
            raise ValueError(
                f"pc_type {pc_type!r}: algebraic multigrid suits the stiffness matrix K, not "
                "the block Newton matrix with its zero multiplier block; use method='schur' "
                "with these options (iterative_petsc_options()), or "
                "fieldsplit_petsc_options() on the block matrix"
            )
        self.direct = pc_type in ("lu", "cholesky")
        comm, alg = self.disc.comm, self.algebra
        with timed("assemble"):
            D = PETSc.Mat().createAIJ(((self.n_lam, None), (self.n_lam, None)), nnz=1, comm=comm)
            D.setDiagonal(alg.M)
            D.assemble()
            nest = PETSc.Mat().createNest([[alg.K, alg.NT], [alg.N, D]], comm=comm)
            self.A0 = PETSc.Mat()
            nest.convert("aij", out=self.A0)
            nest.destroy()
            D.destroy()
            self.b = self.A0.createVecLeft()
        if self.ksp.getPC().getType() == "fieldsplit":
            lo = self.A0.getOwnershipRange()[0]
            self.is_u = PETSc.IS().createStride(self.n_u, first=lo, step=1, comm=comm)
            self.is_lam = PETSc.IS().createStride(
                self.n_lam, first=lo + self.n_u, step=1, comm=comm
            )
            self._near_nullspace = rigid_body_modes(self.V, self.n_u)
            self.is_u.compose("nearnullspace", self._near_nullspace)
            self.ksp.getPC().setFieldSplitIS(("u", self.is_u), ("lam", self.is_lam))

    def newton_matrix(self, active: np.ndarray, out: PETSc.Mat | None = None) -> PETSc.Mat:
        """The symmetric matrix A_s of the Newton step of active set A.

        The Newton matrix of the step is A = L A_s with

            A_s = [ K      N_A^T   0   ]        L = [ I   0    N_I^T M_I^-1 ]
                  [ N_A    0       0   ],           [ 0   -I   0            ]
                  [ 0      0       M_I ]            [ 0   0    I            ]

        (rows and columns ordered u, active, inactive multipliers): the inactive columns N_I^T
        only ever multiply lam_I = 0, and the active rows change sign. So A x = b is
        A_s x = L^-1 b, and the dual A^T z = r is A_s w = r, z = L^-T w (:meth:`solve_transpose`):
        one symmetric indefinite matrix, factored by LDL^T, serves both.

        All active sets share one sparsity pattern (that of A0, zeros kept), so with ``out`` the
        values are overwritten in place and the solver reuses its symbolic factorisation.
        """
        if out is None:
            A = self.A0.copy()
        else:
            A = out
            self.A0.copy(A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        scale = A.createVecLeft()
        scale.array_w[: self.n_u] = 1.0
        scale.array_w[self.n_u :] = active
        A.diagonalScale(L=scale, R=scale)
        diagonal = A.getDiagonal()
        diagonal.array_w[self.n_u :] = np.where(active, 0.0, self.M.array)
        A.setDiagonal(diagonal, addv=PETSc.InsertMode.INSERT_VALUES)
        A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        for vec in (scale, diagonal):
            vec.destroy()
        return A

    def solve_active(self, active: np.ndarray) -> None:
        """One Newton step: solve the linear system of active set ``active`` into :attr:`x`.

        A x = b with b = [f; -g_A; 0], as A_s x = L^-1 b = [f; g_A; 0] (:meth:`newton_matrix`).

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots (a singular Newton matrix).
            LinearSolveError: The solve failed.
        """
        with timed("assemble"):
            self.A = self.newton_matrix(active, out=self.A)
            self.active = active.copy()
            b = self.b.array_w
            b[: self.n_u] = self.f.array
            b[self.n_u :] = np.where(active, self.g.array, 0.0)
        with timed("factorize"):
            set_up(self.ksp, self.A)
        count = null_pivots(self.ksp)
        if count > 0:
            raise np.linalg.LinAlgError(
                f"MUMPS found {count} null pivots: the Newton matrix is singular"
            )
        with timed("newton solve"):
            self.ksp.solve(self.b, self.x)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            cause = mumps_failure(self.ksp)
            raise LinearSolveError(
                f"linear solve of the Newton step failed (KSP reason {reason})"
                + (f": {cause}" if cause else "")
            )
        self.solved = True

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """Solve A^T z = rhs with the Newton matrix A of the last step (the dual problem).

        A^T = A_s L^T (:meth:`newton_matrix`): solve A_s w = rhs with the factors of the last
        step (two triangular solves), then z = L^-T w, i.e. z_u = w_u, z_A = -w_A and
        z_I = w_I - (N w_u)_I / M_I.

        Args:
            rhs: Block vector [j_u; j_lam], laid out as :attr:`x`.
            z: Block vector [y; xi] for the solution, laid out as :attr:`x`.

        Raises:
            RuntimeError: No Newton step was solved, or the solve failed.
        """
        self.check_solved()
        self.ksp.solve(rhs, z)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            raise RuntimeError(f"the dual solve failed (KSP reason {reason})")
        w_u = self.N.createVecRight()
        w_u.array_w[:] = self.split(z)[0]
        n_w = self.N.createVecLeft()
        self.N.mult(w_u, n_w)
        w_lam = z.array_w[self.n_u :]
        w_lam[:] = np.where(self.active, -w_lam, w_lam - n_w.array / self.M.array)
        for vec in (w_u, n_w):
            vec.destroy()
