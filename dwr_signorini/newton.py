"""Semi-smooth Newton (primal-dual active set) method for the algebraic NCP (paper eq. 19-22).

Algebra (Section 4): K stiffness, f load, N_ij = int_GC psi_i (phi_j . n), M = diag(|E_i|),
g_i = int_GC g psi_i. The contact conditions (19) are written with the NCP function (20)

    C_N(u, lam)_i = (M lam)_i - max(0, (M lam)_i + c_n,i (N u - g)_i) = 0,

and with the active set A = {i : (M lam + c_n (N u - g))_i > 0} (21) a Newton step solves

    [ K          N^T        ] [u  ]   [ f       ]
    [ -D_A N     D_I M      ] [lam] = [ -D_A g  ],

i.e. K u + N^T lam = f, (N u)_A = g_A, lam_I = 0. The contact rows are the generalised
derivative of C(w)(mu) = (mu, lam - max(0, lam + u_n - g)) of the paper, scaled so that the
transposed system is exactly the discrete dual problem (11)-(12); see :mod:`dwr_signorini.dual`.

Choice of c_n: c_n,i = E / H_i with H_i the size of macro contact facet i (length in 2D, square
root of the area in 3D). (M lam)_i scales like E u H^(d-2) and c_n (N u)_i like E u H^(d-2) too,
so the active-set test is invariant under scaling E, the loads and the lengths.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .spaces import Discretization
from .timing import timed

__all__ = ["ConvergenceError", "NewtonSystem", "Solution", "default_petsc_options", "solve"]

logger = logging.getLogger(__name__)

_counter = itertools.count()

DATA_QUADRATURE_DEGREE = 8


class ConvergenceError(RuntimeError):
    """The semi-smooth Newton method did not converge.

    Attributes:
        history: One dict per iteration: iteration, active-set size, changes, residuals.
    """

    def __init__(self, message: str, history: list[dict[str, Any]]) -> None:
        lines = [message, "iteration history:"]
        for h in history:
            lines.append(
                "  it {iteration:3d}: |A| = {num_active:6d}, changed = {num_changed:6d}, "
                "equilibrium residual = {residual_equilibrium:.3e}, "
                "NCP residual = {residual_ncp:.3e}".format(**h)
            )
        super().__init__("\n".join(lines))
        self.history = history


def default_petsc_options() -> dict[str, Any]:
    """A direct solver: MUMPS LU where PETSc has it, PETSc's LU otherwise."""
    opts: dict[str, Any] = {"ksp_type": "preonly", "pc_type": "lu"}
    if PETSc.Sys.hasExternalPackage("mumps"):
        opts["pc_factor_mat_solver_type"] = "mumps"
        opts["mat_mumps_icntl_14"] = 200
    return opts


def set_options(obj: PETSc.KSP, prefix: str, options: dict[str, Any]) -> None:
    """Push ``options`` under ``prefix``, apply them to ``obj`` and remove them again."""
    obj.setOptionsPrefix(prefix)
    opts = PETSc.Options()
    opts.prefixPush(prefix)
    for key, value in options.items():
        opts[key] = value
    opts.prefixPop()
    obj.setFromOptions()
    for key in options:
        del opts[prefix + key]


class NewtonSystem:
    """The matrices of the algebraic problem and the Newton matrix of the current active set.

    Owns its PETSc objects (destroyed in ``__del__``); K, N, N^T, M, f and g are assembled once per
    mesh and reused in every Newton step and for the dual problem.
    """

    def __init__(
        self,
        disc: Discretization,
        petsc_options: dict[str, Any] | None = None,
        V: fem.FunctionSpace | None = None,
    ) -> None:
        self.disc = disc
        problem = disc.problem
        V = disc.V if V is None else V
        Q, m = disc.Q, disc.m
        self.V = V
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        mu = ufl.TestFunction(Q)

        # Forms, built once.
        a = ufl.inner(problem.sigma(u), problem.epsilon(v)) * m.dx
        f = problem.vector(problem.body_force, m.x)
        # Loads and gap may be non-polynomial expressions, for which UFL's degree estimate is
        # huge: integrate them with a fixed degree (exact for polynomial data of degree
        # DATA_QUADRATURE_DEGREE - 2 against P2 test functions).
        data = {"quadrature_degree": DATA_QUADRATURE_DEGREE}
        L = ufl.inner(f if f is not None else ufl.as_vector([0.0] * len(v)), v) * m.dx(
            metadata=data
        )
        for tag, t in problem.traction.items():
            L += ufl.inner(problem.vector(t, m.x), v) * m.ds(tag, metadata=data)
        coupling = ufl.inner(mu, ufl.dot(u, m.n)) * m.ds_contact
        self._forms = {
            "a": disc.form(a),
            "L": disc.form(L),
            "N": disc.form(coupling),
            "NT": disc.form(ufl.adjoint(coupling)),
            "M": disc.form(mu * m.ds_contact),
            "g": disc.form(problem.gap_expr(m.x) * mu * m.ds_contact(metadata=data)),
        }
        bcs = disc.bcs if V is disc.V else disc.dirichlet_bcs(V)
        self.bcs = bcs
        with timed("assemble"):
            self._assemble(bcs)
        self.A: PETSc.Mat | None = None
        self.ksp = PETSc.KSP().create(disc.comm)
        self.prefix = f"dwr_signorini_primal_{next(_counter)}_"
        options = default_petsc_options()
        options.update(petsc_options or {})
        set_options(self.ksp, self.prefix, options)

    def _assemble(self, bcs: list[fem.DirichletBC]) -> None:
        """K, N, N^T, f, M, g and the block pattern of the Newton matrix (once per mesh)."""
        problem, disc, V, Q = self.disc.problem, self.disc, self.V, self.disc.Q
        self.K = fem_petsc.assemble_matrix(self._forms["a"], bcs=bcs)
        self.K.assemble()
        self.N = fem_petsc.assemble_matrix(self._forms["N"], bcs=bcs)
        self.N.assemble()
        self.NT = fem_petsc.assemble_matrix(self._forms["NT"], bcs=bcs)
        self.NT.assemble()
        self.f = fem_petsc.assemble_vector(self._forms["L"])
        self.f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.set_bc(self.f.array_w, bcs)
        self.M = self._assemble_q_vector(self._forms["M"])
        self.g = self._assemble_q_vector(self._forms["g"])

        # c_n,i = E / H_i (scale-aware, see module docstring).
        fdim = disc.mesh.topology.dim - 1
        size = self.M.array.copy()
        size = size if fdim == 1 else np.sqrt(size)
        self.c_n = problem.E / size

        # Block layout: per rank [u owned dofs, lam owned dofs].
        self.n_u = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.n_lam = Q.dofmap.index_map.size_local
        D = PETSc.Mat().createAIJ(((self.n_lam, None), (self.n_lam, None)), nnz=1, comm=disc.comm)
        D.setDiagonal(self.M)
        D.assemble()
        nest = PETSc.Mat().createNest([[self.K, self.NT], [self.N, D]], comm=disc.comm)
        self.A0 = PETSc.Mat()
        nest.convert("aij", out=self.A0)
        nest.destroy()
        D.destroy()
        lo, _ = self.A0.getOwnershipRange()
        self._lam_rows = np.arange(lo + self.n_u, lo + self.n_u + self.n_lam, dtype=PETSc.IntType)

        self.x, self.b = self.A0.createVecs()
        self.active = np.zeros(self.n_lam, dtype=bool)

    def _assemble_q_vector(self, form: fem.Form) -> PETSc.Vec:
        vec = fem_petsc.assemble_vector(form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return vec

    def __del__(self) -> None:
        for name in ("K", "N", "NT", "f", "M", "g", "A0", "A", "ksp", "x", "b"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()

    # -- the algebraic NCP --------------------------------------------------------------------
    def gap_residual(self, u: PETSc.Vec) -> np.ndarray:
        """(N u - g) on the owned multiplier rows."""
        Nu = self.N.createVecLeft()
        self.N.mult(u, Nu)
        out = Nu.array - self.g.array
        Nu.destroy()
        return out

    def active_set(self, u: PETSc.Vec, lam: np.ndarray) -> np.ndarray:
        """A = {i : (M lam + c_n (N u - g))_i > 0} (eq. 21), owned rows."""
        return self.M.array * lam + self.c_n * self.gap_residual(u) > 0.0

    def ncp_residual(self, u: PETSc.Vec, lam: np.ndarray) -> np.ndarray:
        """C_N(u, lam) of eq. (20), owned rows."""
        Mlam = self.M.array * lam
        return Mlam - np.maximum(0.0, Mlam + self.c_n * self.gap_residual(u))

    def equilibrium_residual(self, u: PETSc.Vec, lam: np.ndarray) -> float:
        """||K u + N^T lam - f||."""
        r = self.f.duplicate()
        self.K.mult(u, r)
        lam_vec = self.N.createVecLeft()
        lam_vec.array[:] = lam
        tmp = self.f.duplicate()
        self.NT.mult(lam_vec, tmp)
        r.axpy(1.0, tmp)
        r.axpy(-1.0, self.f)
        norm = r.norm()
        for obj in (r, lam_vec, tmp):
            obj.destroy()
        return norm

    def newton_matrix(self, active: np.ndarray) -> PETSc.Mat:
        """The Newton matrix of active set A: contact rows [-D_A N, D_I M]."""
        A = self.A0.copy()
        scale = A.createVecLeft()
        scale.set(1.0)
        scale.setValues(self._lam_rows, np.where(active, -1.0, 0.0))
        scale.assemble()
        A.diagonalScale(L=scale)
        for row, on, mi in zip(self._lam_rows, active, self.M.array, strict=True):
            A.setValue(row, row, 0.0 if on else mi, addv=PETSc.InsertMode.INSERT)
        A.assemble()
        scale.destroy()
        return A

    def solve_active(self, active: np.ndarray) -> None:
        """One Newton step: solve the linear system of active set ``active`` into ``self.x``."""
        with timed("assemble"):
            if self.A is not None:
                self.A.destroy()
            self.A = self.newton_matrix(active)
            self.active = active.copy()
            b = self.b.array_w
            b[: self.n_u] = self.f.array
            b[self.n_u :] = np.where(active, -self.g.array, 0.0)
        with timed("factorize"):
            self.ksp.setOperators(self.A)
            self.ksp.setUp()
        with timed("newton solve"):
            self.ksp.solve(self.b, self.x)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            raise ConvergenceError(
                f"linear solve of the Newton step failed (KSP reason {reason})", []
            )

    def split(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray]:
        """Owned parts (u, lam) of a block vector."""
        return x.array_r[: self.n_u], x.array_r[self.n_u :]


@dataclass
class Solution:
    """The discrete solution w_h = (u_h, lambda_H) and what the dual problem needs.

    Attributes:
        u: Displacement u_h on T_h.
        lam: Normal contact force lambda_H (DG0 on the macro contact facets).
        active: Active set of the last Newton step (owned multiplier rows).
        newton_iterations: Number of linear solves.
        history: Per-iteration record (active-set size, changes, residuals).
        disc: The discretisation.
        system: The Newton system; its last matrix and factorisation serve the dual problem.
    """

    u: fem.Function
    lam: fem.Function
    active: np.ndarray
    newton_iterations: int
    history: list[dict[str, Any]]
    disc: Discretization
    system: NewtonSystem = field(repr=False)

    @property
    def num_active(self) -> int:
        """Global number of active macro contact facets."""
        return self.disc.comm.allreduce(int(self.active.sum()), op=MPI.SUM)


def _norm(comm: MPI.Comm, local: np.ndarray) -> float:
    """Euclidean norm of a distributed array given by its owned entries."""
    return float(np.sqrt(comm.allreduce(float(local @ local), op=MPI.SUM)))


def _global_key(comm: MPI.Comm, active: np.ndarray) -> tuple[int, ...]:
    """A hashable fingerprint of the global active set."""
    local = hash(np.packbits(active).tobytes()) & 0x7FFFFFFF
    return tuple(comm.allgather((local, int(active.sum()))))


def solve(
    problem_or_disc: Any,
    petsc_options: dict[str, Any] | None = None,
    initial_guess: tuple[fem.Function, fem.Function] | None = None,
    max_iterations: int = 50,
    rtol: float = 1e-8,
) -> Solution:
    """Solve Signorini's problem with the semi-smooth Newton method (paper eq. 19-22).

    Args:
        problem_or_disc: A :class:`~dwr_signorini.SignoriniProblem` or a ready
            :class:`~dwr_signorini.spaces.Discretization`.
        petsc_options: Options of the linear solver (prefix ``dwr_signorini_primal_<n>_``),
            merged on top of :func:`default_petsc_options`.
        initial_guess: ``(u0, lam0)`` on this discretisation's V and Q (warm start).
        max_iterations: Most Newton steps before giving up.
        rtol: Relative tolerance on the equilibrium and NCP residuals at convergence.

    Returns:
        The :class:`Solution`.

    Raises:
        ConvergenceError: No convergence, active-set cycling that the safeguard could not break,
            a failed linear solve, or NaN/Inf in an iterate; with the iteration history.
    """
    from .problem import SignoriniProblem
    from .spaces import discretize

    if isinstance(problem_or_disc, SignoriniProblem):
        disc = discretize(problem_or_disc)
    elif isinstance(problem_or_disc, Discretization):
        disc = problem_or_disc
    else:
        raise TypeError(
            "solve() takes a SignoriniProblem or a Discretization, got "
            f"{type(problem_or_disc).__name__}"
        )
    if not isinstance(max_iterations, int) or max_iterations < 1:
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    comm = disc.comm
    system = NewtonSystem(disc, petsc_options)

    u = fem.Function(disc.V, name="u")
    lam = fem.Function(disc.Q, name="lambda")
    if initial_guess is not None:
        u0, lam0 = initial_guess
        if u0.function_space != disc.V or lam0.function_space != disc.Q:
            raise ValueError("initial_guess must be functions on this discretisation's V and Q")
        u.x.array[:] = u0.x.array
        lam.x.array[:] = lam0.x.array

    norm_f = max(system.f.norm(), 1e-300)
    history: list[dict[str, Any]] = []
    seen: dict[tuple[int, ...], int] = {}
    previous: np.ndarray | None = None
    c_scale = 1.0
    c_n_base = system.c_n.copy()
    for it in range(max_iterations + 1):
        u_vec = u.x.petsc_vec
        lam_local = lam.x.array[: system.n_lam]
        active = system.active_set(u_vec, lam_local)
        changed = (
            int(active.size) if previous is None else int(np.count_nonzero(active != previous))
        )
        changed = comm.allreduce(changed, op=MPI.SUM)
        res_eq = system.equilibrium_residual(u_vec, lam_local) / norm_f
        rel_ncp = _norm(comm, system.ncp_residual(u_vec, lam_local)) / max(
            _norm(comm, system.M.array * lam_local), norm_f
        )
        num_active = comm.allreduce(int(active.sum()), op=MPI.SUM)
        history.append(
            {
                "iteration": it,
                "num_active": num_active,
                "num_changed": changed,
                "residual_equilibrium": res_eq,
                "residual_ncp": rel_ncp,
                "c_scale": c_scale,
            }
        )
        logger.info(
            "Newton %d: |A| = %d, changed %d, residuals %.2e / %.2e",
            it,
            num_active,
            changed,
            res_eq,
            rel_ncp,
        )
        if previous is not None and changed == 0:
            if res_eq <= rtol and rel_ncp <= rtol:
                break
            raise ConvergenceError(
                "active set is stationary but the residuals are not small", history
            )
        if it == max_iterations:
            raise ConvergenceError(f"no convergence in {max_iterations} Newton steps", history)

        key = _global_key(comm, active)
        if key in seen and previous is not None:
            # Cycling: change c_n (the weighting of primal against dual information).
            if c_scale >= 1e4:
                raise ConvergenceError(
                    f"active-set cycling (the set of step {it} repeats step {seen[key]}) "
                    "not broken by rescaling c_n",
                    history,
                )
            c_scale *= 10.0
            system.c_n = c_n_base * c_scale
            seen.clear()
            logger.warning("active-set cycling detected; c_n scaled by %g", c_scale)
            active = system.active_set(u_vec, lam_local)
        seen[_global_key(comm, active)] = it

        system.solve_active(active)
        previous = active
        u_new, lam_new = system.split(system.x)
        finite = bool(np.all(np.isfinite(u_new)) and np.all(np.isfinite(lam_new)))
        if not comm.allreduce(finite, op=MPI.LAND):
            history[-1]["nonfinite"] = True
            raise ConvergenceError("NaN or Inf in the Newton iterate", history)
        u.x.array[: system.n_u] = u_new
        u.x.scatter_forward()
        lam.x.array[: system.n_lam] = lam_new
        lam.x.scatter_forward()

    return Solution(
        u=u,
        lam=lam,
        active=system.active.copy(),
        newton_iterations=len(history) - 1,
        history=history,
        disc=disc,
        system=system,
    )
