"""The Newton step of a law with coupled rows (3D friction, Coulomb's law) by LU.

Where a law's projection acts on several multipliers at once (the ball of Tresca's law in
3D, :class:`~dwr_signorini.laws.TangentialBall`; Coulomb's cone, whose threshold is
mu lambda_n, :class:`~dwr_signorini.laws.CoulombCone`), the generalised derivative J of the
NCP on a slipping facet is a full block, and the Newton step (eq. 20 linearised) reads

    [ K      N^T ] [u  ]   [ f ]
    [ W N    G   ] [lam] = [ h ]

with, per row of the multipliers,

* constrained (active, stick): W = -1, G = 0, h = -g (the rows of the symmetric paths);
* free (inactive): W = 0, G = M, h = M free;
* coupled facet f of the components k, l (:class:`~dwr_signorini.laws.Coupling`):
  W_kl = -c_f J_kl, G_kl = (delta_kl - J_kl) M_f, h_k = r_k - c_f sum_l J_kl g_l, on its rows
  k that are not constrained (the normal row of a facet slipping under Coulomb's law is).

J = alpha (I - q q^T) on a slipping facet is symmetric, but its rows multiply c N and its
columns meet N^T (and Coulomb's J has the column mu q under the normal row): the matrix is
not symmetric, and it is factored by LU (MUMPS, the default
``pc_type="lu"`` of this system). The dual problem A^T z = r is solved with the same factors
(``KSPSolveTranspose``); the constrained rows keep the scaling of the symmetric paths, so that
:func:`~dwr_signorini.dual.solve_dual` maps the dual multipliers alike (xi = xi^(1) / c on the
constrained rows), and the coupled rows are those of the NCP itself, whose dual multiplier is
xi (the form b_h carries c, :mod:`dwr_signorini.residuals`).

The block matrix is assembled per step from K, N^T and the rows W N, G (scipy on the owned
rows) in one sparsity pattern for all steps: a multiplier row holds the displacement columns
of every component's row of its facet and the multiplier columns of its facet, zeros kept. So
the factorisation's analysis (ordering, symbolic factorisation) is done once per mesh, and
each step is a numerical factorisation.

Factor reuse: a step whose matrix differs from the factored one in r rows (the multiplier rows
of the facets whose sets or derivative blocks changed) is solved with the old factors and a
rank-r row update (:class:`~.lowrank.RowUpdate`, checked by iterative refinement) when that
costs at most :attr:`~.factor.ReusePolicy.fraction` of a factorisation, as on the symmetric
block path (:mod:`~dwr_signorini.linalg.factor`). The dual problem (and a forward solve)
after such a step factors the step's matrix first (``benchmarks/coupled_reuse.py``).
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.sparse

from ..laws import Coupling
from ..timing import timed
from .base import MULTIGRID, owned_rows
from .factor import FactoredNewtonSystem
from .lowrank import RowUpdate

__all__ = ["CoupledNewtonSystem", "newton_rhs", "newton_rows"]


def _pattern(mat: scipy.sparse.csr_matrix) -> tuple[scipy.sparse.csr_matrix, np.ndarray]:
    """A sparsity pattern (sorted CSR) and its entries' keys row * columns + column."""
    mat = mat.tocsr()
    mat.sort_indices()
    rows = np.repeat(np.arange(mat.shape[0], dtype=np.int64), np.diff(mat.indptr))
    return mat, rows * mat.shape[1] + mat.indices


def newton_rows(
    active: np.ndarray, couplings: list[Coupling], c: np.ndarray, M: np.ndarray
) -> tuple[scipy.sparse.csr_matrix, scipy.sparse.csr_matrix]:
    """The multiplier rows [W N, G] of the Newton matrix: W and G (module docstring).

    Owned rows, local columns (a coupled facet's rows are owned by one rank). Without coupled
    facets W = -D_A and G = D_I M, the rows of the symmetric paths.

    Args:
        active: The constrained rows (active, stick).
        couplings: The coupled facets (:class:`~dwr_signorini.laws.Coupling`).
        c: c_i of the NCP on the owned rows.
        M: M_i, the sizes of the macro contact facets.
    """
    n = len(active)
    coupled = np.zeros(n, dtype=bool)
    for cp in couplings:
        coupled[cp.rows.ravel()] = True
    free = ~active & ~coupled
    w_rows, w_cols, w_vals = [np.flatnonzero(active)], [np.flatnonzero(active)], []
    w_vals.append(-np.ones(len(w_rows[0])))
    g_rows, g_cols, g_vals = [np.flatnonzero(free)], [np.flatnonzero(free)], [M[free]]
    for cp in couplings:
        k = cp.rows.shape[1]
        rows = np.repeat(cp.rows, k, axis=1).ravel()
        cols = np.tile(cp.rows, (1, k)).ravel()
        own = ~active[rows]  # a constrained row of a coupled facet keeps its equation
        J = cp.J.reshape(len(cp.rows), k * k)
        w_rows.append(rows[own])
        w_cols.append(cols[own])
        w_vals.append((-c[cp.rows[:, :1]] * J).ravel()[own])
        eye = np.eye(k).ravel()[None, :]
        g_rows.append(rows[own])
        g_cols.append(cols[own])
        g_vals.append(((eye - J) * M[cp.rows[:, :1]]).ravel()[own])

    def csr(vals: list, rows: list, cols: list) -> scipy.sparse.csr_matrix:
        return scipy.sparse.coo_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
        ).tocsr()

    return csr(w_vals, w_rows, w_cols), csr(g_vals, g_rows, g_cols)


def newton_rhs(
    active: np.ndarray, couplings: list[Coupling], c: np.ndarray, M: np.ndarray,
    g: np.ndarray, free: np.ndarray,
) -> np.ndarray:
    """h, the multiplier rows of the Newton step's right-hand side (module docstring).

    -g on the constrained rows, M free on the free ones, r_k - c_f sum_l J_kl g_l on the rows of
    a coupled facet that are not constrained; ``g`` the offsets of the system that solves the
    step (:class:`~dwr_signorini.laws.Coupling`).
    """
    h = np.where(active, -g, M * free)
    for cp in couplings:
        coupled_h = cp.r - c[cp.rows] * np.einsum("mkl,ml->mk", cp.J, g[cp.rows])
        h[cp.rows] = np.where(active[cp.rows], h[cp.rows], coupled_h)
    return h



class CoupledNewtonSystem(FactoredNewtonSystem):
    """The Newton steps of a law with coupled rows, by LU of the block matrix (module docstring).

    Args:
        disc, petsc_options, V, kwargs: See
            :class:`~dwr_signorini.linalg.base.NewtonLinearSystem`; the default solver is
            MUMPS's LU.
        reuse: See :class:`~dwr_signorini.linalg.factor.FactoredNewtonSystem`.

    Attributes:
        A: The Newton matrix of the last step (None before the first).
        couplings: The coupled facets of the last step.

    Raises:
        ValueError: ``pc_type`` a Cholesky factorisation or a multigrid preconditioner.
    """

    @staticmethod
    def default_options(defaults: dict[str, Any]) -> dict[str, Any]:
        """The defaults with LU where they factor by Cholesky (the matrix is not symmetric)."""
        if defaults.get("pc_type") == "cholesky":
            defaults = {**defaults, "pc_type": "lu"}
        return defaults

    def _setup(self) -> None:
        """Check the PC; the owned rows of N for the products W N."""
        super()._setup()
        pc_type = self.ksp.getPC().getType()
        if pc_type == "cholesky" or pc_type in MULTIGRID:
            raise ValueError(
                f"pc_type {pc_type!r}: the Newton matrix of this contact law (friction in 3D, "
                "Coulomb friction) is not symmetric and has a zero multiplier block where "
                "facets are constrained; factor it by LU (pc_type='lu', the default)"
            )
        self._current = False  # whether the factors are those of the last step's matrix
        self._N = owned_rows(self.N).tocsr()
        self._lo = self.N.getOwnershipRange()[0]
        self.b = self.x.duplicate()
        # the fixed patterns: facet blocks F (all components of a facet), and F |N|
        n, k = self.n_lam, len(self.algebra.components)
        n_q = self.algebra.n_q
        rows = (np.arange(k)[:, None] * n_q + np.arange(n_q)[None, :]).T  # (n_q, k)
        F = scipy.sparse.coo_matrix(
            (np.ones(n_q * k * k), (np.repeat(rows, k, axis=1).ravel(),
                                    np.tile(rows, (1, k)).ravel())), shape=(n, n)).tocsr()
        self._G_pattern = _pattern(F)
        self._B_pattern = _pattern(F @ abs(self._N))

    def _blocks(
        self, active: np.ndarray, couplings: list[Coupling]
    ) -> tuple[scipy.sparse.csr_matrix, scipy.sparse.csr_matrix, np.ndarray]:
        """W, G (owned rows, local columns) and h of the module docstring."""
        W, G = newton_rows(active, couplings, self.c_n, self.M.array)
        return W, G, newton_rhs(active, couplings, self.c_n, self.M.array, self.g.array,
                                self.free)

    def _petsc(
        self, pattern: tuple[scipy.sparse.csr_matrix, np.ndarray], mat: scipy.sparse.csr_matrix,
        cols: tuple[int, int | None], offset: int,
    ) -> PETSc.Mat:
        """``mat`` (owned rows) in the fixed ``pattern`` as a PETSc AIJ matrix, zeros kept.

        Columns are shifted by ``offset`` (the multiplier block's first global row).
        """
        shape, keys = pattern
        mat = mat.tocoo()
        values = np.zeros(len(keys))
        values[np.searchsorted(keys, mat.row.astype(np.int64) * mat.shape[1] + mat.col)] = (
            mat.data
        )
        out = PETSc.Mat().createAIJ(
            size=((shape.shape[0], None), cols),
            csr=(
                shape.indptr.astype(PETSc.IntType),
                (shape.indices + offset).astype(PETSc.IntType),
                values,
            ),
            comm=self.disc.comm,
        )
        out.assemble()
        return out

    def newton_matrix(self, W: scipy.sparse.csr_matrix, G: scipy.sparse.csr_matrix) -> PETSc.Mat:
        """The Newton matrix [K, N^T; W N, G] of the step (module docstring); a new matrix.

        Its pattern is the same for every step (module docstring).
        """
        B = self._petsc(self._B_pattern, W @ self._N, self.N.getSizes()[1], 0)
        G_mat = self._petsc(self._G_pattern, G, (self.n_lam, None), self._lo)
        nest = PETSc.Mat().createNest([[self.K, self.NT], [B, G_mat]], comm=self.disc.comm)
        A = PETSc.Mat()
        nest.convert("aij", out=A)
        for obj in (nest, B, G_mat):
            obj.destroy()
        return A

    def solve_active(
        self, active: np.ndarray, free: np.ndarray | None = None,
        couplings: list[Coupling] | None = None,
    ) -> None:
        """One Newton step: the constrained rows, the free values and the coupled facets.

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots (a singular Newton matrix).
            LinearSolveError: The solve failed.
        """
        couplings = list(couplings or [])
        with timed("assemble"):
            self.active = active.copy()
            self.couplings = couplings
            self.free = np.zeros(self.n_lam) if free is None else np.where(active, 0.0, free)
            for cp in couplings:
                self.free[cp.rows.ravel()] = 0.0
            W, G, h = self._blocks(active, couplings)
            self.write(self.b, self.f.array, h)
            A = self.newton_matrix(W, G)
            if self.A is None:
                self.A = A
            else:  # the same pattern: the factorisation's analysis is kept
                A.copy(self.A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
                A.destroy()
        self.solved = False
        self._solve_step()

    def _factor(self) -> None:
        """Factor the last step's matrix.

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots (a singular Newton matrix).
        """
        self._current = True
        self.factors.factor(self.A)

    def _changed_rows(self) -> np.ndarray:
        """Global rows in which the step's matrix differs from the factored one (all ranks)."""
        ptr, _, new = self.A.getValuesCSR()
        _, _, old = self.factors.matrix.getValuesCSR()
        lengths = np.diff(ptr)
        differs = np.repeat(np.arange(len(lengths)), lengths)[new != old]
        local = self.A.getOwnershipRange()[0] + np.unique(differs)
        return np.sort(np.concatenate(self.disc.comm.allgather(local))).astype(np.int64)

    def _solve_by_update(self) -> bool:
        """Solve the step with the factors of an earlier one and a row update, if that pays.

        The update (:class:`~.lowrank.RowUpdate`) costs a solve of r right-hand sides with the
        old factors (r the changed rows) and two single solves; it is taken when the system's
        :class:`~.factor.ReusePolicy` finds that it pays (from MUMPS's counts), and its result
        is accepted after iterative refinement (:meth:`~.factor.Factorisation.refine`).

        Returns:
            Whether :attr:`x` holds the step.
        """
        if not self.factors.reusable:
            return False
        rows = self._changed_rows()
        if len(rows) == 0:  # the factored matrix itself (a RowUpdate of rank 0 has no columns)
            with timed("newton solve"):
                self.ksp.solve(self.b, self.x)
            self._current = True
            return self.ksp.getConvergedReason() > 0
        if not self.factors.pays(len(rows)):
            return False
        with timed("newton solve"):
            try:
                update = RowUpdate(self.ksp, self.factors.matrix, self.A, rows)
            except np.linalg.LinAlgError:
                return False
            try:
                update.solve(self.b, self.x)
                accurate = self.factors.refine(self.A, update, self.b, self.x, self.n_u)
            except np.linalg.LinAlgError:
                accurate = False
            finally:
                update.destroy()
        self._current = len(rows) == 0  # the factors are those of this step's matrix
        return accurate

    def _factored_current(self) -> None:
        """Factor the last step's matrix if it was solved by an update (dual, forward)."""
        if not self._current:
            self._factor()

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """Solve A^T z = rhs with the factors of the last step (the dual problem)."""
        self.check_solved()
        self._factored_current()
        self.ksp.solveTranspose(rhs, z)
        self.factors.check("the dual solve")

    def solve_forward(self, rhs: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve A x = rhs with the factors of the last step."""
        self.check_solved()
        self._factored_current()
        self.ksp.solve(rhs, x)
        self.factors.check("the solve with the Newton matrix")

    @property
    def n_lam_global(self) -> int:
        """Multiplier rows on all ranks."""
        return self.disc.comm.allreduce(self.n_lam, op=MPI.SUM)
