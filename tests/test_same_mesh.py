"""The same levels on any number of ranks: one run on COMM_SELF (serial) on every rank and one on
COMM_WORLD, compared (``mpirun -n 2``).

Marking takes the global threshold with ties (equal up to round-off) all marked, and the
refinement breaks the ties between equally long edges by geometry, not by vertex numbers
(:func:`dwr_signorini.refine.refine_uniform`): the cell counts agree, and J_h to round-off.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from dolfinx.mesh import CellType

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.refine import refine_uniform

pytestmark = pytest.mark.mpi


def _levels(comm, dim, max_levels):
    """(cells, J_h) per level of the default adaptive run of example 5.1 (2D) or 5.3 (3D)."""
    if dim == 2:
        problem, goal = ex.analytic_problem(comm, 12, 8, CellType.triangle), ex.goal_a(-0.5)
    else:
        problem, goal = ex.obstacle_problem(comm, (2, 4, 4)), ex.goal_obstacle()
    with ds.solve_adaptive(problem, goal, max_levels=max_levels, verbose=False) as res:
        return [(r.num_cells, r.J_h) for r in res.levels]


@pytest.mark.parametrize(("dim", "max_levels"), [(2, 5), (3, 3)])
def test_serial_and_parallel_runs_give_the_same_levels(dim, max_levels):
    serial = _levels(MPI.COMM_SELF, dim, max_levels)
    parallel = _levels(MPI.COMM_WORLD, dim, max_levels)
    assert len(serial) == len(parallel) == max_levels
    for (cells_s, J_s), (cells_p, J_p) in zip(serial, parallel, strict=True):
        assert cells_s == cells_p
        assert J_p == pytest.approx(J_s, rel=1e-10, abs=1e-14)
    assert serial[-1][0] > 2 * serial[0][0]  # the runs did refine


@pytest.mark.parametrize("dim", [2, 3])
def test_refinement_puts_new_vertices_at_the_midpoints(dim):
    """Refined under the tie-breaking map, the vertices go back to the old vertices and the
    midpoints of the edges: on a unit square (cube) of 4^d boxes, multiples of 1/8."""
    if dim == 2:
        msh = dmesh.create_unit_square(MPI.COMM_WORLD, 4, 4, ghost_mode=dmesh.GhostMode.none)
    else:
        msh = dmesh.create_unit_cube(MPI.COMM_WORLD, 4, 4, 4, ghost_mode=dmesh.GhostMode.none)
    msh.topology.create_entities(1)
    fine, _ = refine_uniform(msh)
    x = fine.geometry.x[:, :dim] * 8
    assert np.abs(x - np.round(x)).max() < 1e-12
    cells = fine.topology.index_map(dim).size_global
    assert cells == msh.topology.index_map(dim).size_global * 2**dim
