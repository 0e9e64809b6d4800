"""The adaptive loop at finite strain: solve, estimate, mark and refine a hyperelastic body.

Truths: on every level of an adaptive run the interval contains a reference J computed from
J_h alone on finer uniform meshes (ds.solve, no estimate), and that reference is closer to J
than half the interval is wide; one process and two give the same levels; what the estimate
does not take is refused before the first solve; a level whose Newton method fails from the
previous level's solution raises. Slow: the Neo-Hookean disc pressed by 25 % of its radius,
adaptive against uniform refinement for the contact force, a stress average near the contact
and the stress at the contact edge (``benchmarks/finite_strain_payoff.py`` measures why).
"""

import itertools
import json

from mpi4py import MPI

import numpy as np
import pytest
import ufl

import dwr_signorini as ds
from dwr_signorini import finite_strain
from dwr_signorini.goal import GoalForms
from dwr_signorini.refine import refine_with_tags
from dwr_signorini.semismooth import ConvergenceError

from .problems import from_model
from .test_finite_strain_estimate import GOALS, NU, E, cylinder_problem, disc_mesh, quarter_disc


def edge_stress(u, lam, m):
    """P_yy averaged with a Gaussian weight of width 0.1 at the contact zone's edge.

    The edge of the disc pressed by 25 %: the arc's point at x = 0.58 (reference configuration),
    where the pressure falls to zero and the solution is least smooth.
    """
    mu, lmbda = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    F = ufl.variable(ufl.Identity(2) + ufl.grad(u))
    P = ds.NeoHookean().first_piola(F, mu, lmbda)
    x0, y0 = EDGE
    weight = ufl.exp(-(((m.x[0] - x0) / 0.1) ** 2 + ((m.x[1] - y0) / 0.1) ** 2))
    return weight * P[1, 1] * m.dx


#: The contact edge of the slow run (x from its uniform levels 0-2: 0.47, 0.51, 0.56).
EDGE = (0.58, 1.0 - float(np.sqrt(1.0 - 0.58**2)))
#: The goals of the slow run: the estimate test's two and the stress at the contact edge.
EDGE_GOALS = {**GOALS, "edge": edge_stress}

#: The quarter disc's mesh size and how far its top is pressed (20 % of the radius).
H, PRESS = 0.25, 0.2


@pytest.fixture(scope="module")
def coarse():
    return from_model(quarter_disc, h=H)


def uniform_values(msh, facets, press, levels, goals=GOALS):
    """J_h of every goal of ``goals`` on the uniform refinements ``levels`` (no estimate).

    Two load steps: from zero the Newton method inverts cells of fine meshes.
    """
    out = {}
    for level in range(max(levels) + 1):
        problem = cylinder_problem(msh, facets, press)
        if level in levels:
            with ds.solve_path(problem, None, load_factors=[0.5, 1.0]) as path:
                sol = path.solutions[-1]
                out[level] = {name: GoalForms(goal, sol.u, sol.lam, sol.disc).value()
                              for name, goal in goals.items()}
        msh, _, _, facets = refine_with_tags(problem, None)
    return out


@pytest.fixture(scope="module")
def reference(coarse):
    """J of both goals from J_h on uniform level 4 (37888 cells), with |J_4 - J_3| its error."""
    msh, _, facets = coarse
    values = uniform_values(msh, facets, PRESS, (3, 4))
    return {name: (values[4][name], abs(values[4][name] - values[3][name])) for name in GOALS}


def _same_active_set(record, sol, est):
    """The solution's active set (the dual's) is the one the Newton method converged with."""
    assert sol.num_active == sol.history[-1]["num_active"] == record.num_active


def run(msh, facets, goal, press=PRESS, max_levels=3, **kwargs):
    """The levels (LevelRecords) of solve_adaptive on the disc pressed by ``press``."""
    with ds.solve_adaptive(cylinder_problem(msh, facets, press), goal, max_levels=max_levels,
                           verbose=False, callback=_same_active_set, **kwargs) as result:
        assert isinstance(result.solution, finite_strain.FiniteStrainSolution)
        return result.levels


def adaptive_rows(msh, facets, goal, max_levels=3, **kwargs):
    """(num_dofs, J_h, eta, J_low, J_high, Newton steps) per level of an adaptive run."""
    return [(r.num_dofs, r.J_h, r.eta, r.J_low, r.J_high, r.newton_iterations)
            for r in run(msh, facets, goal, max_levels=max_levels, **kwargs)]


@pytest.mark.parametrize("goal", sorted(GOALS))
def test_adaptive_intervals_contain_reference(coarse, reference, goal, mpi_tmp_path):
    """Three adaptive levels: each interval contains J from J_h on uniform level 4, the DoFs
    grow, and the table is written as for the linear problem."""
    msh, _, facets = coarse
    J_ref, error = reference[goal]
    rows = adaptive_rows(msh, facets, GOALS[goal], output_dir=mpi_tmp_path)
    print(f"\n{goal}: reference {J_ref:.8e} (|J_4 - J_3| = {error:.1e})")
    for level, (dofs, J_h, eta, low, high, newton) in enumerate(rows):
        print(f"level {level} dofs {dofs:5d} J_h {J_h:.8e} eta {eta:+.3e} newton {newton} "
              f"interval ({low:.8e}, {high:.8e}) Ieff {(J_ref - J_h) / eta:.2f}")
        assert low <= J_ref <= high
        assert error < (high - low) / 2  # the reference is finer than the interval
        assert newton >= 1
    dofs = [row[0] for row in rows]
    assert all(b > a for a, b in itertools.pairwise(dofs))
    table = json.loads((mpi_tmp_path / "adaptive.json").read_text())
    assert [row["J_h"] for row in table["levels"]] == [row[1] for row in rows]


@pytest.mark.mpi
@pytest.mark.parametrize("goal", sorted(GOALS))
def test_one_process_and_two_agree(goal):
    """The same levels (DoFs) and J_h, eta on COMM_WORLD as on COMM_SELF, to 1e-9."""
    rows = {}
    for name, comm in (("self", MPI.COMM_SELF), ("world", MPI.COMM_WORLD)):
        msh, _, facets = disc_mesh(comm, H)
        rows[name] = np.array(adaptive_rows(msh, facets, GOALS[goal]))
    print(goal, rows)
    assert np.array_equal(rows["world"][:, 0], rows["self"][:, 0])
    assert np.allclose(rows["world"][:, 1:3], rows["self"][:, 1:3], rtol=1e-9, atol=0.0)


def test_refused_before_the_first_solve(coarse, monkeypatch):
    """What a finite-strain level would refuse is refused by name before anything is solved."""
    msh, _, facets = coarse
    problem = cylinder_problem(msh, facets, PRESS)

    def no_solve(*args, **kwargs):
        raise AssertionError("solved before the options were checked")

    monkeypatch.setattr(finite_strain, "solve", no_solve)
    goal = GOALS["force"]
    for kwargs, match in (
        ({"weights": "higher_order"}, "higher_order"),
        ({"weights": "hierarchical"}, "hierarchical"),
        ({"model_error": problem}, "model_error"),
        ({"models": [problem, problem], "tol": 1e-3}, "models"),
        ({"petsc_options": {"ksp_type": "preonly"}}, "petsc_options"),
        ({"method": "schur"}, "method"),
    ):
        with pytest.raises(ValueError, match=match):
            ds.solve_adaptive(problem, goal, **kwargs)


def test_failed_level_raises(coarse, monkeypatch):
    """A level whose Newton method fails from the previous level's solution raises, saying so
    (no other start is tried)."""
    msh, _, facets = coarse
    newton, calls = finite_strain.newton, []

    def fails_on_level_1(system, *args):
        calls.append(system)
        if len(calls) == 2:
            raise ConvergenceError("finite strain: no convergence (made to fail)", [])
        return newton(system, *args)

    monkeypatch.setattr(finite_strain, "newton", fails_on_level_1)
    with pytest.raises(ConvergenceError, match="previous level's solution"):
        adaptive_rows(msh, facets, GOALS["force"], max_levels=3)
    assert len(calls) == 2


#: The slow run: the disc of mesh size 0.2 pressed by 25 % of its radius; uniform levels 0-3
#: (12800 cells) and adaptive ones up to 40000 cells judged, the reference from J_h alone on
#: uniform levels 3-5 (204800 cells).
SLOW_H, SLOW_PRESS, SLOW_UNIFORM, SLOW_CELLS = 0.2, 0.25, 4, 40000
#: The adaptive runs of the slow test per goal: the defaults, and for the stress at the contact
#: edge also the primal estimator driving (the run that pays there).
SLOW_RUNS = {"force": {"adaptive": {}}, "stress": {"adaptive": {}},
             "edge": {"adaptive": {}, "adaptive eta_p": {"estimator": "eta_p"}}}


def _richardson(j1, j2, j3):
    """Richardson's extrapolation of three J_h of uniform levels with their observed ratio."""
    return j3 + (j3 - j2) / ((j2 - j1) / (j3 - j2) - 1.0)


@pytest.fixture(scope="module")
def slow_runs():
    """Per goal: the reference and the levels of the uniform and the adaptive runs.

    Each goal's forms are compiled by an untimed level first (the runs' times exclude it).
    """
    msh, _, facets = from_model(quarter_disc, h=SLOW_H)
    values = uniform_values(msh, facets, SLOW_PRESS, (3, 4, 5), goals=EDGE_GOALS)
    out = {}
    for name, goal in EDGE_GOALS.items():
        J_ref = _richardson(*(values[k][name] for k in (3, 4, 5)))
        for kwargs in SLOW_RUNS[name].values():
            run(msh, facets, goal, SLOW_PRESS, 1, **kwargs)
        runs = {"uniform": run(msh, facets, goal, SLOW_PRESS, SLOW_UNIFORM, refinement="uniform")}
        for label, kwargs in SLOW_RUNS[name].items():
            runs[label] = run(msh, facets, goal, SLOW_PRESS, 20, max_cells=SLOW_CELLS, **kwargs)
        out[name] = (J_ref, runs)
    return out


def _print_table(goal, J_ref, runs):
    """The runs' levels as Markdown rows (the guide's table), cumulative times."""
    print(f"\n{goal}: reference {J_ref:.9e}\n| run | level | cells | J_h | interval | "
          "error | Newton | time (s) |\n|---|---|---|---|---|---|---|---|")
    for refinement, levels in runs.items():
        seconds = np.cumsum([r.time["total"] for r in levels])
        for r, t in zip(levels, seconds, strict=True):
            print(f"| {refinement} | {r.level} | {r.num_cells} | {r.J_h:.7f} | "
                  f"[{r.J_low:.7f}, {r.J_high:.7f}] | {abs(J_ref - r.J_h):.1e} | "
                  f"{r.newton_iterations} | {t:.2f} |")


@pytest.mark.slow
@pytest.mark.parametrize("goal", ["force", "stress", pytest.param("edge", marks=pytest.mark.xfail(
    strict=True, reason=(
        "measured: J = -1.0023959e-2 (uniform J_3,4,5 = -1.0059965e-2, -1.0031812e-2, "
        "-1.0025672e-2, ratio 4.6); level 0 (200 cells, the weight's width 0.1 unresolved) has "
        "J_low = -1.34740e-2, J_high = -1.05792e-2; the adaptive levels 6 and 7 (18696, 38980 "
        "cells) have J_h = -1.00381e-2, -1.00361e-2 and J_high = -1.00286e-2, -1.00289e-2 "
        "(eta_p level 6: -1.00280e-2): the adaptive J_h stay 1.2e-5 from J and their intervals "
        "miss it by 5e-6; which of the two limits is right is not decided here")))])
def test_slow_intervals_contain_reference(slow_runs, goal):
    """The disc pressed by 25 %: every level of the uniform (0-3) and the adaptive runs (to
    40000 cells) has an interval that contains J from J_h alone on uniform levels 3-5."""
    J_ref, runs = slow_runs[goal]
    _print_table(goal, J_ref, runs)
    missed = [(name, r.level) for name, levels in runs.items() for r in levels
              if not r.J_low <= J_ref <= r.J_high]
    assert not missed
    for name in SLOW_RUNS[goal]:
        cells = [r.num_cells for r in runs[name]]
        assert all(b > a for a, b in itertools.pairwise(cells))


def _payoff(J_ref, runs, name):
    """(uniform time, adaptive time, uniform cells, adaptive cells) to the finest uniform
    level's error: the adaptive run ``name``'s first level at least as close to J_ref
    (infinite time and cells if none is)."""
    finest = runs["uniform"][-1]
    target = abs(J_ref - finest.J_h)
    uniform_time = sum(r.time["total"] for r in runs["uniform"])
    spent = np.cumsum([r.time["total"] for r in runs[name]])
    reached = [(t, r.num_cells) for r, t in zip(runs[name], spent, strict=True)
               if abs(J_ref - r.J_h) <= target]
    time, cells = reached[0] if reached else (np.inf, np.inf)
    print(f"\n{name}: uniform error {target:.2e} in {uniform_time:.2f} s ({finest.num_cells} "
          f"cells), reached after {time:.2f} s ({cells} cells)")
    return uniform_time, time, finest.num_cells, cells


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "measured (h = 0.2, 25 %, reference from uniform levels 3-5, times without compilation): "
    "uniform level 3 (12800 cells) has errors 2.2e-4 (force), 1.9e-5 (stress), 3.6e-5 (edge) "
    "after 0.96, 1.18, 1.30 s in all; the adaptive runs reach them after 2.29 s (level 6, 25324 "
    "cells), 2.54 s (level 6, 21776 cells) and 0.98 s (eta_p, level 4, 4688 cells): force and "
    "stress gain nothing per cell, the edge stress 2.7x, and a level costs about 0.2-0.3 s "
    "whatever its cells (most of it the estimate), so four uniform levels are hard to beat"))
@pytest.mark.parametrize("goal", sorted(EDGE_GOALS))
def test_slow_adaptive_reaches_uniform_error_faster(slow_runs, goal):
    """Adaptivity reaches the error of the finest uniform level in at most 1/3 of its time."""
    J_ref, runs = slow_runs[goal]
    times = [_payoff(J_ref, runs, name)[:2] for name in SLOW_RUNS[goal]]
    assert min(t for _, t in times) <= times[0][0] / 3


@pytest.mark.slow
def test_slow_edge_stress_adaptive_needs_half_the_cells(slow_runs):
    """The stress at the contact edge: the adaptive run driven by eta_p reaches the error of
    uniform level 3 with at most half its cells (its time is printed; the time ratios are
    measured by benchmarks/finite_strain_payoff.py: 0.75-0.84 of the uniform run's)."""
    J_ref, runs = slow_runs["edge"]
    _, _, uniform_cells, cells = _payoff(J_ref, runs, "adaptive eta_p")
    assert cells <= uniform_cells / 2
