"""The price of a factorisation and of a solve with its factors, from MUMPS's own counts.

Factor reuse (:mod:`~dwr_signorini.linalg.block`, :mod:`~dwr_signorini.linalg.coupled`) solves a
Newton step with the factors of an earlier one and a low-rank update when its solves cost less
than a fraction of a new factorisation. The decision changes the iterates by round-off (an
update is accepted at a relative error of :data:`~dwr_signorini.linalg.block.REUSE_RTOL`), so it
must not depend on measured time: the same input has to give the same Newton history on every
run. :class:`FactorCost` prices both from the counts MUMPS reports after a factorisation, which
are the same on every rank and every run:

* the factorisation: RINFOG(3), its floating-point operations;
* a solve: INFOG(29), the entries of the factors, each read once per triangular solve, priced
  at :data:`SOLVE_ENTRY_COST` factorisation flops (a solve is memory bound, a factorisation
  runs dense BLAS-3 kernels).

Measured on this package's Newton matrices (2D and 3D, block LDL^T and coupled LU, 1k-30k
rows, one rank): t_solve / t_factor = k INFOG(29) / RINFOG(3) with k from 16 to 45, growing
with the size as the factorisation's kernels get denser; :data:`SOLVE_ENTRY_COST` is the
middle of that range, so a decision is off by at most a factor of about two in time, not in
result.
"""

from __future__ import annotations

from dataclasses import dataclass

from petsc4py import PETSc

from .mumps import mumps_factor

__all__ = ["DENSE_RELATIVE_RATE", "SOLVE_ENTRY_COST", "FactorCost"]

#: The cost of a solve per entry of the factors, in flops of the factorisation.
SOLVE_ENTRY_COST = 25.0

#: The rate of an update's dense products (BLAS-3 on n x 2r blocks) relative to the rate of
#: the sparse factorisation, per floating-point operation.
DENSE_RELATIVE_RATE = 2.0


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

    @property
    def solve(self) -> float:
        """The cost of one solve with the factors, in factorisations."""
        return SOLVE_ENTRY_COST * self.entries / self.flops

    def dense(self, flops: float) -> float:
        """The cost of ``flops`` operations of dense products, in factorisations."""
        return flops / (DENSE_RELATIVE_RATE * self.flops)
