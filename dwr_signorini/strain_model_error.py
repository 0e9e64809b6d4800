r"""The error small strain makes in J: the model error against a hyperelastic material (eq. (M6)).

Linear elasticity at small strain is the linearisation at u = 0 of a hyperelastic law with the
same E, nu (:mod:`~dwr_signorini.materials`), and its contact condition the linearisation of the
deformed gap d(x + u) (:mod:`~dwr_signorini.finite_strain`). As for a simpler contact law
(:mod:`~dwr_signorini.model_error`, eq. (M1)), the error of leaving out finite strain is the
richer model's residual at the simpler solution, weighted by the richer model's dual solution
there (Braack and Ern, 2003). On one discretisation, w_s = (u_s, lambda_s) the small-strain
solution and F_r = (R, C) the finite-strain discrete residual (the equilibrium rows R and the
NCP C_i = M_i lam_i - max(0, M_i lam_i - c_i G_i(u)), G_i(u) = int_Ei d(x + u) ds),

    J(w_r) - J(w_s) ~ eta_M = -z_r . F_r(w_s) = rho_r(w_s)(z_r) - rho_s(w_s)(z_r)       (M6)
          = int [sigma(u_s) - P(F(u_s))] : grad y dx
            + int lam_s [grad d(x + u_s) + n] . y ds  -  sum_i xi_i C_i(w_s),

z_r = (y, xi) the solution of F_r'(w_s)^T z_r = J'(w_s): the transposed finite-strain Newton
matrix at w_s, with the set that the finite-strain set test takes there
(:func:`~dwr_signorini.finite_strain_estimate.solve_dual`). The small-strain residual vanishes
on the discrete z_r (Galerkin orthogonality of w_s, and its NCP holds per macro facet), so the
loads cancel and (M6) holds the difference of the stresses, of the contact forces' directions
(n the small-strain contact direction, -grad d(x) for a flat obstacle) and the deformed gap's
NCP. For a goal linear in w, eta_M = J(w^1) - J(w_s), w^1 the finite-strain Newton iterate
from w_s (:attr:`~dwr_signorini.model_error.ModelError.newton_step`).

**Indicators.** Per cell the summands of the integrals of (M6) (facet integrals on the cell
beside the facet) and the NCP terms spread by area over the cells beside each macro facet; they
sum to eta_M. Per macro contact facet the Gamma_C part (the contact forces' and the NCP's).

**The interval.** Unlike a friction law, the material is nonlinear on its set: w^1 is not the
finite-strain solution even where the set settles. The next simplified Newton step (the same
factors) changes J by c_2 = -z_r . F_r(w^1) (:attr:`~dwr_signorini.model_error.ModelError.
correction`, quadratic in the step), and the steps after it by about c_2 q / (1 - q), q the
contraction. The interval is that of (M1) (:func:`~dwr_signorini.model_error.model_interval`,
widened by the goal's nonlinearity |J(w^1) - J(w_s) - eta_M|) joined with itself shifted by
2 c_2: it holds J(w_r) - J(w_s) while q <= 1/2 (an estimate, as the other intervals).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from .finite_strain import FiniteStrainSolution, FiniteStrainSystem, cell_degree, residual_forms
from .finite_strain_estimate import contact_facet_indicators, solve_dual
from .goal import Goal, GoalForms
from .model_error import ModelError, check_richer, indicator_functions, model_interval

__all__ = ["strain_interval", "strain_model_error"]


def strain_interval(
    value: float, step: float, correction: float, changed: int, roundoff: float = 0.0
) -> tuple[float, float]:
    """The interval of J(w_r) - J(w_s) for a richer material (module docstring).

    Args:
        value: eta_M of (M6).
        step: J(w^1) - J(w_s).
        correction: c_2 = -z_r . F_r(w^1).
        changed: The rows whose set the finite-strain set test changes at w^1.
        roundoff: The round-off of J.

    Returns:
        ``(low, high)``: :func:`~dwr_signorini.model_error.model_interval` joined with itself
        shifted by 2 c_2.
    """
    low, high = model_interval(value, step, changed, roundoff)
    return min(low, low + 2.0 * correction), max(high, high + 2.0 * correction)


def strain_model_error(
    sol: Any,
    goal: Goal,
    richer: Any,
    localize: Callable[[ufl.Form], np.ndarray],
    roundoff: float = 0.0,
) -> ModelError:
    """eta_M of (M6) for a small-strain solution and the problem with a hyperelastic material.

    Args:
        sol: The :class:`~dwr_signorini.Solution` of the small-strain problem.
        goal: The goal, as for :func:`~dwr_signorini.estimate`.
        richer: The same problem with a finite-strain material
            (:func:`~dwr_signorini.model_error.check_richer`).
        localize: Cell indicators (on T_h, local array) of a scalar form.
        roundoff: The round-off of J (widens the interval).

    Returns:
        The :class:`~dwr_signorini.model_error.ModelError` (collective), with ``material``
        the richer material and ``correction`` c_2.

    Raises:
        TypeError, ValueError: ``richer`` is not ``sol``'s problem with a hyperelastic
            material, or ``sol`` is a load step of a path.
    """
    check_richer(sol.disc.problem, richer)
    if sol.disc.u_old is not None:
        raise ValueError(
            "model_error: sol is a load step of solve_path (frictional history); estimate the "
            "model error of a single solve"
        )
    disc = sol.disc.for_problem(richer)
    system = FiniteStrainSystem(disc, sol.ncp_scale)
    try:
        return _strain_model_error(sol, goal, system, localize, roundoff)
    finally:
        system.destroy()


def _state(sol: Any, system: FiniteStrainSystem) -> tuple[FiniteStrainSolution, np.ndarray]:
    """w_s as a state of the finite-strain system (its set from the set test), and F_r(w_s)."""
    system.set_load(1.0)
    system.u.x.array[:] = sol.u.x.array
    system.lam.x.array[:] = sol.lam.x.array
    R, G, _ = system.residuals()
    active, C, _ = system.ncp(G)
    u = fem.Function(system.disc.V, name="u")
    lam = fem.Function(system.disc.Q, name="lambda")
    u.x.array[:] = sol.u.x.array
    lam.x.array[:] = sol.lam.x.array
    state = FiniteStrainSolution(u, lam, active, 0, [], system.disc, system)
    return state, np.concatenate([R, G, C])


def _difference_form(sol: Any, state: FiniteStrainSolution, y: fem.Function) -> ufl.Form:
    """rho_r(w_s)(y, 0) - rho_s(w_s)(y, 0): the integrals of (M6) (the loads cancel)."""
    small, disc = sol.disc, state.disc
    m = disc.m
    dx = m.dx(metadata={"quadrature_degree": cell_degree(disc)})
    dsc = m.ds_contact(metadata={"quadrature_degree": disc.problem.quadrature_degree})
    internal, _, contact, _ = residual_forms(disc, state.u, state.lam, 1.0, y, dx, dsc)
    n = small.directions(small.problem.law.components(m.mesh.topology.dim))[0]
    small_strain = small.fields.elastic_form(state.u, y, dx) + state.lam * ufl.dot(y, n) * dsc
    return small_strain - internal - contact


def _pairing(system: FiniteStrainSystem, F: np.ndarray, z: Any) -> float:
    """-z . F for F = (R, G, C) (owned rows): rho_r(w)(z) on the discrete space."""
    n_u, n_q = system.n_u, system.n_q
    local = float(F[:n_u] @ z.y.x.array[:n_u] + F[n_u + n_q:] @ z.xi.x.array[:n_q])
    return -system.disc.comm.allreduce(local, op=MPI.SUM)


def _newton_step(
    system: FiniteStrainSystem, state: FiniteStrainSolution, F: np.ndarray, z: Any,
    goal_forms: GoalForms,
) -> tuple[float, float, int]:
    """J(w^1) - J(w_s), c_2 = -z . F_r(w^1) and the rows whose set changes at w^1.

    w^1 is the finite-strain Newton iterate from w_s, solved with the factors of the dual
    solve (the same matrix); the state's functions are restored after.
    """
    n_u, n_q = system.n_u, system.n_q
    J_s = goal_forms.value()
    du, dlam = system.step(state.active, F[:n_u], F[n_u: n_u + n_q], assemble=False)
    system.update(du, dlam)
    R1, G1, _ = system.residuals()
    active1, C1, _ = system.ncp(G1)
    correction = _pairing(system, np.concatenate([R1, G1, C1]), z)
    saved = state.u.x.array.copy(), state.lam.x.array.copy()
    state.u.x.array[:], state.lam.x.array[:] = system.u.x.array, system.lam.x.array
    J_1 = goal_forms.value()
    state.u.x.array[:], state.lam.x.array[:] = saved
    changed = system.disc.comm.allreduce(int((active1 != state.active).sum()), op=MPI.SUM)
    return J_1 - J_s, correction, changed


def _strain_model_error(
    sol: Any, goal: Goal, system: FiniteStrainSystem, localize: Callable, roundoff: float
) -> ModelError:
    """:func:`strain_model_error` on the finite-strain Newton system ``system``."""
    disc = system.disc
    state, F = _state(sol, system)
    goal_forms = GoalForms(goal, state.u, state.lam, disc)
    z = solve_dual(state, goal_forms)
    n_u, n_q = system.n_u, system.n_q
    difference = _difference_form(sol, state, z.y)
    ncp = -z.xi.x.array[:n_q] * F[n_u + n_q:]
    facet = contact_facet_indicators(disc, difference, disc.problem.quadrature_degree)
    facet_terms = facet.x.array[:n_q] + ncp
    cells, facets = indicator_functions(disc, ncp, system.M, localize, localize(difference))
    facets.x.array[:n_q] = facet_terms
    facets.x.scatter_forward()
    n_local = cells.function_space.dofmap.index_map.size_local
    value = disc.comm.allreduce(float(cells.x.array[:n_local].sum()), op=MPI.SUM)
    step, correction, changed = _newton_step(system, state, F, z, goal_forms)
    return ModelError(
        value=value,
        interval=strain_interval(value, step, correction, changed, roundoff),
        indicators=cells,
        facet_indicators=facets,
        law=disc.problem.law,
        newton_step=step,
        num_changed=changed,
        material=disc.problem.material_law,
        correction=correction,
    )
