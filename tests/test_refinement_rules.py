"""Refinement rules and a target growth per level (3D, example 5.3's problem, a few levels).

* ``refinement_rule="longest_edge"`` bisects each marked macro cell through its longest edge:
  for the same marked cells the refined mesh has fewer cells than with all edges, and at least
  one more cell per marked cell (each marked cell is split);
* ``growth=g`` makes each adaptive level have about g times the macro cells of the last one;
  the fraction that gives it is searched with few refinements (``search_fraction``, checked on
  cell ratios with a known inverse).
"""

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.marking import mark, mark_at_most, search_fraction
from dwr_signorini.refine import refine_marked


def _cells(problem):
    return problem.mesh.topology.index_map(problem.mesh.topology.dim).size_global


@pytest.mark.mpi
def test_longest_edge_rule_spreads_less_than_all_edges():
    comm = MPI.COMM_WORLD
    problem = ex.obstacle_problem(comm, (1, 4, 4))
    with ds.solve(problem) as sol, ds.estimate(sol, ex.goal_obstacle()) as est:
        marked = mark(sol.disc, est.indicators.x.array, "fixed_fraction", 0.1)
        count = comm.allreduce(len(marked))
        edges, _ = refine_marked(problem, marked, "edges")
        longest, parent = refine_marked(problem, marked, "longest_edge")
    before = _cells(problem)
    assert before + count <= _cells(longest) < _cells(edges)
    # every marked cell has children: no marked cell is left as it was
    children = np.bincount(parent, minlength=problem.mesh.topology.index_map(3).size_local)
    assert np.all(children[marked] >= 2)


@pytest.mark.mpi
@pytest.mark.parametrize("rule", ["edges", "longest_edge"])
def test_growth_sets_the_cells_per_level(rule):
    with ds.solve_adaptive(ex.obstacle_problem(MPI.COMM_WORLD, (1, 4, 4)), ex.goal_obstacle(),
                           max_levels=3, growth=2.0, refinement_rule=rule, verbose=False) as res:
        macro = [r.num_macro_cells for r in res.levels]
    ratios = np.array(macro[1:]) / np.array(macro[:-1])
    assert np.all((1.5 <= ratios) & (ratios <= 2.7)), (rule, macro)
    with pytest.raises(ValueError, match="growth"):
        ds.solve_adaptive(ex.obstacle_problem(MPI.COMM_WORLD, (1, 4, 4)), ex.goal_obstacle(),
                          growth=1.0)
    with pytest.raises(ValueError, match="refinement_rule"):
        ds.solve_adaptive(ex.obstacle_problem(MPI.COMM_WORLD, (1, 4, 4)), ex.goal_obstacle(),
                          refinement_rule="bisect")


@pytest.mark.mpi
def test_mark_at_most_keeps_the_fraction_below_the_cap_and_caps_above_it():
    """Doerfler's set where it refines less than max_growth (the same cells as mark), the
    marking for growth max_growth where the fraction would refine more."""
    comm = MPI.COMM_WORLD
    problem = ex.obstacle_problem(comm, (1, 4, 4))
    with ds.solve(problem) as sol, ds.estimate(sol, ex.goal_obstacle()) as est:
        eta = est.indicators.x.array
        small = mark(sol.disc, eta, "doerfler", 0.3)
        alone, _ = refine_marked(problem, small, "edges")
        cap = 1.01 * _cells(alone) / _cells(problem)
        marked, refined, _, fraction = mark_at_most(sol.disc, problem, eta, "doerfler", 0.3, cap)
        assert fraction == 0.3 and np.array_equal(marked, small)
        assert _cells(refined) == _cells(alone)
        everything, _ = refine_marked(problem, mark(sol.disc, eta, "doerfler", 1.0), "edges")
        assert _cells(everything) > 2.5 * _cells(problem)  # so that the cap below bites
        marked, refined, _, fraction = mark_at_most(sol.disc, problem, eta, "doerfler", 1.0, 1.8)
        assert fraction < 1.0
        assert 1.5 < _cells(refined) / _cells(problem) < 2.1
        with pytest.raises(ValueError, match="max_growth"):
            mark_at_most(sol.disc, problem, eta, "doerfler", 0.3, 1.0)


def _recorded(ratio_of):
    calls = []

    def trial(fraction):
        calls.append(fraction)
        return ratio_of(fraction), fraction

    return trial, calls


@pytest.mark.parametrize("a, p", [(20.0, 1.0), (40.0, 0.7), (10.0, 1.5), (300.0, 2.0)])
@pytest.mark.parametrize("growth", [1.5, 2.0, 4.0])
@pytest.mark.parametrize("first", [0.01, 0.3])
def test_search_fraction_finds_a_smooth_growth_in_few_trials(a, p, growth, first):
    """Ratios 1 + a f^p: the fraction (growth - 1)^(1/p) / a^(1/p) is found to 5 % in <= 4."""
    trial, calls = _recorded(lambda f: 1.0 + a * f**p)
    fraction, ratio, kept, count = search_fraction(trial, growth, first)
    assert abs(ratio / growth - 1.0) < 0.05
    assert kept == fraction and ratio == 1.0 + a * fraction**p
    assert count == len(calls) <= 4, calls
    assert all(0.0 < f <= 1.0 for f in calls)


def test_search_fraction_in_steps_and_out_of_reach():
    """Counts in steps (no fraction within 5 %) end with the closest trial; a growth that even
    the fraction 1 does not reach ends at 1."""
    def steps(f):
        return 1.0 + 0.6 * np.floor(5 * f)  # 1, 1.6, 2.2, ...

    trial, calls = _recorded(steps)
    fraction, ratio, _, count = search_fraction(trial, 2.0, 0.05)
    assert count == len(calls) <= 8
    assert ratio == 2.2 and min(abs(np.log(steps(f) / 2.0)) for f in calls) == abs(np.log(1.1))
    trial, calls = _recorded(lambda f: 1.0 + 0.5 * f)
    fraction, ratio, _, _ = search_fraction(trial, 2.0, 0.1)
    assert fraction == 1.0 and ratio == 1.5
    assert all(0.0 < f <= 1.0 for f in calls)
