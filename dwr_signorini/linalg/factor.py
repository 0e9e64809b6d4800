"""A factored Newton matrix kept for later steps, and when its reuse pays.

The paths that factor the Newton matrix (:mod:`~dwr_signorini.linalg.block`, LDL^T;
:mod:`~dwr_signorini.linalg.coupled`, LU) share :class:`FactoredNewtonSystem`: its
:class:`Factorisation` factors a copy of the step's matrix with MUMPS (one sparsity pattern for
all steps, so the analysis is kept), solves with the factors, and turns MUMPS's failures into
:class:`~dwr_signorini.linalg.base.LinearSolveError` (or LinAlgError for null pivots). A step
is solved with the factors of an earlier one and a low-rank update (:mod:`~.lowrank`), checked
by iterative refinement (:meth:`Factorisation.refine`), when its solves cost less than a
fraction of a new factorisation (:class:`ReusePolicy`, a value handed to the systems).

The decision changes the iterates by round-off (an update is accepted at a relative error of
:attr:`ReusePolicy.rtol`), so it must not depend on measured time: the same input has to give
the same Newton history on every run. :class:`ReusePolicy` prices both from the counts MUMPS
reports after a factorisation (:class:`FactorCost`), which are the same on every rank and
every run:

* the factorisation: RINFOG(3), its floating-point operations;
* a solve: INFOG(29), the entries of the factors, each read once per triangular solve, priced
  at :attr:`ReusePolicy.solve_entry_cost` factorisation flops (a solve is memory bound, a
  factorisation runs dense BLAS-3 kernels).

Measured on this package's Newton matrices (2D and 3D, block LDL^T and coupled LU, 1k-30k
rows, one rank): t_solve / t_factor = k INFOG(29) / RINFOG(3) with k from 16 to 45, growing
with the size as the factorisation's kernels get denser; the default
:attr:`ReusePolicy.solve_entry_cost` is the middle of that range, so a decision is off by at
most a factor of about two in time, not in result.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from ..lifetime import destroy_attributes
from ..timing import timed
from .base import LinearSolveError, NewtonLinearSystem
from .mumps import mumps_factor, mumps_failure, null_pivots, set_up

__all__ = ["FactorCost", "FactoredNewtonSystem", "Factorisation", "ReusePolicy"]


@dataclass(frozen=True)
class FactorCost:
    """The counts of a MUMPS factorisation that price its reuse (module docstring).

    Attributes:
        flops: The factorisation's floating-point operations (RINFOG(3)).
        entries: The entries of the factors (INFOG(29)).
    """

    flops: float
    entries: float

    @classmethod
    def of(cls, ksp: PETSc.KSP) -> FactorCost | None:
        """The counts of the factorisation held by ``ksp``'s preconditioner.

        Args:
            ksp: A set-up solver.

        Returns:
            The counts, or None where the preconditioner is no MUMPS factorisation (then no
            step reuses its factors).
        """
        factor = mumps_factor(ksp)
        if factor is None:
            return None
        entries = float(factor.getMumpsInfog(29))
        if entries < 0:  # MUMPS counts in millions where the number does not fit an int
            entries = -entries * 1e6
        return cls(max(float(factor.getMumpsRinfog(3)), 1.0), entries)


@dataclass(frozen=True)
class ReusePolicy:
    """When a Newton step is solved with the factors of an earlier one (module docstring).

    Attributes:
        fraction: A step reuses the factors if its solves take at most this part of a
            factorisation; negative: never (every step is factored).
        block_solve_cost: The time of a solve of k right-hand sides at once with MUMPS's
            factors, in single solves per right-hand side (about 0.2-0.3 for 8-40 right-hand
            sides on 3D factors of 30k DoFs).
        solve_entry_cost: The cost of a solve per entry of the factors, in flops of the
            factorisation.
        dense_relative_rate: The rate of an update's dense products (BLAS-3 on n x 2r blocks)
            relative to the rate of the sparse factorisation, per floating-point operation.
        rtol: Largest relative error (estimated by iterative refinement, per block, max norms)
            of a step solved by reusing the factors.
        refine_steps: Most steps of iterative refinement of a solve by reused factors before
            they are refused.

    An update costs two single solves, one solve of k right-hand sides at once and dense
    products; it is taken when that is at most :attr:`fraction` of the last factorisation.
    A system takes its policy as ``reuse`` (e.g. ``NewtonSystem(disc, reuse=ReusePolicy(
    fraction=-1.0))`` factors every step); without one, the class attribute
    :attr:`FactoredNewtonSystem.reuse` (these defaults).
    """

    fraction: float = 0.7
    block_solve_cost: float = 0.3
    solve_entry_cost: float = 25.0
    dense_relative_rate: float = 2.0
    rtol: float = 1e-9
    refine_steps: int = 3

    def solve(self, cost: FactorCost) -> float:
        """The cost of one solve with factors.

        Args:
            cost: The counts of the factorisation.

        Returns:
            The cost, in factorisations.
        """
        return self.solve_entry_cost * cost.entries / cost.flops

    def dense(self, cost: FactorCost, flops: float) -> float:
        """The cost of dense products.

        Args:
            cost: The counts of the factorisation.
            flops: The products' floating-point operations.

        Returns:
            The cost, in factorisations.
        """
        return flops / (self.dense_relative_rate * cost.flops)

    def pays(self, cost: FactorCost, rhs: int, dense: float = 0.0) -> bool:
        """Whether an update of the factors is to be taken.

        Args:
            cost: The counts of the factorisation.
            rhs: The right-hand sides of the update's solve with the factors (two single
                solves come on top).
            dense: The floating-point operations of its dense products.

        Returns:
            Whether the update costs at most :attr:`fraction` of the factorisation.
        """
        price = (2 + self.block_solve_cost * rhs) * self.solve(cost) + self.dense(cost, dense)
        return price <= self.fraction


class Factorisation:
    """The factors of a Newton matrix held by a solver's preconditioner, kept for later steps.

    Args:
        ksp: The solver (``preonly`` with MUMPS's LDL^T or LU by default); its owner's.
        policy: When the factors are reused.

    Attributes:
        matrix: A copy of the factored matrix, the solver's operator (None before the first
            factorisation).
        cost: The counts of the last factorisation (None: no MUMPS factorisation, no reuse).
        count: Factorisations so far.
    """

    def __init__(self, ksp: PETSc.KSP, policy: ReusePolicy) -> None:
        self.ksp, self.policy = ksp, policy
        self.matrix: PETSc.Mat | None = None
        self.cost: FactorCost | None = None
        self.count = 0

    def factor(self, A: PETSc.Mat) -> None:
        """Factor a copy of ``A`` (the same pattern as before: the analysis is kept).

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots (a singular Newton matrix).
        """
        if self.matrix is None:
            self.matrix = A.copy()
        else:
            A.copy(self.matrix, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        with timed("factorize"):
            set_up(self.ksp, self.matrix)
        self.cost = FactorCost.of(self.ksp)
        self.count += 1
        count = null_pivots(self.ksp)
        if count > 0:
            raise np.linalg.LinAlgError(
                f"MUMPS found {count} null pivots: the Newton matrix is singular"
            )

    @property
    def reusable(self) -> bool:
        """Whether later steps may reuse the factors (there are some, priced, and allowed)."""
        return self.matrix is not None and self.cost is not None and self.policy.fraction >= 0

    def pays(self, rhs: int, dense: float = 0.0) -> bool:
        """Whether an update of ``rhs`` right-hand sides and ``dense`` flops pays (policy)."""
        return self.cost is not None and self.policy.pays(self.cost, rhs, dense)

    def check(self, what: str) -> None:
        """LinearSolveError if the last solve failed, with MUMPS's reason.

        Args:
            what: The solve, for the message.
        """
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            cause = mumps_failure(self.ksp)
            raise LinearSolveError(
                f"{what} failed (KSP reason {reason})" + (f": {cause}" if cause else "")
            )

    def refine(self, A: PETSc.Mat, update: Any, rhs: PETSc.Vec, x: PETSc.Vec, n_u: int) -> bool:
        """Iterative refinement of A x = rhs, at most ``refine_steps``; whether x is accurate.

        The correction d of A d = rhs - A x (solved by ``update``, a low-rank update of the
        factors) measures the error of x: once it is below the policy's ``rtol`` of x in each
        block (displacements, the first ``n_u`` owned entries, and multipliers; max norms),
        x + d is accepted. A correction above it is applied and the next step measures again:
        the Woodbury solves lose a few digits when the capacitance matrix is ill-conditioned,
        and one more step recovers them at the cost of one solve, not a factorisation.
        """
        residual, correction = rhs.duplicate(), x.duplicate()
        comm = A.getComm().tompi4py()
        try:
            for _ in range(self.policy.refine_steps):
                A.mult(x, residual)
                residual.aypx(-1.0, rhs)
                update.solve(residual, correction)
                x.axpy(1.0, correction)
                accurate = True
                for part in (slice(0, n_u), slice(n_u, None)):
                    size = comm.allreduce(
                        float(np.max(np.abs(x.array_r[part]), initial=0.0)), op=MPI.MAX
                    )
                    error = comm.allreduce(
                        float(np.max(np.abs(correction.array_r[part]), initial=0.0)), op=MPI.MAX
                    )
                    accurate &= error <= self.policy.rtol * size
                if accurate:
                    return True
            return False
        finally:
            for vec in (residual, correction):
                vec.destroy()

    def destroy(self) -> None:
        """Destroy the copy of the factored matrix (collective; the solver is its owner's)."""
        destroy_attributes(self, ("matrix",))


class FactoredNewtonSystem(NewtonLinearSystem):
    """A Newton system that factors its Newton matrix and reuses the factors (module docstring).

    Args:
        args, kwargs: See :class:`~dwr_signorini.linalg.base.NewtonLinearSystem`.
        reuse: When a step is solved with the factors of an earlier one (None: the class's
            :attr:`reuse`, the defaults of :class:`ReusePolicy`).

    Attributes:
        reuse: The reuse policy.
        factors: The :class:`Factorisation` of the Newton matrices.
        A: The Newton matrix of the last step (None before the first).
        b: The right-hand side of the last step.
        reused: Steps solved with the factors of an earlier step.
    """

    reuse: ReusePolicy = ReusePolicy()

    _petsc_objects = (*NewtonLinearSystem._petsc_objects, "A", "b")

    def __init__(self, *args: Any, reuse: ReusePolicy | None = None, **kwargs: Any) -> None:
        if reuse is not None:
            self.reuse = reuse
        self.factors: Factorisation | None = None
        super().__init__(*args, **kwargs)

    def _setup(self) -> None:
        """The factorisation of the steps (the subclasses add their own set-up)."""
        self.A: PETSc.Mat | None = None
        self.factors = Factorisation(self.ksp, self.reuse)
        self.reused = 0

    @property
    def factorizations(self) -> int:
        """Factorisations so far."""
        return 0 if self.factors is None else self.factors.count

    def _factor(self) -> None:
        """Factor the Newton matrix of the last step (the subclasses keep what goes with it)."""
        self.factors.factor(self.A)

    def _solve_by_update(self) -> bool:
        """Solve the step with the factors of an earlier one, if that pays; whether it did."""
        raise NotImplementedError

    def _solve_step(self) -> None:
        """Solve the assembled step A x = b: by an update of old factors, or factored anew.

        Raises:
            numpy.linalg.LinAlgError: MUMPS found null pivots (a singular Newton matrix).
            LinearSolveError: The solve failed.
        """
        if self._solve_by_update():
            self.reused += 1
            self.solved = True
            return
        self._factor()
        with timed("newton solve"):
            self.ksp.solve(self.b, self.x)
        self.factors.check("linear solve of the Newton step")
        self.solved = True

    def destroy(self) -> None:
        """Destroy the PETSc objects and remove the options (collective; idempotent)."""
        super().destroy()
        if self.factors is not None:
            self.factors.destroy()
