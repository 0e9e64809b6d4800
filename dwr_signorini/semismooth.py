"""The bookkeeping of the semi-smooth Newton method: residuals, history, sets, safeguards.

:class:`NewtonLoop` measures an iterate (the residuals as backward errors, the sets the rule (21)
and its tangential analogue want, :meth:`~dwr_signorini.algebra.ContactAlgebra.newton_sets`),
decides whether the method has converged or failed, picks the next step's sets with the cycling
safeguard (Murty's least-index rule) and solves the step's linear system, turning its failures
into a :class:`ConvergenceError` with the iteration history. The loop itself is
:func:`dwr_signorini.newton.solve`'s.
"""

from __future__ import annotations

import logging
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from dolfinx import fem

from .algebra import distributed_norm
from .collective import CollectiveError, collective, log_on_root
from .laws import Coupling
from .linalg import LinearSolveError, NewtonLinearSystem, mumps_failure

__all__ = ["ConvergenceError", "NewtonLoop"]

logger = logging.getLogger("dwr_signorini.newton")

#: Steps on settled sets an iterative solve may take, each with a tighter tolerance, to bring
#: its residuals below rtol
MAX_REFINEMENTS = 2


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
                + (" [damped]" if h.get("damped") else "")
                + (" [NaN/Inf]" if h.get("nonfinite") else "")
            )
        super().__init__("\n".join(lines))
        self.history = history


def _global_key(comm: MPI.Comm, *states: np.ndarray) -> tuple[bytes, ...]:
    """The global sets, exactly (packed bits of every rank's owned rows), as a dict key."""
    local = b"".join(np.packbits(a).tobytes() + a.size.to_bytes(8, "little") for a in states)
    return tuple(comm.allgather(local))


class NewtonLoop:
    """The semi-smooth Newton method's bookkeeping: residuals, history, sets, safeguards.

    The sets of a step are the constrained rows of each component of the contact law (active,
    stick), the multiplier values on the free ones (0 inactive, +-s slip) and the coupled rows
    of a projection onto a ball (3D slip, :class:`~dwr_signorini.laws.Coupling`), from
    :meth:`~dwr_signorini.algebra.ContactAlgebra.newton_sets` at the previous iterate. On the
    coupled rows the step is that of a smooth Newton method: a coupled row counts as changed
    while its NCP residual is above ``rtol`` of its size, and a step whose sets are those of
    the step before is not cycling.
    """

    def __init__(self, system: NewtonLinearSystem, rtol: float, max_iterations: int) -> None:
        self.system, self.rtol, self.max_iterations = system, rtol, max_iterations
        self.comm = system.disc.comm
        self.lam_vec = system.N.createVecLeft()
        self.nt_lam = system.f.duplicate()
        self.norm_f = system.f.norm()
        self.norm_K = system.algebra.stiffness_norm()
        self.history: list[dict[str, Any]] = []
        self.loose = system.set_loose(True)
        self.seen: dict[tuple[bytes, ...], int] = {}
        self.previous: np.ndarray | None = None
        self.previous_free: np.ndarray | None = None
        self.couplings: list[Coupling] = []
        self.last_key: tuple[bytes, ...] | None = None
        self.safeguard_since: int | None = None
        self.violated: np.ndarray | None = None
        self.switching: np.ndarray | None = None
        # a law whose projections act on several components (Coulomb's, Tresca's in 3D)
        self.coupled_law = any(len(idx) > 1 for idx, _ in system.algebra.conditions)
        self.damped_since: int | None = None
        self.step_length = 1.0
        #: A force-controlled obstacle's displacement still changing (then the sets settling
        #: is not the end: dwr_signorini.force)
        self.moving = False
        #: Steps taken on settled sets with a tightened linear solve (see _refining)
        self.refinements = 0
        self.q_start = system.disc.Q.dofmap.index_map.local_range[0]

    def destroy(self) -> None:
        """Release the work vectors."""
        self.lam_vec.destroy()
        self.nt_lam.destroy()

    def measure(
        self, it: int, u: fem.Function, lam: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The residuals of the iterate (a history record) and the sets the rule (21) wants.

        Residuals as backward errors: the equilibrium residual relative to the size of the
        terms K u, B^T lam, f; the NCP functions entry by entry relative to their terms' size.
        """
        system, comm = self.system, self.comm
        u_vec = u.x.petsc_vec
        u_max = comm.allreduce(float(np.max(np.abs(u.x.array), initial=0.0)), op=MPI.MAX)
        wanted, free, ncp, size, self.couplings = system.algebra.newton_sets(u_vec, lam, u_max)
        relative = np.divide(ncp, size, out=np.zeros_like(ncp), where=size > 0)
        if self.previous is None:
            violated = np.ones_like(wanted)
        else:
            violated = (wanted != self.previous) | (
                ~wanted & ~self.previous & (free != self.previous_free)
            )
        self.switching = violated.copy()  # the rows whose set the rule would change
        for coupling in self.couplings:
            rows = coupling.rows.ravel()
            violated[rows] |= relative[rows] > self.rtol
        self.violated = violated
        self.lam_vec.array_w[:] = lam
        system.NT.mult(self.lam_vec, self.nt_lam)
        norm_Ku = self.norm_K * distributed_norm(comm, u.x.array[: system.n_u])
        scale_eq = max(self.norm_f, self.nt_lam.norm(), norm_Ku, 1e-300)
        res_eq = system.algebra.equilibrium_residual(u_vec, lam) / scale_eq
        local_ncp = np.max(relative, initial=0.0)
        rel_ncp = comm.allreduce(float(local_ncp), op=MPI.MAX)
        num_changed = comm.allreduce(int(violated.sum()), op=MPI.SUM)
        record = {
            "iteration": it,
            "num_active": self._count(wanted, 0),
            "num_changed": num_changed,
            "residual_equilibrium": res_eq,
            "residual_ncp": rel_ncp,
            "ncp_scale": system.algebra.ncp_scale,
            "safeguard": self.safeguard_since is not None,
            "loose": self.loose,
        }
        if len(system.algebra.components) > 1:
            record["num_stick"] = self._count(wanted, 1)
        self.history.append(record)
        log_on_root(
            comm, logger, logging.INFO, "Newton %d: |A| = %d, changed %d, residuals %.2e / %.2e",
            it, record["num_active"], num_changed, res_eq, rel_ncp,
        )
        return wanted, free

    def _refining(self) -> bool:
        """Whether to take one more step on settled sets, with a tighter linear solve.

        An iterative solve may leave the NCP residual above ``rtol`` when the sets settle (its
        tolerance is relative to the whole right-hand side, the NCP residual to each facet's
        size); the system tightens its tolerance (``system.refine()``) at most
        ``MAX_REFINEMENTS`` times. Direct solvers have nothing to tighten.
        """
        if self.refinements >= MAX_REFINEMENTS or not self.system.refine():
            return False
        self.refinements += 1
        return True

    def _count(self, rows: np.ndarray, component: int) -> int:
        """Global number of set rows of one component."""
        part = self.system.algebra.components_of(rows)[component]
        return self.comm.allreduce(int(part.sum()), op=MPI.SUM)

    def finished(self, it: int) -> bool:
        """Converged (True), or one more step to take; raises when the method has failed."""
        record = self.history[-1]
        # after a damped step the iterate is not the solution of its sets' system: their full
        # step comes next (the sets repeating is what ends the damping, see _damped)
        settled = (
            self.previous is not None and record["num_changed"] == 0 and self.step_length == 1.0
            and not self.moving
        )
        self.resolve = settled and self.loose
        if self.resolve:  # the sets have settled: solve their system again, accurately
            self.loose = self.system.set_loose(False)
        elif settled:
            if record["residual_equilibrium"] <= self.rtol and record["residual_ncp"] <= self.rtol:
                return True
            if self._refining():
                return False
            raise ConvergenceError(
                f"the active set is stationary but the residuals are not below rtol={self.rtol:g}: "
                "the linear solves are inaccurate (check petsc_options; a direct solver is "
                "the default)" + self.unsettled_facets(),
                self.history,
            )
        if it == self.max_iterations:
            extra = (
                f" (least-index safeguard active since step {self.safeguard_since})"
                if self.safeguard_since is not None
                else ""
            )
            raise ConvergenceError(
                f"no convergence in max_iterations={self.max_iterations} Newton steps{extra}; "
                "raise max_iterations or warm-start from a nearby solution"
                + self.unsettled_facets(),
                self.history,
            )
        return False

    def unsettled_facets(self, most: int = 8) -> str:
        """Where the method has not settled, for a :class:`ConvergenceError`'s message.

        The macro contact facets whose sets the last test would change or whose NCP residual
        is above ``rtol`` (their midpoints, at most ``most``, with the component), the last
        residuals, and for a frictional law what to try. Collective.
        """
        system, comm = self.system, self.comm
        algebra = system.algebra
        mask = np.zeros(algebra.n_q * len(algebra.components), dtype=bool)
        if self.violated is not None:
            mask |= self.violated
        x = system.disc.Q.tabulate_dof_coordinates()[: algebra.n_q]
        names = [c.name for c in algebra.components]
        local = [
            (names[k], "(" + ", ".join(f"{v:.6g}" for v in x[i, : system.disc.mesh.geometry.dim])
             + ")")
            for k, part in enumerate(algebra.components_of(mask))
            for i in np.flatnonzero(part)
        ]
        found = [f for rank in comm.allgather(local) for f in rank]
        record = self.history[-1] if self.history else None
        lines = [f"; {len(found)} facet rows not settled"]
        if found:
            shown = ", ".join(f"{name} at {point}" for name, point in found[:most])
            lines.append(f" ({shown}{', ...' if len(found) > most else ''})")
        if record is not None:
            lines.append(
                f"; last residuals: equilibrium {record['residual_equilibrium']:.2e}, "
                f"NCP {record['residual_ncp']:.2e}"
            )
        if algebra.disc.problem.law.frictional:
            lines.append(
                "; to try: ds.solve_path with the load in n steps (e.g. press first, then "
                "shear), a smaller friction coefficient or threshold first (its solution as "
                "initial_guess), or more max_iterations"
            )
        return "".join(lines)

    def next_set(
        self, it: int, wanted: np.ndarray, free: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, list[Coupling]]:
        """The sets of the next step: the rule's, with the cycling safeguard (see :func:`solve`).

        Returns:
            The constrained rows, the free values and the coupled facets whose rows the step
            neither constrains nor frees.
        """
        if self.resolve:
            new, new_free = self.previous, self.previous_free
            # The sets visited by loose steps say nothing of cycling of the accurate ones: an
            # accurate step back to one of them corrects a loose step's error on nearly
            # degenerate rows. The accurate steps keep their own record, and their safeguard.
            self.seen.clear()
            self.safeguard_since = None
        else:
            new, new_free = wanted, free
        key = self._key(new, new_free)
        repeated = key in self.seen and key != self.last_key
        if repeated and self.loose:
            # Loose steps can cycle on their solves' error alone (nearly degenerate rows on
            # the wrong side): from here on every step is solved accurately, with its own record.
            log_on_root(self.comm, logger, logging.INFO,
                        "step %d repeats the sets of step %d: accurate solves", it, self.seen[key])
            self.loose = self.system.set_loose(False)
            self.seen.clear()
            repeated = False
        self.step_length = 1.0
        if self.coupled_law and (repeated or self.damped_since is not None):
            return self._damped(it, key, new, new_free, repeated)
        if repeated and not self.resolve:
            if self.safeguard_since is not None:
                raise ConvergenceError(
                    f"active-set cycling: the set of step {it} repeats step {self.seen[key]} "
                    "even under the least-index safeguard (is the body clamped, i.e. is "
                    "N K^-1 N^T positive definite?)" + self.unsettled_facets(),
                    self.history,
                )
            log_on_root(
                self.comm, logger, logging.WARNING,
                "active-set cycling (step %d repeats step %d): least-index safeguard",
                it, self.seen[key],
            )
            self.safeguard_since = it
            self.seen.clear()
        if self.safeguard_since is not None and not self.resolve:
            # the least index among the rows whose set changes (a coupled row whose NCP
            # residual is not small yet has no set to change: its coupling follows the iterate)
            first = self._least_index(self.switching)
            new = np.where(first, wanted, self.previous)
            new_free = np.where(first, free, self.previous_free)
            key = self._key(new, new_free)
            self.history[-1]["num_active"] = self._count(new, 0)
            self.history[-1]["safeguard"] = True
        self.seen[key] = it
        self.last_key = key
        # a facet whose rows are all constrained (stick) is not coupled in this step
        couplings = [c.restricted(~new[c.rows].all(axis=1)) for c in self.couplings]
        return new, new_free, couplings

    def _damped(
        self, it: int, key: tuple[bytes, ...], new: np.ndarray, free: np.ndarray,
        repeated: bool,
    ) -> tuple[np.ndarray, np.ndarray, list[Coupling]]:
        """The sets of a step of a law with coupled rows once its sets have cycled.

        Murty's rule is for the linear complementarity problem of the normal contact (a
        P-matrix); Coulomb's law is not one, and on it the rule can cycle too (measured: a
        2-cycle of slip directions that changing one row per step does not break). Instead the
        step takes the rule's sets and only half of the Newton update (:attr:`step_length`)
        while its sets differ from the last step's; once they repeat, full steps converge on
        the coupled rows as a smooth Newton method.
        """
        if self.damped_since is None:
            log_on_root(
                self.comm, logger, logging.WARNING,
                "active-set cycling (step %d repeats step %d): damped steps", it,
                self.seen[key],
            )
            self.damped_since = it
        if repeated or key != self.last_key:
            self.step_length = 0.5
            self.history[-1]["damped"] = True
        self.seen[key] = it
        self.last_key = key
        couplings = [c.restricted(~new[c.rows].all(axis=1)) for c in self.couplings]
        return new, free, couplings

    def _key(self, new: np.ndarray, free: np.ndarray) -> tuple[bytes, ...]:
        """The global sets of a step as a key: constrained, free > 0, free < 0, coupled."""
        coupled = np.zeros_like(new)
        for c in self.couplings:
            coupled |= c.mask(len(new))
        return _global_key(self.comm, new, free > 0, free < 0, coupled & ~new)

    def _least_index(self, mask: np.ndarray) -> np.ndarray:
        """Only the set entry with the smallest global number (on its owning rank).

        Rows are numbered component by component (all normal rows first).
        """
        comm, n_q = self.comm, self.system.algebra.n_q
        local = np.flatnonzero(mask)
        n_global = self.system.disc.Q.dofmap.index_map.size_global
        if local.size:
            k, i = divmod(int(local[0]), n_q) if n_q else (0, 0)
            mine = k * n_global + self.q_start + i
        else:
            mine = np.iinfo(np.int64).max
        first = comm.allreduce(mine, op=MPI.MIN)
        out = np.zeros_like(mask)
        if local.size and mine == first:
            out[local[0]] = True
        return out

    def linear_solve(
        self, it: int, new: np.ndarray, free: np.ndarray, couplings: list[Coupling] | None = None
    ) -> None:
        """The linear system of the step's sets, its failures as :class:`ConvergenceError`."""
        system, history = self.system, self.history
        try:
            # A failure that one rank sees first (after the solve's last collective) is
            # raised on every rank (dwr_signorini.collective).
            with collective(self.comm, f"Newton step {it}: the linear solve"):
                system.solve_active(new, free, couplings)
        except (LinearSolveError, PETSc.Error, np.linalg.LinAlgError) as err:
            raise ConvergenceError(
                f"Newton step {it}: linear solve failed ({_failure_name(system, err)}); "
                f"{_failure_hint(system, err)}",
                history,
            ) from err
        self.previous, self.previous_free = new, free


def _failure_name(system: NewtonLinearSystem, err: BaseException) -> str:
    """What failed in a linear solve, for the message of :class:`ConvergenceError`."""
    reason = system.ksp.getConvergedReason()
    names = vars(PETSc.KSP.ConvergedReason).items()
    name = next((k for k, v in names if v == reason and k.isupper()), str(reason))
    if isinstance(err, CollectiveError):
        ranks = ", ".join(map(str, err.ranks))
        size = system.disc.comm.size
        on = f" on rank(s) {ranks} of {size}" if size > 1 else ""
        name = f"{err.error_type}{on}: {err.error_message.splitlines()[0]}"
    elif isinstance(err, PETSc.Error):
        name = f"PETSc error {err.ierr}"
    elif isinstance(err, np.linalg.LinAlgError):
        # LinAlgError: the Cholesky factorisation of S_AA (method="schur") failed.
        name = str(err)
    return name


def _failure_hint(system: NewtonLinearSystem, err: BaseException) -> str:
    """What to check after a failed linear solve."""
    cause = mumps_failure(system.ksp)
    if cause is not None:
        return cause
    if isinstance(err, (PETSc.Error, np.linalg.LinAlgError)) or system.ksp.getConvergedReason() == (
        PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED
    ):
        return (
            "the factorisation or preconditioner failed: the Newton matrix is "
            "singular (the body is not held in place, check dirichlet; or active "
            "contact constraints are linearly dependent, e.g. a contact facet whose "
            "nodes are all clamped), or the preconditioner in petsc_options does "
            "not suit this saddle-point system"
        )
    return "the linear solver did not converge: check petsc_options"
