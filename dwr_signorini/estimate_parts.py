"""What estimates of different goals at one solution share: the parts that do not depend on J.

An estimate of J at w_h (:func:`~dwr_signorini.estimate`) weights the residuals at w_h with the
dual solution z_h of J and with the reconstruction of w_h (eq. (13), (15)). Only z_h and what is
made from it depend on J; these do not:

* the patch reconstructor (:class:`~dwr_signorini.reconstruction.Reconstructor`) and the DG0
  space of the indicators;
* the P2 system of the final active set with its factorisation (``weights="higher_order"``,
  :class:`FactoredP2`; on the band around the contact zone, ``weights="local"``,
  :class:`LocalP2`) or its two-level set-up (``weights="hierarchical"``,
  :class:`~dwr_signorini.hierarchical.HierarchicalP2`): only the right-hand side of the P2 dual
  changes with J. Kept only within a memory budget (:class:`SolverBudget`): a P2 solver
  that is not kept is made for each estimate and released after it, as without the parts;
* the P2 primal solution w^(2) and the primal weights A w_h - w_h, lambda^+ of each kind of
  weights;
* whether ``weights="auto"``'s P2 weights fit in memory;
* the compiled forms of the indicators (:class:`ResidualForms`): rho(w_h)(.), C(w_h)(.),
  R_A and rho* without its J' term are compiled once with slot functions for z_h and its
  weights, into which each goal's values are copied before the assembly.

A load path's history (:func:`~dwr_signorini.path_history.history_estimates`) estimates, at every
kept step, another goal at the solution that the step's own estimate judged: the path gives
each kept :class:`~dwr_signorini.Solution` an :class:`EstimateParts`
(:attr:`~dwr_signorini.Solution.estimate_parts`) before its own estimate, and every later
estimate at that solution reuses them. The solution owns them and releases them in its
``destroy()``; an estimate of a solution without them makes its own and releases them at its
end (its reconstructor goes to the :class:`~dwr_signorini.Estimate`, as before). The reuse
changes no number beyond round-off: the same factors, solutions and weights (the J' term of
rho* is assembled apart from the rest, ``tests/test_estimate_parts.py``).
"""

from __future__ import annotations

from typing import Any

from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .algebra import ContactAlgebra
from .dual import DualSolution, solve_dual
from .force import ForceControl
from .goal import GoalForms, localize
from .hierarchical import HierarchicalP2
from .lifetime import Releasable
from .linalg import CoupledNewtonSystem, NewtonSystem, memory
from .local_p2 import ContactBand, band_options
from .newton import Solution
from .pairs import images_of
from .quadrature import with_quadrature_degrees
from .reconstruction import Reconstructor
from .residuals import active_set_remainder, contact_term, dual_residual, primal_residual
from .timing import timed
from .weights import memory_fallback, p2_weights_memory

__all__ = [
    "EstimateParts",
    "FactoredP2",
    "IndicatorForm",
    "MasterShare",
    "ResidualForms",
    "SolverBudget",
    "keep_estimate_parts",
    "ncp_scale_function",
    "release_estimate_parts",
]


def ncp_scale_function(sol: Solution) -> fem.Function:
    """The c of the NCP function the solution was computed with, as a function on Lambda_H."""
    # c is the same for every component of the law: the normal rows' values
    return sol.multiplier_function(sol.system.algebra.components_of(sol.system.c_n)[0], "c")


class IndicatorForm:
    """The cell indicators of a scalar form: its integrands times a DG0 test function (Section 4).

    Compiled once; :meth:`assemble` assembles it with the current values of its functions.

    Args:
        disc: The discretisation.
        form: The scalar form.
        DG0: A space on T_h (cell indicators) or on the fine slave facets (facet indicators).
        degree: The quadrature degree of non-polynomial integrands.
    """

    def __init__(self, disc: Any, form: ufl.Form, DG0: fem.FunctionSpace,
                 degree: int | None) -> None:
        q = ufl.TestFunction(DG0)
        groups: dict[tuple, list] = {}
        for itg in localize(with_quadrature_degrees(form, degree), q).integrals():
            key = (itg.integral_type(), itg.subdomain_id(), itg.metadata().get("quadrature_degree"))
            groups.setdefault(key, []).append(itg)
        # One form per (type, subdomain, degree): integrals of one subdomain with different
        # degrees compiled into one kernel assembled to another sum than their own (measured:
        # rho* with J' added -1.318e-4 against -2.027e-4 for its integrals one by one).
        self.compiled = [disc.form(ufl.Form(group)) for group in groups.values()]
        index_map = DG0.dofmap.index_map
        self._size = (index_map.size_local + index_map.num_ghosts) * DG0.dofmap.index_map_bs

    def assemble(self) -> np.ndarray:
        """The indicators (local array, ghosts included, their contributions summed)."""
        out = np.zeros(self._size)
        for compiled in self.compiled:
            vec = fem_petsc.assemble_vector(compiled)
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            out += vec.array
            vec.destroy()
        return out


class MasterShare:
    """The trace part of a form moved from the slave to the master cells (:mod:`.pairs`).

    Args:
        disc: The discretisation.
        form: The weighted form.
        weight: The displacement weight v (a function, or a sum of functions).
        DG0: The space of the cell indicators.
        degree: The quadrature degree of non-polynomial integrands.

    The part of ``form`` linear in the master trace P v of the displacement weight v (every
    image of v in the form, :func:`~dwr_signorini.pairs.images_of`), which the localisation put
    on the slave cells, is localised per fine slave facet and goes from the cell beside each
    facet to the master cells its points project into: the array of a call is added to the
    indicators and sums to zero (zero without contact pairs). Compiled once.
    """

    def __init__(self, disc: Any, form: ufl.Form, weight: Any, DG0: fem.FunctionSpace,
                 degree: int | None) -> None:
        self.DG0, self.part, self.geometry = DG0, None, None
        if disc.slave_mesh is None:
            return
        functions = weight.ufl_operands if isinstance(weight, ufl.algebra.Sum) else (weight,)
        images = [g for v in functions for g in images_of(form, v)]
        if images:
            part = sum(ufl.derivative(form, g, g) for g in images)  # the form is linear in P v
            self.geometry = disc.master_trace().geometry
            self.part = IndicatorForm(disc, part, self.geometry.Fs, degree)

    def __call__(self) -> np.ndarray:
        """The shares with the current values of the form's functions."""
        imap = self.DG0.dofmap.index_map
        if self.part is None:
            return np.zeros(imap.size_local + imap.num_ghosts)
        return self.geometry.share(self.part.assemble(), self.DG0)

#: The P2 primal weights of one kind: (u^+, A u_h - u_h or None without eta, lambda^+).
PrimalWeights = tuple[Any, Any, tuple]


class FactoredP2(Releasable):
    """The P2 system of the final active set factored once, its primal solved (higher_order).

    Args:
        sol: The solved discrete problem.
        rec: Its reconstructor (the P2 space ``rec.V2h``).
        petsc_options: The linear solver options of the P2 system.

    Raises:
        numpy.linalg.LinAlgError, LinearSolveError: As the P2 Newton step's solve.

    The system in P2 on T_h with Lambda_H and the final active set, the same kind of linear
    solver as the primal problem's (block or Schur complement) with the options prefix
    ``<primal prefix>p2_``; where an obstacle is under a given force, the bordered system at
    w_h's delta (:mod:`~dwr_signorini.force`). Its solution is the P2 primal w^(2); each goal's
    P2 dual is one transposed solve with its factors (:meth:`dual`).
    """

    def __init__(self, sol: Solution, rec: Reconstructor, petsc_options: Any,
                 algebra: ContactAlgebra | None = None, system: type | None = None) -> None:
        self.force: ForceControl | None = None
        with timed("higher-order solve"):
            self.system = (type(sol.system) if system is None else system)(
                sol.disc, petsc_options, V=rec.V2h, prefix=sol.system.prefix + "p2_",
                ncp_scale=sol.ncp_scale, algebra=algebra,
            )
        try:
            with timed("higher-order solve"):
                self._solve(sol)
        except BaseException:
            self.destroy()
            raise
        system = self.system
        u2 = fem.Function(rec.V2h, name="u2")
        u_arr, lam_arr = system.split(system.x)
        u2.x.array[: system.n_u] = u_arr
        u2.x.scatter_forward()
        self.primal = (u2, sol.multiplier_functions(lam_arr, "lambda2"))

    def _solve(self, sol: Solution) -> None:
        """The P2 Newton step of w_h's final sets (bordered where the obstacle is forced)."""
        couplings = sol.system.couplings

        def solve(act: np.ndarray, free: np.ndarray, cps: Any) -> None:
            self.system.solve_active(act, free, cps)

        if sol.obstacle_displacement is None:
            solve(sol.system.active, sol.system.free, couplings)
        else:
            self.force = self.system.force_control = ForceControl(self.system, move=False)
            self.force.step(solve, sol.system.active, sol.system.free, couplings)

    def dual(self, goal: GoalForms, z: DualSolution | None = None) -> DualSolution:
        """The P2 dual of ``goal``: one transposed solve with the P2 factors (z_h unused)."""
        with timed("higher-order solve"):
            return solve_dual(self.system, goal)

    def destroy(self) -> None:
        """Release the P2 system and its force control (collective; idempotent)."""
        if self.force is not None:
            self.force.destroy()
            self.force = None
        if self.system is not None:
            self.system.destroy()
            self.system = None


class LocalP2(FactoredP2):
    """The P2 systems of the final active set on the band around Gamma_C (``weights="local"``).

    Args:
        sol: The solved discrete problem (a single body: no master trace).
        rec: Its reconstructor.
        petsc_options: The linear solver options of the band's P2 system (MUMPS orders it
            with :data:`~dwr_signorini.local_p2.BAND_ORDERING` unless they say otherwise).
        band: The band (:func:`contact_band`), or None: made here.

    Raises:
        NotImplementedError: A contact pair, whose master side the band does not follow.

    :class:`FactoredP2` on the band of :mod:`~dwr_signorini.local_p2`: the primal's data off
    the band's free nodes is i_2h^(2) w_h, a dual's i_2h^(2) z_h of its goal. The band's
    system is factored (the block path) whatever the primal's method: where that is the
    Krylov path (3D from 200k DoFs) the band is a small part of the mesh.
    """

    def __init__(self, sol: Solution, rec: Reconstructor, petsc_options: Any,
                 band: ContactBand | None = None) -> None:
        self.rec = rec
        self.band = contact_band(sol, rec) if band is None else band
        with timed("reconstruct"):
            data = rec.patch_quadratic(sol.u)
        algebra = ContactAlgebra(sol.disc, rec.V2h, sol.ncp_scale, band=(self.band, data))
        factored = isinstance(sol.system, (NewtonSystem, CoupledNewtonSystem))
        super().__init__(sol, rec, band_options(petsc_options), algebra,
                         type(sol.system) if factored else NewtonSystem)

    def dual(self, goal: GoalForms, z: DualSolution | None = None) -> DualSolution:
        """The P2 dual of ``goal`` on the band, i_2h^(2) z_h off its free nodes (z_h needed)."""
        if z is None:
            raise ValueError("the band's P2 dual needs z_h: its data off the band")
        with timed("reconstruct"):
            data = self.rec.patch_quadratic(z.y)
        with timed("higher-order solve"):
            return solve_dual(self.system, goal, data)


def contact_band(sol: Solution, rec: Reconstructor) -> ContactBand:
    """The band of :mod:`~dwr_signorini.local_p2` around ``sol``'s contact zone (collective).

    Args:
        sol: The solution (its normal multiplier marks the contact zone).
        rec: Its reconstructor (the P2 space).

    Returns:
        The band.

    Raises:
        NotImplementedError: A contact pair, whose master side the band does not follow.
    """
    if sol.disc.slave_mesh is not None:
        raise NotImplementedError(
            "weights='local' solves P2 on a band around Gamma_C of one body; a contact pair "
            "needs the master side too: use 'higher_order' or 'hierarchical'"
        )
    with timed("higher-order solve"):
        return ContactBand(sol.disc, rec.V2h, zone=sol.multipliers[0])


def _options_key(petsc_options: Any) -> str:
    """A key of the P2 solver's options (a dict, or None)."""
    return repr(None if petsc_options is None else sorted(petsc_options.items()))


class ResidualForms:
    """The indicators' forms of one kind of weights, compiled once with slots for z_h's values.

    Args:
        sol: The solution.
        parts: Its parts (the reconstructor's spaces, c, the DG0 space).
        primal: The kind's (u^+, A u_h - u_h or None, lambda^+).
        want_eta: Whether rho* is wanted.
        degree: The quadrature degree of non-polynomial integrands.

    rho(w_h)(w_y, xi^+ - xi), C(w_h)(xi), R_A(w_h, w^+, xi^+) and, for eta,
    rho*(w_h, z_h)(A w_h - w_h, lambda^+ - lambda) without its J' term (eq. (13), (15),
    :mod:`~dwr_signorini.residuals`): w^+ and A w_h - w_h are the kind's (fixed), z_h = (y, xi,
    zeta), the dual weight w_y and xi^+ are slot functions on their spaces, into which
    :meth:`indicators` copies each goal's values. The J' term is the goal's own
    (:func:`~dwr_signorini.estimator.estimate` adds it).
    """

    def __init__(self, sol: Solution, parts: EstimateParts, primal: PrimalWeights,
                 want_eta: bool, degree: int | None) -> None:
        disc, rec, DG0 = sol.disc, parts.rec, parts.DG0
        u_plus, w_u, lam_plus = primal
        n = len(sol.multipliers)
        self.y = fem.Function(disc.V, name="y")
        self.xi = tuple(fem.Function(disc.Q, name=f"xi_{k}") for k in range(n))
        self.w_y = fem.Function(rec.V2h, name="w_y")
        self.xi_plus = tuple(fem.Function(rec.P1h, name=f"xi_plus_{k}") for k in range(n))
        self.zeta = (None if sol.obstacle_displacement is None
                     else fem.Constant(disc.mesh, PETSc.ScalarType(0.0)))
        c = parts.c
        w_xi = tuple(p - f for p, f in zip(self.xi_plus, self.xi, strict=True))
        forms = [
            primal_residual(sol, self.w_y, w_xi, c),
            contact_term(sol, self.xi, c),
            active_set_remainder(sol, u_plus, lam_plus, self.xi_plus, c),
        ]
        if want_eta:
            z = DualSolution(self.y, *self.xi, zeta=self.zeta)
            w_lam = tuple(p - f for p, f in zip(lam_plus, sol.multipliers, strict=True))
            forms.append(dual_residual(sol, None, z, w_u, w_lam, c))
        self.forms = [IndicatorForm(disc, f, DG0, degree) for f in forms]
        #: The master-trace images P y, P w_y in the forms (contact pairs): functions of the
        #: values the slots had when the forms were built, made again from the new ones.
        self.images = [(g, slot) for slot in (self.y, self.w_y) for f in forms
                       for g in images_of(f, slot)]
        self.disc = disc
        weighted = [(0, self.w_y), (3, w_u)] if want_eta else [(0, self.w_y)]
        self.shares = [(k, MasterShare(disc, forms[k], w, DG0, degree)) for k, w in weighted]

    def indicators(self, z: DualSolution, w_y: fem.Function,
                   xi_plus: tuple[fem.Function, ...]) -> list[np.ndarray]:
        """The indicators of rho, C, R_A (and rho* without J') with a goal's z_h and weights."""
        pairs = [(self.y, z.y), (self.w_y, w_y),
                 *zip(self.xi, z.multipliers, strict=True),
                 *zip(self.xi_plus, xi_plus, strict=True)]
        for slot, f in pairs:
            slot.x.array[:] = f.x.array
        for image, slot in self.images:
            image.x.array[:] = self.disc.trace_image(slot).x.array
        if self.zeta is not None:
            self.zeta.value = 0.0 if z.zeta is None else z.zeta
        out = [form.assemble() for form in self.forms]
        for k, share in self.shares:
            out[k] += share()
        return out


class SolverBudget:
    """The memory that the P2 solvers kept by the parts of several solutions may take.

    Attributes:
        kept: The predicted bytes of the solvers kept now.

    A load path's kept steps hold their P2 solvers until the path ends; each is kept only where
    the predicted memory of the P2 weights (:func:`~dwr_signorini.weights.p2_weights_memory`) of
    those already kept, this one and one more (the next step's own estimate) fits in the share
    :data:`~dwr_signorini.linalg.memory.FACTOR_FRACTION` of the available memory
    (:func:`~dwr_signorini.linalg.memory.available_memory`), the rule by which
    ``weights="auto"`` takes P2 weights. Where the available memory is measured it already
    holds the kept solvers, which so count twice: the rule keeps fewer than would fit.
    """

    def __init__(self) -> None:
        self.kept = 0

    def admit(self, V2: fem.FunctionSpace, kind: str, free: int | None = None) -> int | None:
        """The predicted bytes of a P2 solver ``kind`` on V2 if it may be kept, else None.

        Collective (the prediction and the available memory are the same on every rank).
        ``free``: the band's unconstrained dofs for ``"local"``
        (:func:`~dwr_signorini.weights.p2_weights_memory`).
        """
        need = p2_weights_memory(V2, kind, free)
        available = memory.available_memory(V2.mesh.comm)
        if self.kept + 2 * need > memory.FACTOR_FRACTION * available:
            return None
        self.kept += need
        return need

    def release(self, nbytes: int) -> None:
        """Return the bytes of released solvers."""
        self.kept -= nbytes


class EstimateParts(Releasable):
    """The goal-independent parts of the estimates at one solution (module docstring).

    Args:
        sol: The solution that owns them (:attr:`~dwr_signorini.Solution.estimate_parts`); the
            parts hold no reference back to it, each method is given it.
        budget: Where the P2 solvers may be kept for later estimates (:class:`SolverBudget`),
            or None: each is released after its estimate.

    Attributes:
        rec: The reconstructor, or None once handed to an estimate.
        DG0: The DG0 space on T_h of the indicators.
    """

    def __init__(self, sol: Solution, budget: SolverBudget | None = None) -> None:
        self.budget, self._kept_bytes = budget, 0
        with timed("reconstruct"):
            self.rec: Reconstructor | None = Reconstructor(sol.disc)
        self.DG0 = fem.functionspace(sol.disc.mesh, ("DG", 0))
        self.c = ncp_scale_function(sol)
        self._forms: dict[tuple[str, bool, int | None], ResidualForms] = {}
        self._solvers: dict[tuple[str, str], Releasable] = {}
        self._primal: dict[tuple[str, bool], PrimalWeights] = {}
        self._fallback: dict[str, str | None] = {}
        self._band: ContactBand | None = None

    def band(self, sol: Solution) -> ContactBand:
        """The band of ``weights="local"`` (made once; collective the first time)."""
        if self._band is None:
            self._band = contact_band(sol, self.rec)
        return self._band

    def _free(self, sol: Solution, kind: str) -> int | None:
        """The band's unconstrained dofs for ``"local"``, else None."""
        return self.band(sol).free_dofs if kind == "local" else None

    def fallback(self, sol: Solution, kind: str) -> str | None:
        """Why ``"auto"`` keeps the patch weights instead of P2 weights ``kind``, or None."""
        if kind not in self._fallback:
            self._fallback[kind] = memory_fallback(sol, self.rec, kind, self._free(sol, kind))
        return self._fallback[kind]

    def p2_solutions(
        self, sol: Solution, kind: str, goal: GoalForms, z: DualSolution, primal: bool,
        petsc_options: Any,
    ) -> tuple[DualSolution, tuple[fem.Function, tuple[fem.Function, ...]] | None]:
        """The P2 dual of ``goal`` and, if ``primal``, the P2 primal, with the kept P2 solver.

        Args:
            sol: The solution.
            kind: ``"higher_order"`` (factored) or ``"hierarchical"`` (two-level).
            goal: The goal's derivatives at w_h.
            z: z_h, the start of the two-level dual.
            primal: Whether the P2 primal w^(2) is wanted (for eta).
            petsc_options: The factored P2 system's options (a solver per options).

        Returns:
            z^(2) and w^(2) (or None).
        """
        key = (kind, "" if kind == "hierarchical" else _options_key(petsc_options))
        solver = self._solvers.get(key)
        kept = solver is not None
        if not kept:
            solver = self._new_solver(sol, kind, petsc_options)
        try:
            if kind == "hierarchical":
                return solver.solutions(sol, goal, z, primal)
            return solver.dual(goal, z), solver.primal if primal else None
        finally:
            if not kept:
                self._keep_or_release(sol, key, solver)

    def _new_solver(self, sol: Solution, kind: str, petsc_options: Any) -> Releasable:
        """A P2 solver of the weights ``kind``."""
        if kind == "hierarchical":
            return HierarchicalP2(sol, self.rec.V2h)
        if kind == "local":
            return LocalP2(sol, self.rec, petsc_options, self.band(sol))
        return FactoredP2(sol, self.rec, petsc_options)

    def _keep_or_release(self, sol: Solution, key: tuple[str, str], solver: Releasable) -> None:
        """Keep a new P2 solver for later estimates where the budget admits it, else release it."""
        need = (None if self.budget is None
                else self.budget.admit(self.rec.V2h, key[0], self._free(sol, key[0])))
        if need is None:
            solver.destroy()
        else:
            self._solvers[key] = solver
            self._kept_bytes += need

    def primal_weights(
        self, sol: Solution, kind: str, want_eta: bool, w2: tuple[fem.Function, tuple] | None
    ) -> PrimalWeights:
        """u^+, A u_h - u_h (for eta) and lambda^+ of the weights ``kind``, made once.

        Args:
            sol: The solution.
            kind: The weights; ``"patch"`` reconstructs w_h patch-wise (``w2`` None).
            want_eta: Whether A u_h - u_h is wanted (the P2 ones are made for eta only).
            w2: The P2 primal of ``kind``, or None for the patch weights.
        """
        key = (kind, want_eta)
        if key not in self._primal:
            self._primal[key] = self._make_primal(sol, want_eta, w2)
        return self._primal[key]

    def _make_primal(self, sol: Solution, want_eta: bool, w2: tuple | None) -> PrimalWeights:
        rec = self.rec
        with timed("reconstruct"):
            if w2 is None:  # the patch reconstruction of w_h
                w_u = rec.patch_weight(sol.u)
                return sol.u + w_u, w_u, self.linear(sol.multipliers)
            u_plus = w2[0]
            w_u = rec.weight(u_plus, sol.u) if want_eta else None
            return u_plus, w_u, self.linear(w2[1])

    def residual_forms(
        self, sol: Solution, kind: str, want_eta: bool, degree: int | None
    ) -> ResidualForms:
        """The compiled indicator forms of the weights ``kind`` (made once; after its primal)."""
        key = (kind, want_eta, degree)
        if key not in self._forms:
            with timed("indicators"):
                self._forms[key] = ResidualForms(
                    sol, self, self._primal[(kind, want_eta)], want_eta, degree
                )
        return self._forms[key]

    def linear(self, functions: tuple[fem.Function, ...]) -> tuple:
        """The linear reconstructions i_2H^(1) of multipliers, one per component."""
        return tuple(self.rec.patch_linear_multiplier(f) for f in functions)

    def hand_over(self) -> Reconstructor | None:
        """The reconstructor, which its caller now owns (these parts no longer release it)."""
        rec, self.rec = self.rec, None
        return rec

    def destroy(self) -> None:
        """Release the P2 solvers and the reconstructor (collective; idempotent)."""
        for solver in self._solvers.values():
            solver.destroy()
        self._solvers.clear()
        if self.budget is not None:
            self.budget.release(self._kept_bytes)
        self._kept_bytes = 0
        self._primal.clear()
        self._forms.clear()
        if self.rec is not None:
            self.rec.destroy()
            self.rec = None


def keep_estimate_parts(sol: Solution, budget: SolverBudget | None = None) -> None:
    """Give ``sol`` the parts its estimates share (kept until it is released).

    Args:
        sol: The solution.
        budget: The memory its P2 solvers may take, shared with other kept solutions; None:
            they are released after each estimate (the rest is kept).
    """
    if sol.estimate_parts is None:
        sol.estimate_parts = EstimateParts(sol, budget)


def release_estimate_parts(sol: Solution, est: Any = None) -> None:
    """Release ``sol``'s shared parts now, ``est`` taking over the reconstructor it uses.

    Args:
        sol: The solution.
        est: An :class:`~dwr_signorini.Estimate` of ``sol`` that outlives the parts, or None.
    """
    parts = sol.estimate_parts
    if parts is None:
        return
    if est is not None and est.reconstructor is parts.rec and parts.rec is not None:
        est.owns_reconstructor = True
        parts.hand_over()
    parts.destroy()
    sol.estimate_parts = None
