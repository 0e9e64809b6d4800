"""The pieces of the semi-smooth Newton method for Coulomb's law, on problems written by hand.

* the set test of one facet (laws.CoulombCone.newton_set): a facet entering contact, a facet
  reversing its slip, a consistent slip, a facet on the cone's edge, a stuck solution;
* a one-facet Coulomb problem built so that the plain rule cycles (slip one way, slip the other
  way) and the set rules converge to its exact stick solution in two steps;
* the price of factor reuse from MUMPS's counts (linalg.factor.FactorCost, ReusePolicy);
* the message of a failed solve names the unsettled facets, the residuals and what to try.
"""

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini.laws import CoulombCone, Tangential
from dwr_signorini.linalg.factor import FactorCost, ReusePolicy

CONE = CoulombCone(Tangential())
MU = 0.5


def _sets(Mlam_n, Mlam_t, res_n, res_t, c=1.0):
    """newton_set of 2D facets with M = 1, g = 0: (active, stick, slip, J)."""
    Mlam = np.array([Mlam_n, Mlam_t], dtype=float)
    residual = np.array([res_n, res_t], dtype=float)
    m = Mlam.shape[1]
    ones = np.ones(m)
    constrained, free, _, _, (slip, J, r) = CONE.newton_set(
        Mlam, residual, c * ones, ones, np.zeros((2, m)), 1.0, 1.0, MU * ones
    )
    assert np.all(free == 0.0) and np.all(r == 0.0)
    return constrained[0], constrained[1], slip, J


def test_a_facet_entering_contact_enters_without_friction():
    """lambda = 0 and penetrating (x_n > 0) with a large tangential displacement: the normal
    row is constrained, the tangential one neither stuck nor slipping (lambda_t = 0)."""
    active, stick, slip, _ = _sets([0.0], [0.0], [1.0], [5.0])
    assert active[0] and not stick[0] and not slip[0]


def test_a_facet_reversing_its_slip_sticks():
    """lambda = (1, 0.5) (slipping +, s = 0.5) and x_t = 0.5 - 2 = -1.5 beyond -s: stick, not
    slip the other way."""
    active, stick, slip, _ = _sets([1.0], [0.5], [0.0], [-2.0])
    assert active[0] and stick[0] and not slip[0]


def test_a_consistent_slip_is_coupled_to_the_normal_force():
    """x_t = 0.5 + 0.3 > s along lambda_t: slip, with dP_t / dx_n = mu sign(x_t)."""
    active, stick, slip, J = _sets([1.0], [0.5], [0.0], [0.3])
    assert active[0] and slip[0] and not stick[0]
    assert J[0, 1, 0] == MU and J[0, 0, 0] == 1.0 and J[0, 1, 1] == 0.0


def test_solutions_keep_their_sets():
    """A stuck solution (|lambda_t| < mu lambda_n, u_t = 0) sticks; a facet on the cone's edge
    (x_t = s, u_t = 0: degenerate) slips along lambda_t; an open facet is inactive."""
    active, stick, slip, _ = _sets([1.0, 1.0, 0.0], [0.2, 0.5, 0.0], [0.0, 0.0, -1.0],
                                   [0.0, 0.0, 0.0])
    assert list(active) == [True, True, False]
    assert list(stick) == [True, False, False]
    assert list(slip) == [False, True, False]


def _one_facet_step(state, f_n=1.0, f_t=0.3, k=1.0):
    """The step of the sets of ``state`` on the one-facet problem (see the test below).

    Equilibrium k u + lambda = f in each direction; active: u_n = 0; stick: u_t = 0; slip:
    lambda_t = mu d lambda_n; entering (neither): lambda_t = 0.
    """
    active, stick, slip, J = state
    if not active:
        return 0.0, 0.0, f_n / k, f_t / k
    lam_n, u_n = f_n, 0.0
    if stick:
        return lam_n, f_t, u_n, 0.0
    lam_t = J * lam_n if slip else 0.0
    return lam_n, lam_t, u_n, (f_t - lam_t) / k


def test_a_constructed_cycle_of_the_plain_rule_is_broken():
    """One facet, k = 1, f = (1, 0.3), mu = 0.5, c = 10 (a facet-scale stiffness ten times the
    body's): the exact solution sticks (lambda = (1, 0.3), u = 0). From slipping +, the plain
    rule slips -, then + again (x_t = -1.5, then 7.5: a 2-cycle); the set rules stick after
    one step and the next test confirms it."""
    c, lam_n, lam_t, u_n, u_t = 10.0, 1.0, 0.5, 0.0, -0.2  # the iterate of a step slipping +
    plain = []
    for _ in range(4):  # the plain rule, by hand: slip along x_t where |x_t| > s
        x_t = lam_t + c * u_t
        d = np.sign(x_t)
        plain.append(d)
        lam_t, u_t = MU * d * lam_n, 0.3 - MU * d * lam_n
    assert plain == [-1.0, 1.0, -1.0, 1.0]
    lam_t, u_t = 0.5, -0.2
    for step in range(3):
        active, stick, slip, J = _sets([lam_n], [lam_t], [u_n], [u_t], c=c)
        if step == 0:
            assert stick[0]
        state = (active[0], stick[0], slip[0], J[0, 1, 0] if slip[0] else 0.0)
        new = _one_facet_step(state)
        if new == (lam_n, lam_t, u_n, u_t):
            break
        lam_n, lam_t, u_n, u_t = new
    assert step == 1 and (lam_n, lam_t, u_t) == (1.0, 0.3, 0.0)


def test_from_zero_the_one_facet_problem_converges():
    """From lambda = 0, u = 0 the steps are: no contact (x_n = 0), entering without friction
    (u_t = 0.3 slides), slipping along the slide, reversing through stick: the solution."""
    c = 10.0
    lam_n = lam_t = u_n = u_t = 0.0
    visited = []
    for _ in range(8):
        active, stick, slip, J = _sets([lam_n], [lam_t], [u_n], [u_t], c=c)
        state = (bool(active[0]), bool(stick[0]), bool(slip[0]), J[0, 1, 0] if slip[0] else 0.0)
        visited.append(state[:3])
        new = _one_facet_step(state)
        if new == (lam_n, lam_t, u_n, u_t):
            break
        lam_n, lam_t, u_n, u_t = new
    assert (lam_n, lam_t, u_n, u_t) == (1.0, 0.3, 0.0, 0.0)
    assert len(visited) <= 6, visited


def test_factor_cost_from_mumps_counts():
    """A factored tridiagonal matrix: the factorisation's flops and the factors' entries
    (at least the matrix's 3n - 2) are positive; a solve costs less than a factorisation
    here only by the model's constant; no MUMPS factor: no price (no reuse)."""
    n = 200
    A = PETSc.Mat().createAIJ([n, n], nnz=3, comm=MPI.COMM_SELF)
    for i in range(n):
        A.setValue(i, i, 4.0)
        if i:
            A.setValue(i, i - 1, -1.0)
            A.setValue(i - 1, i, -1.0)
    A.assemble()
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.setOperators(A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    ksp.setUp()
    cost = FactorCost.of(ksp)
    assert cost is not None and cost.flops > 0 and cost.entries >= 3 * n - 2
    assert ReusePolicy().solve(cost) == pytest.approx(25.0 * cost.entries / cost.flops)
    assert ReusePolicy(solve_entry_cost=10.0).solve(cost) == pytest.approx(
        10.0 * cost.entries / cost.flops)
    assert ReusePolicy(fraction=1e9).pays(cost, 8) and not ReusePolicy(fraction=-1.0).pays(cost, 0)
    ksp.getPC().setType("jacobi")
    assert FactorCost.of(ksp) is None
    ksp.destroy()
    A.destroy()


@pytest.mark.mpi
def test_a_failed_coulomb_solve_names_its_facets_and_what_to_try():
    """max_iterations = 2 on a patch test that needs more: the error names the unsettled
    facets with their coordinates, the last residuals and solve_path."""
    from . import friction_cases as fc

    case = fc.UniformCase("triangle", 0.3, 2.0, n=8)
    with pytest.raises(ds.ConvergenceError) as info:
        ds.solve(case.problem(MPI.COMM_WORLD), max_iterations=2)
    message = str(info.value)
    assert "facet rows not settled" in message and " at (" in message
    assert "last residuals" in message and "ds.solve_path" in message
