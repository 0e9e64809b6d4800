"""Estimates of several goals at one solution share its goal-independent parts
(:mod:`dwr_signorini.estimate_parts`), and give the numbers of fresh estimates.

Truths, serially and on 2 ranks:

* the indicator forms compiled once with slot functions (:class:`ResidualForms`) give, goal
  after goal, the indicators of the forms built with each goal's own functions
  (:mod:`dwr_signorini.residuals` assembled directly), to round-off: on a contact pair (the
  master traces P y, P w_y of the slots made again from their new values) and under a given
  force (the dual's zeta);
* an estimate of a goal made with the parts that an estimate of another goal left with the
  solution equals, to 1e-10, a fresh estimate of the same goal at the same solution (its own
  reconstruction, P2 solves and compiled forms): J_h, eta_p, eta, the contact term, R_A and
  every cell indicator, with the patch, factored P2 and hierarchical P2 weights; the second goal
  makes no P2 solver (kept within the memory budget) and compiles no residual form of its own.
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl

import dwr_signorini as ds
from dwr_signorini import estimate_parts, estimator
from dwr_signorini import obstacles as ob
from dwr_signorini.dual import solve_dual
from dwr_signorini.goal import GoalForms
from dwr_signorini.residuals import (
    active_set_remainder,
    contact_term,
    dual_residual,
    primal_residual,
)
from dwr_signorini.settings import EstimateOptions

from .problems import block, make
from .test_pair_share import blocks_problem, lower_displacement

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD


def contact_force(u, lam, m):
    """The contact force (a goal in the multiplier)."""
    return lam * m.ds_contact


def mean_uy(u, lam, m):
    """A goal linear in u."""
    return u[1] * m.dx


def pressure_moment(u, lam, m):
    """The second moment of the contact pressure (the force alone is given: F)."""
    return lam * m.x[0] ** 2 * m.ds_contact


def forced_punch():
    """The unit square pressed onto a plane under a given force (dwr_signorini.force)."""
    msh, tags = block(COMM, 8, 8)
    return make(msh, tags, gap=ob.Plane((0.0, 0.0), (0.0, -1.0), force=0.05), E=1.0)


def summary(est):
    """The numbers of an estimate: its totals and its owned cell indicators."""
    n = est.indicators.function_space.dofmap.index_map.size_local
    totals = np.array([est.J_h, est.eta_p, est.eta, est.contact_term, est.active_set_remainder])
    return totals, est.indicators.x.array[:n].copy()


def counting(monkeypatch, cls):
    """Count the constructions of ``cls``."""
    made = []
    original = cls.__init__

    def init(self, *args, **kwargs):
        made.append(1)
        original(self, *args, **kwargs)

    monkeypatch.setattr(cls, "__init__", init)
    return made


def case_of(name):
    """The problem and two goals of a case."""
    if name == "pair":
        return blocks_problem(), (lower_displacement, contact_force)
    return forced_punch(), (mean_uy, pressure_moment)


def direct_indicators(sol, goal_forms, z, parts, weights):
    """The indicators of rho, C, R_A and rho* (without J') from forms built with the goal's own
    functions, and those of the slot forms, for the weights ``weights``."""
    degree = sol.disc.problem.quadrature_degree
    inp = estimator._Inputs(sol, goal_forms, z, parts, EstimateOptions(weights=weights))
    w_y, xi_plus, u_plus, w_u, lam_plus = estimator._weights(inp, weights)
    slots = parts.residual_forms(sol, weights, True, degree).indicators(z, w_y, xi_plus)
    c = parts.c
    w_xi = tuple(p - f for p, f in zip(xi_plus, z.multipliers, strict=True))
    w_lam = tuple(p - f for p, f in zip(lam_plus, sol.multipliers, strict=True))
    forms = [primal_residual(sol, w_y, w_xi, c), contact_term(sol, z.multipliers, c),
             active_set_remainder(sol, u_plus, lam_plus, xi_plus, c),
             dual_residual(sol, None, z, w_u, w_lam, c)]
    direct = estimator._assemble_indicators(sol.disc, forms, parts.DG0, degree)
    for k, weight in ((0, w_y), (3, w_u)):
        direct[k] += estimate_parts.MasterShare(sol.disc, forms[k], weight, parts.DG0, degree)()
    return slots, direct


@pytest.mark.parametrize("case", ["pair", "force"])
@pytest.mark.parametrize("weights", ["patch", "higher_order"])
def test_slot_forms_are_the_forms_of_each_goals_functions(case, weights):
    problem, goals = case_of(case)
    with ds.solve(problem) as sol:
        parts = estimate_parts.EstimateParts(sol)
        try:
            for goal in goals:
                goal_forms = GoalForms(goal, sol.u, sol.lam, sol.disc)
                z = solve_dual(sol.system, goal_forms)
                slots, direct = direct_indicators(sol, goal_forms, z, parts, weights)
                n = parts.DG0.dofmap.index_map.size_local
                for a, b in zip(slots, direct, strict=True):
                    scale = COMM.allreduce(float(np.abs(b[:n]).max(initial=0.0)), op=MPI.MAX)
                    diff = COMM.allreduce(float(np.abs(a[:n] - b[:n]).max(initial=0.0)),
                                          op=MPI.MAX)
                    assert diff <= 1e-12 * scale
                assert COMM.allreduce(float(np.abs(direct[0][:n]).max()), op=MPI.MAX) > 0
        finally:
            parts.destroy()


@pytest.mark.parametrize("case", ["pair", "force"])
@pytest.mark.parametrize("weights", ["patch", "higher_order", "hierarchical"])
def test_second_goal_with_kept_parts_is_a_fresh_estimate(monkeypatch, case, weights):
    problem, goals = case_of(case)
    with ds.solve(problem) as sol:
        fresh = []
        for goal in goals:
            with ds.estimate(sol, goal, weights=weights) as est:
                fresh.append(summary(est))
        solvers = {kind: counting(monkeypatch, getattr(estimate_parts, kind))
                   for kind in ("FactoredP2", "HierarchicalP2")}
        forms = counting(monkeypatch, estimate_parts.ResidualForms)
        budget = estimate_parts.SolverBudget()
        estimate_parts.keep_estimate_parts(sol, budget)
        kept = []
        for goal in goals:
            with ds.estimate(sol, goal, weights=weights) as est:
                kept.append(summary(est))
        assert sol.estimate_parts is not None
        assert (budget.kept > 0) == (weights != "patch")  # the P2 solver kept
        estimate_parts.release_estimate_parts(sol)
        assert sol.estimate_parts is None and budget.kept == 0
    assert len(forms) == 1
    assert sum(len(m) for m in solvers.values()) == (0 if weights == "patch" else 1)
    for (totals, cells), (ref_totals, ref_cells) in zip(kept, fresh, strict=True):
        assert abs(ref_totals[2]) > 1e-12  # an estimate that carries something
        np.testing.assert_allclose(totals, ref_totals, rtol=1e-10, atol=1e-16)
        scale = COMM.allreduce(float(np.abs(ref_cells).max(initial=0.0)), op=MPI.MAX)
        assert COMM.allreduce(float(np.abs(cells - ref_cells).max(initial=0.0)),
                              op=MPI.MAX) <= 1e-10 * scale


def test_indicators_of_integrals_with_different_degrees_on_one_subdomain():
    """rho* with the goal's J' added (a zero-valued facet integral of another quadrature degree
    on Gamma_C) has the indicators of its integrals one by one: compiled as one kernel, the
    facet integrals of one subdomain with degrees 1, 8, 2 and 8 had assembled to -1.318e-4
    against -2.027e-4 for the same integrals apart."""
    from dolfinx import fem

    from dwr_signorini.dual import solve_dual
    from dwr_signorini.estimate_parts import IndicatorForm, ncp_scale_function
    from dwr_signorini.goal import GoalForms
    from dwr_signorini.quadrature import with_quadrature_degrees
    from dwr_signorini.reconstruction import Reconstructor
    from dwr_signorini.residuals import dual_residual

    from .helpers import total_force
    from .problems import indented_block

    comm = MPI.COMM_WORLD
    with ds.solve(indented_block(comm, 16, 12, 0.002)) as sol:
        goal = GoalForms(total_force, sol.u, sol.lam, sol.disc)
        z = solve_dual(sol.system, goal)
        rec = Reconstructor(sol.disc)
        try:
            w_lam = (rec.patch_linear_multiplier(sol.lam) - sol.lam,)
            form = dual_residual(sol, goal, z, rec.patch_weight(sol.u), w_lam,
                                 ncp_scale_function(sol))
            degree = sol.disc.problem.quadrature_degree
            DG0 = fem.functionspace(sol.disc.mesh, ("DG", 0))
            n = DG0.dofmap.index_map.size_local

            def total(f):
                return comm.allreduce(float(IndicatorForm(sol.disc, f, DG0, degree)
                                            .assemble()[:n].sum()))

            apart = sum(total(ufl.Form([itg]))
                        for itg in with_quadrature_degrees(form, degree).integrals())
            assert total(form) == pytest.approx(apart, rel=1e-12, abs=1e-18)
        finally:
            rec.destroy()
