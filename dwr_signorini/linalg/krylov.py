r"""The Newton step as one saddle-point system, one multigrid cycle per iteration (``"krylov"``).

A Newton step K u + N_A^T lam_A = a, (N u)_A = b_A, lam_I = 0 (a = f, or f - N_I^T free_I
with the free values of a frictional law) is the symmetric indefinite system

    [K, G^T; G, 0] [u; l] = [a; C b_A],    G = C N_A,    lam_A = C l,

with C = diag(c_n), the NCP scale of the rows (E / H_i by default), so that both block rows
measure forces and one residual norm weighs them alike. The inactive multiplier rows are the
identity (l_I = 0). It is solved by GMRES, preconditioned from the right by the block upper
triangular

    P = [K~, G^T; 0, -S~],    S~ = ALPHA C (N diag(K)^-1 N^T)_AA C,

where K~^-1 is one cycle of algebraic multigrid on K (the solver of ``petsc_options``, by
default :func:`~dwr_signorini.linalg.options.iterative_petsc_options`: GAMG, smoothed
aggregation with the rigid body modes, set up once per mesh) and S~ is the sparse Jacobi
approximation of the Schur complement G K^-1 G^T, factored once per active set (its size is the
number of multipliers). A GMRES iteration costs one multigrid cycle, one product with K and N,
and a solve with the small factors: about one CG iteration on K. Nothing of the size of K is
factored and nothing dense is stored, so memory grows linearly with the mesh.

The path of :class:`~dwr_signorini.linalg.schur.SchurNewtonSystem` with a Krylov solver of K
(``method="schur"`` with ``iterative_petsc_options()``) solves S_AA by CG with an accurate K
solve in every iteration. On example 5.3 at 146k DoFs (238 active facets, 1 rank) one Newton
step from zero took there 9.8 (loose) and 27.8 (accurate) times one CG + GAMG solve of K, and
here 1.1 and 2.1 (``benchmarks/krylov_saddle.py``). ALPHA = 3 was the best of 1, 2, 3, 4 and 8
there (accurate step: 2.58, 2.37, 2.06, 2.25, 2.69 K solves): the Jacobi approximation
underestimates the compliance of the contact facets.

The dual problem (the transposed Newton matrix; K symmetric) reads, with eta_A = -xi_A,

    K y + N_A^T eta_A = j_u,    (N y)_A = j_lam,A,    xi_I = (j_lam,I - (N y)_I) / M_I,

the same saddle-point system with other data, solved the same way.
"""

from __future__ import annotations

from typing import Any

from petsc4py import PETSc

import numpy as np

from ..timing import timed
from .base import LinearSolveError, NewtonLinearSystem
from .jacobi import check_independent, factor_on_active, jacobi_schur_approximation
from .mumps import mumps_failure, set_up
from .nullspace import rigid_body_modes
from .options import LOOSE_RTOL, SCHUR_KRYLOV_OPTIONS, OptionsScope, iterative_petsc_options

__all__ = ["ALPHA", "SADDLE_KRYLOV_OPTIONS", "KrylovNewtonSystem"]

#: The tightest relative tolerance :meth:`KrylovNewtonSystem.refine` sets (round-off below it).
TIGHTEST_RTOL = 1e-14

#: The scale of the Jacobi approximation of the Schur complement in the preconditioner.
ALPHA = 3.0

#: Defaults of the GMRES on the saddle-point system (prefix ``<prefix>saddle_``).
SADDLE_KRYLOV_OPTIONS: dict[str, Any] = {
    "ksp_type": "gmres",
    "ksp_pc_side": "right",
    "ksp_norm_type": "unpreconditioned",
    "ksp_gmres_restart": 300,
    "ksp_rtol": 1e-10,
    "ksp_atol": 0.0,
    "ksp_max_it": 3000,
}

#: Defaults of the factorisation of S~ (prefix ``<prefix>schur_``): that of the Schur path's CG.
_FACTOR_OPTIONS = {k: v for k, v in SCHUR_KRYLOV_OPTIONS.items() if not k.startswith("ksp_")}


class _Masks:
    """The active set as the arrays the operator and the preconditioner use (owned rows)."""

    def __init__(self, n_lam: int) -> None:
        self.active = np.zeros(n_lam, dtype=bool)
        self.scale = np.zeros(n_lam)  # c_n on active rows, 0 on the others
        self.inactive = np.ones(n_lam)

    def set(self, active: np.ndarray, c_n: np.ndarray) -> None:
        self.active = active.copy()
        self.scale = np.where(active, c_n, 0.0)
        self.inactive = (~active).astype(float)


class _SaddleOperator:
    """Context of the python matrix [K, G^T; G, P_I] on the block vector [u; l]."""

    def __init__(self, system: KrylovNewtonSystem) -> None:
        self.system = system
        self.K, self.N, self.NT = system.K, system.N, system.NT
        self.n_u = system.n_u
        self._u, self._Ku = self.K.createVecRight(), self.K.createVecRight()
        self._l, self._Nu = self.N.createVecLeft(), self.N.createVecLeft()

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """The product [K x_u + G^T x_l; G x_u + P_I x_l] into y."""
        masks = self.system.masks
        xa, ya = x.array_r, y.array_w
        self._u.array_w[:] = xa[: self.n_u]
        self._l.array_w[:] = masks.scale * xa[self.n_u :]
        self.K.mult(self._u, self._Ku)
        self.NT.multAdd(self._l, self._Ku, self._Ku)
        self.N.mult(self._u, self._Nu)
        ya[: self.n_u] = self._Ku.array_r
        ya[self.n_u :] = masks.scale * self._Nu.array_r + masks.inactive * xa[self.n_u :]

    def destroy(self, mat: PETSc.Mat) -> None:
        """Destroy the work vectors with the python matrix."""
        for vec in (self._u, self._Ku, self._l, self._Nu):
            vec.destroy()


class _BlockTriangular:
    """Context of the python preconditioner P^-1: y_l = -S~^-1 r_l, y_u = K~^-1 (r_u - G^T y_l)."""

    def __init__(self, system: KrylovNewtonSystem) -> None:
        self.system = system
        self.n_u = system.n_u
        self._r, self._y = system.K.createVecRight(), system.K.createVecRight()
        self._t, self._s = system.N.createVecLeft(), system.N.createVecLeft()
        self._force = system.K.createVecRight()

    def apply(self, pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """One application: a solve with the factors of S~ and one multigrid cycle."""
        system, masks = self.system, self.system.masks
        xa, ya = x.array_r, y.array_w
        r_l = xa[self.n_u :]
        # S~ = ALPHA C S_hat C on the active rows: l = -C^-1 S_hat^-1 C^-1 r / ALPHA.
        c = np.where(masks.active, masks.scale, 1.0)
        self._t.array_w[:] = np.where(masks.active, r_l / c, 0.0)
        system.factor_ksp.getPC().apply(self._t, self._s)
        y_l = np.where(masks.active, -self._s.array_r / (ALPHA * c), r_l)
        self._t.array_w[:] = masks.scale * y_l
        self._r.array_w[:] = xa[: self.n_u]
        system.NT.mult(self._t, self._force)
        self._r.axpy(-1.0, self._force)
        system.ksp.getPC().apply(self._r, self._y)
        ya[: self.n_u] = self._y.array_r
        ya[self.n_u :] = y_l

    def destroy(self, pc: PETSc.PC) -> None:
        """Destroy the work vectors with the python preconditioner."""
        for vec in (self._r, self._y, self._t, self._s, self._force):
            vec.destroy()


class KrylovNewtonSystem(NewtonLinearSystem):
    """``method="krylov"``: each Newton step and the dual as one saddle-point system by GMRES.

    Args:
        disc, petsc_options, V, kwargs: See
            :class:`~dwr_signorini.linalg.base.NewtonLinearSystem`.

    Attributes:
        masks: The active set of the last step as the operator's arrays.
        iterations: GMRES iterations so far (all steps and dual solves).
        direct: False (nothing of the size of K is factored).

    See the module docstring. ``petsc_options`` are for the multigrid of K (defaults
    :func:`~dwr_signorini.linalg.options.iterative_petsc_options`; only its preconditioner is
    used); the GMRES reads ``<prefix>saddle_`` options (defaults :data:`SADDLE_KRYLOV_OPTIONS`),
    the factorisation of S~ ``<prefix>schur_`` options.
    """

    _petsc_objects = (
        "saddle_ksp",
        "factor_ksp",
        "_operator",
        "_P",
        "_S_hat",
        "_rhs",
        "_sol",
        *NewtonLinearSystem._petsc_objects,
        "_near_nullspace",
    )

    direct = False

    @staticmethod
    def default_options(defaults: dict[str, Any]) -> dict[str, Any]:
        """The multigrid options of K, in place of the package's direct defaults."""
        return iterative_petsc_options()

    def _setup(self) -> None:
        """The multigrid of K (once per mesh), S_hat, the operator and the GMRES."""
        self.masks = _Masks(self.n_lam)
        self.iterations = 0
        self._P: PETSc.Mat | None = None
        self._near_nullspace = rigid_body_modes(self.V, self.n_u)
        self.K.setNearNullSpace(self._near_nullspace)
        with timed("factorize"):
            try:
                set_up(self.ksp, self.K)
            except PETSc.Error as err:
                raise LinearSolveError(
                    "the multigrid preconditioner of the stiffness matrix K could not be set "
                    f"up: {mumps_failure(self.ksp) or err}"
                ) from err
            self._S_hat = jacobi_schur_approximation(self.algebra)
        self._scopes = [
            OptionsScope(self.prefix + "schur_", _FACTOR_OPTIONS),
            OptionsScope(self.prefix + "saddle_", SADDLE_KRYLOV_OPTIONS),
        ]
        comm = self.disc.comm
        self.factor_ksp = PETSc.KSP().create(comm)
        self._scopes[0].apply(self.factor_ksp)
        n = self.n_u + self.n_lam
        self._operator = PETSc.Mat().createPython(((n, None), (n, None)), comm=comm)
        self._operator.setPythonContext(_SaddleOperator(self))
        self._operator.setUp()
        self.saddle_ksp = PETSc.KSP().create(comm)
        self.saddle_ksp.setOperators(self._operator)
        pc = self.saddle_ksp.getPC()
        pc.setType("python")
        pc.setPythonContext(_BlockTriangular(self))
        self._scopes[1].apply(self.saddle_ksp)
        self._rtol = self.saddle_ksp.getTolerances()[0]
        self._rhs, self._sol = self._operator.createVecs()

    def set_loose(self, loose: bool) -> bool:
        """The GMRES to at least the loose tolerance of the Schur path's S_AA, or to its own.

        Returns:
            ``loose``.
        """
        rtol = max(self._rtol, LOOSE_RTOL[1]) if loose else self._rtol
        self.saddle_ksp.setTolerances(rtol=rtol)
        return loose

    def refine(self) -> bool:
        """The GMRES tolerance a hundredfold tighter, down to :data:`TIGHTEST_RTOL`.

        Returns:
            Whether it was tightened.
        """
        rtol = self.saddle_ksp.getTolerances()[0]
        if rtol <= TIGHTEST_RTOL:
            return False
        self.saddle_ksp.setTolerances(rtol=max(rtol / 100.0, TIGHTEST_RTOL))
        return True

    def _set_active(self, active: np.ndarray) -> None:
        """The masks of ``active`` and the factors of S_hat on it (null pivots: LinAlgError)."""
        self.masks.set(active, self.c_n)
        self._P = factor_on_active(self.factor_ksp, self._S_hat, active, self._P)
        check_independent(self.factor_ksp)

    def _solve(self, a: np.ndarray, b: np.ndarray, guess: tuple | None) -> tuple:
        """[u; lam_A] of K u + N_A^T lam_A = a, (N u)_A = b_A (owned arrays) by the GMRES."""
        masks = self.masks
        self._rhs.array_w[: self.n_u] = a
        self._rhs.array_w[self.n_u :] = masks.scale * b
        self.saddle_ksp.setInitialGuessNonzero(guess is not None)
        if guess is not None:
            c = np.where(masks.active, masks.scale, 1.0)
            self._sol.array_w[: self.n_u] = guess[0]
            self._sol.array_w[self.n_u :] = np.where(masks.active, guess[1] / c, 0.0)
        self.saddle_ksp.solve(self._rhs, self._sol)
        self.iterations += self.saddle_ksp.getIterationNumber()
        reason = self.saddle_ksp.getConvergedReason()
        if reason < 0:
            raise LinearSolveError(
                f"GMRES on the saddle-point system did not converge (KSP reason {reason}, "
                f"{self.saddle_ksp.getIterationNumber()} iterations)"
            )
        u, scaled = self.split(self._sol)
        return u.copy(), masks.scale * scaled

    def solve_active(
        self, active: np.ndarray, free: np.ndarray | None = None, couplings: Any = None
    ) -> None:
        """One Newton step for ``active``, warm-started from the last, into :attr:`x`.

        With free values (friction) the load is f - B_I^T free_I, and lam_I = free_I.
        """
        self._check_uncoupled(couplings)
        with timed("newton solve"):
            guess = self.split(self.x) if self.solved else None
            self._set_active(active)
            self.active = active.copy()
            force = self._set_free(active, free)
            load = self.f.array_r if force is None else self.f.array_r - force.array_r
            if force is not None:
                force.destroy()
            u, lam = self._solve(load, self.g.array_r, guess)
            self.write(self.x, u, lam + self.free)
        self.solved = True

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """A^T z = rhs, the dual problem (:meth:`.NewtonLinearSystem.solve_transpose`)."""
        self.check_solved()
        j_u, j_lam = self.split(rhs)
        try:
            y, eta = self._solve(j_u, j_lam, None)
        except LinearSolveError as err:
            raise RuntimeError(f"the dual solve failed: {err}") from err
        u = self.K.createVecRight()
        u.array_w[:] = y
        self._write_dual(z, u, eta, j_lam)
        u.destroy()

    def destroy(self) -> None:
        """Destroy the PETSc objects and remove the options (collective; idempotent)."""
        super().destroy()
        for scope in getattr(self, "_scopes", ()):
            scope.destroy()
        self._scopes = []

