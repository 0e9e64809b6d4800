"""Rebalancing the macro mesh after adaptive refinement (:mod:`dwr_signorini.partition`).

The mesh must stay the same (cells, volume, the measure of every facet and cell tag) while its
distribution evens out, and an adaptive run must give the same levels whether it redistributes
or not: the discrete problems are the same, only the ranks' shares and the warm start differ.
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import partition
from dwr_signorini.reconstruction import Reconstructor
from dwr_signorini.refine import refine_marked
from dwr_signorini.spaces import discretize
from dwr_signorini.transfer import transfer_solution

pytestmark = pytest.mark.mpi


def _measures(problem):
    """Global cells, volume, and the measure of each facet tag and cell tag."""
    msh = problem.mesh
    comm = msh.comm
    tdim = msh.topology.dim
    one = fem.Constant(msh, 1.0)

    def total(form):
        return comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)

    out = {"cells": msh.topology.index_map(tdim).size_global, "volume": total(one * ufl.dx)}
    ds_ = ufl.Measure("ds", domain=msh, subdomain_data=problem.facet_tags)
    for tag in np.unique(np.concatenate(comm.allgather(problem.facet_tags.values))).tolist():
        out[f"facet {tag}"] = total(one * ds_(int(tag)))
    if problem.cell_tags is not None:
        dx = ufl.Measure("dx", domain=msh, subdomain_data=problem.cell_tags)
        for tag in np.unique(np.concatenate(comm.allgather(problem.cell_tags.values))).tolist():
            out[f"cell {tag}"] = total(one * dx(int(tag)))
    return out


def _refined_at_a_corner(comm, problem=None, times=2):
    """Example 5.3 (on 2 x 8 x 8 boxes), refined in the cells nearest a corner; the parents."""
    problem = problem or ex.obstacle_problem(comm, (2, 8, 8))
    parent = None
    for _ in range(times):
        msh = problem.mesh
        mid = msh.geometry.x[ex_cells(msh)].mean(axis=1)
        marked = np.flatnonzero(np.linalg.norm(mid, axis=1) < 0.4).astype(np.int32)
        problem, parent = refine_marked(problem, marked)
    return problem, parent


def _by_position(f):
    """The owned values of ``f`` on all ranks, ordered by the coordinates of their dofs."""
    V = f.function_space
    n = V.dofmap.index_map.size_local
    bs = V.dofmap.index_map_bs
    x = np.round(V.tabulate_dof_coordinates()[:n], 12)
    values = f.x.array[: n * bs].reshape(n, bs)
    x = np.concatenate(MPI.COMM_WORLD.allgather(x))
    values = np.concatenate(MPI.COMM_WORLD.allgather(values))
    return values[np.lexsort(x.T[::-1])]


def ex_cells(msh):
    """The geometry nodes of the owned cells."""
    from dwr_signorini import compat

    n = msh.topology.index_map(msh.topology.dim).size_local
    return compat.geometry_dofmap(msh)[:n]


def test_rebalance_keeps_the_mesh_and_evens_the_shares():
    comm = MPI.COMM_WORLD
    problem, _ = _refined_at_a_corner(comm)
    before = _measures(problem)
    balanced = partition.rebalance(problem, threshold=1.0, min_cells=0)
    if comm.size == 1:
        assert balanced is None
        return
    assert balanced is not None
    after = _measures(balanced)
    assert after.keys() == before.keys()
    for key, value in before.items():
        assert after[key] == pytest.approx(value, rel=1e-12), key
    assert partition.imbalance(balanced.mesh) < 1.1
    assert partition.rebalance(balanced, min_cells=0) is None  # balanced already
    assert partition.rebalance(problem, threshold=1.0) is None  # small: kept as it is


def test_warm_start_after_redistribution_is_the_one_without():
    """Through the cells' origins (rebalance_level) the warm start evaluates the last level's
    reconstructions in the same old cells as through the parent map on the mesh as refined:
    the same values at the same points, whichever rank holds them now."""
    comm = MPI.COMM_WORLD
    coarse = ex.obstacle_problem(comm, (1, 6, 6))
    sol = ds.solve(coarse)
    rec = Reconstructor(sol.disc)
    refined, parent = _refined_at_a_corner(comm, coarse, times=1)
    moved, origin = partition.rebalance_level(refined, parent, threshold=1.0, min_cells=0)
    if comm.size == 1:
        assert moved is refined and origin is parent
    else:
        assert isinstance(origin, partition.CellOrigin)
        assert partition.imbalance(moved.mesh) < partition.imbalance(refined.mesh)
    kept = transfer_solution(sol, discretize(refined), rec, parent)
    carried = transfer_solution(sol, discretize(moved), rec, origin)
    assert np.abs(_by_position(kept[0])).max() > 0  # a deformed body, in contact
    assert np.abs(_by_position(kept[1])).max() > 0
    for a, b in zip(kept, carried, strict=True):
        np.testing.assert_allclose(_by_position(b), _by_position(a), rtol=1e-12, atol=1e-14)
    rec.destroy()
    sol.destroy()


def test_adaptive_run_gives_the_same_levels_with_and_without_rebalancing(monkeypatch):
    """Redistribution changes no discrete problem: the first refined level is the same mesh
    (J_h and eta to round-off, the same Newton steps from the same warm start); later levels
    are refined from another numbering, which breaks
    the ties between equally long edges otherwise, so they are the same problem at about the
    same resolution: cells within 5 %, J_h apart by less than a tenth of the estimated error."""
    comm = MPI.COMM_WORLD
    runs = {}
    for threshold in (np.inf, 1.0):
        monkeypatch.setattr(partition, "REBALANCE_THRESHOLD", threshold)
        monkeypatch.setattr(partition, "REBALANCE_MIN_CELLS", 0)
        with ds.solve_adaptive(ex.obstacle_problem(comm, (1, 4, 4)), ex.goal_obstacle(),
                               max_levels=4, weights="patch", fraction=0.2) as res:
            runs[threshold] = list(res.levels)
    plain, balanced = runs[np.inf], runs[1.0]
    for a, b in zip(plain[:2], balanced[:2], strict=True):
        assert b.num_cells == a.num_cells
        assert b.newton_iterations == a.newton_iterations  # the same warm start
        assert b.J_h == pytest.approx(a.J_h, rel=1e-9)
        assert b.eta == pytest.approx(a.eta, rel=1e-6)
    for a, b in zip(plain[2:], balanced[2:], strict=True):
        assert b.num_cells == pytest.approx(a.num_cells, rel=0.05)
        assert abs(b.J_h - a.J_h) < 0.1 * abs(a.eta)
