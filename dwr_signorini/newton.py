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

The linear solvers of the steps live in :mod:`dwr_signorini.linalg`; this module holds the
semi-smooth loop, its safeguards and the :class:`Solution`. ``method`` of :func:`solve` picks
one: ``"block"`` (reference, :class:`~dwr_signorini.linalg.NewtonSystem`) factors the block
Newton matrix in every step (``petsc_options`` for the block matrix, e.g.
:func:`~dwr_signorini.linalg.fieldsplit_petsc_options`); ``"schur"``
(:class:`~dwr_signorini.linalg.SchurNewtonSystem`) solves S_AA lam_A = (N K^-1 f)_A - g_A,
S = N K^-1 N^T, with ``petsc_options`` for K: a direct solver (the default, K factored once, S
dense, at most :data:`~dwr_signorini.linalg.SCHUR_MAX_MULTIPLIERS` multipliers) or a Krylov
solver (:func:`~dwr_signorini.linalg.iterative_petsc_options`: CG + GAMG on K, CG on S_AA, for
large 3D meshes); ``"krylov"`` (:class:`~dwr_signorini.linalg.KrylovNewtonSystem`) solves each
step and the dual as one saddle-point system by GMRES with one multigrid cycle of K per
iteration (``petsc_options`` for the multigrid,
:func:`~dwr_signorini.linalg.iterative_petsc_options` by default). All give the same iterates
up to the solvers' tolerances, and the dual problem is solved the same way. ``None`` (the
default): ``"block"`` when ``petsc_options`` are given, otherwise the rule of
:func:`~dwr_signorini.linalg.choose_method`: in 3D ``"krylov"`` from 200k DoFs and where MUMPS's
analysis predicts a factorisation that does not fit in memory
(:mod:`~dwr_signorini.linalg.memory`), the dense Schur path for large 3D problems with few
multipliers and for 2D solves without ``initial_guess``, else ``"block"``.

**Safeguards.** The active set of step k is A = {i : (M lam + c_n (N u - g))_i > 0} (eq. 21),
evaluated at the previous iterate, with two safeguards:

* *Round-off.* In the test (M lam + c_n (N u - g))_i > 0 each part counts as zero below its
  round-off level (``1e-10`` relative to ``M_i max|u| + |g_i|`` and to ``max_j |(M lam)_j|``).
  Without it a bi-active index (lambda_i = 0 and (N u - g)_i = 0 at the solution, e.g. grazing
  contact) would change sides on round-off noise and the iteration could cycle; and the
  decisions stay independent of c_n.
* *Cycling.* If an active set repeats, the update switches to Murty's least-index rule: of the
  indices the rule (21) would change, only the one with the smallest global number changes
  sides. On the multipliers the contact conditions are a linear complementarity problem with the
  matrix N K^-1 N^T, symmetric positive definite (a P-matrix) when Gamma_D clamps the body, for
  which this rule terminates finitely (K. G. Murty, Opsearch 11, 1974, 123-130). A law with
  coupled rows (Coulomb's, Tresca's in 3D) is not such a problem, and on it the rule can cycle
  too: there a repeat switches to damped steps instead (the rule's sets, half the Newton update,
  while the sets change; full steps once they repeat).

**Inexact steps.** With a Krylov solver of K (``method="schur"``,
:class:`~dwr_signorini.linalg.KrylovSchurComplement`) the steps are *inexact* while the active
set changes: their solves stop at the relative tolerances :data:`~dwr_signorini.linalg.LOOSE_RTOL`,
which are enough to decide the next active set. When it settles, its system is solved once more
at the tolerances of ``petsc_options`` (one more step, whose iterate the convergence test then
checks); direct solvers are always exact. A loose solve can put a nearly degenerate row on the
wrong side, so loose steps can cycle on the solves' error alone: a set that repeats among loose
steps makes every following step accurate (instead of the least-index rule), and the accurate
steps keep their own record of the sets they visit (a set a loose step visited is no cycle when
an accurate one returns to it). Measured on an adaptive 3D level of 1.08M DoFs: 6 rows cycled
under loose solves, and the least-index rule took 12 steps in all.

After the first step every iterate has (N u - g)_A = 0 and lam_I = 0, so the test reduces to
lam_i > 0 on A and (N u - g)_i > 0 on I whatever c_n is: c_n (``ncp_scale``) only weighs an
initial guess against the gap, and the iterates from a zero initial guess do not depend on it.
"""

from __future__ import annotations

import functools
import logging
import time
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import fem

from . import finite_strain
from .agreement import check_options_on_ranks
from .algebra import ContactAlgebra
from .collective import log_on_root
from .force import ForceControl
from .laws import multiplier_names
from .linalg import (
    KrylovNewtonSystem,
    LinearSolveError,
    NewtonLinearSystem,
    SchurNewtonSystem,
    choose_method,
    memory,
    system_class,
)
from .rigid import RigidHold, free_motions, held_method
from .semismooth import ConvergenceError, NewtonLoop
from .settings import SolverOptions
from .solution import Solution, traction_vector
from .spaces import Discretization
from .timing import timed

__all__ = ["Solution", "method_name", "solve"]

logger = logging.getLogger(__name__)


def solve(
    problem_or_disc: Any,
    petsc_options: dict[str, Any] | None = None,
    initial_guess: tuple[fem.Function, ...] | None = None,
    max_iterations: int = 50,
    rtol: float = 1e-8,
    ncp_scale: str | float = "physical",
    method: str | None = None,
    petsc_options_prefix: str | None = None,
    form_compiler_options: dict[str, Any] | None = None,
    jit_options: dict[str, Any] | None = None,
    *,
    options: SolverOptions | None = None,
) -> Solution:
    """Solve Signorini's problem with the semi-smooth Newton method (paper eq. 19-22).

    Args:
        problem_or_disc: A :class:`~dwr_signorini.SignoriniProblem` or a ready
            :class:`~dwr_signorini.spaces.Discretization`.
        petsc_options: Options of the linear solver (as
            :class:`~dwr_signorini.settings.SolverOptions`).
        initial_guess: ``(u0, lam0)`` (or ``(u0, lam0, lam_t0)`` with friction) on this
            discretisation's V and Q (warm start).
        max_iterations: Most Newton steps before giving up.
        rtol: Tolerance at convergence (as :class:`~dwr_signorini.settings.SolverOptions`).
        ncp_scale: c of the NCP function (20): ``"physical"`` (default, E / H_i on macro
            contact facet i) or a number c > 0 (the paper's c = 1 reproduces its Tables 1-2).
        method: Linear solver of the Newton steps, one of :data:`~dwr_signorini.linalg.METHODS`
            (module docstring). ``None`` (the default): ``"block"`` when ``petsc_options`` are
            given (they are for the block matrix), otherwise the rule of
            :func:`~dwr_signorini.linalg.choose_method`, told by MUMPS's analysis whether a
            factorisation of a large 3D problem fits in memory. :attr:`Solution.method` tells
            which was used.
        petsc_options_prefix: Base options prefix of this solve (default: a new unique
            ``dwr_signorini_<n>_``).
        form_compiler_options: Passed to ``dolfinx.fem.form`` for the forms of the Newton
            system (as dolfinx's ``LinearProblem`` takes them).
        jit_options: Passed to ``dolfinx.fem.form`` likewise.
        options: All of the above but the problem and the initial guess as one
            :class:`~dwr_signorini.settings.SolverOptions`, instead of the keywords.

    Returns:
        The :class:`Solution`; for a finite-strain problem (a hyperelastic ``material``) a
        :class:`~dwr_signorini.finite_strain.FiniteStrainSolution` (the full load in one
        Newton solve, :mod:`dwr_signorini.finite_strain`).

    Raises:
        TypeError, ValueError: Arguments of the wrong type or value, naming the argument
            (for a finite-strain problem: ``petsc_options``, ``method`` and the compiler
            options are not taken yet).
        ConvergenceError: No convergence in ``max_iterations`` steps, active-set cycling that
            the safeguard could not break, a failed linear solve, NaN/Inf in the data (loads,
            gap) or in an iterate; with the iteration history. Raised on every rank.
    """
    disc = _discretization(problem_or_disc)
    keywords = SolverOptions(
        petsc_options, method, ncp_scale, max_iterations, rtol, petsc_options_prefix,
        form_compiler_options, jit_options,
    )
    if options is None:
        options = keywords
    elif not isinstance(options, SolverOptions) or keywords != SolverOptions():
        raise TypeError(
            "options must be a SolverOptions, given instead of the solver's keyword arguments"
        )
    _check_initial_guess(disc, initial_guess)
    check_options_on_ranks(disc.mesh, "solve", options, initial_guess=initial_guess is None)
    if disc.problem.finite_strain:
        return finite_strain.solve(disc, finite_strain.check_options(options), initial_guess)
    tic = time.perf_counter()
    if disc is problem_or_disc:  # the caller's: the caller releases it
        sol = _solve(disc, initial_guess, options)
    else:
        try:
            sol = _solve(disc, initial_guess, options)
        except BaseException:
            disc.destroy()
            raise
        sol.owns_disc = True
    _log_solution(sol, time.perf_counter() - tic)
    return sol


def _log_solution(sol: Solution, seconds: float) -> None:
    """One INFO line on rank 0 for a finished solve (the logger ``dwr_signorini.newton``).

    Collective with friction (the stick and slip counts are reduced on every rank).
    """
    friction = "" if sol.stick is None else f", stick {sol.num_stick}, slip {sol.num_slip}"
    if sol.disc.comm.rank != 0:
        return
    logger.info(
        "solve: %d DoFs, %d contact elements: %d Newton steps (%s), %d active%s, %.2f s",
        sol.disc.num_dofs, sol.disc.num_contact_elements, sol.newton_iterations, sol.method,
        sol.num_active, friction, seconds,
    )


def _discretization(problem_or_disc: Any) -> Discretization:
    """The discretisation to solve on: ``problem_or_disc``'s (timed as "discretize"), or itself."""
    from .problem import SignoriniProblem
    from .spaces import discretize

    if isinstance(problem_or_disc, SignoriniProblem):
        with timed("discretize"):
            return discretize(problem_or_disc)
    if isinstance(problem_or_disc, Discretization):
        return problem_or_disc
    raise TypeError(
        "problem must be a SignoriniProblem or a Discretization (the first argument of "
        f"solve()), got {type(problem_or_disc).__name__}"
    )


def _check_initial_guess(disc: Discretization, initial_guess: Any) -> None:
    """Check that ``initial_guess`` holds the law's functions on ``disc``'s V and Q."""
    if initial_guess is None:
        return
    num = len(disc.problem.law.components(disc.mesh.topology.dim))
    if not isinstance(initial_guess, (tuple, list)) or not 2 <= len(initial_guess) <= 1 + num:
        pair = "(u0, lam0) or a triple (u0, lam0, lam_t0)" if num > 1 else "(u0, lam0)"
        raise TypeError(
            f"initial_guess must be a pair {pair} of dolfinx Functions, got "
            f"{type(initial_guess).__name__}"
            + (f" of length {len(initial_guess)}" if isinstance(initial_guess, (tuple, list))
               else "")
        )
    u0, *lam0 = initial_guess
    if getattr(u0, "function_space", None) != disc.V or any(
        getattr(f, "function_space", None) != disc.Q for f in lam0
    ):
        raise ValueError(
            "initial_guess must be functions on this discretisation's V and Q "
            "(transfer them with dwr_signorini.transfer.transfer_solution)"
        )


#: Most re-solves of a force-controlled obstacle whose contact frame turned with delta.
FRAME_RESOLVES = 10


def _solve(
    disc: Discretization,
    initial_guess: tuple[fem.Function, ...] | None,
    options: SolverOptions,
) -> Solution:
    """:func:`solve` with checked arguments, until N's contact frame is that of the final delta.

    N is assembled at the delta the solve starts from; where the frame turns with a
    force-controlled obstacle's delta (:meth:`~dwr_signorini.algebra.ContactAlgebra.
    frame_change`), the solve is repeated from its solution (the system assembled at its
    delta) until N changes by at most ``rtol``: the solution is then the displacement-
    controlled one at its delta, and the estimator's forms (in the frame at delta) are its.
    """
    sol = _solve_once(disc, initial_guess, options)
    for _ in range(FRAME_RESOLVES):
        if sol.system.algebra.frame_change() <= options.rtol:
            return sol
        earlier = sol
        try:
            sol = _solve_once(disc, (earlier.u, *earlier.multipliers), options)
        finally:
            earlier.destroy()
        sol.history[:0] = earlier.history
        sol.newton_iterations += earlier.newton_iterations + 1
    change = sol.system.algebra.frame_change()
    sol.destroy()
    raise ConvergenceError(
        f"the contact frame of the obstacle under a given force still turns by {change:.2e} "
        f"(relative change of N) after {FRAME_RESOLVES} re-solves at its displacement",
        sol.history,
    )


def _solve_once(
    disc: Discretization,
    initial_guess: tuple[fem.Function, ...] | None,
    options: SolverOptions,
) -> Solution:
    """One Newton solve: set up the Newton system, run the loop."""
    compile_options = options.compile_options
    symmetric = disc.problem.law.symmetric(disc.mesh.topology.dim)
    assembled = None
    method = options.method
    motions = free_motions(disc)
    obstacle = disc.problem.force_obstacle
    if motions.count or obstacle is not None:
        method = held_method(method, motions.count)
    if method is None:
        if options.petsc_options is not None:
            method = "block"
        else:
            method, assembled = _automatic_method(
                disc, symmetric, initial_guess is None, options.ncp_scale, compile_options
            )
    try:
        system = system_class(method, symmetric)(
            disc,
            options.petsc_options,
            prefix=options.petsc_options_prefix,
            ncp_scale=options.ncp_scale,
            compile_options=compile_options,
            algebra=assembled,
        )
    except LinearSolveError as err:
        raise ConvergenceError(str(err), []) from err
    hold = force = None
    try:
        if obstacle is not None:
            force = ForceControl(system)
            system.force_control = force  # the dual problem is the bordered system's
        if motions.count or obstacle is not None:
            hold = RigidHold(
                motions, system.N, system.algebra.n_q, system.algebra.c_n, system.M.array,
                disc.problem, None if force is None else (force.rate(), force.force),
            )
        return _semismooth_newton(
            system, initial_guess, options.max_iterations, options.rtol, hold, force
        )
    except BaseException:
        if force is not None:
            force.destroy()
        system.destroy()
        raise


def _automatic_method(
    disc: Discretization,
    symmetric: bool,
    cold_start: bool,
    ncp_scale: str | float,
    compile_options: dict[str, Any],
) -> tuple[str, ContactAlgebra | None]:
    """The method of ``method=None``: :func:`choose_method`, told whether a factorisation fits.

    Where the rule picks a factored path for a 3D level of at least
    :data:`~dwr_signorini.linalg.memory.PROBE_MIN_DOFS` DoFs with a symmetric law, the algebra
    is assembled here and MUMPS's analysis of K predicts the memory of factoring it
    (:func:`~dwr_signorini.linalg.memory.factorization_fits`), unless a rough estimate from the
    size already fits (:func:`~dwr_signorini.linalg.memory.surely_fits`); where the prediction
    does not fit, the Krylov path is taken. The algebra is handed on to the Newton system.

    Returns:
        The method and the assembled algebra (None where no probe ran).
    """
    tdim = disc.mesh.topology.dim
    # the multiplier rows: one per macro contact facet and component of the law
    num_multipliers = disc.num_contact_elements * len(disc.problem.law.components(tdim))
    rule = {"cold_start": cold_start, "symmetric": symmetric}
    method = choose_method(tdim, disc.num_dofs, num_multipliers, **rule)
    if tdim != 3 or method == "krylov" or not symmetric or disc.num_dofs < memory.PROBE_MIN_DOFS:
        return method, None
    dense = num_multipliers if method == "schur" else 0
    if memory.surely_fits(disc.num_dofs, disc.comm, dense):
        return method, None
    assembled = ContactAlgebra(disc, None, ncp_scale, compile_options)
    try:
        fits, need, available = memory.factorization_fits(assembled.K, tdim, dense)
    except BaseException:
        assembled.destroy()
        raise
    if not fits:
        log_on_root(
            disc.comm, logger, logging.INFO,
            "a factorisation of K would take %.2f GB of the %.2f GB available per rank: "
            "method 'krylov'", need / 1e9, available / 1e9,
        )
    return choose_method(tdim, disc.num_dofs, num_multipliers, fits=fits, **rule), assembled


def _semismooth_newton(
    system: NewtonLinearSystem,
    initial_guess: tuple[fem.Function, ...] | None,
    max_iterations: int,
    rtol: float,
    hold: RigidHold | None = None,
    force: ForceControl | None = None,
) -> Solution:
    """The loop of :func:`solve` on a set-up Newton system (see there).

    With ``hold`` (a body held only by contact) a step's set that leaves a free rigid motion
    unheld is completed by :meth:`~dwr_signorini.rigid.RigidHold.complete`.
    """
    disc = system.disc
    if not _all_finite(disc.comm, system.f.array, system.g.array):
        raise ConvergenceError(
            "NaN or Inf in the assembled load vector f or gap vector g: body_force, traction "
            "and gap must be finite everywhere on the mesh",
            [],
        )
    u, lams = _initial_iterate(system, initial_guess)
    loop = NewtonLoop(system, rtol, max_iterations)
    try:
        for it in range(max_iterations + 1):
            lam_owned = np.concatenate([f.x.array[: system.algebra.n_q] for f in lams])
            wanted, free = loop.measure(it, u, lam_owned)
            if loop.finished(it):
                break
            new, new_free, couplings = loop.next_set(it, wanted, free)
            if hold is not None:
                new = hold.apply(loop, system, u, new)
            if force is None:
                loop.linear_solve(it, new, new_free, couplings)
            else:
                force.step(functools.partial(loop.linear_solve, it), new, new_free, couplings)
                loop.moving = force.moving(rtol)
            u_new, lam_new = system.split(system.x)
            if not _all_finite(disc.comm, u_new, lam_new):
                loop.history[-1]["nonfinite"] = True
                raise ConvergenceError(
                    f"NaN or Inf in the Newton iterate of step {it} (singular or ill-posed "
                    "linear system?)",
                    loop.history,
                )
            theta = loop.step_length  # 1, or 1/2 once the sets of a coupled law cycled
            _update(u, u_new, theta)
            for f, values in zip(lams, system.algebra.components_of(lam_new), strict=True):
                _update(f, values, theta)
    finally:
        loop.destroy()
    system.set_loose(False)  # the dual problem reuses the system: at full accuracy
    out = _solution(system, u, lams, loop.history)
    if force is not None:
        out.obstacle_displacement = force.delta
    return out


def _update(f: fem.Function, values: np.ndarray, theta: float) -> None:
    """The owned values of ``f`` moved to ``values`` (a fraction ``theta`` of the way)."""
    owned = f.x.array[: len(values)]
    owned[:] = values if theta == 1.0 else owned + theta * (values - owned)
    f.x.scatter_forward()


def _all_finite(comm: MPI.Comm, *arrays: np.ndarray) -> bool:
    """Whether every entry of the arrays is finite on every rank (collective)."""
    ok = all(bool(np.all(np.isfinite(a))) for a in arrays)
    return bool(comm.allreduce(ok, op=MPI.LAND))


def _initial_iterate(
    system: NewtonLinearSystem, initial_guess: tuple[fem.Function, ...] | None
) -> tuple[fem.Function, list[fem.Function]]:
    """The displacement and the law's multipliers (lambda, then lambda_t) to start from.

    The displacement holds the prescribed Dirichlet values.
    """
    disc = system.disc
    u = fem.Function(disc.V, name="u")
    names = multiplier_names(system.algebra.components, "lambda")
    lams = [fem.Function(disc.Q, name=name) for name in names]
    if initial_guess is not None:
        u.x.array[:] = initial_guess[0].x.array
        for f, guess in zip(lams, initial_guess[1:], strict=False):
            f.x.array[:] = guess.x.array
        if not _all_finite(disc.comm, u.x.array, *(f.x.array for f in lams)):
            raise ValueError("initial_guess contains NaN or Inf")
    system.algebra.set_prescribed(u.x.array)  # the iterates satisfy the Dirichlet values
    return u, lams


def _solution(
    system: NewtonLinearSystem, u: fem.Function, lams: list[fem.Function],
    history: list[dict[str, Any]],
) -> Solution:
    """The :class:`Solution` of the converged loop."""
    comm = system.disc.comm
    algebra = system.algebra
    sets = algebra.components_of(system.active)
    free = algebra.components_of(system.free)
    stick = slip = lam_t = None
    if len(sets) > 1:
        coupled = np.zeros(len(system.active), dtype=bool)
        for cp in system.couplings:
            coupled[cp.rows.ravel()] = True
        moving = (free[1] != 0.0) | algebra.components_of(coupled)[1]
        stick, slip = sets[1] & sets[0], ~sets[1] & sets[0] & moving
        lam_t = lams[1] if len(lams) == 2 else traction_vector(system.disc, lams[1:])
    return Solution(
        u=u,
        lam=lams[0],
        active=sets[0].copy(),
        newton_iterations=len(history) - 1,
        history=history,
        disc=system.disc,
        system=system,
        ncp_scale=algebra.ncp_scale,
        method=method_name(system),
        num_active=comm.allreduce(int(sets[0].sum()), op=MPI.SUM),
        lam_t=lam_t,
        stick=stick,
        slip=slip,
        tangential=tuple(lams[1:]),
    )


def method_name(system: NewtonLinearSystem) -> str:
    """The name of the path ``system`` takes, as :attr:`Solution.method` reports it.

    ``"block"``, ``"schur"`` (K factored) or ``"krylov"``
    (:class:`~dwr_signorini.linalg.KrylovNewtonSystem`, or the Schur path with a Krylov solver
    of K).

    Args:
        system: A Newton system.

    Returns:
        The name, as :attr:`Solution.method` reports it.
    """
    if isinstance(system, KrylovNewtonSystem) or (
        isinstance(system, SchurNewtonSystem) and not system.direct
    ):
        return "krylov"
    return "schur" if isinstance(system, SchurNewtonSystem) else "block"
