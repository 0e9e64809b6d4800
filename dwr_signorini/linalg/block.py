"""The Newton step by the block matrix (``method="block"``, the reference) and its transpose.

Each Newton step solves

    [ K          N^T    ] [u  ]   [ f       ]
    [ -D_A N     D_I M  ] [lam] = [ -D_A g  ]

through the symmetric matrix A_s of the same equations (:meth:`NewtonSystem.newton_matrix`),
factored by MUMPS's LDL^T; the dual problem A^T z = r uses the same factors.

Factor reuse: a step whose active set differs from that of the factors in r multipliers is
solved with those factors and a rank-2r correction (:class:`~.lowrank.WoodburyUpdate`), when its
solves (one of 2k right-hand sides for the k of those rows that no earlier step against the same
factors had changed, and two single ones) and its dense products take at most
:attr:`~.factor.ReusePolicy.fraction` of the last factorisation, both priced from MUMPS's counts
by the system's :class:`~.factor.ReusePolicy` (never measured time, so the same input takes the
same decisions and iterates on every run). The columns of earlier steps are
kept (:class:`~.lowrank.FactorColumns`). Steps of iterative refinement
(:meth:`~.factor.Factorisation.refine`) correct it until the correction, the estimate of the
error, is below the policy's ``rtol``; a refused or inaccurate update falls back to factoring
the new matrix, so that the null-pivot check applies.
The last semi-smooth Newton steps often change a few contact facets: those steps, and the dual
problem after them, then cost a few solves instead of a factorisation.
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from ..timing import timed
from .base import MULTIGRID
from .factor import FactoredNewtonSystem
from .lowrank import FactorColumns, WoodburyUpdate
from .nullspace import rigid_body_modes

__all__ = ["NewtonSystem"]


class NewtonSystem(FactoredNewtonSystem):
    """The Newton steps by the block matrix: A_s assembled and factored in every step.

    Args:
        disc, petsc_options, V, kwargs: See
            :class:`~dwr_signorini.linalg.base.NewtonLinearSystem`; ``petsc_options`` are for
            the block matrix (e.g. :func:`~dwr_signorini.linalg.options.fieldsplit_petsc_options`).
        reuse: See :class:`~dwr_signorini.linalg.factor.FactoredNewtonSystem`.

    Attributes:
        A0: The block pattern [K, N^T; N, M] (all active sets share it).
        A: Symmetric form of the Newton matrix of the last step (:meth:`newton_matrix`; None
            before the first step).
        direct: Whether the solver is a factorisation.
        factorizations: Factorisations so far; ``reused``: steps solved with the factors of
            an earlier step (module docstring).

    Raises:
        ValueError: A multigrid preconditioner, which does not suit the block matrix.
    """

    _petsc_objects = (
        *FactoredNewtonSystem._petsc_objects,
        "_update",
        "_columns",
        "A0",
        "is_u",
        "is_lam",
        "_near_nullspace",
    )

    def _setup(self) -> None:
        """Check the PC; the block pattern A0 of the Newton matrices; the field split if any."""
        super()._setup()
        pc_type = self.ksp.getPC().getType()
        if pc_type in MULTIGRID:
            raise ValueError(
                f"pc_type {pc_type!r}: algebraic multigrid suits the stiffness matrix K, not "
                "the block Newton matrix with its zero multiplier block; use method='krylov' "
                "(or method='schur' with these options), or fieldsplit_petsc_options() on the "
                "block matrix"
            )
        self.direct = pc_type in ("lu", "cholesky")
        self._reuse = self.direct and self.ksp.getType() == "preonly"
        self._factored_active: np.ndarray | None = None  # None: no factors to reuse
        self._update: WoodburyUpdate | None = None
        self._columns: FactorColumns | None = None  # of the current factors, per changed row
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

    def solve_active(
        self, active: np.ndarray, free: np.ndarray | None = None, couplings: Any = None
    ) -> None:
        """One Newton step: solve the linear system of active set ``active`` into :attr:`x`.

        A x = b with b = [f; -g_A; M_I free_I], as A_s x = L^-1 b = [f - B_I^T free_I; g_A;
        M_I free_I] (:meth:`newton_matrix`; free = 0 without friction).

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots (a singular Newton matrix).
            LinearSolveError: The solve failed.
        """
        self._check_uncoupled(couplings)
        with timed("assemble"):
            self.A = self.newton_matrix(active, out=self.A)
            self.active = active.copy()
            force = self._set_free(active, free)
            b = self.b.array_w
            b[: self.n_u] = self.f.array
            b[self.n_u :] = np.where(active, self.g.array, 0.0)
            if force is not None:
                b[: self.n_u] -= force.array
                b[self.n_u :] += self.M.array * self.free
                force.destroy()
        if self._update is not None:
            self._update.destroy()
            self._update = None
        self._solve_step()

    def _factor(self) -> None:
        """Factor the Newton matrix of this step; its columns are kept for later updates."""
        self._factored_active = None
        if self._columns is not None:
            self._columns.destroy()
            self._columns = None
        self.factors.factor(self.A)
        self._factored_active = self.active.copy()
        self._columns = FactorColumns(self.ksp, self.factors.matrix)

    def _changed_rows(self, active: np.ndarray) -> np.ndarray:
        """Global rows of the multipliers whose activity differs from the factors' (all ranks)."""
        first = self.A.getOwnershipRange()[0] + self.n_u
        local = first + np.flatnonzero(active != self._factored_active)
        return np.sort(np.concatenate(self.disc.comm.allgather(local))).astype(np.int64)

    def _solve_by_update(self) -> bool:
        """Solve the step with the factors of an earlier one, if that pays (module docstring).

        Returns:
            Whether :attr:`x` holds the step.
        """
        if not self._reuse or self._factored_active is None or not self.factors.reusable:
            return False
        comm, active = self.disc.comm, self.active
        rows = self._changed_rows(active)
        if len(rows) == 0:  # the factored matrix itself
            with timed("newton solve"):
                self.ksp.solve(self.b, self.x)
            return self.ksp.getConvergedReason() > 0
        new_rows = len(self._columns.missing(rows))
        lo, hi = self.A.getOwnershipRange()
        dense = comm.allreduce((hi - lo) * (2 * len(rows)) ** 2, MPI.MAX)  # U^T Z
        if not self.factors.pays(2 * new_rows, dense):
            return False
        with timed("newton solve"):
            try:
                update = WoodburyUpdate(self._columns, self.A, rows)
            except np.linalg.LinAlgError:
                return False
            try:
                update.solve(self.b, self.x)
                accurate = self._refine(update, self.b, self.x)
            except np.linalg.LinAlgError:
                accurate = False
            # the inactive rows M_I lam_I = M_I free_I hold exactly, as in a direct solve
            self.x.array_w[self.n_u :][~active] = self.free[~active]
        if not accurate:
            update.destroy()
            return False
        self._update = update
        return True

    def _refine(self, update: WoodburyUpdate, rhs: PETSc.Vec, x: PETSc.Vec) -> bool:
        """Iterative refinement of A_s x = rhs (:meth:`~.factor.Factorisation.refine`)."""
        return self.factors.refine(self.A, update, rhs, x, self.n_u)

    def _solve_symmetric(self, rhs: PETSc.Vec, w: PETSc.Vec) -> int:
        """A_s w = rhs for the last step's A_s: its factors, or the old ones and the update.

        Through the update, iterative refinement (:meth:`_refine`) checks w; if it is not
        accurate, A_s is factored and w solved with its factors.

        Returns:
            The KSP's converged reason (> 0: solved).
        """
        if self._update is not None:
            self._update.solve(rhs, w)
            if self._refine(self._update, rhs, w):
                return self.ksp.getConvergedReason()
            self._update.destroy()  # not accurate for this right-hand side: factor A_s
            self._update = None
            self._factor()
        self.ksp.solve(rhs, w)
        return self.ksp.getConvergedReason()

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """Solve A^T z = rhs with the Newton matrix A of the last step (the dual problem).

        A^T = A_s L^T (:meth:`newton_matrix`): solve A_s w = rhs with the factors of the last
        step (two triangular solves), then z = L^-T w, i.e. z_u = w_u, z_A = -w_A and
        z_I = w_I - (N w_u)_I / M_I. Arguments and errors:
        :meth:`.NewtonLinearSystem.solve_transpose`.
        """
        self.check_solved()
        reason = self._solve_symmetric(rhs, z)
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

