r"""The P2 solutions of the higher-order weights, by a two-level solver instead of a factorisation.

``weights="higher_order"`` solves the dual problem (11)-(12), and for eta the primal one, in P2
on T_h (with Lambda_H and the final active set) by a factorisation of the P2 system, which in 3D
costs many times the P1 level. ``weights="hierarchical"`` solves the same two P2 systems, to a
relative residual of :data:`HIERARCHICAL_RTOL`, by FGMRES preconditioned with a two-level sweep
in the hierarchical basis of P2 = P1 + span{edge functions} (the P2 nodal functions that vanish
at the vertices; on Q2 those of the edges, faces and cells):

1. *edge step*: one symmetric SOR sweep on the edge block of the P2 stiffness matrix, which is
   well conditioned on every mesh;
2. *coarse step*: the residual tested with the P1 functions (P^T r, P the interpolation
   P1 -> P2) and with the multipliers, corrected by the Newton matrix of the last step (the
   primal) or its transpose (the dual), with the factorisations the P1 dual already used
   (:mod:`~dwr_signorini.dual`);
3. the edge step again.

The dual's unknowns are y and the multiplier xi^(1) of the Newton system's scaling (c = 1 in
b_h, see :mod:`~dwr_signorini.residuals`): xi = xi^(1) / c on the active facets; the primal's
are the correction of w_h. The iterations start from z_h and w_h written in P2. No matrix of
the size of the P2 system is factored: each iteration costs two SOR sweeps on the edge
unknowns, one solve with the existing factors and a few sparse matrix-vector products.
``tests/test_hierarchical.py`` checks both solutions against the directly solved P2 systems.
On coarse 3D meshes where the patch-wise recovery of z_h misses the first contact
(``benchmarks/weights_3d.py``) it gives the estimate of the higher-order weights, in a third to
a seventh of their time on the indentation there; with hundreds of active multipliers
(example 5.3) FGMRES needs more iterations and the factorisation is as fast.
"""

from __future__ import annotations

import math

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem
from dolfinx.cpp import mesh as _cpp_mesh
from dolfinx.fem import petsc as fem_petsc

from .algebra import ContactAlgebra
from .dual import DualSolution, dual_rhs
from .goal import GoalForms
from .lifetime import destroy_attributes
from .newton import Solution
from .timing import timed

__all__ = ["HIERARCHICAL_RTOL", "hierarchical_solutions"]

#: Relative residual of the P2 systems at which ``weights="hierarchical"`` stops.
HIERARCHICAL_RTOL = 1e-3

#: Relative to the right-hand side: a residual of w_h below it counts as solved (round-off).
ROUNDOFF = 1e-12

#: Most FGMRES iterations on a P2 system.
MAX_ITERATIONS = 200


def _edge_index_set(V2: fem.FunctionSpace) -> PETSc.IS:
    """The owned non-vertex dofs of V2 (all components), as global PETSc indices."""
    imap, bs = V2.dofmap.index_map, V2.dofmap.index_map_bs
    layout = V2.dofmap.dof_layout
    num_vertices = _cpp_mesh.cell_num_entities(V2.mesh.topology.cell_type, 0)
    vertex_dofs = [d for i in range(num_vertices) for d in layout.entity_dofs(0, i)]
    is_vertex = np.zeros(imap.size_local + imap.num_ghosts, dtype=bool)
    is_vertex[V2.dofmap.list[:, vertex_dofs].ravel()] = True
    edges = np.flatnonzero(~is_vertex[: imap.size_local]).astype(np.int32)
    blocks = imap.local_to_global(edges)
    indices = (blocks[:, None] * bs + np.arange(bs)[None, :]).ravel().astype(PETSc.IntType)
    return PETSc.IS().createGeneral(indices, comm=V2.mesh.comm)


class _P2System:
    """The P2 Newton system of the final active set (or its transpose) and its solver.

    FGMRES with the two-level preconditioner, on one solution; the matrices serve both solves.
    Unknowns [u (P2, owned dofs); lambda (owned multipliers)]. With the P2 stiffness K_2 and
    coupling N_2 (Dirichlet rows and columns removed, as in the P1 system) the Newton matrix of
    :mod:`~dwr_signorini.linalg` is A = [[K_2, N_2^T], [-D_A N_2, D_I M]]; with
    :attr:`transpose` the solver works on A^T = [[K_2, -N_2^T D_A], [N_2, D_I M]], the dual
    system of :mod:`~dwr_signorini.dual`, whose multiplier is xi^(1).
    """

    _petsc_objects = ("P", "edges", "edge_ksp", "ksp", "op", "b", "x", "rhs1", "z1")

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
        """The P2 algebra, the prolongation P, the edge smoother and the FGMRES solver."""
        disc, system = self.disc, self.system
        # K_2, N_2, f_2, g on V2: what the factored P2 solve of weights="higher_order" uses.
        self.algebra = ContactAlgebra(disc, V2, sol.ncp_scale)
        self.K2, self.N2 = self.algebra.K, self.algebra.N
        self.P = fem_petsc.interpolation_matrix(disc.V, V2)
        self.P.assemble()
        self.edges = _edge_index_set(V2)
        # The edge step: one symmetric SOR sweep on the edge block (per process).
        A_ee = self.K2.createSubMatrix(self.edges, self.edges)
        self.edge_ksp = PETSc.KSP().create(disc.comm)
        self.edge_ksp.setOperators(A_ee)
        self.edge_ksp.setType("richardson")
        self.edge_ksp.getPC().setType("sor")
        self.edge_ksp.setNormType(PETSc.KSP.NormType.NONE)
        self.edge_ksp.setTolerances(max_it=1)
        A_ee.destroy()

        self.n2 = self.K2.getLocalSize()[0]
        self.n_lam = system.n_lam
        self.inactive_mass = np.where(system.active, 0.0, system.M.array)
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
        """The operator applied to x, into ``out`` (owned arrays)."""
        active = self.system.active
        u, lam = x[: self.n2], x[self.n2 :]
        u_vec, out_u = self._u_vec(np.ascontiguousarray(u)), self._u_vec(out[: self.n2])
        # A^T couples -N^T D_A xi into the displacement rows, A couples N^T lambda.
        lam_vec = self._lam_vec(np.ascontiguousarray(-lam * active if self.transpose else lam))
        out_lam = self._lam_vec(out[self.n2 :])
        tmp = out_u.duplicate()
        self.K2.mult(u_vec, out_u)
        self.N2.multTranspose(lam_vec, tmp)
        out_u.axpy(1.0, tmp)
        self.N2.mult(u_vec, out_lam)
        n_u = out_lam.array if self.transpose else np.where(active, -out_lam.array, 0.0)
        out[: self.n2] = out_u.array
        out[self.n2 :] = n_u + self.inactive_mass * lam
        for vec in (u_vec, out_u, lam_vec, out_lam, tmp):
            vec.destroy()

    def edge_solve(self, r: np.ndarray) -> np.ndarray:
        """One smoothing step for A_ee d_e = r_e, as a full P2 array (zero at the vertices)."""
        r_vec = self._u_vec(np.ascontiguousarray(r))
        d_vec = r_vec.duplicate()
        d_vec.zeroEntries()
        r_e, d_e = r_vec.getSubVector(self.edges), d_vec.getSubVector(self.edges)
        self.edge_ksp.solve(r_e, d_e)
        r_vec.restoreSubVector(self.edges, r_e)
        d_vec.restoreSubVector(self.edges, d_e)
        out = d_vec.array.copy()
        for vec in (r_vec, d_vec):
            vec.destroy()
        return out

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

    def solve(self, transpose: bool, u0: fem.Function, lam0: np.ndarray, b_u: np.ndarray,
              b_lam: np.ndarray, rtol: float, atol: float = 0.0) -> tuple[fem.Function, np.ndarray]:
        """FGMRES on A^T (``transpose``) or A from (P u0, lam0) to ``rtol`` (or ``atol``).

        Returns:
            u on V2 and lambda on the owned multipliers.
        """
        self.transpose = transpose
        u_start = self._u_vec(self.x.array_w[: self.n2])
        self.P.mult(u0.x.petsc_vec, u_start)
        u_start.destroy()
        self.x.array_w[self.n2 :] = lam0
        self.b.array_w[: self.n2] = b_u
        self.b.array_w[self.n2 :] = b_lam
        self.ksp.setTolerances(rtol=rtol, atol=atol, max_it=MAX_ITERATIONS)
        self.ksp.solve(self.b, self.x)
        if self.ksp.getConvergedReason() < 0:
            raise RuntimeError(
                f"the hierarchical P2 solve did not converge (KSP reason "
                f"{self.ksp.getConvergedReason()}, {self.ksp.getIterationNumber()} iterations)"
            )
        u = fem.Function(self.V2)
        u.x.array[: self.n2] = self.x.array_r[: self.n2]
        u.x.scatter_forward()
        return u, self.x.array_r[self.n2 :].copy()

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
    """The preconditioner: edge step, coarse step, edge step (a symmetric two-level sweep)."""

    def __init__(self, system: _P2System) -> None:
        self.s = system

    def apply(self, pc: PETSc.PC, r: PETSc.Vec, d: PETSc.Vec) -> None:
        s = self.s
        n2 = s.n2
        res = r.array_r.copy()
        out = np.zeros_like(res)
        out[:n2] = s.edge_solve(res[:n2])
        k = np.empty_like(res)
        s.apply(out, k)
        rest = res - k
        d_u, d_lam = s.coarse_solve(rest[:n2], rest[n2:])
        out[:n2] += d_u
        out[n2:] += d_lam
        s.apply(out, k)
        out[:n2] += s.edge_solve((res - k)[:n2])
        d.array_w[:] = out


def _finite(sol: Solution, u: fem.Function, lam: np.ndarray) -> None:
    finite = bool(np.all(np.isfinite(u.x.array)) and np.all(np.isfinite(lam)))
    if not sol.disc.comm.allreduce(finite, op=MPI.LAND):
        raise RuntimeError("NaN or Inf in a hierarchical P2 solution")


def _dual(p2: _P2System, sol: Solution, goal: GoalForms, z: DualSolution,
          rtol: float) -> DualSolution:
    """z^(2) from z_h, with the right-hand side of :func:`~dwr_signorini.dual.dual_rhs` on V2."""
    system = sol.system
    b = p2.b.duplicate()
    dual_rhs(p2.algebra, goal, b)
    b_u, b_lam = b.array_r[: p2.n2].copy(), b.array_r[p2.n2 :].copy()
    b.destroy()
    xi = sol.stacked(z.multipliers)
    xi1 = np.where(system.active, xi * system.c_n, xi)
    y, xi1 = p2.solve(True, z.y, xi1, b_u, b_lam, rtol)
    _finite(sol, y, xi1)
    y.name = "y2"
    xi2 = sol.multiplier_functions(np.where(system.active, xi1 / system.c_n, xi1), "xi2")
    return DualSolution(y, *xi2)


def _primal(
    p2: _P2System, sol: Solution, rtol: float
) -> tuple[fem.Function, tuple[fem.Function, ...]]:
    """w^(2) as the correction of w_h in the P2 Newton system of the final active set.

    A [u; lam] = [f_2; -D_A g], with the prescribed Dirichlet values lifted as in the P1 system
    (:class:`~dwr_signorini.algebra.ContactAlgebra` on V2, as for ``weights="higher_order"``).
    The correction starts from zero, so ``rtol`` is relative to the residual of w_h (its rows
    mix forces and gaps, whose right-hand sides differ by many orders of magnitude). Where w_h
    already solves the P2 system (a displacement linear in x, as in a patch test) that residual
    is round-off: the solve then stops at ``ROUNDOFF`` times the norm of the right-hand side.
    """
    system, algebra = sol.system, p2.algebra
    start = np.zeros(p2.n2 + p2.n_lam)
    u = fem.Function(p2.V2, name="u2")
    p2.P.mult(sol.u.x.petsc_vec, u.x.petsc_vec)  # w_h written in P2 (the coarse step's P)
    u.x.scatter_forward()
    start[: p2.n2] = u.x.array[: p2.n2]
    start[p2.n2 :] = sol.stacked()
    p2.transpose = False
    residual = np.empty_like(start)
    p2.apply(start, residual)
    residual[: p2.n2] = algebra.f.array - residual[: p2.n2]
    # the constrained rows -(B u)_A = -g_A, the free ones M_I lam_I = M_I free_I (0 inactive)
    rhs = np.where(system.active, -algebra.g.array, algebra.M.array * system.free)
    residual[p2.n2 :] = rhs - residual[p2.n2 :]
    zero = np.zeros(p2.n_lam)
    rhs_norm = math.sqrt(sol.disc.comm.allreduce(
        float(algebra.f.array @ algebra.f.array + algebra.g.array[system.active] @
              algebra.g.array[system.active]), op=MPI.SUM))
    du, dlam = p2.solve(False, fem.Function(sol.disc.V), zero, residual[: p2.n2],
                        residual[p2.n2 :], rtol, atol=ROUNDOFF * rhs_norm)
    _finite(sol, du, dlam)
    u.x.array[:] += du.x.array
    return u, sol.multiplier_functions(start[p2.n2 :] + dlam, "lambda2")


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
    rtol = HIERARCHICAL_RTOL if rtol is None else rtol
    if not rtol > 0:
        raise ValueError(f"rtol must be positive, got {rtol}")
    with timed("higher-order solve"):
        p2 = _P2System(sol, V2)
    # The coarse step is a preconditioner of a flexible GMRES to rtol: an iterative P1 solver
    # (method="krylov") solves it to its loose tolerance; direct solvers are exact anyway.
    loose = sol.system.set_loose(True)
    try:
        with timed("higher-order solve"):
            z2 = _dual(p2, sol, goal, z, rtol)
            w2 = _primal(p2, sol, rtol) if primal else None
    finally:
        if loose:
            sol.system.set_loose(False)
        p2.destroy()
    return z2, w2
