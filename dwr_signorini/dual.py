"""The discrete dual problem: the transposed system of the last Newton step (Section 4).

With the Newton matrix of the final active set A (see :mod:`dwr_signorini.linalg`),

    [ K        -N^T D_A ] [y ]   [ J'_u      ]
    [ N         D_I M   ] [xi] = [ J'_lambda ],

which is the discrete form of the dual problem (11)-(12) with c = 1 in b:
``a(v, y) - int chi xi v_n = J'_u(v)`` and ``int mu y_n + int (1 - chi) xi mu = J'_lambda(mu)``,
chi the indicator of the active macro facets. With the scale c of the NCP
(:mod:`dwr_signorini.residuals`) the dual problem has ``int c chi xi v_n``; its xi is the
computed one divided by c on the active facets, which :func:`solve_dual` returns.

It is solved by the Newton system with the factorisations of the last Newton step
(``solve_transpose`` of :mod:`dwr_signorini.linalg`), so it costs no factorisation: with
``method="block"`` one solve with the factors of the symmetric form A_s of the Newton matrix
A = L A_s and a sparse back-substitution with L^T
(:meth:`~dwr_signorini.linalg.block.NewtonSystem.newton_matrix`); with ``method="schur"``, K
symmetric and eta_A = -xi_A,

    K y + N_A^T eta_A = J'_u,    (N y)_A = J'_lambda,A,    xi_I = (J'_lambda,I - (N y)_I) / M_I,

by two solves with the factors of K and one with the Cholesky factor of S_AA = (N K^-1 N^T)_AA.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .algebra import ContactAlgebra
from .collective import collective
from .goal import Goal, GoalForms
from .laws import multiplier_names
from .linalg import NewtonLinearSystem
from .quadrature import with_quadrature_degrees
from .timing import timed

__all__ = ["DualSolution", "dual_rhs", "multiplier_functions", "slip_offset_goal", "solve_dual"]


@dataclass
class DualSolution:
    """z_h = (y_h, xi_H), the discrete dual solution (and xi_t, or xi_t1, xi_t2, with friction).

    ``zeta`` is the dual's entry for the displacement of an obstacle under a given force (the
    bordered system's, :mod:`~dwr_signorini.force`), else None.
    """

    y: fem.Function
    xi: fem.Function
    xi_t: fem.Function | None = None
    xi_t2: fem.Function | None = None
    zeta: float | None = None

    @property
    def multipliers(self) -> tuple[fem.Function, ...]:
        """The dual multipliers of the contact law's components: (xi,), (xi, xi_t) or three."""
        return tuple(f for f in (self.xi, self.xi_t, self.xi_t2) if f is not None)


def dual_rhs(
    system: NewtonLinearSystem | ContactAlgebra, goal: GoalForms, out: PETSc.Vec,
    frozen: fem.Function | None = None,
) -> PETSc.Vec:
    """Assemble [J'_u(w_h); J'_lambda(w_h)] into the block vector ``out`` (zero on Gamma_D).

    Non-polynomial integrands of J' are integrated with the problem's ``quadrature_degree``, as
    in the dual residual of the estimator, so that it vanishes on discrete test functions.
    On a band's system (:mod:`~dwr_signorini.local_p2`) the displacement rows take the data
    ``frozen`` on the constrained nodes (lifted from the free rows).
    """
    disc = system.disc
    algebra = system if isinstance(system, ContactAlgebra) else system.algebra
    degree = disc.problem.quadrature_degree
    arr = out.array_w
    arr[:] = 0.0
    V = system.V
    if goal.has_u:
        form = goal.dJ_u
        if V is not goal.u.function_space:
            form = ufl.replace(form, {form.arguments()[0]: ufl.TestFunction(V)})
        if goal._has_u_direct:
            b = fem_petsc.assemble_vector(disc.form(with_quadrature_degrees(form, degree)))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        else:  # J depends on u through its master trace only
            b = fem.Function(V).x.petsc_vec.copy()
        if goal.dJ_trace is not None:
            _add_master_trace_part(disc, goal, V, degree, b)
        if algebra.band is None:
            fem_petsc.set_bc(b, system.bcs)
        else:  # the band's conditions first (see ContactBand.conditions)
            algebra.band.lift(b, frozen, algebra.stiffness_form, system.bcs)
        arr[: system.n_u] = b.array
        b.destroy()
    rows = algebra.components_of(arr[system.n_u :])
    for k, dJ in enumerate(goal.dJ_multipliers):
        if dJ is not None:
            b = fem_petsc.assemble_vector(disc.form(with_quadrature_degrees(dJ, degree)))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            rows[k][:] = b.array
            b.destroy()
    return out


def _add_master_trace_part(
    disc: Any, goal: GoalForms, V: fem.FunctionSpace, degree: int | None, b: PETSc.Vec
) -> None:
    """Add P^T J'_{Pu} to b: the part of J'_u that reaches u through its master trace P u."""
    trace = disc.master_trace(V)
    form = ufl.replace(goal.dJ_trace, {goal.dJ_trace.arguments()[0]: ufl.TestFunction(trace.W)})
    b_w = fem_petsc.assemble_vector(disc.form(with_quadrature_degrees(form, degree)))
    b_w.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    moved = trace.P.createVecRight()
    trace.P.multTranspose(b_w, moved)
    b.array_w[:] += moved.array_r
    for vec in (b_w, moved):
        vec.destroy()


def solve_dual(
    system: NewtonLinearSystem, goal: GoalForms, frozen: fem.Function | None = None
) -> DualSolution:
    """Solve the dual problem (11)-(12) with the transposed last Newton matrix.

    Args:
        system: The solved Newton system (its last factorisations are reused).
        goal: The goal's derivatives at w_h.
        frozen: On a band's system (:mod:`~dwr_signorini.local_p2`), the dual's values on the
            constrained nodes; else None.

    Returns:
        z_h = (y_h, xi_H) on the system's displacement space and Lambda_H.
    """
    if not system.solved:
        raise RuntimeError("the Newton system has not been solved: no matrix to transpose")
    rhs = system.x.duplicate()
    z = system.x.duplicate()
    try:
        return _solve_dual(system, goal, rhs, z, frozen)
    finally:
        rhs.destroy()
        z.destroy()


def _solve_dual(
    system: NewtonLinearSystem, goal: GoalForms, rhs: PETSc.Vec, z: PETSc.Vec,
    frozen: fem.Function | None,
) -> DualSolution:
    """:func:`solve_dual` into the work vectors ``rhs`` and ``z`` (the caller destroys them)."""
    with timed("goal"):
        dual_rhs(system, goal, rhs, frozen)
    force = getattr(system, "force_control", None)  # an obstacle under a given force
    with timed("dual solve"), collective(system.disc.comm, "the dual solve"):
        if force is None:
            system.solve_transpose(rhs, z)
        else:  # the bordered system's dual (dwr_signorini.force)
            force.solve_transpose(rhs, z, goal.rate(system.disc.fields.obstacle_displacement))
    y = fem.Function(system.V, name="y")
    y.x.array[: system.n_u] = z.array_r[: system.n_u]
    y.x.scatter_forward()
    # The transposed Newton matrix has the rows of B in its constrained block, i.e. c = 1 in
    # b_h: xi = xi^(1) / c on the constrained rows (see dwr_signorini.residuals).
    xi_1 = z.array_r[system.n_u :]
    xi_all = np.where(system.active, xi_1 / system.c_n, xi_1)
    xis = multiplier_functions(system, xi_all, "xi")
    finite = bool(np.all(np.isfinite(y.x.array)) and np.all(np.isfinite(xi_all)))
    if not system.disc.comm.allreduce(finite, op=MPI.LAND):
        raise RuntimeError("NaN or Inf in the dual solution")
    out = DualSolution(y, *xis)
    if force is not None:
        out.zeta = force.zeta
    return out


def multiplier_functions(
    system: NewtonLinearSystem, values: np.ndarray, name: str
) -> list[fem.Function]:
    """One function on Lambda_H per component of the law from the stacked owned rows.

    Args:
        system: The Newton system (its algebra's layout of the multiplier rows).
        values: The owned multiplier rows.
        name: The name of the first function; the next get the tangential suffixes.

    Returns:
        The functions, normal first (ghosts updated).
    """
    names = multiplier_names(system.algebra.components, name)
    out = []
    for k, part in enumerate(system.algebra.components_of(values)):
        f = fem.Function(system.disc.Q, name=names[k])
        f.x.array[: len(part)] = part
        f.x.scatter_forward()
        out.append(f)
    return out


def slip_offset_goal(system: NewtonLinearSystem, xi: np.ndarray) -> Goal:
    """The sensitivity of J to the slip offsets g_l = B_l u_old of a load step, as a goal.

    With the sets of the system's last Newton step and its dual solution (``xi`` the owned
    multiplier rows as :func:`solve_dual` returns them), L(v) = J(w(u_old + v)) -
    J(w(u_old)) = - sum_l (w_l, v . e_l)_GC (:func:`~dwr_signorini.path_history.history_goal`).
    Under a given force with friction the offsets are B_l (u_old - delta_0 d + ...), delta_0
    the earlier step's displacement: the goal is L(u - delta d), delta that step's
    ``m.obstacle_displacement`` (its derivative in delta, -L(d), enters that step's dual).

    Args:
        system: The solved Newton system of the step (its sets, couplings and c_n).
        xi: The dual's multiplier rows (owned, stacked).

    Returns:
        ``goal(u, lam, m, lam_t) -> ufl.Form``, L(u), on the system's discretisation.
    """
    z = np.where(system.active, xi * system.c_n, xi)  # the raw dual (solve_dual's map undone)
    w = np.where(system.active, z, 0.0)
    for cp in system.couplings:
        own = ~system.active[cp.rows]  # (m, k): the coupled rows that are not constrained
        zc = np.where(own, z[cp.rows], 0.0)
        c = system.c_n[cp.rows[:, 0]]
        w[cp.rows] += c[:, None] * np.einsum("mk,mkl->ml", zc, cp.J)
    weights = multiplier_functions(system, w, "history_weight")[1:]
    disc = system.disc
    directions = disc.directions(system.algebra.components)[1:]
    moves = disc.fields.obstacle_motion() is not None  # offsets from u_old - delta_0 d

    def goal(u: Any, lam: Any, m: Any, lam_t: Any) -> Any:
        form = None
        u_rel = disc.relative(u)  # u - P u with contact pairs (GoalForms differentiates P u)
        if moves and m.obstacle_displacement is not None:  # delta_0: the earlier step's delta
            u_rel = u_rel - m.obstacle_displacement * disc.fields.approach()
        for w_l, e_l in zip(weights, directions, strict=True):
            term = -w_l * ufl.dot(u_rel, e_l) * m.ds_contact
            form = term if form is None else form + term
        return form

    return goal
