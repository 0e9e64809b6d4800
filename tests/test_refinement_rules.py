"""Refinement rules and a target growth per level (3D, example 5.3's problem, a few levels).

* ``refinement_rule="longest_edge"`` bisects each marked macro cell through its longest edge:
  for the same marked cells the refined mesh has fewer cells than with all edges, and at least
  one more cell per marked cell (each marked cell is split);
* ``growth=g`` makes each adaptive level have about g times the macro cells of the last one.
"""

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.marking import mark
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
