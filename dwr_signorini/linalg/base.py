"""What the linear solvers of the Newton steps share: the algebra, the options, the block layout.

Also what more than one of them uses: :class:`LinearSolveError`, the preconditioners that do
not suit a block Newton matrix (:data:`MULTIGRID`) and a rank's rows of a matrix
(:func:`owned_rows`).

A Newton system (:class:`~dwr_signorini.linalg.block.NewtonSystem`,
:class:`~dwr_signorini.linalg.schur.SchurNewtonSystem`) solves, for an active set A, the
linear system of one semi-smooth Newton step

    K u + N^T lam = f,    (N u)_A = g_A,    lam_I = 0,

into the block vector x = [u; lam] (per rank: owned displacement dofs, then owned multiplier
rows), and the transposed system of the last step (the dual problem, :mod:`dwr_signorini.dual`)
with the same factorisations.

Lifetimes: a system owns its PETSc objects (its :class:`~dwr_signorini.algebra.ContactAlgebra`,
solvers, vectors) and its options (:class:`~dwr_signorini.linalg.options.OptionsScope`), and
releases them in :meth:`NewtonLinearSystem.destroy`, which is collective. Nothing is destroyed
from ``__del__``, and no helper holds a reference back to its system, so no reference cycle
keeps PETSc objects alive; an object dropped without ``destroy()`` is released by petsc4py's
deferred, collective garbage collection (``PETSc.garbage_cleanup``).
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.sparse
from dolfinx import fem

from ..algebra import ContactAlgebra
from ..lifetime import destroy_attributes
from ..spaces import Discretization
from .options import OptionsScope, default_petsc_options, unique_prefix

__all__ = ["MULTIGRID", "LinearSolveError", "NewtonLinearSystem", "owned_rows"]

#: Multigrid preconditioners: for K (``method="schur"``, ``"krylov"``), not for a block Newton
#: matrix with its zero multiplier block.
MULTIGRID = ("gamg", "hypre", "ml", "mg")


class LinearSolveError(RuntimeError):
    """A linear solve of a Newton step failed (the Newton loop adds its history)."""


def owned_rows(mat: PETSc.Mat) -> scipy.sparse.csr_matrix:
    """The rows of ``mat`` this rank owns, with global column indices, as a scipy matrix."""
    indptr, indices, values = mat.getValuesCSR()
    shape = (len(indptr) - 1, mat.getSize()[1])
    return scipy.sparse.csr_matrix((values, indices, indptr), shape=shape)


def _defaults_for(tdim: int, options: dict[str, Any] | None) -> dict[str, Any]:
    """The default options, without the factorisation's when ``options`` choose another PC."""
    defaults = default_petsc_options(tdim)
    if (options or {}).get("pc_type", defaults["pc_type"]) not in ("lu", "cholesky"):
        defaults = {
            k: v
            for k, v in defaults.items()
            if k != "pc_factor_mat_solver_type" and not k.startswith("mat_mumps_")
        }
    return defaults


class NewtonLinearSystem:
    """Base of the Newton systems: algebra, options scope, block vector, active set.

    Args:
        disc: The discretisation.
        petsc_options: Options of the linear solver, merged on top of
            :func:`~dwr_signorini.linalg.options.default_petsc_options`.
        V: The displacement space (default ``disc.V``).
        prefix: The options prefix (default: a new unique ``dwr_signorini_<n>_``).
        ncp_scale: c of the NCP function (20): ``"physical"`` (c_n,i = E / H_i) or a number.
        compile_options: ``form_compiler_options`` and ``jit_options`` for the forms.
        algebra: The algebra of ``disc`` and ``V``, assembled already (e.g. for a memory
            probe, :mod:`~dwr_signorini.linalg.memory`); the system takes it over and
            destroys it. None: assembled here.

    Attributes:
        algebra: K, N, N^T, M, f, g, c_n of this mesh and space.
        prefix: The options prefix of the linear solver.
        options: The options in effect (defaults and ``petsc_options``).
        ksp: The linear solver (prefix :attr:`prefix`).
        x: Block vector [u; lam] of the last Newton step (split it with :meth:`split`).
        active: Active set of the last Newton step (owned multiplier rows).
        couplings: The coupled facets of the last step (:class:`~dwr_signorini.laws.Coupling`;
            empty on the symmetric paths).
        solved: Whether a Newton step was solved, so that :meth:`solve_transpose` can reuse
            its factorisation.
    """

    #: Attributes holding PETSc objects (besides the algebra), destroyed by :meth:`destroy`.
    _petsc_objects: tuple[str, ...] = ("ksp", "x")

    def __init__(
        self,
        disc: Discretization,
        petsc_options: dict[str, Any] | None = None,
        V: fem.FunctionSpace | None = None,
        prefix: str | None = None,
        ncp_scale: str | float = "physical",
        compile_options: dict[str, Any] | None = None,
        algebra: ContactAlgebra | None = None,
    ) -> None:
        self.disc = disc
        self.prefix = unique_prefix() if prefix is None else prefix
        self.algebra: ContactAlgebra | None = algebra
        self._scope: OptionsScope | None = None
        self.solved = False
        try:  # on any failure, what exists so far is destroyed and its options removed
            if self.algebra is None:
                self.algebra = ContactAlgebra(disc, V, ncp_scale, compile_options)
            defaults = self.default_options(_defaults_for(disc.mesh.topology.dim, petsc_options))
            self._scope = OptionsScope(self.prefix, defaults, petsc_options)
            self.options = self._scope.options
            self.ksp = PETSc.KSP().create(disc.comm)
            self._scope.apply(self.ksp)
            n = self.algebra.n_u + self.algebra.n_lam
            self.x = PETSc.Vec().createMPI((n, None), comm=disc.comm)
            self.active = np.zeros(self.algebra.n_lam, dtype=bool)
            self.free = np.zeros(self.algebra.n_lam)
            self.couplings: list[Any] = []  # coupled facets of the last step (laws.Coupling)
            self._setup()
        except BaseException:
            self.destroy()
            raise

    @staticmethod
    def default_options(defaults: dict[str, Any]) -> dict[str, Any]:
        """The default options of this kind of system, from the package's defaults."""
        return defaults

    def _setup(self) -> None:
        """Set up the linear solver (the subclasses'); on failure everything is destroyed."""

    # The algebra's pieces, for the callers that read them off the system.
    @property
    def V(self) -> fem.FunctionSpace:
        """The displacement space."""
        return self.algebra.V

    @property
    def bcs(self) -> list[fem.DirichletBC]:
        """Homogeneous Dirichlet conditions on V."""
        return self.algebra.bcs

    @property
    def n_u(self) -> int:
        """Owned displacement dofs of this rank."""
        return self.algebra.n_u

    @property
    def n_lam(self) -> int:
        """Owned multiplier rows of this rank."""
        return self.algebra.n_lam

    @property
    def K(self) -> PETSc.Mat:
        """The stiffness matrix."""
        return self.algebra.K

    @property
    def N(self) -> PETSc.Mat:
        """The coupling matrix N."""
        return self.algebra.N

    @property
    def NT(self) -> PETSc.Mat:
        """N^T, assembled."""
        return self.algebra.NT

    @property
    def f(self) -> PETSc.Vec:
        """The load vector."""
        return self.algebra.f

    @property
    def M(self) -> PETSc.Vec:
        """The diagonal of M (sizes of the macro contact facets)."""
        return self.algebra.M

    @property
    def g(self) -> PETSc.Vec:
        """The gap vector."""
        return self.algebra.g

    @property
    def c_n(self) -> np.ndarray:
        """c_n,i of the NCP function (20) on the owned multiplier rows."""
        return self.algebra.c_n

    def split(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray]:
        """Owned parts (u, lam) of a block vector."""
        return x.array_r[: self.n_u], x.array_r[self.n_u :]

    def write(self, out: PETSc.Vec, u: np.ndarray, lam: np.ndarray) -> None:
        """Write owned parts (u, lam) into a block vector."""
        arr = out.array_w
        arr[: self.n_u] = u
        arr[self.n_u :] = lam

    def set_loose(self, loose: bool) -> bool:
        """Loose or full-accuracy linear solves; direct solvers are always exact.

        Returns:
            Whether the following Newton steps are solved loosely (here never).
        """
        return False

    def refine(self) -> bool:
        """Tighten the tolerance of the following solves, if they are iterative.

        Returns:
            Whether it was tightened (direct solvers: never).
        """
        return False

    def solve_active(
        self, active: np.ndarray, free: np.ndarray | None = None, couplings: Any = None
    ) -> None:
        """One Newton step for the active set ``active`` (owned rows) into :attr:`x`.

        Args:
            active: The constrained rows (active, stick): (B u)_i = g_i there.
            free: The multiplier's values on the other rows (0 where inactive, +-s where a
                frictional law slips); None: all 0.
            couplings: Coupled facets (:class:`~dwr_signorini.laws.Coupling`, a law whose
                Newton matrix is not symmetric): only
                :class:`~dwr_signorini.linalg.coupled.CoupledNewtonSystem` takes them.
        """
        raise NotImplementedError

    def _check_uncoupled(self, couplings: Any) -> None:
        """ValueError if ``couplings`` has a coupled facet: the symmetric paths have none."""
        if any(len(c.rows) for c in couplings or ()):
            raise ValueError(
                f"{type(self).__name__} solves symmetric Newton matrices; coupled rows (Tresca "
                "friction in 3D, Coulomb friction) need CoupledNewtonSystem (method='block')"
            )

    def _set_free(self, active: np.ndarray, free: np.ndarray | None) -> PETSc.Vec | None:
        """Record the free values; B_I^T free_I, their force on the displacement rows, or None.

        The rows of the free multipliers read M_I lam_I = M_I free_I: with lam_I known, their
        columns move to the right-hand side, f - B_I^T free_I. None when every free value is 0
        (frictionless problems: the step is the same, operation by operation).
        """
        self.free = np.zeros(self.n_lam) if free is None else np.where(active, 0.0, free)
        if not self.disc.comm.allreduce(bool(np.any(self.free)), op=MPI.LOR):
            return None
        lam = self.N.createVecLeft()
        lam.array_w[:] = self.free
        force = self.f.duplicate()
        self.NT.mult(lam, force)
        lam.destroy()
        return force

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """Solve A^T z = rhs with the Newton matrix A of the last step (the dual problem).

        Args:
            rhs: Block vector [j_u; j_lam], laid out as :attr:`x`.
            z: Block vector [y; xi] for the solution, laid out as :attr:`x`.

        Raises:
            RuntimeError: No Newton step was solved, or the solve failed.
        """
        raise NotImplementedError

    def _write_dual(
        self, z: PETSc.Vec, y: PETSc.Vec, eta: np.ndarray, j_lam: np.ndarray
    ) -> None:
        """Write the dual z = [y; xi], solved by eliminating the multipliers' rows, into ``z``.

        With eta_A from K y + N_A^T eta_A = j_u, (N y)_A = j_lam,A: xi_A = -eta_A and
        xi_I = (j_lam,I - (N y)_I) / M_I, the inactive rows of A^T (see
        :mod:`~dwr_signorini.linalg.schur`).
        """
        n_y = self.N.createVecLeft()
        self.N.mult(y, n_y)
        xi = np.where(self.active, -eta, (j_lam - n_y.array_r) / self.M.array_r)
        self.write(z, y.array_r, xi)
        n_y.destroy()

    def solve_forward(self, rhs: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve A x = rhs with the Newton matrix A of the last step, through its transpose.

        A = L A_s (:meth:`~dwr_signorini.linalg.block.NewtonSystem.newton_matrix`), and
        :meth:`solve_transpose` computes z = L^-T A_s^-1 r, so A^-1 b = L^T (A^T)^-1 L^-1 b
        with (L^-1 b)_u = b_u - N_I^T M_I^-1 b_I, (L^-1 b)_A = -b_A, (L^-1 b)_I = b_I and
        (L^T z)_u = z_u, (L^T z)_A = -z_A, (L^T z)_I = z_I + (N z_u)_I / M_I: the same
        factorisations on either path, no new one.
        """
        active, M = self.active, self.M.array
        b_u, b_lam = self.split(rhs)
        lam = self.N.createVecLeft()
        lam.array_w[:] = np.where(active, 0.0, b_lam / M)
        force = self.N.createVecRight()
        self.N.multTranspose(lam, force)
        w = rhs.duplicate()
        self.write(w, b_u - force.array, np.where(active, -b_lam, b_lam))
        self.solve_transpose(w, x)
        force.array_w[:] = self.split(x)[0]
        self.N.mult(force, lam)
        z_lam = x.array_w[self.n_u :]
        z_lam[:] = np.where(active, -z_lam, z_lam + lam.array / M)
        for vec in (lam, force, w):
            vec.destroy()

    def check_solved(self) -> None:
        """RuntimeError if no Newton step was solved (no matrix to transpose)."""
        if not self.solved:
            raise RuntimeError("the Newton system has not been solved: no matrix to transpose")

    def destroy(self) -> None:
        """Destroy the PETSc objects and remove the options (collective; idempotent)."""
        destroy_attributes(self, self._petsc_objects)
        if self.algebra is not None:
            self.algebra.destroy()
        if self._scope is not None:
            self._scope.destroy()
