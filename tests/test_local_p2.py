"""The P2 weights on a band around the contact zone (``weights="local"``).

:mod:`dwr_signorini.local_p2` solves the P2 dual and primal of the final active set on the cells
near Gamma_C, with the patch reconstructions as data on the nodes a cell outside the band
touches. Truths:

- the band's geometry: on a strip of triangles whose contact boundary is its bottom side, k
  layers are the cells of the k rows of cells above Gamma_C; around a part of Gamma_C, every
  cell with a vertex on it and nothing farther than k cells;
- a band that holds every cell constrains no node, and is the P2 system of the whole mesh: the
  estimate equals that of ``weights="higher_order"`` to round-off (2D, 3D, Coulomb's coupled
  rows, an obstacle under a given force, the Krylov path, quadrilaterals, hexahedra), serially
  and on 2 ranks;
- off the band the P2 dual and primal are the patch reconstructions, exactly;
- the interval of ``weights="auto"``, which takes these weights on a level whose contact set is
  not resolved, holds example 5.1's exact J (``tests/test_interval.py``).
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem
from dolfinx.mesh import CellType

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import local_p2
from dwr_signorini import obstacles as ob
from dwr_signorini.dual import solve_dual
from dwr_signorini.estimate_parts import LocalP2
from dwr_signorini.goal import GoalForms
from dwr_signorini.local_p2 import ContactBand, band_cells, band_options
from dwr_signorini.reconstruction import Reconstructor
from dwr_signorini.weights import p2_weights_memory

from .problems import block, make, strip_problem

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD


def _midpoints(disc, cells):
    x = disc.mesh.geometry.x
    dofs = disc.mesh.geometry.dofmap[cells]
    return x[dofs].mean(axis=1)


def _count(local: int) -> int:
    return COMM.allreduce(int(local), op=MPI.SUM)


@pytest.mark.parametrize("layers", [1, 2, 5])
def test_band_is_the_rows_of_cells_above_gamma_c(layers):
    """The strip (4 x 1, 16 x 4 macro cells, T_h 32 x 8 rows of triangles) is in contact on
    its bottom side: a fine cell lies in one row of height 1/8, so k layers are the cells whose
    midpoint is below k / 8."""
    disc = ds.discretize(strip_problem(COMM, 16, 4))
    cells = band_cells(disc, layers)
    num_cells = disc.mesh.topology.index_map(2).size_local
    below = np.flatnonzero(_midpoints(disc, np.arange(num_cells))[:, 1] < layers / 8)
    assert np.array_equal(cells, below)
    assert _count(cells.size) == 64 * layers  # 32 columns of 2 triangles per row


def test_band_around_part_of_gamma_c():
    """Around the facets where lambda does not vanish (x in [1.5, 2.5] of the strip's bottom):
    every cell with a vertex there and a row along all of Gamma_C are in, no cell farther
    than 3 cells (3 x the longest edge, sqrt(2) / 8) from that part."""
    disc = ds.discretize(strip_problem(COMM, 16, 4))
    zone = fem.Function(disc.Q)
    zone.interpolate(lambda x: ((x[0] > 1.5) & (x[0] < 2.5)).astype(float))
    cells = band_cells(disc, 3, zone)
    num_cells = disc.mesh.topology.index_map(2).size_local
    mid = _midpoints(disc, np.arange(num_cells))
    inside = set(cells.tolist())
    assert set(np.flatnonzero(mid[:, 1] < 1 / 8).tolist()) <= inside
    near = (mid[:, 0] > 1.6) & (mid[:, 0] < 2.4) & (mid[:, 1] < 0.3)
    assert set(np.flatnonzero(near).tolist()) <= inside
    reach = 3 * np.sqrt(2) / 8
    far = np.maximum(np.maximum(1.5 - mid[:, 0], mid[:, 0] - 2.5), 0.0)
    farther = np.hypot(far, mid[:, 1]) > reach
    assert not inside & set(np.flatnonzero(farther & (mid[:, 1] > 1 / 8)).tolist())
    assert _count(cells.size) < _count(num_cells) / 2
    with pytest.raises(ValueError, match="at least one layer"):
        band_cells(disc, 0)


def _goal(u, lam, m):
    """A goal of both fields: the contact force and the mean vertical displacement."""
    return lam * m.ds_contact + u[1] * m.dx


def _coulomb(comm):
    problem = ex.friction_problem(comm)
    return problem.with_mesh(problem.mesh, problem.facet_tags, law=ds.Coulomb(0.3))


def _forced(comm):
    msh, tags = block(comm, 8, 8)
    disc = ob.Sphere((0.5, -2.0), 2.0, force=0.05, direction=(0.0, 1.0))
    return make(msh, tags, gap=disc, E=1.0)


WHOLE = {
    "strip 2D": (lambda comm: strip_problem(comm, 16, 4), _goal, {}),
    "example 5.3": (lambda comm: ex.obstacle_problem(comm, (1, 4, 4)), ex.goal_obstacle(), {}),
    "Coulomb friction 2D": (_coulomb, ex.goal_friction_force(), {}),
    "disc under a given force": (_forced, _goal, {}),
    "example 5.3, Krylov path": (lambda comm: ex.obstacle_problem(comm, (1, 4, 4)),
                                 ex.goal_obstacle(), {"method": "krylov"}),
    "example 5.1, quadrilaterals": (
        lambda comm: ex.analytic_problem(comm, 6, 4, CellType.quadrilateral), ex.goal_a(-0.5), {}),
    "example 5.3, hexahedra": (
        lambda comm: ex.obstacle_problem(comm, (1, 4, 4), cell_type=CellType.hexahedron),
        ex.goal_obstacle(), {}),
}


@pytest.mark.parametrize("case", WHOLE)
def test_band_of_every_cell_is_the_higher_order_estimate(case, monkeypatch):
    build, goal, options = WHOLE[case]
    monkeypatch.setattr(local_p2, "BAND_LAYERS", {2: 1000, 3: 1000})
    with ds.solve(build(COMM), **options) as sol:
        assert _count(sol.system.active.sum()) > 0
        with ds.estimate(sol, goal, weights="higher_order") as high:
            with ds.estimate(sol, goal, weights="local") as local:
                assert local.weights == "local"
                assert local.J_h == high.J_h
                scale = abs(high.rho) + abs(high.rho_star) + abs(high.contact_term)
                assert abs(local.eta - high.eta) <= 1e-9 * scale, (local.eta, high.eta)
                assert abs(local.eta_p - high.eta_p) <= 1e-9 * scale
                assert local.active_set_remainder == pytest.approx(
                    high.active_set_remainder, rel=1e-8, abs=1e-12 * scale)
        rec = Reconstructor(sol.disc)
        try:
            band = ContactBand(sol.disc, rec.V2h, zone=sol.multipliers[0])
            assert band.free_dofs == band.total_dofs
        finally:
            rec.destroy()


@pytest.mark.parametrize("cell", [CellType.triangle, CellType.quadrilateral])
def test_off_the_band_the_p2_solutions_are_the_patch_reconstructions(cell, monkeypatch):
    """The band's P2 dual and primal (3 layers) equal i_2h^(2) z_h and i_2h^(2) w_h on every
    node that a cell outside the band touches (u_D on Gamma_D), and differ from them inside."""
    monkeypatch.setattr(local_p2, "BAND_LAYERS", {2: 3})
    with ds.solve(strip_problem(COMM, 16, 4, cell)) as sol:
        forms = GoalForms(_goal, sol.u, sol.lam, sol.disc, None)
        z = solve_dual(sol.system, forms)
        rec = Reconstructor(sol.disc)
        try:
            with LocalP2(sol, rec, None) as p2:
                frozen = p2.band.frozen
                assert _count(frozen.size) > 0
                assert p2.band.free_dofs < p2.band.total_dofs
                bs = rec.V2h.dofmap.index_map_bs
                z2 = p2.dual(forms, z)
                u2 = p2.primal[0]
                for solution, data in ((z2.y, rec.patch_quadratic(z.y)),
                                       (u2, rec.patch_quadratic(sol.u))):
                    got = solution.x.array.reshape(-1, bs)
                    want = data.x.array.reshape(-1, bs)
                    clamped = np.zeros(len(got), dtype=bool)
                    for bc in p2.system.bcs[1:]:  # Gamma_D (the band's own comes first)
                        clamped[bc.dof_indices()[0] // bs] = True
                    off = frozen[~clamped[frozen]]
                    assert np.array_equal(got[off], want[off])
                    free = np.setdiff1d(np.arange(len(got)), frozen)
                    assert COMM.allreduce(float(np.abs(got[free] - want[free]).max(initial=0)),
                                          op=MPI.MAX) > 0
                with pytest.raises(ValueError, match="needs z_h"):
                    p2.dual(forms)
        finally:
            rec.destroy()


def test_band_options_and_memory():
    """MUMPS orders the band by AMF unless the options say otherwise; the band's predicted
    memory is that of the whole mesh's P2 weights when it holds every dof, less otherwise."""
    assert band_options(None)["mat_mumps_icntl_7"] == 2
    assert band_options({"mat_mumps_icntl_7": 0})["mat_mumps_icntl_7"] == 0
    iterative = {"ksp_type": "gmres", "pc_type": "gamg"}
    assert band_options(iterative) == iterative
    disc = ds.discretize(strip_problem(COMM, 16, 4))
    V2 = disc.vector_space(2)
    n = V2.dofmap.index_map.size_global * V2.dofmap.index_map_bs
    whole = p2_weights_memory(V2, "higher_order")
    assert p2_weights_memory(V2, "local", n) == whole
    assert p2_weights_memory(V2, "local", n // 4) < whole


def test_contact_pair_is_refused():
    """Two bodies: the band does not follow the master side, so "local" is refused naming the
    weights to use, and "auto" takes the P2 weights of the whole mesh."""
    from .test_pairs import UPPER_SLAVE, blocks_problem

    with ds.solve(blocks_problem(UPPER_SLAVE)) as sol:
        with pytest.raises(NotImplementedError, match="higher_order"):
            ds.estimate(sol, lambda u, lam, m: lam * m.ds_contact, weights="local")


def test_auto_takes_the_band_on_an_unresolved_3d_level():
    """Example 5.3's first level (contact on few facets, not resolved): "auto" takes the band,
    whose estimate is the same as with weights="local"."""
    goal = ex.goal_obstacle()
    with ds.solve(ex.obstacle_problem(COMM, (1, 4, 4))) as sol:
        with ds.estimate(sol, goal) as auto, ds.estimate(sol, goal, weights="local") as local:
            assert not auto.resolved
            assert auto.weights == "local"
            assert auto.eta == pytest.approx(local.eta, rel=1e-12)
