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
finite-strain solution even where the set settles. With the factors of the dual solve (the
Newton matrix at w_s, its set fixed) the chord steps w^(k+1) = w^k - N(w_s)^-1 F_r(w^k) go on
towards it at the price of a residual and a triangular solve each, while each step at least
halves the equilibrium residual (at most :data:`MAX_CHORD`, converged below
:data:`CHORD_RTOL`). Where they converge and the set test keeps the set, the last iterate is the
finite-strain discrete solution on w_s's set, and the interval is that of (M1) for the Newton
step (:func:`~dwr_signorini.model_error.model_interval`: eta_M +- the goal's nonlinearity
|J(w^1) - J(w_s) - eta_M|) joined with the chord's change of J +- twice its last increment.
Where they do not (a small-strain state far from the finite-strain one: near-inverted cells
make the tangent at w_s a poor one) or the set changes, the Newton step is a linearisation of
unknown quality and the interval is (M1)'s for changed sets, hull(0, 2 eta_M) +- the goal's
nonlinearity, joined with the chord's change as above: an estimate, as the other intervals.
:attr:`~dwr_signorini.model_error.ModelError.correction` holds the chord steps' change of J
after the Newton step.

**Where small strain is far out of its range** its solution can invert a cell (det(I + grad
u_s) <= 0, a strain beyond 100 % at a corner of the contact zone), where the hyperelastic law is
undefined: the model error is then not estimated, ``value`` nan and the interval (-inf, inf),
said in a warning; ``solve_adaptive(..., models=[...])`` switches to finite strain there.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from .collective import log_on_root
from .finite_strain import FiniteStrainSolution, FiniteStrainSystem, cell_degree, residual_forms
from .finite_strain_estimate import contact_facet_indicators, solve_dual
from .goal import Goal, GoalForms
from .model_error import ModelError, indicator_functions, model_interval

__all__ = ["strain_interval", "strain_model_error"]

#: Most Newton and chord steps after eta_M (module docstring).
MAX_CHORD = 10
#: The chord steps have converged where the equilibrium residual relative to its terms is below.
CHORD_RTOL = 1e-8

logger = logging.getLogger("dwr_signorini.estimator")


def strain_interval(
    value: float, changes: list[float], changed: int, converged: bool, roundoff: float = 0.0
) -> tuple[float, float]:
    """The interval of J(w_r) - J(w_s) for a richer material (module docstring).

    Args:
        value: eta_M of (M6).
        changes: J(w^k) - J(w_s) of the Newton step (k = 1) and the chord steps after it.
        changed: The rows whose set the finite-strain set test changes at the last iterate.
        converged: Whether the chord steps converged.
        roundoff: The round-off of J.

    Returns:
        ``(low, high)``: :func:`~dwr_signorini.model_error.model_interval` of the Newton step
        (as where the sets change unless the chord steps converged on an unchanged set),
        joined with the last chord iterate's change of J +- twice its last increment.
    """
    settled = 0 if converged and changed == 0 else max(changed, 1)
    low, high = model_interval(value, changes[0], settled, roundoff)
    last = abs(changes[-1] - changes[-2]) if len(changes) > 1 else abs(changes[0] - value)
    spread = 2.0 * last + abs(roundoff)
    return min(low, changes[-1] - spread), max(high, changes[-1] + spread)


def strain_model_error(
    sol: Any,
    goal: Goal,
    disc: Any,
    localize: Callable[[ufl.Form], np.ndarray],
    roundoff: float = 0.0,
) -> ModelError:
    """eta_M of (M6) at a small-strain solution, for a problem with a hyperelastic material.

    Called by :func:`~dwr_signorini.model_error.model_error`, which checks the input.

    Args:
        sol: The :class:`~dwr_signorini.Solution` of the small-strain problem.
        goal: The goal, as for :func:`~dwr_signorini.estimate`.
        disc: ``sol``'s discretisation with the richer problem (``for_problem``).
        localize: Cell indicators (on T_h, local array) of a scalar form.
        roundoff: The round-off of J (widens the interval).

    Returns:
        The :class:`~dwr_signorini.model_error.ModelError` (collective), with ``material``
        the richer material and ``correction`` the chord steps' change of J after the
        Newton step.
    """
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


def _chord(
    system: FiniteStrainSystem, state: FiniteStrainSolution, F: np.ndarray,
    goal_forms: GoalForms,
) -> tuple[list[float], int, bool]:
    """J(w^k) - J(w_s) of the Newton step w^1 and the chord steps after it (module docstring).

    Every step solves with the factors of the dual solve (the finite-strain Newton matrix at
    w_s, its set fixed): w^(k+1) = w^k - N(w_s)^-1 F_r(w^k), at most :data:`MAX_CHORD` steps;
    converged where the equilibrium residual (relative to its terms) is below
    :data:`CHORD_RTOL`, given up where a step does not halve it. The state's functions are
    restored after.

    Returns:
        The changes of J, the rows whose set the set test changes at the last iterate and
        whether the chord steps converged.
    """
    n_u, n_q = system.n_u, system.n_q
    comm = system.disc.comm
    J_s = goal_forms.value()
    saved = state.u.x.array.copy(), state.lam.x.array.copy()
    R, G, changes = F[:n_u], F[n_u: n_u + n_q], []
    previous, converged = np.inf, False
    for _ in range(MAX_CHORD):
        du, dlam = system.step(state.active, R, G, assemble=False)
        system.update(du, dlam)
        state.u.x.array[:], state.lam.x.array[:] = system.u.x.array, system.lam.x.array
        changes.append(goal_forms.value() - J_s)
        R, G, scale = system.residuals()
        residual = np.sqrt(comm.allreduce(float(R @ R), op=MPI.SUM)) / scale
        converged = residual <= CHORD_RTOL
        if converged or residual > 0.5 * previous:
            break
        previous = residual
    active, _, _ = system.ncp(G)
    state.u.x.array[:], state.lam.x.array[:] = saved
    changed = comm.allreduce(int((active != state.active).sum()), op=MPI.SUM)
    return changes, changed, converged


def _inverted(disc: Any, localize: Callable) -> ModelError:
    """The model error where the small-strain solution inverts a cell: undefined (module doc)."""
    log_on_root(disc.comm, logger, logging.WARNING,
                "model error of small strain: the small-strain solution inverts a cell "
                "(det(I + grad u) <= 0), where the hyperelastic law is undefined; the model "
                "error is not estimated (nan, interval (-inf, inf))")
    n_q = disc.Q.dofmap.index_map.size_local
    zero = np.zeros(n_q)
    cells, facets = indicator_functions(disc, zero, np.ones(n_q), localize)
    return ModelError(value=math.nan, interval=(-math.inf, math.inf), indicators=cells,
                      facet_indicators=facets, law=disc.problem.law,
                      material=disc.problem.material_law, correction=math.nan)


def _strain_model_error(
    sol: Any, goal: Goal, system: FiniteStrainSystem, localize: Callable, roundoff: float
) -> ModelError:
    """:func:`strain_model_error` on the finite-strain Newton system ``system``."""
    disc = system.disc
    state, F = _state(sol, system)
    if system.min_det_F() <= 0.0:
        return _inverted(disc, localize)
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
    changes, changed, converged = _chord(system, state, F, goal_forms)
    return ModelError(
        value=value,
        interval=strain_interval(value, changes, changed, converged, roundoff),
        indicators=cells,
        facet_indicators=facets,
        law=disc.problem.law,
        newton_step=changes[0],
        num_changed=changed,
        material=disc.problem.material_law,
        correction=changes[-1] - changes[0],
    )
