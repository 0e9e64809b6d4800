r"""A rigid obstacle under a given force: its displacement delta, one unknown more.

An obstacle of :mod:`dwr_signorini.obstacles` given with ``force=F`` and a direction of approach
d moves rigidly by delta d; the offset of the normal condition in the contact frame (the gap
along the obstacle's normal n_c, g (n . n_c), :meth:`~dwr_signorini.spaces.Discretization.
normal_gap`) of the moved obstacle is g_c(x; delta), whose rate m_i = int_GC (dg_c/ddelta) psi_i
(m < 0 where the obstacle approaches; n_c moves with the obstacle, and both enter the
derivative) shifts the active rows, and delta is the unknown that makes the contact force
balance F.

Its equilibrium is stated with the contact force on the obstacle, the traction lam n_c of the
body on it, against its direction of approach:

    w^T lam = F,    w_i = int_GC (-n_c . d) psi_i.

On a plane (n_c its normal, constant) w = -m: the equilibrium is the derivative of the
Lagrangian 1/2 a(u, u) - l(u) - F delta + lam . (N u - g_c(delta)) and the bordered matrix below
is symmetric; on a curved obstacle the two differ by the turn of n_c with delta.

With friction the obstacle's motion along the contact frame's tangents e_l is a slip of the
obstacle: the tangential offsets are g_l = B_l (u_old + t + (delta - delta_0) d)
(:meth:`~dwr_signorini.fields.MeshFields.obstacle_motion`), at the rate m_l,i = int (d . e_l)
psi_i in delta, and the body's traction on the obstacle is lam_n n_c + lam_l e_l, so the
balance is

    w^T lam = sum_k w_k . lam_k = F,    w_k,i = int_GC (-e_k . d) psi_i    (e_0 = n_c),

over all the law's rows (:attr:`~dwr_signorini.algebra.ContactAlgebra.resultant`); on a plane
approached along its normal d . e_l = 0 and the frictional system is the frictionless one's.

So the Newton step of an active set A solves the bordered
system

    [ A     b ] [x    ]   [ r(g(delta_k) - m delta_k) ]
    [ c^T   0 ] [delta] = [ F                         ],

A the Newton matrix of :mod:`dwr_signorini.newton` (the last step's, for the dual problem), b its
column for delta (the gap's shift m delta on the active rows), c^T x = w^T lam. It is solved
with A's factorisation (:class:`ForceControl`): x1 = A^-1 r and x2 = A^-1 r(f = 0, g = m), the
response to a unit delta (m = (m_0, m_l) on the normal and tangential rows; on a coupled
facet its right-hand side -c J m, the iterate's r = P(x) - J x being data; the same active
set: the factors are reused), then
delta = (F - w^T lam1) / (w^T lam2) and x = x1 + delta x2. For a plane m does not depend on
delta and the step is exact; for a curved obstacle it is Newton's step in delta (the set is
not final until delta has settled too).

The dual problem is the transposed bordered system (:meth:`ForceControl.solve_transpose`): with
A^T z1 = j and A^T z2 = c, zeta = (x2 . j + j_delta) / (x2 . c) and z = z1 - zeta z2 (as
b = -A x2, b^T z = -x2 . A^T z); a goal J(w_h) linear in (u, lam) then satisfies
J = z . r + zeta F with the final set. A goal may use delta (``m.obstacle_displacement``);
j_delta = dJ/ddelta is differentiated by UFL (:meth:`~dwr_signorini.goal.GoalForms.rate`).

The P2 weights of the estimate (``weights="higher_order"``, ``"hierarchical"``) solve the same
bordered systems in P2 with the final active set, at w_h's delta (``move=False``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from .laws import Coupling
from .linalg import NewtonLinearSystem

__all__ = ["ForceControl"]

#: A linear solve of the bordered system's sets: ``(active, free, couplings) -> None``.
Solve = Callable[[np.ndarray, np.ndarray, "list[Coupling] | None"], None]


class ForceControl:
    """The bordered Newton steps of a force-controlled obstacle (module docstring).

    Args:
        system: The system it borders.
        move: Whether a step moves the obstacle to the new delta (the gap reassembled, the
            discretisation's Constant set): the Newton loop's; the P2 solves of the weights
            keep w_h's delta (their linear system at it, exact for a plane).

    Attributes:
        delta: The obstacle's displacement along its direction (the current iterate).
        change: The change of delta in the last step (its absolute value).
        x2: The response of the last step's system to a unit delta (block vector).
        zeta: The dual's entry for delta of the last dual solve (None before one).

    The same logic borders any system of the same layout: the Newton system of the primal
    problem (block path), the P2 system of the factored higher-order weights (a Newton system
    on the P2 space) and the two-level P2 system of the hierarchical weights
    (:mod:`~dwr_signorini.hierarchical`). What it reads off ``system``: ``disc``, ``algebra``
    (f, g, n_q, gap_rate, resultant, set_obstacle_displacement), the block vector ``x``,
    ``split`` and ``solve_transpose``.
    """

    def __init__(self, system: NewtonLinearSystem, move: bool = True) -> None:
        self.system = system
        self.move = move
        self.obstacle = system.disc.problem.force_obstacle
        self.comm: MPI.Comm = system.disc.comm
        self.delta = float(system.disc.fields.obstacle_displacement.value)
        self.change = np.inf
        self.x2 = system.x.duplicate()
        self.zeta: float | None = None
        system.algebra.set_obstacle_displacement(self.delta)

    @property
    def force(self) -> float:
        """The prescribed resultant F."""
        return float(self.obstacle.force)

    def rate(self) -> np.ndarray:
        """-m: the rows' gap residual per unit approach (owned normal rows)."""
        return -self.system.algebra.gap_rate

    def _dot(self, a: np.ndarray, b: np.ndarray) -> float:
        return float(self.comm.allreduce(float(a @ b), op=MPI.SUM))

    def step(
        self, solve: Solve, active: np.ndarray, free: np.ndarray,
        couplings: list[Coupling] | None = None,
    ) -> None:
        """One bordered Newton step into ``system.x``; delta (and, with ``move``, the gap) updated.

        Args:
            solve: ``(active, free, couplings) -> None``, the linear solve of the loop for the
                step's sets into ``system.x``
                (:meth:`~dwr_signorini.semismooth.NewtonLoop.linear_solve`).
            active: The step's constrained rows.
            free: The free multiplier values.
            couplings: The step's coupled facets (:class:`~dwr_signorini.laws.Coupling`).
        """
        self.unit_response(solve, active, free, couplings)
        solve(active, free, couplings)
        self.balance()

    def unit_response(
        self, solve: Solve, active: np.ndarray, free: np.ndarray,
        couplings: list[Coupling] | None = None,
    ) -> None:
        """x2: the bordered system's response to a unit delta (module docstring).

        The right-hand side's derivative in delta: f = 0, g = (m, m_t) (the normal rows' gap
        rate and, with friction, the tangential offsets' rate int (d . e_l) psi), nothing
        free, and the coupled facets' r = P(x) - J x (data of the iterate) zero.

        Args:
            solve: ``(active, free, couplings) -> None``, a solve of the bordered system into
                ``system.x`` with its algebra's f and g.
            active: The step's constrained rows.
            free: The free multiplier values (only their shape is used).
            couplings: The step's coupled facets, or None.
        """
        system, alg = self.system, self.system.algebra
        f_now, g_now = alg.f.array.copy(), alg.g.array.copy()
        still = [dataclasses.replace(cp, r=np.zeros_like(cp.r)) for cp in couplings or ()]
        try:
            alg.f.array_w[:] = 0.0
            alg.g.array_w[:] = 0.0
            alg.g.array_w[: alg.n_q] = alg.gap_rate
            alg.g.array_w[alg.n_q :] = alg.slip_rate
            solve(active, np.zeros_like(free), still)
            system.x.copy(self.x2)
        finally:
            alg.f.array_w[:] = f_now
            alg.g.array_w[:] = g_now

    def balance(self) -> None:
        """The new delta from the force row, ``system.x`` holding x1, the solution at delta_k.

        The bordered step in increments: d delta = (F - w^T lam1) / (w^T lam2), x = x1 +
        d delta x2 (the same step as the module docstring's; x1 solved at delta_k).
        """
        system = self.system
        w = system.algebra.resultant
        lam1 = system.split(system.x)[1]
        lam2 = system.split(self.x2)[1]
        response = self._dot(w, lam2)
        if response == 0.0:
            raise np.linalg.LinAlgError(
                "the force-controlled obstacle touches no active facet: its force cannot be "
                "balanced"
            )
        change = (self.force - self._dot(w, lam1)) / response
        system.x.axpy(change, self.x2)
        self.change = abs(change)
        self.delta += change
        if self.move:
            system.algebra.set_obstacle_displacement(self.delta)

    def moving(self, rtol: float) -> bool:
        """Whether delta still changes by more than ``rtol`` of its size (Newton in delta)."""
        return self.change > rtol * max(abs(self.delta), 1e-300)

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec, j_delta: float = 0.0) -> float:
        """The dual of the bordered system: z (block vector) and zeta, its entry for delta.

        Args:
            rhs: [j_u; j_lam], the goal's derivative in (u, lam), laid out as ``system.x``.
            z: Block vector for the dual's (y, xi).
            j_delta: The goal's derivative in delta.

        Returns:
            zeta.
        """
        system = self.system
        c = rhs.duplicate()
        c.set(0.0)
        c.array_w[system.n_u :] = system.algebra.resultant
        z2 = rhs.duplicate()
        z2.set(0.0)  # an iterative system starts from it
        try:
            system.solve_transpose(rhs, z)
            system.solve_transpose(c, z2)
            x2 = self.x2.array_r
            zeta = (self._dot(x2, rhs.array_r) + j_delta) / self._dot(x2, c.array_r)
            z.axpy(-zeta, z2)
            self.zeta = zeta
        finally:
            c.destroy()
            z2.destroy()
        return zeta

    def destroy(self) -> None:
        """Release the work vector (collective)."""
        self.x2.destroy()
