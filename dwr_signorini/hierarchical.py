r"""The P2 solutions of the higher-order weights, by a two-level solver instead of a factorisation.

``weights="higher_order"`` solves the dual problem (11)-(12), and for eta the primal one, in P2
on T_h (with Lambda_H and the final active set) by a factorisation of the P2 system, which in 3D
costs many times the P1 level. ``weights="hierarchical"`` solves the same two P2 systems, to a
relative residual of :data:`HIERARCHICAL_RTOL`, by FGMRES preconditioned with a two-level cycle
on P1 subset P2 (a p-multigrid cycle; on Q2 the coarse space is Q1):

1. *smoothing*: :data:`SMOOTHING_STEPS` Chebyshev steps with Jacobi on the P2 stiffness
   matrix (on all its unknowns);
2. *coarse step*: the residual tested with the P1 functions (P^T r, P the interpolation
   P1 -> P2) and with the multipliers, corrected by the Newton matrix of the last step (the
   primal) or its transpose (the dual), with the factorisations the P1 dual already used
   (:mod:`~dwr_signorini.dual`);
3. the smoothing again.

The operator is the Newton matrix of the final sets for every law: a law with coupled rows
(Coulomb friction, Tresca friction in 3D) brings its slipping facets' rows
(:func:`~dwr_signorini.linalg.coupled.newton_rows`), and the coarse step its P1 LU factors.
The dual's unknowns are y and the multiplier xi^(1) of the Newton system's scaling (c = 1 in
b_h, see :mod:`~dwr_signorini.residuals`): xi = xi^(1) / c on the active facets; the primal's
are the correction of w_h. The iterations start from z_h and w_h written in P2. No matrix of
the size of the P2 system is factored: each iteration costs two smoothing steps, one solve with
the existing factors and a few sparse matrix-vector products.
``tests/test_hierarchical.py`` checks both solutions against the directly solved P2 systems.
On coarse 3D meshes where the patch-wise recovery of z_h misses the first contact
(``benchmarks/weights_3d.py``) it gives the estimate of the higher-order weights, in a third to
a seventh of their time on the indentation there; with hundreds of active multipliers
(example 5.3) FGMRES needs more iterations and the factorisation is as fast.
"""

from __future__ import annotations

import math
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .algebra import ContactAlgebra
from .dual import DualSolution, dual_rhs
from .force import ForceControl
from .goal import GoalForms
from .lifetime import Releasable, destroy_attributes
from .linalg.coupled import newton_rhs, newton_rows
from .linalg.options import OptionsScope, unique_prefix
from .newton import Solution
from .timing import timed

__all__ = ["HIERARCHICAL_RTOL", "HierarchicalP2", "hierarchical_solutions"]

#: Relative residual of the P2 systems at which ``weights="hierarchical"`` stops. With the
#: Chebyshev smoother a residual of 1e-3 left eta 1.7 % from the factored P2 weights' on a level
#: of the strip of ``tests/test_hierarchical.py``; 1e-4 left at most 3.6e-4 there and 2e-5 on
#: the Hertz block of ``benchmarks/p2_weights_cost.py`` (41k P1 DoFs, nu = 0.49).
HIERARCHICAL_RTOL = 1e-4

#: The bordered systems of an obstacle under a given force solve each of their P2 systems to
#: this fraction of the tolerance: z = z1 - zeta z2 (:mod:`~dwr_signorini.force`) may cancel.
BORDERED_RTOL_FACTOR = 0.1

#: Relative to the right-hand side: a residual of w_h below it counts as solved (round-off).
ROUNDOFF = 1e-12

#: Chebyshev steps (Jacobi-preconditioned, on all P2 unknowns) of one smoothing step. Measured
#: on the nearly incompressible Hertz block of ``benchmarks/p2_weights_cost.py`` (147k P1 DoFs,
#: nu = 0.49), FGMRES iterations of the dual and the primal: 36 and 24 with one SOR sweep on the
#: edge unknowns only, 21 and 13 with one SOR sweep on all P2 unknowns, 13 and 8 with three;
#: 22 and 14 with two Chebyshev steps, 15 and 9 with four, 11 and 7 with eight. A Chebyshev step
#: costs one product with K_2, a symmetric SOR sweep about six.
SMOOTHING_STEPS = 4

#: The smoother's options: Chebyshev on the eigenvalues of diag(K_2)^-1 K_2 in
#: [0.1, 1.1] x the largest one, estimated by a few Krylov steps (rank-count independent, unlike
#: SOR, which sweeps per process).
SMOOTHER = {
    "ksp_type": "chebyshev",
    "pc_type": "jacobi",
    "ksp_max_it": SMOOTHING_STEPS,
    "ksp_norm_type": "none",
    "ksp_chebyshev_esteig": "0,0.1,0,1.1",
}

#: Most FGMRES iterations on a P2 system.
MAX_ITERATIONS = 200


def _smoother(K2: PETSc.Mat) -> PETSc.KSP:
    """:data:`SMOOTHING_STEPS` Chebyshev steps with Jacobi on K_2 from zero (:data:`SMOOTHER`)."""
    scope = OptionsScope(unique_prefix(), SMOOTHER)
    ksp = PETSc.KSP().create(K2.getComm())
    try:
        ksp.setOperators(K2)
        scope.apply(ksp)
    except BaseException:
        ksp.destroy()
        raise
    finally:
        scope.destroy()
    return ksp


class _P2System:
    """The P2 Newton system of the final active set (or its transpose) and its solver.

    FGMRES with the two-level preconditioner, on one solution; the matrices serve both solves.
    Unknowns [u (P2, owned dofs); lambda (owned multipliers)]. With the P2 stiffness K_2 and
    coupling N_2 (Dirichlet rows and columns removed, as in the P1 system) the Newton matrix of
    :mod:`~dwr_signorini.linalg` is A = [[K_2, N_2^T], [W N_2, G]], with the multiplier rows
    W, G of the final sets and the law's coupled facets
    (:func:`~dwr_signorini.linalg.coupled.newton_rows`: W = -D_A, G = D_I M for a symmetric
    law; the rows -c J N_2, (I - J) M of a slipping facet otherwise), the matrix the factored
    P2 system of ``weights="higher_order"`` builds; with :attr:`transpose` the solver works on
    A^T = [[K_2, N_2^T W^T], [N_2, G^T]], the dual system of :mod:`~dwr_signorini.dual`, whose
    multiplier is xi^(1) on the constrained rows.
    """

    _petsc_objects = ("P", "smoother", "r_s", "d_s", "ksp", "op", "b", "x", "rhs1", "z1")

    def __init__(self, sol: Solution, V2: fem.FunctionSpace) -> None:
        self.disc, self.system, self.V2 = sol.disc, sol.system, V2
        self.transpose = True
        self.algebra: ContactAlgebra | None = None
        try:  # a failure in the set-up releases what was made (collective)
            self._set_up(sol, V2)
        except BaseException:
            self.destroy()
            raise

    def _set_up(self, sol: Solution, V2: fem.FunctionSpace) -> None:
        """The P2 algebra, the prolongation P, the smoother and the FGMRES solver."""
        disc, system = self.disc, self.system
        # K_2, N_2, f_2, g on V2: what the factored P2 solve of weights="higher_order" uses.
        self.algebra = ContactAlgebra(disc, V2, sol.ncp_scale)
        self.K2, self.N2 = self.algebra.K, self.algebra.N
        self.P = fem_petsc.interpolation_matrix(disc.V, V2)
        self.P.assemble()
        self.smoother = _smoother(self.K2)
        self.r_s, self.d_s = self.K2.createVecs()

        self.n2 = self.K2.getLocalSize()[0]
        self.n_lam = system.n_lam
        self.W, self.G = newton_rows(system.active, system.couplings, self.algebra.c_n,
                                     self.algebra.M.array)
        self.WT, self.GT = self.W.T.tocsr(), self.G.T.tocsr()
        n = self.n2 + self.n_lam
        self.op = PETSc.Mat().createPython(((n, None), (n, None)), comm=disc.comm)
        self.op.setPythonContext(_Operator(self))
        self.op.setUp()
        self.b, self.x = self.op.createVecs()
        self.rhs1 = system.x.duplicate()
        self.z1 = system.x.duplicate()

        self.ksp = PETSc.KSP().create(disc.comm)
        self.ksp.setOperators(self.op)
        self.ksp.setType("fgmres")
        self.ksp.setGMRESRestart(MAX_ITERATIONS)
        pc = self.ksp.getPC()
        pc.setType("python")
        pc.setPythonContext(_TwoLevel(self))
        self.ksp.setInitialGuessNonzero(True)

    # -- pieces on owned arrays ------------------------------------------------------------
    def _u_vec(self, arr: np.ndarray) -> PETSc.Vec:
        return PETSc.Vec().createWithArray(arr, size=(self.n2, None), comm=self.disc.comm)

    def _lam_vec(self, arr: np.ndarray) -> PETSc.Vec:
        return PETSc.Vec().createWithArray(arr, size=(self.n_lam, None), comm=self.disc.comm)

    def apply(self, x: np.ndarray, out: np.ndarray) -> None:
        """A (or A^T with :attr:`transpose`) applied to x, into ``out`` (owned arrays)."""
        u, lam = x[: self.n2], x[self.n2 :]
        u_vec, out_u = self._u_vec(np.ascontiguousarray(u)), self._u_vec(out[: self.n2])
        # A^T couples N^T W^T xi into the displacement rows, A couples N^T lambda.
        lam_vec = self._lam_vec(np.ascontiguousarray(self.WT @ lam if self.transpose else lam))
        out_lam = self._lam_vec(out[self.n2 :])
        tmp = out_u.duplicate()
        self.K2.mult(u_vec, out_u)
        self.N2.multTranspose(lam_vec, tmp)
        out_u.axpy(1.0, tmp)
        self.N2.mult(u_vec, out_lam)
        n_u = out_lam.array if self.transpose else self.W @ out_lam.array
        out[: self.n2] = out_u.array
        out[self.n2 :] = n_u + (self.GT if self.transpose else self.G) @ lam
        for vec in (u_vec, out_u, lam_vec, out_lam, tmp):
            vec.destroy()

    def smooth(self, r: np.ndarray) -> np.ndarray:
        """One smoothing step for K_2 d = r (owned P2 arrays)."""
        self.r_s.array_w[:] = r
        self.smoother.solve(self.r_s, self.d_s)
        return self.d_s.array_r.copy()

    def coarse_solve(self, r_u: np.ndarray, r_lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The P1 correction by the factors of the last Newton step: (P d_u, d_lam).

        The Newton matrix (:meth:`~dwr_signorini.linalg.base.NewtonLinearSystem.solve_forward`)
        or its transpose (``solve_transpose``) of the P1 system, on the residual tested with
        the P1 functions.
        """
        system = self.system
        r_vec = self._u_vec(np.ascontiguousarray(r_u))
        r_1 = self.P.createVecRight()
        self.P.multTranspose(r_vec, r_1)
        for bc in system.bcs:
            bc.set(r_1.array_w, alpha=0.0)
        system.write(self.rhs1, r_1.array[: system.n_u], r_lam)
        if self.transpose:
            system.solve_transpose(self.rhs1, self.z1)
        else:
            system.solve_forward(self.rhs1, self.z1)
        d_u, d_lam = (a.copy() for a in system.split(self.z1))
        r_1.array_w[:] = 0.0
        r_1.array_w[: system.n_u] = d_u
        out = r_vec.duplicate()
        self.P.mult(r_1, out)
        d_2 = out.array.copy()
        for vec in (r_vec, r_1, out):
            vec.destroy()
        return d_2, d_lam

    def written(self, u: fem.Function) -> np.ndarray:
        """The owned values of a function of the P1 space written in P2 (P u)."""
        out = self._u_vec(np.zeros(self.n2))
        self.P.mult(u.x.petsc_vec, out)
        values = out.array.copy()
        out.destroy()
        return values

    def solve(self, transpose: bool, start: np.ndarray, b: np.ndarray, rtol: float,
              atol: float = 0.0) -> np.ndarray:
        """FGMRES on A^T (``transpose``) or A from ``start`` to ``rtol`` (or ``atol``).

        Args:
            transpose: Which of the two.
            start: The initial iterate [u (P2); lambda] (owned values).
            b: The right-hand side, laid out as ``start``.
            rtol: The relative residual to reach (of the norm of ``b``).
            atol: The absolute residual that suffices.

        Returns:
            The solution [u (P2); lambda] (owned values).
        """
        self.transpose = transpose
        self.x.array_w[:] = start
        self.b.array_w[:] = b
        self.ksp.setTolerances(rtol=rtol, atol=atol, max_it=MAX_ITERATIONS)
        self.ksp.solve(self.b, self.x)
        if self.ksp.getConvergedReason() < 0:
            raise RuntimeError(
                f"the hierarchical P2 solve did not converge (KSP reason "
                f"{self.ksp.getConvergedReason()}, {self.ksp.getIterationNumber()} iterations)"
            )
        return self.x.array_r.copy()

    def function(self, values: np.ndarray, name: str) -> fem.Function:
        """The P2 displacement of a solution's owned values [u; lambda]."""
        u = fem.Function(self.V2, name=name)
        u.x.array[: self.n2] = values[: self.n2]
        u.x.scatter_forward()
        return u

    def destroy(self) -> None:
        """Destroy the PETSc objects (collective; idempotent)."""
        destroy_attributes(self, self._petsc_objects)
        if self.algebra is not None:
            self.algebra.destroy()


class _Operator:
    """The P2 operator as a PETSc shell matrix (petsc4py's Python matrix protocol)."""

    def __init__(self, system: _P2System) -> None:
        self.s = system

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.s.apply(x.array_r, y.array_w)


class _TwoLevel:
    """The preconditioner: smoothing, coarse step, smoothing (a symmetric two-level cycle)."""

    def __init__(self, system: _P2System) -> None:
        self.s = system

    def apply(self, pc: PETSc.PC, r: PETSc.Vec, d: PETSc.Vec) -> None:
        s = self.s
        n2 = s.n2
        res = r.array_r.copy()
        out = np.zeros_like(res)
        out[:n2] = s.smooth(res[:n2])
        k = np.empty_like(res)
        s.apply(out, k)
        rest = res - k
        d_u, d_lam = s.coarse_solve(rest[:n2], rest[n2:])
        out[:n2] += d_u
        out[n2:] += d_lam
        s.apply(out, k)
        out[:n2] += s.smooth((res - k)[:n2])
        d.array_w[:] = out


class _Bordered:
    """The two-level P2 system as the system a ForceControl borders.

    An obstacle under a given force (:class:`~dwr_signorini.force.ForceControl`): its ``x``,
    ``split`` and ``solve_transpose``.
    """

    def __init__(self, p2: _P2System, rtol: float) -> None:
        self.p2, self.rtol = p2, rtol
        self.disc, self.algebra, self.n_u = p2.disc, p2.algebra, p2.n2
        self.x = p2.b.duplicate()

    def split(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray]:
        """Owned parts (u, lam) of a vector of the P2 system."""
        return x.array_r[: self.n_u], x.array_r[self.n_u :]

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """A^T z = rhs by FGMRES from z's values."""
        z.array_w[:] = self.p2.solve(True, z.array_r.copy(), rhs.array_r.copy(), self.rtol)

    def destroy(self) -> None:
        """Release the block vector (collective)."""
        self.x.destroy()


def _finite(sol: Solution, values: np.ndarray) -> None:
    finite = bool(np.all(np.isfinite(values)))
    if not sol.disc.comm.allreduce(finite, op=MPI.LAND):
        raise RuntimeError("NaN or Inf in a hierarchical P2 solution")


def _dual(p2: _P2System, sol: Solution, goal: GoalForms, z: DualSolution, rtol: float,
          force: ForceControl | None = None) -> DualSolution:
    """z^(2) from z_h, with the right-hand side of :func:`~dwr_signorini.dual.dual_rhs` on V2.

    With ``force`` the bordered system's dual (:meth:`~dwr_signorini.force.ForceControl.
    solve_transpose`, its unit response x2 solved before).
    """
    system = sol.system
    b = p2.b.duplicate()
    dual_rhs(p2.algebra, goal, b)
    xi = sol.stacked(z.multipliers)
    xi1 = np.where(system.active, xi * system.c_n, xi)
    start = np.concatenate([p2.written(z.y), xi1])
    try:
        if force is None:
            out = p2.solve(True, start, b.array_r.copy(), rtol)
        else:
            zvec = b.duplicate()
            zvec.array_w[:] = start
            force.solve_transpose(b, zvec, goal.rate(sol.disc.fields.obstacle_displacement))
            out = zvec.array_r.copy()
            zvec.destroy()
    finally:
        b.destroy()
    _finite(sol, out)
    xi1 = out[p2.n2 :]
    xi2 = sol.multiplier_functions(np.where(system.active, xi1 / system.c_n, xi1), "xi2")
    return DualSolution(p2.function(out, "y2"), *xi2,
                        zeta=None if force is None else force.zeta)


def _forward(
    p2: _P2System, sol: Solution, free: np.ndarray, rtol: float, start: np.ndarray | None
) -> np.ndarray:
    """A x = [f_2; h] of the P2 algebra's f and g, from ``start`` (or 0).

    h = [-D_A g; M_I free_I] and the coupled facets' rows
    (:func:`~dwr_signorini.linalg.coupled.newton_rhs`, as the factored P2 system's).

    Solved as the correction of ``start``, so ``rtol`` is relative to the residual of the
    start (its rows mix forces and gaps, whose right-hand sides differ by many orders of
    magnitude). Where the start already solves the P2 system (a displacement linear in x, as in
    a patch test) that residual is round-off: the solve then stops at ``ROUNDOFF`` times the
    norm of the right-hand side.

    Returns:
        x = [u (P2); lambda] (owned values).
    """
    system, algebra = sol.system, p2.algebra
    start = np.zeros(p2.n2 + p2.n_lam) if start is None else start
    p2.transpose = False
    residual = np.empty_like(start)
    p2.apply(start, residual)
    # the constrained rows -(B u)_A = -g_A, the free ones M_I lam_I = M_I free_I (0 inactive)
    h = newton_rhs(system.active, system.couplings, algebra.c_n, algebra.M.array,
                   algebra.g.array, free)
    rhs = np.concatenate([algebra.f.array, h])
    g_active = algebra.g.array[system.active]
    rhs_norm = math.sqrt(sol.disc.comm.allreduce(
        float(algebra.f.array @ algebra.f.array + g_active @ g_active), op=MPI.SUM))
    correction = p2.solve(False, np.zeros_like(start), rhs - residual, rtol,
                          atol=ROUNDOFF * rhs_norm)
    return start + correction


def _primal(
    p2: _P2System, sol: Solution, rtol: float, force: ForceControl | None = None
) -> tuple[fem.Function, tuple[fem.Function, ...]]:
    """w^(2) as the correction of w_h in the P2 Newton system of the final active set.

    A [u; lam] = [f_2; -D_A g], with the prescribed Dirichlet values lifted as in the P1 system
    (:class:`~dwr_signorini.algebra.ContactAlgebra` on V2, as for ``weights="higher_order"``),
    from w_h written in P2 (:func:`_forward`). With ``force`` the bordered step from w_h's
    delta (:meth:`~dwr_signorini.force.ForceControl.balance`, its unit response solved before).
    """
    start = np.concatenate([p2.written(sol.u), sol.stacked()])
    out = _forward(p2, sol, sol.system.free, rtol, start)
    if force is not None:
        force.system.x.array_w[:] = out
        force.balance()
        out = force.system.x.array_r.copy()
    _finite(sol, out)
    return p2.function(out, "u2"), sol.multiplier_functions(out[p2.n2 :], "lambda2")


def _solutions(p2: _P2System, sol: Solution, goal: GoalForms, z: DualSolution, primal: bool,
               rtol: float) -> tuple[DualSolution, Any]:
    """The P2 dual (and primal), bordered where an obstacle is under a given force."""
    if sol.obstacle_displacement is None:
        return _dual(p2, sol, goal, z, rtol), _primal(p2, sol, rtol) if primal else None
    rtol = BORDERED_RTOL_FACTOR * rtol
    bordered = _Bordered(p2, rtol)
    force = ForceControl(bordered, move=False)
    try:
        def solve(active: np.ndarray, free: np.ndarray, couplings: Any) -> None:
            bordered.x.array_w[:] = _forward(p2, sol, free, rtol, None)  # a symmetric law

        force.unit_response(solve, sol.system.active, sol.system.free)
        z2 = _dual(p2, sol, goal, z, rtol, force)
        return z2, _primal(p2, sol, rtol, force) if primal else None
    finally:
        force.destroy()
        bordered.destroy()


class HierarchicalP2(Releasable):
    """The two-level P2 solver of one solution's final active set, set up once for every goal.

    The P2 system (K_2, N_2, the prolongation, the edge smoother, FGMRES) and the P2 primal
    w^(2) do not depend on the goal: estimates of several goals at one solution
    (:class:`~dwr_signorini.estimate_parts.EstimateParts`) solve only their dual with it.

    Args:
        sol: The solved discrete problem (its last Newton factorisations are reused).
        V2: The P2 (Q2) vector space on T_h.
        rtol: Relative residual to reach (default :data:`HIERARCHICAL_RTOL`).
    """

    def __init__(self, sol: Solution, V2: fem.FunctionSpace, rtol: float | None = None) -> None:
        self.rtol = HIERARCHICAL_RTOL if rtol is None else rtol
        if not self.rtol > 0:
            raise ValueError(f"rtol must be positive, got {rtol}")
        self.primal: tuple[fem.Function, tuple[fem.Function, ...]] | None = None
        with timed("higher-order solve"):
            self.p2: _P2System | None = _P2System(sol, V2)

    def solutions(
        self, sol: Solution, goal: GoalForms, z: DualSolution, primal: bool
    ) -> tuple[DualSolution, tuple[fem.Function, tuple[fem.Function, ...]] | None]:
        """The P2 dual of ``goal`` from z_h, and the P2 primal (solved once) if ``primal``.

        ``sol`` is the solution the solver was set up for (it holds no reference to it).
        """
        # The coarse step is a preconditioner of a flexible GMRES to rtol: an iterative P1
        # solver (method="krylov") solves it to its loose tolerance; direct solvers are exact.
        loose = sol.system.set_loose(True)
        try:
            with timed("higher-order solve"):
                z2, w2 = _solutions(self.p2, sol, goal, z, primal and self.primal is None,
                                    self.rtol)
        finally:
            if loose:
                sol.system.set_loose(False)
        if w2 is not None:
            self.primal = w2
        return z2, self.primal if primal else None

    def destroy(self) -> None:
        """Release the P2 system (collective; idempotent)."""
        if self.p2 is not None:
            self.p2.destroy()
            self.p2 = None


def hierarchical_solutions(
    sol: Solution,
    goal: GoalForms,
    z: DualSolution,
    V2: fem.FunctionSpace,
    primal: bool,
    rtol: float | None = None,
) -> tuple[DualSolution, tuple[fem.Function, tuple[fem.Function, ...]] | None]:
    """The P2 dual (and primal) of the final active set by the two-level solver (module docstring).

    Args:
        sol: The solved discrete problem (its last Newton factorisations are reused).
        goal: The goal's derivatives at w_h.
        z: z_h = (y_h, xi_H), the P1 dual of the same Newton system, the dual's start.
        V2: The P2 (Q2) vector space on T_h.
        primal: Also solve the primal problem (for eta), from w_h.
        rtol: Relative residual to reach (default :data:`HIERARCHICAL_RTOL`).

    Returns:
        z^(2) = (y, xi) with y in V2, and w^(2) = (u, multipliers) or ``None``.
    """
    with HierarchicalP2(sol, V2, rtol) as solver:
        return solver.solutions(sol, goal, z, primal)
