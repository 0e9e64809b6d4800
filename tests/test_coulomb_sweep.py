"""Coulomb's semi-smooth Newton method from zero on a sweep of exact problems, and its determinism.

* The exact uniform patch tests of :mod:`tests.friction_cases` (stick ratios 0.05-0.999, slip
  ratios 1.001-100, triangles, quadrilaterals, tetrahedra, hexahedra, oblique shear in 3D),
  one ``ds.solve`` each from zero: below the uniqueness bound of the discrete problem
  (mu < sqrt(3 - 4 nu) / (2 - 2 nu) = 0.958 at nu = 0.3) lambda_n, lambda_t and the slip are
  the exact ones to 1e-8, in at most 15 Newton steps, median at most 8. Above it (mu = 2) the
  discrete problem has other solutions than the uniform one (one is found from zero: a
  corner facet lifts off and the rest slips); there the method converges, the result
  keeps its multipliers in Coulomb's cone facet by facet, and at stick ratios the load path
  "press, then shear" ends at the uniform solution.
* The Cattaneo-Mindlin problems of ``examples`` (a cylinder / a sphere pressed onto a rigid flat
  and sheared) solved in one step from zero, mu from 0.01 to 2.
* Determinism: one solve three times gives the same Newton history and result to the last bit.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import cases

from . import friction_cases as fc

COMM = MPI.COMM_WORLD
TOL = 1e-8


def _solve_case(case, law, rtol=1e-10):
    """(Newton steps, errors) of one case solved from zero with Coulomb's law or with
    Tresca's of the same threshold on this problem (s = mu lambda_n)."""
    law = ds.Coulomb(case.mu) if law == "coulomb" else ds.Tresca(case.mu * case.exact()["lam_n"])
    with ds.solve(case.problem(COMM, law), rtol=rtol) as sol:
        return sol.newton_iterations, fc.errors(case, sol)


@pytest.mark.mpi
@pytest.mark.parametrize("law", ["coulomb", "tresca"])
@pytest.mark.parametrize("cell", list(fc.CELLS))
def test_uniform_patch_tests_converge_from_zero_to_the_exact_solution(cell, law):
    """Every stick and slip ratio, mu = 0.01, 0.3 and 0.9 (both shear directions in 3D): exact to
    1e-8 (relative to lambda_n, and to the top's displacement for the slip), at most 15
    Newton steps, median at most 8."""
    cases = [c for c in fc.sweep() if c.cell == cell and c.mu < 1.0]
    assert len(cases) == len(fc.STICK_RATIOS + fc.SLIP_RATIOS) * 3 * (c_dim(cell) - 1)
    steps, wrong = [], []
    for case in cases:
        n, err = _solve_case(case, law)
        steps.append(n)
        if max(err.values()) > TOL:
            wrong.append((case.label, err))
    assert not wrong, wrong
    assert max(steps) <= 15 and np.median(steps) <= 8, steps


def c_dim(cell):
    return 2 if cell in ("triangle", "quadrilateral") else 3


def _coulomb_law_holds(case, sol, tol=1e-8):
    """lambda_n >= 0 and |lambda_t| <= mu lambda_n on every macro contact facet (all ranks).

    From the multipliers themselves, not from the package's NCP residual; the gap condition
    is weak (per macro facet), so it is left to the residual of the solve.
    """
    d = case.dim
    n_q = sol.system.algebra.n_q
    lam_n = sol.lam.x.array[:n_q]
    lam_t = (sol.lam_t.x.array[:n_q, None] if d == 2
             else sol.lam_t.x.array.reshape(-1, 3)[:n_q, :2])
    scale = case.exact()["lam_n"]
    ok = np.all(lam_n >= -tol * scale)
    ok &= np.all(np.linalg.norm(lam_t, axis=1) <= case.mu * lam_n + tol * scale)
    return bool(COMM.allreduce(bool(ok), op=MPI.LAND))


@pytest.mark.mpi
@pytest.mark.parametrize("cell", list(fc.CELLS))
def test_above_the_uniqueness_bound_the_method_converges_to_a_solution(cell):
    """mu = 2: every case converges from zero (default max_iterations) to a state whose
    multipliers lie in Coulomb's cone facet by facet (the uniform one or another solution)."""
    cases = [c for c in fc.sweep() if c.cell == cell and c.mu > 1.0]
    for case in cases:
        with ds.solve(case.problem(COMM), rtol=1e-10) as sol:
            assert sol.history[-1]["residual_ncp"] <= 1e-10, case.label
            assert _coulomb_law_holds(case, sol), case.label


@pytest.mark.mpi
@pytest.mark.parametrize("ratio", [0.05, 0.5, 0.999])
@pytest.mark.parametrize("cell", ["triangle", "tetrahedron"])
def test_press_then_shear_reaches_the_uniform_solution_at_mu_2(cell, ratio):
    """mu = 2, stick ratios, along the path (0, -delta), (D_t, -delta): the uniform solution,
    exact to 1e-8. (At slip ratios the path too ends at another solution of the discrete
    problem: above the bound, which one depends on the path.)"""
    case = fc.UniformCase(cell, 2.0, ratio, math.radians(30.0), n=16 if c_dim(cell) == 2 else 4)
    full = case.problem(COMM)
    zero_shear = ds.SignoriniProblem(
        full.mesh, full.facet_tags, contact=fc.BOTTOM,
        dirichlet={fc.TOP: (*([0.0] * (case.dim - 1)), -fc.PRESS)}, E=fc.E, nu=case.nu,
        model=full.model, traction=_press_tractions(case), gap=0.0, friction=full.law,
    )
    out = {}

    def keep(record, sol, est):
        out["err"] = fc.errors(case, sol)

    goal = (lambda u, lam, m, lam_t: lam * m.ds_contact)  # noqa: E731
    with ds.solve_path([zero_shear, full], goal, callback=keep, verbose=False):
        pass
    assert max(out["err"].values()) <= TOL, out["err"]


def _press_tractions(case):
    """The side tractions of the pressed block without shear."""
    lmbda, _ = case.lame()
    sxx = -lmbda * fc.PRESS / fc.HEIGHT
    d = case.dim
    out = {}
    for k, tag in enumerate(fc.SIDES[: 2 * (d - 1)]):
        t = np.zeros(d)
        t[k // 2] = -sxx if k % 2 == 0 else sxx
        out[tag] = tuple(t)
    return out


@pytest.mark.mpi
@pytest.mark.parametrize("mu", [0.01, 0.3, 2.0])
def test_cattaneo_mindlin_in_one_step_from_zero(mu):
    """The 2D Cattaneo-Mindlin problem (a cylinder pressed onto a rigid flat and sheared,
    partial slip at mu = 0.3) solved in one step from zero: at most 15 Newton steps."""
    problem = cases.cattaneo_mindlin_path(COMM, mu=mu, steps=1, h_contact=0.02)[-1]
    with ds.solve(problem) as sol:
        assert sol.newton_iterations <= 15
        assert sol.num_active > 0 and sol.history[-1]["residual_ncp"] <= 1e-8


@pytest.mark.serial
def test_the_same_solve_gives_the_same_iterates_every_run():
    """A Coulomb solve that reuses factors (the sheared block on a cylinder) three times: the
    same Newton history and the same u, lambda, lambda_t to the last bit."""
    from .test_coulomb import cylinder

    runs = []
    for _ in range(3):
        with ds.solve(cylinder(top=(0.015, -0.02))) as sol:
            history = [(h["num_active"], h["num_changed"], h["residual_equilibrium"],
                        h["residual_ncp"]) for h in sol.history]
            state = [f.x.array.copy() for f in (sol.u, sol.lam, sol.lam_t)]
            runs.append((history, state, sol.system.reused))
    first = runs[0]
    for history, state, _ in runs[1:]:
        assert history == first[0]
        for a, b in zip(state, first[1], strict=True):
            assert np.array_equal(a, b)
