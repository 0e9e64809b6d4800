r"""The P2 dual by a two-level hierarchical solver: the higher-order dual without its factorisation.

``weights="higher_order"`` solves the dual problem (11)-(12) in P2 on T_h (with Lambda_H and the
final active set) by a factorisation of the P2 system, which in 3D costs many times the P1 level.
``weights="hierarchical"`` solves the same P2 system, to a relative residual of
:data:`HIERARCHICAL_RTOL`, by FGMRES preconditioned with a two-level sweep in the hierarchical
basis of P2 = P1 + span{edge functions} (the P2 nodal functions that vanish at the vertices; on
Q2 those of the edges, faces and cells):

1. *edge step*: one symmetric SOR sweep on the edge block of the P2 stiffness matrix, which is
   well conditioned on every mesh;
2. *coarse step*: the residual tested with the P1 functions (P^T r, P the interpolation
   P1 -> P2) and with the multipliers, corrected by the transposed Newton matrix of the last
   step, whose factorisations the P1 dual already used (:mod:`~dwr_signorini.dual`);
3. the edge step again.

The unknowns are y and the multiplier xi^(1) of the Newton system's scaling (c = 1 in b_h, see
:mod:`~dwr_signorini.residuals`): xi = xi^(1) / c on the active facets. The iteration starts
from z_h written in P2. No matrix of the size of the P2 system is factored: each iteration costs
two SOR sweeps on the edge unknowns, one solve with the existing factors and a few sparse
matrix-vector products. ``tests/test_hierarchical.py`` checks the solution against the directly
solved P2 dual. On coarse 3D meshes where the patch-wise recovery of z_h misses the first
contact (``benchmarks/unresolved_3d.py``) it gives the estimate of the higher-order dual.
"""

from __future__ import annotations

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.cpp import mesh as _cpp_mesh
from dolfinx.fem import petsc as fem_petsc

from .dual import DualSolution
from .goal import GoalForms
from .lifetime import destroy_attributes
from .newton import Solution
from .quadrature import with_quadrature_degrees
from .timing import timed

__all__ = ["HIERARCHICAL_RTOL", "hierarchical_dual"]

#: Relative residual of the P2 dual system at which ``weights="hierarchical"`` stops.
HIERARCHICAL_RTOL = 1e-3


#: Most FGMRES iterations on the P2 dual system.
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


class _P2DualSystem:
    """The P2 dual system, its two-level preconditioner and its solver on one solution.

    Unknowns [y (P2, owned dofs); xi^(1) (owned multipliers)]; operator, with the P2 stiffness
    K_2 and coupling N_2 (Dirichlet rows and columns removed, as in the P1 system),

        [ K_2    -N_2^T D_A ]
        [ N_2     D_I M     ],

    the transposed Newton matrix of :mod:`~dwr_signorini.dual` in P2.
    """

    _petsc_objects = ("K2", "N2", "P", "edges", "edge_ksp", "ksp", "op", "b", "x", "rhs1", "z1")

    def __init__(self, sol: Solution, goal: GoalForms, V2: fem.FunctionSpace) -> None:
        disc, system = sol.disc, sol.system
        self.disc, self.system, self.V2 = disc, system, V2
        m = disc.m
        u2, v2 = ufl.TrialFunction(V2), ufl.TestFunction(V2)
        mu = ufl.TestFunction(disc.Q)
        bcs = disc.dirichlet_bcs(V2)
        a = disc.problem.elastic_form(u2, v2, m.dx)
        if callable(disc.problem.E) or callable(disc.problem.nu):
            a = with_quadrature_degrees(a)
        self.K2 = fem_petsc.assemble_matrix(disc.form(a), bcs=bcs)
        self.K2.assemble()
        self.N2 = fem_petsc.assemble_matrix(
            disc.form(ufl.inner(mu, ufl.dot(u2, m.n)) * m.ds_contact), bcs=bcs
        )
        self.N2.assemble()
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
        b = self.b.array_w
        b[:] = 0.0
        if goal.has_u:
            # As the P1 and P2 right-hand sides of the dual (dwr_signorini.dual.dual_rhs).
            form = ufl.replace(goal.dJ_u, {goal.dJ_u.arguments()[0]: v2})
            vec = fem_petsc.assemble_vector(disc.form(form))
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            fem_petsc.set_bc(vec, bcs)
            b[: self.n2] = vec.array
            vec.destroy()
        if goal.has_lam:
            vec = fem_petsc.assemble_vector(disc.form(goal.dJ_lam))
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            b[self.n2 :] = vec.array
            vec.destroy()
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
        y, xi1 = x[: self.n2], x[self.n2 :]
        y_vec, out_u = self._u_vec(np.ascontiguousarray(y)), self._u_vec(out[: self.n2])
        xi_vec = self._lam_vec(np.ascontiguousarray(xi1 * self.system.active))
        out_lam = self._lam_vec(out[self.n2 :])
        tmp = out_u.duplicate()
        self.K2.mult(y_vec, out_u)
        self.N2.multTranspose(xi_vec, tmp)
        out_u.axpy(-1.0, tmp)
        self.N2.mult(y_vec, out_lam)
        out[: self.n2] = out_u.array
        out[self.n2 :] = out_lam.array + self.inactive_mass * xi1
        for vec in (y_vec, out_u, xi_vec, out_lam, tmp):
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
        """The P1 correction by the factors of the last Newton step: (P d_u, d_lam)."""
        system = self.system
        r_vec = self._u_vec(np.ascontiguousarray(r_u))
        r_1 = self.P.createVecRight()
        self.P.multTranspose(r_vec, r_1)
        for bc in system.bcs:
            bc.set(r_1.array_w, alpha=0.0)
        system.write(self.rhs1, r_1.array[: system.n_u], r_lam)
        system.solve_transpose(self.rhs1, self.z1)
        d_u, d_lam = system.split(self.z1)
        r_1.array_w[:] = 0.0
        r_1.array_w[: system.n_u] = d_u
        out = r_vec.duplicate()
        self.P.mult(r_1, out)
        d_2 = out.array.copy()
        for vec in (r_vec, r_1, out):
            vec.destroy()
        return d_2, d_lam.copy()

    def solve(self, z: DualSolution, rtol: float) -> DualSolution:
        """FGMRES from z_h to ``rtol``; the solution as (y on V2, xi on Lambda_H)."""
        system = self.system
        y0 = self._u_vec(self.x.array_w[: self.n2])
        self.P.mult(z.y.x.petsc_vec, y0)
        y0.destroy()
        xi = z.xi.x.array[: self.n_lam]
        self.x.array_w[self.n2 :] = np.where(system.active, xi * system.c_n, xi)
        self.ksp.setTolerances(rtol=rtol, atol=0.0, max_it=MAX_ITERATIONS)
        self.ksp.solve(self.b, self.x)
        if self.ksp.getConvergedReason() < 0:
            raise RuntimeError(
                f"the hierarchical P2 dual did not converge (KSP reason "
                f"{self.ksp.getConvergedReason()}, {self.ksp.getIterationNumber()} iterations)"
            )
        y = fem.Function(self.V2, name="y2")
        y.x.array[: self.n2] = self.x.array_r[: self.n2]
        y.x.scatter_forward()
        out = fem.Function(self.disc.Q, name="xi2")
        xi1 = self.x.array_r[self.n2 :]
        out.x.array[: self.n_lam] = np.where(system.active, xi1 / system.c_n, xi1)
        out.x.scatter_forward()
        return DualSolution(y=y, xi=out)

    def destroy(self) -> None:
        destroy_attributes(self, self._petsc_objects)


class _Operator:
    """The P2 dual operator as a PETSc shell matrix (petsc4py's Python matrix protocol)."""

    def __init__(self, system: _P2DualSystem) -> None:
        self.s = system

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.s.apply(x.array_r, y.array_w)


class _TwoLevel:
    """The preconditioner: edge step, coarse step, edge step (a symmetric two-level sweep)."""

    def __init__(self, system: _P2DualSystem) -> None:
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


def hierarchical_dual(
    sol: Solution,
    goal: GoalForms,
    z: DualSolution,
    V2: fem.FunctionSpace,
    rtol: float | None = None,
) -> DualSolution:
    """The P2 dual z^(2) by FGMRES with the two-level preconditioner, from z_h (module docstring).

    Args:
        sol: The solved discrete problem (its last Newton factorisations are reused).
        goal: The goal's derivatives at w_h.
        z: z_h = (y_h, xi_H), the P1 dual of the same Newton system.
        V2: The P2 (Q2) vector space on T_h.
        rtol: Relative residual to reach (default :data:`HIERARCHICAL_RTOL`).

    Returns:
        (y, xi) with y in V2 and xi on Lambda_H.
    """
    rtol = HIERARCHICAL_RTOL if rtol is None else rtol
    if not rtol > 0:
        raise ValueError(f"rtol must be positive, got {rtol}")
    with timed("reconstruct"):
        p2 = _P2DualSystem(sol, goal, V2)
    try:
        with timed("reconstruct"):
            out = p2.solve(z, rtol)
    finally:
        p2.destroy()
    finite = bool(np.all(np.isfinite(out.y.x.array)) and np.all(np.isfinite(out.xi.x.array)))
    if not sol.disc.comm.allreduce(finite, op=MPI.LAND):
        raise RuntimeError("NaN or Inf in the hierarchical dual")
    return out
