"""Semi-smooth Newton (primal-dual active set) method for the algebraic NCP (paper eq. 19-22).

With the algebra of :mod:`dwr_signorini.algebra` (K, N, M, f, g, c_n) the contact conditions (19)
are written with the NCP function (20)

    C_N(u, lam)_i = (M lam)_i - max(0, (M lam)_i + c_n,i (N u - g)_i) = 0,

and with the active set A = {i : (M lam + c_n (N u - g))_i > 0} (21) a Newton step solves

    [ K          N^T        ] [u  ]   [ f       ]
    [ -D_A N     D_I M      ] [lam] = [ -D_A g  ],

i.e. K u + N^T lam = f, (N u)_A = g_A, lam_I = 0. The contact rows are the generalised
derivative of C(w)(mu) = (mu, lam - max(0, lam + u_n - g)) of the paper, scaled so that the
transposed system is exactly the discrete dual problem (11)-(12); see :mod:`dwr_signorini.dual`.

The linear solvers of the steps live in :mod:`dwr_signorini.linalg` (``method`` of :func:`solve`:
``"block"``, the block matrix factored by LDL^T, or ``"schur"``, elimination of u with a dense
or Krylov S_AA); this module holds the semi-smooth loop, its safeguards and the
:class:`Solution`. The option helpers are re-exported here from
:mod:`dwr_signorini.linalg.options`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem

from .algebra import check_ncp_scale, distributed_norm
from .collective import CollectiveError, collective
from .lifetime import Releasable
from .linalg import (
    LOOSE_RTOL,
    METHODS,
    SCHUR_KRYLOV_OPTIONS,
    SCHUR_MAX_MULTIPLIERS,
    SYSTEMS,
    DenseSchurComplement,
    KrylovSchurComplement,
    LinearSolveError,
    NewtonLinearSystem,
    NewtonSystem,
    SchurNewtonSystem,
    choose_method,
    default_petsc_options,
    fieldsplit_petsc_options,
    iterative_petsc_options,
    mumps_failure,
    null_pivots,
)
from .spaces import Discretization

__all__ = [
    "LOOSE_RTOL",
    "METHODS",
    "SCHUR_KRYLOV_OPTIONS",
    "SCHUR_MAX_MULTIPLIERS",
    "ConvergenceError",
    "DenseSchurComplement",
    "KrylovSchurComplement",
    "NewtonSystem",
    "SchurNewtonSystem",
    "Solution",
    "default_petsc_options",
    "fieldsplit_petsc_options",
    "iterative_petsc_options",
    "mumps_failure",
    "null_pivots",
    "solve",
]

logger = logging.getLogger(__name__)


class ConvergenceError(RuntimeError):
    """The semi-smooth Newton method did not converge.

    The message ends with the iteration history, one line per step.

    Args:
        message: What failed.
        history: One dict per iteration: ``iteration``, ``num_active``, ``num_changed``,
            ``residual_equilibrium``, ``residual_ncp`` (and ``safeguard``, ``nonfinite``).

    Attributes:
        history: One dict per iteration: iteration, active-set size, changes, residuals.
    """

    def __init__(self, message: str, history: list[dict[str, Any]]) -> None:
        lines = [message, "iteration history:" if history else "(before the first Newton step)"]
        for h in history:
            lines.append(
                "  it {iteration:3d}: |A| = {num_active:6d}, changed = {num_changed:6d}, "
                "equilibrium residual = {residual_equilibrium:.3e}, "
                "NCP residual = {residual_ncp:.3e}".format(**h)
                + (" [least-index safeguard]" if h.get("safeguard") else "")
                + (" [NaN/Inf]" if h.get("nonfinite") else "")
            )
        super().__init__("\n".join(lines))
        self.history = history


@dataclass
class Solution(Releasable):
    """The discrete solution w_h = (u_h, lambda_H) and what the dual problem needs.

    Owns the Newton system (its factorisations serve the dual problem): release it with
    :meth:`destroy` (collective), or use the solution as a context manager,
    ``with ds.solve(problem) as sol: ...``.

    Attributes:
        u: Displacement u_h on T_h.
        lam: Normal contact force lambda_H (DG0 on the macro contact facets).
        active: Active set of the last Newton step (owned multiplier rows).
        newton_iterations: Number of linear solves.
        history: Per-iteration record (active-set size, changes, residuals).
        disc: The discretisation.
        system: The Newton system; its last factorisations serve the dual problem
            (:meth:`~dwr_signorini.linalg.base.NewtonLinearSystem.solve_transpose`).
        num_active: Global number of active macro contact facets (computed once, in
            :func:`solve`: reading it needs no communication).
        ncp_scale: The c of the NCP function (20) the solution was computed with; the
            estimator uses the same (:attr:`system`'s ``c_n``).
        method: The linear solver of the Newton steps that was used (``"block"``,
            ``"schur"``).
    """

    u: fem.Function
    lam: fem.Function
    active: np.ndarray
    newton_iterations: int
    history: list[dict[str, Any]]
    disc: Discretization
    system: NewtonLinearSystem = field(repr=False)
    num_active: int = 0
    ncp_scale: str | float = "physical"
    method: str = "block"

    def destroy(self) -> None:
        """Release the Newton system's PETSc objects and options (collective; idempotent)."""
        self.system.destroy()

    def multiplier_function(self, values: Any, name: str) -> fem.Function:
        """A function on Lambda_H from values on the owned multipliers (ghosts updated).

        Args:
            values: One value per owned multiplier (an array of length ``system.n_lam``).
            name: The function's name.

        Returns:
            A new DG0 function on Lambda_H.
        """
        out = fem.Function(self.disc.Q, name=name)
        out.x.array[: self.system.n_lam] = values
        out.x.scatter_forward()
        return out



def _global_key(comm: MPI.Comm, active: np.ndarray) -> tuple[bytes, ...]:
    """The global active set, exactly (packed bits of every rank's owned rows), as a dict key."""
    return tuple(comm.allgather(np.packbits(active).tobytes() + active.size.to_bytes(8, "little")))


#: Relative round-off level of the two parts of the active-set test (21): (N u - g)_i below it
#: times M_i max|u| + |g_i|, and (M lam)_i below it times max_j |(M lam)_j|, count as zero.
_ROUNDOFF = 1e-10


def solve(
    problem_or_disc: Any,
    petsc_options: dict[str, Any] | None = None,
    initial_guess: tuple[fem.Function, fem.Function] | None = None,
    max_iterations: int = 50,
    rtol: float = 1e-8,
    ncp_scale: str | float = "physical",
    method: str | None = None,
    petsc_options_prefix: str | None = None,
    form_compiler_options: dict[str, Any] | None = None,
    jit_options: dict[str, Any] | None = None,
) -> Solution:
    """Solve Signorini's problem with the semi-smooth Newton method (paper eq. 19-22).

    The active set of step k is A = {i : (M lam + c_n (N u - g))_i > 0} (eq. 21), evaluated at
    the previous iterate, with two safeguards:

    * *Round-off.* In the test (M lam + c_n (N u - g))_i > 0 each part counts as zero below its
      round-off level (``1e-10`` relative to ``M_i max|u| + |g_i|`` and to ``max_j |(M lam)_j|``).
      Without it a bi-active index (lambda_i = 0 and (N u - g)_i = 0 at the solution, e.g.
      grazing contact) would change sides on round-off noise and the iteration could cycle; and
      the decisions stay independent of c_n.
    * *Cycling.* If an active set repeats, the update switches to Murty's least-index rule: of the
      indices the rule (21) would change, only the one with the smallest global number changes
      sides. On the multipliers the contact conditions are a linear complementarity problem with
      the matrix N K^-1 N^T, symmetric positive definite (a P-matrix) when Gamma_D clamps the
      body, for which this rule terminates finitely (K. G. Murty, Opsearch 11, 1974, 123-130).

    With a Krylov solver of K (``method="schur"``, :class:`KrylovSchurComplement`) the steps are
    *inexact* while the active set changes: their solves stop at the relative tolerances
    :data:`LOOSE_RTOL`, which are enough to decide the next active set. When it settles, its
    system is solved once more at the tolerances of ``petsc_options`` (one more step, whose
    iterate the convergence test then checks); direct solvers are always exact.

    After the first step every iterate has (N u - g)_A = 0 and lam_I = 0, so the test reduces to
    lam_i > 0 on A and (N u - g)_i > 0 on I whatever c_n is: c_n (``ncp_scale``)
    only weighs an initial guess against the gap, and the iterates from a zero initial guess do
    not depend on it.

    Args:
        problem_or_disc: A :class:`~dwr_signorini.SignoriniProblem` or a ready
            :class:`~dwr_signorini.spaces.Discretization`.
        petsc_options: Options of the linear solver, merged on top of
            :func:`default_petsc_options`, under ``petsc_options_prefix``. They win over the
            command line for the same key; the command line wins over the defaults.
            They stay in PETSc's options database until :meth:`Solution.destroy`.
        initial_guess: ``(u0, lam0)`` on this discretisation's V and Q (warm start).
        max_iterations: Most Newton steps before giving up.
        rtol: Tolerance at convergence on the equilibrium residual, relative to the size of
            its terms (max of ``||K|| ||u||``, ``||N^T lam||``, ``||f||``: a backward error,
            which does not grow with lambda/mu or mesh grading), and on the NCP residual (20),
            entry by entry
            relative to ``|M lam|_i + c_n,i (M_i max|u| + |g_i|)``.
        ncp_scale: c of the NCP function (20), the same for the Newton method, the dual
            problem and the estimator (:mod:`dwr_signorini.residuals`): ``"physical"`` (default,
            c_n,i = E / H_i on macro contact facet i, invariant under a change of units) or a
            number c > 0 (c_n,i = c; the paper's c = 1 reproduces its Tables 1-2).
        method: Linear solver of the Newton steps, one of :data:`METHODS`. ``"block"``
            (reference, :class:`NewtonSystem`) factors the block Newton matrix in every step
            (``petsc_options`` for the block matrix, e.g. :func:`fieldsplit_petsc_options`);
            ``"schur"`` (:class:`SchurNewtonSystem`) solves S_AA lam_A = (N K^-1 f)_A - g_A,
            S = N K^-1 N^T, with ``petsc_options`` for K: a direct solver (the default, K
            factored once, S dense, at most :data:`SCHUR_MAX_MULTIPLIERS` multipliers) or a
            Krylov solver (:func:`iterative_petsc_options`: CG + GAMG on K, CG on S_AA, for
            large 3D meshes). All give the same iterates up to the solvers' tolerances, and
            the dual problem is solved the same way. ``None`` (the default): ``"block"`` when
            ``petsc_options`` are given (they are for the block matrix), otherwise the rule of
            :func:`~dwr_signorini.linalg.choose_method` (the dense Schur path for large 3D
            problems with few multipliers, and for 2D solves without ``initial_guess``).
            :attr:`Solution.method` tells which was used.
        petsc_options_prefix: Base options prefix of this solve (default: a new unique
            ``dwr_signorini_<n>_``); inner solvers use sub-prefixes
            (:mod:`dwr_signorini.linalg.options`), so e.g. ``-<prefix>ksp_view`` on the
            command line takes effect.
        form_compiler_options: Passed to ``dolfinx.fem.form`` for the forms of the Newton
            system (as dolfinx's ``LinearProblem`` takes them).
        jit_options: Passed to ``dolfinx.fem.form`` likewise.

    Returns:
        The :class:`Solution`.

    Raises:
        TypeError, ValueError: Arguments of the wrong type or value, naming the argument.
        ConvergenceError: No convergence in ``max_iterations`` steps, active-set cycling that
            the safeguard could not break, a failed linear solve, NaN/Inf in the data (loads,
            gap) or in an iterate; with the iteration history. Raised on every rank.
    """
    from .problem import SignoriniProblem
    from .spaces import discretize

    if isinstance(problem_or_disc, SignoriniProblem):
        disc = discretize(problem_or_disc)
    elif isinstance(problem_or_disc, Discretization):
        disc = problem_or_disc
    else:
        raise TypeError(
            "problem must be a SignoriniProblem or a Discretization (the first argument of "
            f"solve()), got {type(problem_or_disc).__name__}"
        )
    if (
        isinstance(max_iterations, bool)
        or not isinstance(max_iterations, int)
        or max_iterations < 1
    ):
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    ncp_scale = check_ncp_scale(ncp_scale)
    for name, value in (("rtol", rtol),):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < np.inf:
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    if method is not None and method not in METHODS:
        raise ValueError(f"method must be one of {METHODS} or None, got {method!r}")
    for name, value in (
        ("form_compiler_options", form_compiler_options),
        ("jit_options", jit_options),
    ):
        if value is not None and not isinstance(value, dict):
            raise TypeError(f"{name} must be a dict, got {type(value).__name__}")
    if petsc_options is not None and not isinstance(petsc_options, dict):
        raise TypeError(
            "petsc_options must be a dict of PETSc options such as {'pc_type': 'lu'}, got "
            f"{type(petsc_options).__name__}"
        )
    if petsc_options_prefix is not None and (
        not isinstance(petsc_options_prefix, str)
        or not petsc_options_prefix
        or not petsc_options_prefix.endswith("_")
    ):
        raise ValueError(
            "petsc_options_prefix must be a non-empty string ending with '_' (e.g. 'contact_') "
            f"or None, got {petsc_options_prefix!r}"
        )
    if initial_guess is not None:
        if not isinstance(initial_guess, (tuple, list)) or len(initial_guess) != 2:
            raise TypeError(
                "initial_guess must be a pair (u0, lam0) of dolfinx Functions, got "
                f"{type(initial_guess).__name__}"
            )
        u0, lam0 = initial_guess
        if (
            getattr(u0, "function_space", None) != disc.V
            or getattr(lam0, "function_space", None) != disc.Q
        ):
            raise ValueError(
                "initial_guess must be functions on this discretisation's V and Q "
                "(transfer them with dwr_signorini.adapt.transfer_solution)"
            )
    if method is None:
        method = (
            "block"
            if petsc_options is not None
            else choose_method(
                disc.mesh.topology.dim,
                disc.num_dofs,
                disc.num_contact_elements,
                cold_start=initial_guess is None,
            )
        )
    try:
        system = SYSTEMS[method](
            disc,
            petsc_options,
            prefix=petsc_options_prefix,
            ncp_scale=ncp_scale,
            compile_options={
                "form_compiler_options": form_compiler_options,
                "jit_options": jit_options,
            },
        )
    except LinearSolveError as err:
        raise ConvergenceError(str(err), []) from err
    try:
        return _semismooth_newton(system, initial_guess, max_iterations, rtol)
    except BaseException:
        system.destroy()
        raise


def _semismooth_newton(
    system: NewtonLinearSystem,
    initial_guess: tuple[fem.Function, fem.Function] | None,
    max_iterations: int,
    rtol: float,
) -> Solution:
    """The loop of :func:`solve` on a set-up Newton system (see there)."""
    disc = system.disc
    comm = disc.comm

    def all_finite(*arrays: np.ndarray) -> bool:
        ok = all(bool(np.all(np.isfinite(a))) for a in arrays)
        return bool(comm.allreduce(ok, op=MPI.LAND))

    if not all_finite(system.f.array, system.g.array):
        raise ConvergenceError(
            "NaN or Inf in the assembled load vector f or gap vector g: body_force, traction "
            "and gap must be finite everywhere on the mesh",
            [],
        )

    n_u, n_lam = system.n_u, system.n_lam
    M = system.M.array
    u = fem.Function(disc.V, name="u")
    lam = fem.Function(disc.Q, name="lambda")
    if initial_guess is not None:
        u.x.array[:] = initial_guess[0].x.array
        lam.x.array[:] = initial_guess[1].x.array
        if not all_finite(u.x.array, lam.x.array):
            raise ValueError("initial_guess contains NaN or Inf")
    system.algebra.set_prescribed(u.x.array)  # the iterates satisfy the Dirichlet values
    q_start = disc.Q.dofmap.index_map.local_range[0]

    def least_index(mask: np.ndarray) -> np.ndarray:
        """Only the set entry with the smallest global index (on its owning rank)."""
        local = np.flatnonzero(mask)
        mine = q_start + int(local[0]) if local.size else np.iinfo(np.int64).max
        first = comm.allreduce(mine, op=MPI.MIN)
        out = np.zeros_like(mask)
        if local.size and mine == first:
            out[local[0]] = True
        return out

    lam_vec = system.N.createVecLeft()
    nt_lam = system.f.duplicate()
    norm_f = system.f.norm()
    norm_K = system.algebra.stiffness_norm()
    history: list[dict[str, Any]] = []
    loose = system.set_loose(True)
    seen: dict[tuple[bytes, ...], int] = {}
    previous: np.ndarray | None = None
    safeguard_since: int | None = None
    try:
        for it in range(max_iterations + 1):
            u_vec = u.x.petsc_vec
            lam_local = lam.x.array[:n_lam]
            Mlam = M * lam_local
            gap_res = system.algebra.gap_residual(u_vec)
            test = Mlam + system.c_n * gap_res
            # The terms of the test (21) at their round-off level, entry by entry.
            u_max = comm.allreduce(float(np.max(np.abs(u.x.array), initial=0.0)), op=MPI.MAX)
            gap_size = M * u_max + np.abs(system.g.array)
            force_size = comm.allreduce(float(np.max(np.abs(Mlam), initial=0.0)), op=MPI.MAX)
            size = np.abs(Mlam) + system.c_n * gap_size
            clean = np.where(np.abs(Mlam) > _ROUNDOFF * force_size, Mlam, 0.0) + system.c_n * (
                np.where(np.abs(gap_res) > _ROUNDOFF * gap_size, gap_res, 0.0)
            )
            wanted = clean > 0.0
            if previous is None:
                violated = np.ones_like(wanted)
                rule = wanted
            else:
                violated = wanted != previous
                rule = wanted

            # Residuals as backward errors: the equilibrium residual relative to the size of
            # the terms K u, N^T lam, f; the NCP function (20) entry by entry relative to `size`.
            lam_vec.array_w[:] = lam_local
            system.NT.mult(lam_vec, nt_lam)
            norm_Ku = norm_K * distributed_norm(comm, u.x.array[:n_u])
            scale_eq = max(norm_f, nt_lam.norm(), norm_Ku, 1e-300)
            res_eq = system.algebra.equilibrium_residual(u_vec, lam_local) / scale_eq
            ncp = np.abs(Mlam - np.maximum(0.0, test))
            local_ncp = np.max(
                np.divide(ncp, size, out=np.zeros_like(ncp), where=size > 0), initial=0.0
            )
            rel_ncp = comm.allreduce(float(local_ncp), op=MPI.MAX)
            num_changed = comm.allreduce(int(violated.sum()), op=MPI.SUM)
            record = {
                "iteration": it,
                "num_active": comm.allreduce(int(rule.sum()), op=MPI.SUM),
                "num_changed": num_changed,
                "residual_equilibrium": res_eq,
                "residual_ncp": rel_ncp,
                "ncp_scale": system.algebra.ncp_scale,
                "safeguard": safeguard_since is not None,
                "loose": loose,
            }
            history.append(record)
            logger.info(
                "Newton %d: |A| = %d, changed %d, residuals %.2e / %.2e",
                it,
                record["num_active"],
                num_changed,
                res_eq,
                rel_ncp,
            )
            settled = previous is not None and num_changed == 0
            resolve = settled and loose
            if resolve:  # the active set has settled: solve its system again, accurately
                loose = system.set_loose(False)
            elif settled:
                if res_eq <= rtol and rel_ncp <= rtol:
                    break
                raise ConvergenceError(
                    f"the active set is stationary but the residuals are not below rtol={rtol:g}: "
                    "the linear solves are inaccurate (check petsc_options; a direct solver is "
                    "the default)",
                    history,
                )
            if it == max_iterations:
                extra = (
                    f" (least-index safeguard active since step {safeguard_since})"
                    if safeguard_since is not None
                    else ""
                )
                raise ConvergenceError(
                    f"no convergence in max_iterations={max_iterations} Newton steps{extra}; "
                    "raise max_iterations or warm-start from a nearby solution",
                    history,
                )

            new = previous if resolve else rule
            key = _global_key(comm, new)
            if key in seen and not resolve:
                if safeguard_since is not None:
                    raise ConvergenceError(
                        f"active-set cycling: the set of step {it} repeats step {seen[key]} "
                        "even under the least-index safeguard (is the body clamped, i.e. is "
                        "N K^-1 N^T positive definite?)",
                        history,
                    )
                logger.warning(
                    "active-set cycling (step %d repeats step %d): least-index safeguard",
                    it,
                    seen[key],
                )
                safeguard_since = it
                seen.clear()
            if safeguard_since is not None and not resolve:
                new = previous ^ least_index(violated)
                key = _global_key(comm, new)
                record["num_active"] = comm.allreduce(int(new.sum()), op=MPI.SUM)
                record["safeguard"] = True
            seen[key] = it

            try:
                # A failure that one rank sees first (after the solve's last collective) is
                # raised on every rank (dwr_signorini.collective).
                with collective(comm, f"Newton step {it}: the linear solve"):
                    system.solve_active(new)
            except (LinearSolveError, PETSc.Error, np.linalg.LinAlgError) as err:
                # LinAlgError: the Cholesky factorisation of S_AA (method="schur") failed.
                reason = system.ksp.getConvergedReason()
                names = vars(PETSc.KSP.ConvergedReason).items()
                name = next((k for k, v in names if v == reason and k.isupper()), str(reason))
                if isinstance(err, CollectiveError):
                    ranks = ", ".join(map(str, err.ranks))
                    on = f" on rank(s) {ranks} of {comm.size}" if comm.size > 1 else ""
                    name = f"{err.error_type}{on}: {err.error_message.splitlines()[0]}"
                elif isinstance(err, PETSc.Error):
                    name = f"PETSc error {err.ierr}"
                elif isinstance(err, np.linalg.LinAlgError):
                    name = str(err)
                cause = mumps_failure(system.ksp)
                if cause is not None:
                    hint = cause
                elif isinstance(err, (PETSc.Error, np.linalg.LinAlgError)) or reason == (
                    PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED
                ):
                    hint = (
                        "the factorisation or preconditioner failed: the Newton matrix is "
                        "singular (the body is not held in place, check dirichlet; or active "
                        "contact constraints are linearly dependent, e.g. a contact facet whose "
                        "nodes are all clamped), or the preconditioner in petsc_options does "
                        "not suit this saddle-point system"
                    )
                else:
                    hint = "the linear solver did not converge: check petsc_options"
                raise ConvergenceError(
                    f"Newton step {it}: linear solve failed ({name}); {hint}", history
                ) from err
            previous = new
            u_new, lam_new = system.split(system.x)
            if not all_finite(u_new, lam_new):
                record["nonfinite"] = True
                raise ConvergenceError(
                    f"NaN or Inf in the Newton iterate of step {it} (singular or ill-posed "
                    "linear system?)",
                    history,
                )
            u.x.array[:n_u] = u_new
            u.x.scatter_forward()
            lam.x.array[:n_lam] = lam_new
            lam.x.scatter_forward()
    finally:
        lam_vec.destroy()
        nt_lam.destroy()
    system.set_loose(False)  # the dual problem reuses the system: at full accuracy

    return Solution(
        u=u,
        lam=lam,
        active=system.active.copy(),
        newton_iterations=len(history) - 1,
        history=history,
        disc=disc,
        system=system,
        ncp_scale=system.algebra.ncp_scale,
        method="schur" if isinstance(system, SchurNewtonSystem) else "block",
        num_active=comm.allreduce(int(system.active.sum()), op=MPI.SUM),
    )
