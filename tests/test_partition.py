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
from dwr_signorini.refine import refine_marked

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
    for tag in np.unique(comm.allgather(np.unique(problem.facet_tags.values))[0]).tolist():
        out[f"facet {tag}"] = total(one * ds_(int(tag)))
    if problem.cell_tags is not None:
        dx = ufl.Measure("dx", domain=msh, subdomain_data=problem.cell_tags)
        for tag in np.unique(problem.cell_tags.values).tolist():
            out[f"cell {tag}"] = total(one * dx(int(tag)))
    return out


def _refined_at_a_corner(comm):
    """Example 5.3 on 2 x 8 x 8 boxes, refined twice in the cells nearest a corner."""
    problem = ex.obstacle_problem(comm, (2, 8, 8))
    for _ in range(2):
        msh = problem.mesh
        mid = msh.geometry.x[ex_cells(msh)].mean(axis=1)
        marked = np.flatnonzero(np.linalg.norm(mid, axis=1) < 0.4).astype(np.int32)
        problem, _ = refine_marked(problem, marked)
    return problem


def ex_cells(msh):
    """The geometry nodes of the owned cells."""
    from dwr_signorini import compat

    n = msh.topology.index_map(msh.topology.dim).size_local
    return compat.geometry_dofmap(msh)[:n]


def test_rebalance_keeps_the_mesh_and_evens_the_shares():
    comm = MPI.COMM_WORLD
    problem = _refined_at_a_corner(comm)
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


def test_adaptive_run_gives_the_same_levels_with_and_without_rebalancing(monkeypatch):
    """Redistribution changes no discrete problem: the first refined level is the same mesh
    (J_h and eta to round-off); later levels are refined from another numbering, which breaks
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
        assert b.J_h == pytest.approx(a.J_h, rel=1e-9)
        assert b.eta == pytest.approx(a.eta, rel=1e-6)
    for a, b in zip(plain[2:], balanced[2:], strict=True):
        assert b.num_cells == pytest.approx(a.num_cells, rel=0.05)
        assert abs(b.J_h - a.J_h) < 0.1 * abs(a.eta)
