r"""The error a simpler contact law makes in J: the model error estimate (theory, eq. (M1)).

Braack and Ern (Multiscale Model. Simul. 1, 2003) estimate the error of a simpler model by the
residual of the richer one at the simpler solution, weighted by a dual solution; Rademacher
(Numer. Math. 2019) does so for frictional contact. Here, on one discretisation: w_s = (u_s,
lambda_s) solves the simpler law (frictionless, or Tresca), ``richer`` is the same problem with
the richer law (Tresca or Coulomb), and

    J(w_r) - J(w_s) ~ eta_M = rho_r(w_s^*)(z_r) = -sum_k (lambda_k^*, y . e_k)_GC [k new]
                              - sum_k sum_i xi_k,i C_k,i(w_s^*),                     (M1)

where

* w_s^* is w_s with the multipliers the simpler law lacks (the tangential traction of a
  frictionless solution) set as the richer law prescribes: the fixed point of its projection,
  lambda_t = P_t(lambda_t + c (B_t u_s)) at lambda_n of w_s (``+-s`` or ``+-mu lambda_n``
  along the slip of u_s, 0 where u_s does not slip), found through the law's NCP functions
  (:meth:`~dwr_signorini.algebra.ContactAlgebra.ncp_residual`);
* C_k,i is the richer law's algebraic NCP function (20) at w_s^* (zero on the rows the simpler
  law shares with it where it holds, nonzero on Tresca's rows that Coulomb's cone replaces);
* z_r = (y, xi) is the dual solution of the richer law's Newton matrix at w_s^*, with the sets
  its set test takes there (``newton_sets``): the transposed system of one Newton step of the
  richer law from w_s^*, as :mod:`dwr_signorini.dual` solves it.

The simpler model's residual vanishes on the discrete test function z_r (Galerkin
orthogonality of w_s), so the richer residual is the difference of the two: the volume terms
cancel and (M1) holds only facet terms. For a goal linear in w, (M1) is J(w^1) - J(w_s^*), w^1
the first Newton iterate of the richer law from w_s^* (:attr:`ModelError.newton_step`): the
estimate is exact where that step lands on the richer solution (a friction law whose sets at
w_s^* are its final ones, e.g. a body that slips everywhere) and is a linearisation otherwise.

Indicators: per macro contact facet the summand of (M1) (:attr:`ModelError.facet_indicators`),
and per cell of T_h the same spread over the fine facets of each macro facet by area (the cells
beside Gamma_C, :attr:`ModelError.indicators`); both sum to eta_M.
"""

from __future__ import annotations

import math
import types
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

from .dual import slip_offset_goal, solve_dual
from .goal import Goal, GoalForms
from .laws import multiplier_names
from .linalg import system_class
from .model_regions import FINITE_STRAIN, MIXED, new_rows, regional

__all__ = ["ModelError", "check_richer", "law_phrase", "model_error"]

#: Which law is richer than which (by the laws' ``name``): the simpler law's name maps to the
#: laws that extend it.
RICHER = {"frictionless": ("tresca", "coulomb"), "tresca": ("coulomb",)}

#: The attributes of a problem that the richer one must share (the data).
DATA = (
    "facet_tags", "model", "quadrature_degree", "cell_tags", "E", "nu", "contact_tags",
    "pairs", "dirichlet_values", "body_force", "traction", "gap", "boundary_projection",
)

#: What leaving out the richer law means, by the (simpler, richer) laws' names.
PHRASES = {
    ("frictionless", "tresca"): "leaving out friction",
    ("frictionless", "coulomb"): "leaving out friction",
    ("tresca", "coulomb"): "Tresca in place of Coulomb",
    ("frictionless", FINITE_STRAIN): "small strain in place of finite strain",
    (MIXED, "coulomb"): "leaving out friction",
}


def law_phrase(simple: str, rich: str) -> str:
    """The words for the model error of the law ``simple`` in place of ``rich`` (their names).

    Args:
        simple: The name of the law that ran (``"frictionless"``, ``"tresca"``, ...).
        rich: The name of the richer law.

    Returns:
        E.g. ``"leaving out friction"``; ``"<simple> in place of <rich>"`` for other pairs.
    """
    return PHRASES.get((simple, rich), f"{simple} in place of {rich}")



#: Most fixed-point steps for the multipliers the simpler law lacks.
MAX_FILL_STEPS = 50


@dataclass
class ModelError:
    """The estimate (M1) of J(richer) - J(simpler) at the simpler solution, and its parts.

    Attributes:
        value: eta_M of (M1).
        interval: The interval of J(richer) - J(simpler) (:func:`model_interval`).
        indicators: DG0 function on T_h of signed cell indicators; they sum to ``value``.
        facet_indicators: Function on Lambda_H (one value per macro contact facet); they sum
            to ``value``.
        law: The richer law (the solution's own for a richer material).
        newton_step: J(w^1) - J(w_s^*), w^1 the richer law's Newton iterate from w_s^*;
            equal to ``value`` for a goal linear in w (module docstring).
        num_slip: The slipping facets of the richer law's sets at w_s^* (global).
        num_changed: The multiplier rows whose set the richer law's set test changes at w^1
            (global). 0: w^1 is the richer discrete solution where the law is piecewise linear
            on its sets (2D), and (M1) is exact for a linear goal.
        material: The richer problem's finite-strain material, or None (a richer law).
        correction: With a richer material: the change of J of the chord steps after the
            Newton step (:mod:`~dwr_signorini.strain_model_error`), else 0.
        history: At a load step (``history=True``): the sensitivity of the richer step's J to
            its u_old, a goal of the previous step (eq. (M7)), else None.
        steps: Along a load path (:mod:`~dwr_signorini.path_model_error`): each step's
            summand of (M7), the first step first; else ().
    """

    value: float
    interval: tuple[float, float]
    indicators: fem.Function = field(repr=False)
    facet_indicators: fem.Function = field(repr=False)
    law: Any = None
    newton_step: float = math.nan
    num_slip: int = 0
    num_changed: int = -1
    material: Any = None
    correction: float = 0.0
    history: Goal | None = field(default=None, repr=False)
    steps: tuple[float, ...] = ()

    @property
    def richer(self) -> str:
        """The richer model's name: the law's (``"coulomb"``, ...), or ``"finite_strain"``."""
        return self.law.name if self.material is None else FINITE_STRAIN


def model_interval(
    value: float, step: float, changed: int, roundoff: float = 0.0
) -> tuple[float, float]:
    """The interval of J(richer) - J(simpler) (theory, after eq. (M1)).

    With r = ``|step - value|`` (the goal's nonlinearity over the Newton step) plus the
    round-off: ``value +- r`` where the richer law's sets settle at w^1 (``changed`` = 0: w^1
    is the richer solution); where they do not, the sign of ``value`` and at most twice it,
    ``hull(0, 2 value) +- r``: the step is a linearisation that can overshoot (a body that sticks
    under the richer law slips under its set test at the simpler state) but has the right sign.

    Args:
        value: eta_M of (M1).
        step: J(w^1) - J(w_s^*).
        changed: :attr:`ModelError.num_changed`.
        roundoff: The round-off of J.

    Returns:
        ``(low, high)``.
    """
    r = abs(step - value) + abs(roundoff)
    if changed == 0:
        return value - r, value + r
    return min(0.0, 2.0 * value) - r, max(0.0, 2.0 * value) + r


def _same(a: Any, b: Any, depth: int = 0) -> bool:
    """Whether two data of a problem are the same: equal, or built alike.

    Problems built twice from the same code hold distinct but equal objects (an obstacle, a
    lambda): objects of one type compare by their attributes, functions by their code and the
    values they close over, containers item by item.
    """
    if a is b:
        return True
    if type(a) is not type(b) or depth > 8:
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool(np.all(a == b))
    if isinstance(a, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k], depth + 1) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(
            _same(x, y, depth + 1) for x, y in zip(a, b, strict=True)
        )
    if isinstance(a, types.FunctionType):
        if a.__code__ != b.__code__:
            return False
        cells = zip(a.__closure__ or (), b.__closure__ or (), strict=True)
        return all(_same(c.cell_contents, d.cell_contents, depth + 1) for c, d in cells)
    if hasattr(a, "__dict__") and not isinstance(a, type):
        return _same(vars(a), vars(b), depth + 1)
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False


def check_richer(simple: Any, richer: Any) -> None:
    """Check that ``richer`` is ``simple`` with a richer law (ValueError, TypeError).

    A richer contact law (frictionless < Tresca < Coulomb) at the same material, or a
    hyperelastic material (:mod:`~dwr_signorini.strain_model_error`) at the same contact law.

    Args:
        simple: The problem of the solution.
        richer: The problem with the richer law.
    """
    from .problem import SignoriniProblem

    if not isinstance(richer, SignoriniProblem):
        raise TypeError(
            "model_error must be a SignoriniProblem (the same problem with a richer law), got "
            f"{type(richer).__name__}"
        )
    if richer.mesh is not simple.mesh:
        raise ValueError(
            "model_error: the richer problem must live on the solution's macro mesh (the same "
            "dolfinx mesh object)"
        )
    for name in DATA:
        if not _same(getattr(simple, name), getattr(richer, name)):
            raise ValueError(
                f"model_error: the richer problem has other data ({name!r} differs); it must be "
                "the same problem with another friction law or material"
            )
    if simple.finite_strain or richer.finite_strain:
        _check_richer_material(simple, richer)
        return
    s, r = simple.law.name, richer.law.name
    if regional(simple.law) and r == "coulomb":
        if not _same(simple.law.data.mu, richer.law.data):
            raise ValueError(
                "model_error: a per-region model must have the richer Coulomb law's mu on its "
                f"region, got {simple.law.data.mu!r} and {richer.law.data!r}"
            )
        return
    if r not in RICHER.get(s, ()):
        raise ValueError(
            f"model_error: the law {richer.law!r} is not richer than the solution's "
            f"{simple.law!r}; richer laws: frictionless < Tresca < Coulomb"
        )


def _check_richer_material(simple: Any, richer: Any) -> None:
    """The material case of :func:`check_richer`: small strain against a hyperelastic law."""
    if simple.finite_strain:
        raise ValueError(
            "model_error: the solution's material is already a finite-strain law "
            f"({simple.material_law!r}); the model error of small strain is estimated at a "
            "small-strain solution, with the richer problem's material hyperelastic"
        )
    if not _same(simple.law, richer.law):
        raise ValueError(
            f"model_error: the richer problem changes the material ({richer.material_law!r}) "
            f"and the contact law ({simple.law!r} -> {richer.law!r}); estimate one model "
            "error at a time"
        )


def _owned(functions: Any, n_q: int) -> np.ndarray:
    """The owned rows of the multipliers, component by component."""
    return np.concatenate([f.x.array[:n_q] for f in functions])


def _fill(algebra: Any, u_vec: Any, lam: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The multipliers of the rows ``rows`` (a mask) at the fixed point of P (module doc).

    lam_k <- P_k(M lam + c (B u - g)) / M on the rows the simpler law lacks, the others kept;
    P_k = M lam_k - C_k from the law's NCP functions. Stops when nothing changes.
    """
    comm = algebra.comm
    M = algebra.M.array
    for _ in range(MAX_FILL_STEPS):
        P = M * lam - algebra.ncp_residual(u_vec, lam)
        new = lam.copy()
        new[rows] = P[rows] / M[rows]
        change = float(np.max(np.abs(new - lam), initial=0.0))
        size = float(np.max(np.abs(new), initial=0.0))
        lam = new
        if comm.allreduce(change <= 1e-14 * size, op=MPI.LAND):
            break
    return lam


def _functions(disc: Any, algebra: Any, lam: np.ndarray, name: str) -> list[fem.Function]:
    """Functions on Lambda_H from the owned rows, one per component."""
    out = []
    for values, label in zip(
        algebra.components_of(lam), multiplier_names(algebra.components, name), strict=True
    ):
        f = fem.Function(disc.Q, name=label)
        f.x.array[: len(values)] = values
        f.x.scatter_forward()
        out.append(f)
    return out


def model_error(
    sol: Any,
    goal: Goal,
    richer: Any,
    localize: Callable[[ufl.Form], np.ndarray],
    roundoff: float = 0.0,
    history: bool = False,
) -> ModelError:
    """eta_M of (M1) for the solution ``sol`` of the simpler law and the problem ``richer``.

    Or of (M6) where ``richer`` has a hyperelastic material
    (:func:`~dwr_signorini.strain_model_error.strain_model_error`).

    Args:
        sol: The :class:`~dwr_signorini.Solution` of the simpler law.
        goal: The goal, as for :func:`~dwr_signorini.estimate`.
        richer: The same problem with a richer law or material (:func:`check_richer`).
        localize: Cell indicators (on T_h, local array) of a scalar form.
        roundoff: The round-off of J (widens the interval).
        history: ``sol`` is a load step: the richer step measures its slip from the same
            u_old (``sol.disc.u_old``), and :attr:`ModelError.history` is its sensitivity to
            u_old (one summand of (M7), :mod:`~dwr_signorini.path_model_error`).

    Returns:
        The :class:`ModelError` (collective).

    Raises:
        TypeError, ValueError: ``richer`` is no problem, or not ``sol``'s problem with a
            richer law (:func:`check_richer`); ``sol`` is a load step of a path (without
            ``history``: its model error is that of the path, eq. (M7)); an obstacle under a
            given force.
    """
    check_richer(sol.disc.problem, richer)
    if richer.force_obstacle is not None:
        raise ValueError(
            f"model_error: the obstacle {richer.force_obstacle!r} is under a given force, whose "
            "displacement the richer model's Newton step does not border: the model error of a "
            "force-controlled problem is not supported (prescribe the obstacle's position)"
        )
    if sol.disc.u_old is not None and not history:
        raise ValueError(
            "model_error: sol is a load step of solve_path, whose richer model is a load path "
            "too: pass the richer path's problems (a sequence, one per step) as model_error, "
            "with sol from solve_path(..., keep_steps=True) (eq. (M7))"
        )
    disc = sol.disc.for_problem(richer)
    if history and sol.disc.u_old is not None:
        start = sol.disc.fields.obstacle_start
        disc.set_u_old(sol.disc.u_old, sol.disc.obstacle_translation,
                       None if start is None else float(start.value))
    if richer.finite_strain:
        from .strain_model_error import strain_model_error  # it builds on this module

        return strain_model_error(sol, goal, disc, localize, roundoff)
    symmetric = richer.law.symmetric(disc.mesh.topology.dim)
    system = system_class("block", symmetric)(
        disc, None, prefix=sol.system.prefix + "model_", ncp_scale=sol.ncp_scale
    )
    try:
        return _model_error(sol, goal, disc, system, localize, roundoff)
    finally:
        system.destroy()


def _model_error(
    sol: Any, goal: Goal, disc: Any, system: Any, localize: Callable, roundoff: float
) -> ModelError:
    """:func:`model_error` on the richer law's Newton system ``system``."""
    algebra, comm = system.algebra, disc.comm
    n_q, known = algebra.n_q, len(sol.multipliers)
    u = fem.Function(disc.V, name="u")
    u.x.array[:] = sol.u.x.array
    lam0 = np.zeros(algebra.n_lam)
    lam0[: known * n_q] = _owned(sol.multipliers, n_q)
    rows = new_rows(sol.disc.problem.law, algebra, known)
    lam = _fill(algebra, u.x.petsc_vec, lam0, rows)
    lams = _functions(disc, algebra, lam, "lambda")
    u_max = comm.allreduce(float(np.max(np.abs(u.x.array), initial=0.0)), op=MPI.MAX)
    wanted, free, _, _, couplings = algebra.newton_sets(u.x.petsc_vec, lam, u_max)
    couplings = [c.restricted(~wanted[c.rows].all(axis=1)) for c in couplings]
    system.solve_active(wanted, free, couplings)
    goal_forms = GoalForms(goal, u, lams[0], disc, tuple(lams[1:]) or None)
    z = solve_dual(system, goal_forms)
    # (M1) per macro contact facet: the new multipliers' work on y, the NCP weighted by xi
    By = system.N.createVecLeft()
    system.N.mult(z.y.x.petsc_vec, By)
    C = algebra.ncp_residual(u.x.petsc_vec, lam)
    xi = _owned(z.multipliers, n_q)
    terms = -xi * C
    terms[rows] -= lam[rows] * By.array[rows]
    By.destroy()
    facet = np.sum(algebra.components_of(terms), axis=0)
    value = comm.allreduce(float(facet.sum()), op=MPI.SUM)
    cells, facet_f = indicator_functions(disc, facet, algebra.M.array[:n_q], localize)
    step, changed = _step(system, goal, goal_forms, disc, algebra, (wanted, free, couplings))
    history = None if disc.u_old is None else slip_offset_goal(system, xi)
    return ModelError(
        value=value,
        interval=model_interval(value, step, changed, roundoff),
        indicators=cells,
        facet_indicators=facet_f,
        law=disc.problem.law,
        newton_step=step,
        num_slip=_num_slip(couplings, wanted, free, algebra, comm),
        num_changed=changed,
        history=history,
    )


def indicator_functions(
    disc: Any,
    facet: np.ndarray,
    M: np.ndarray,
    localize: Callable[[ufl.Form], np.ndarray],
    cell_terms: np.ndarray | None = None,
) -> tuple[fem.Function, fem.Function]:
    """The model indicators per cell and per macro contact facet from the facets' summands.

    Args:
        disc: The discretisation.
        facet: The summands per macro contact facet (owned rows).
        M: The facets' measures (owned rows).
        localize: Cell indicators (on T_h, local array) of a scalar form.
        cell_terms: Further terms per cell (local array on T_h), or None.

    Returns:
        ``(cells, facets)``: DG0 on T_h, ``facet`` spread by area over the cells beside each
        macro facet plus ``cell_terms``; and ``facet`` as a function on Lambda_H.
    """
    n_q = len(facet)
    facet_f = fem.Function(disc.Q, name="model_facet_indicators")
    facet_f.x.array[:n_q] = facet
    facet_f.x.scatter_forward()
    density = fem.Function(disc.Q)
    density.x.array[:n_q] = np.divide(facet, M, out=np.zeros(n_q), where=M > 0)
    density.x.scatter_forward()
    cells = fem.Function(fem.functionspace(disc.mesh, ("DG", 0)), name="model_indicators")
    n_local = cells.function_space.dofmap.index_map.size_local
    cells.x.array[:n_local] = localize(density * disc.m.ds_contact)[:n_local]
    if cell_terms is not None:
        cells.x.array[:n_local] += cell_terms[:n_local]
    cells.x.scatter_forward()
    return cells, facet_f


def _step(
    system: Any, goal: Goal, at: GoalForms, disc: Any, algebra: Any, sets: tuple
) -> tuple[float, int]:
    """J(w^1) - J(w_s^*) and the rows whose set test at w^1 differs from ``sets``.

    w^1 is the richer law's Newton iterate from w_s^* (in :attr:`system.x`); ``sets`` are the
    ``(constrained, free, couplings)`` of that step.
    """
    u_arr, lam_arr = system.split(system.x)
    u1 = fem.Function(disc.V)
    u1.x.array[: system.n_u] = u_arr
    u1.x.scatter_forward()
    lams = _functions(disc, algebra, lam_arr, "lambda1")
    step = GoalForms(goal, u1, lams[0], disc, tuple(lams[1:]) or None)
    comm = disc.comm
    u_max = comm.allreduce(float(np.max(np.abs(u1.x.array), initial=0.0)), op=MPI.MAX)
    lam1 = _owned(lams, algebra.n_q)
    wanted, free, _, _, couplings = algebra.newton_sets(u1.x.petsc_vec, lam1, u_max)
    couplings = [c.restricted(~wanted[c.rows].all(axis=1)) for c in couplings]
    old, new = (sets[0], sets[1], sets[2]), (wanted, free, couplings)
    masks = [_coupled(c, len(wanted)) for c in (old[2], new[2])]
    changed = (
        (new[0] != old[0])
        | (~new[0] & (np.sign(new[1]) != np.sign(old[1])))
        | (masks[0] != masks[1])
    )
    num = comm.allreduce(int(changed.sum()), op=MPI.SUM)
    return step.value() - at.value(), num


def _coupled(couplings: list, n: int) -> np.ndarray:
    """The rows of the coupled facets as a mask of ``n`` owned rows."""
    out = np.zeros(n, dtype=bool)
    for c in couplings:
        out |= c.mask(n)
    return out


def _num_slip(
    couplings: list, wanted: np.ndarray, free: np.ndarray, algebra: Any, comm: Any
) -> int:
    """The facets that slip in the richer law's sets at w_s^* (coupled or free with +-s)."""
    parts = algebra.components_of(wanted)
    moving = np.zeros(algebra.n_q, dtype=bool)
    for c in couplings:
        moving[c.rows[:, 0] % algebra.n_q] = True
    for k, f in enumerate(algebra.components_of(free)[1:], start=1):
        moving |= ~parts[k] & (f != 0.0)
    return comm.allreduce(int(moving.sum()), op=MPI.SUM)

