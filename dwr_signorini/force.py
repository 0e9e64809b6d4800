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

So the Newton step of an active set A solves the bordered
system

    [ A     b ] [x    ]   [ r(g(delta_k) - m delta_k) ]
    [ c^T   0 ] [delta] = [ F                         ],

A the Newton matrix of :mod:`dwr_signorini.newton` (the last step's, for the dual problem), b its
column for delta (the gap's shift m delta on the active rows), c^T x = w^T lam. It is solved
with A's factorisation (:class:`ForceControl`): x1 = A^-1 r and x2 = A^-1 r(f = 0, g = m), the
response to a unit delta (the same active set: the factors are reused), then
delta = (F - w^T lam1) / (w^T lam2) and x = x1 + delta x2. For a plane m does not depend on
delta and the step is exact; for a curved obstacle it is Newton's step in delta (the set is
not final until delta has settled too).

The dual problem is the transposed bordered system (:meth:`ForceControl.solve_transpose`): with
A^T z1 = j and A^T z2 = c, zeta = (x2 . j + j_delta) / (x2 . c) and z = z1 - zeta z2 (as
b = -A x2, b^T z = -x2 . A^T z); a goal J(w_h) linear in (u, lam) then satisfies
J = z . r + zeta F with the final set. A goal may use delta (``m.obstacle_displacement``);
j_delta = dJ/ddelta is its central difference (:meth:`ForceControl.goal_rate`).
"""

from __future__ import annotations

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

from .linalg import NewtonLinearSystem

__all__ = ["ForceControl"]


class ForceControl:
    """The bordered Newton steps of a force-controlled obstacle (module docstring).

    Args:
        system: The Newton system (block path).

    Attributes:
        delta: The obstacle's displacement along its direction (the current iterate).
        change: The change of delta in the last step (its absolute value).
        x2: The response of the last step's system to a unit delta (block vector).
        zeta: The dual's entry for delta of the last dual solve (None before one).
    """

    def __init__(self, system: NewtonLinearSystem) -> None:
        self.system = system
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

    def step(self, solve: object, active: np.ndarray, free: np.ndarray) -> None:
        """One bordered Newton step into ``system.x``; delta and the gap updated.

        Args:
            solve: ``(active, free) -> None``, the linear solve of the loop for the step's sets
                (:meth:`~dwr_signorini.semismooth.NewtonLoop.linear_solve`).
            active: The step's constrained rows.
            free: The free multiplier values.
        """
        system, alg = self.system, self.system.algebra
        n_q = alg.n_q
        m = alg.gap_rate.copy()
        f_now, g_now = alg.f.array.copy(), alg.g.array.copy()
        try:
            alg.f.array_w[:] = 0.0  # the response to a unit delta: f = 0, g = m, nothing free
            alg.g.array_w[:] = 0.0
            alg.g.array_w[:n_q] = m
            solve(active, np.zeros_like(free))
            system.x.copy(self.x2)
            alg.f.array_w[:] = f_now
            alg.g.array_w[:] = g_now
            alg.g.array_w[:n_q] -= m * self.delta
            solve(active, free)
        finally:
            alg.f.array_w[:] = f_now
            alg.g.array_w[:] = g_now
        w = alg.resultant
        lam1 = system.split(system.x)[1][:n_q]
        lam2 = system.split(self.x2)[1][:n_q]
        response = self._dot(w, lam2)
        if response == 0.0:
            raise np.linalg.LinAlgError(
                "the force-controlled obstacle touches no active facet: its force cannot be "
                "balanced"
            )
        delta = (self.force - self._dot(w, lam1)) / response
        system.x.axpy(delta, self.x2)
        self.change = abs(delta - self.delta)
        self.delta = delta
        alg.set_obstacle_displacement(delta)

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
        n_u, n_q = system.n_u, system.algebra.n_q
        c = rhs.duplicate()
        c.set(0.0)
        c.array_w[n_u : n_u + n_q] = system.algebra.resultant
        z2 = rhs.duplicate()
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

    def goal_rate(self, value: object) -> float:
        """dJ/ddelta of a goal that uses delta (``m.obstacle_displacement``), collective.

        By the central difference of J(w_h) at delta +- h with w_h fixed, h = 1e-3 max(abs(delta),
        1e-3 of the mesh's size): exact to round-off for a goal polynomial of degree <= 2 in
        delta (the difference's error is h^2 / 6 times the third derivative). The gap is not
        reassembled: only the goal's form reads the Constant here.

        Args:
            value: ``() -> float``, J(w_h) at the Constant's current value.

        Returns:
            The derivative (0 for a goal that does not use delta).
        """
        constant = self.system.disc.fields.obstacle_displacement
        delta = self.delta
        size = self.comm.allreduce(
            float(np.max(np.ptp(self.system.disc.macro_mesh.geometry.x, axis=0))), op=MPI.MAX
        )
        h = 1e-3 * max(abs(delta), 1e-3 * size)
        values = []
        try:
            for shift in (h, -h):
                constant.value = delta + shift
                values.append(value())
        finally:
            constant.value = delta
        return (values[0] - values[1]) / (2.0 * h)

    def destroy(self) -> None:
        """Release the work vector (collective)."""
        self.x2.destroy()
