"""A ghosted macro mesh (dolfinx's default ghost mode, also gmsh's) gives the serial results.

The examples build unghosted meshes; a user's mesh is usually ghosted (``shared_facet``). One
solve, estimate and adaptive step on a ghosted simplex mesh on all ranks must agree with the same
on one process (J_h to 1e-10, eta_p and eta to 1e-9, the same cells and marks).
"""

from mpi4py import MPI

import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

from .problems import estimate_rel


def _ghosted_strip(comm):
    msh = mesh.create_rectangle(
        comm, [(0.0, 0.0), (4.0, 1.0)], [24, 6], mesh.CellType.triangle,
        ghost_mode=mesh.GhostMode.shared_facet,
    )


    return ds.SignoriniProblem(
        msh, ex.tag_block_facets(msh, 1.0), contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,), E=10.0, nu=0.3, body_force=(0.0, -1.0),
        gap=lambda x: 0.02 * (x[0] - 2.0) ** 2 - 0.01,
    )


def _energy(u, lam, m):
    return lam * m.ds_contact + 0.5 * u[1] ** 2 * m.dx


@pytest.mark.mpi
@pytest.mark.parametrize("weights", ["patch", "auto"])
def test_ghosted_mesh_solve_estimate_and_adaptive_step_equal_serial(weights):
    """With the patch weights every number agrees to round-off. With ``weights="auto"`` the
    unresolved first level is estimated with the P2 weights on the band around the contact zone
    (factored: they agree to round-off too, ``tests.problems.estimate_rel``)."""
    runs = {}
    for name, comm in (("world", MPI.COMM_WORLD), ("self", MPI.COMM_SELF)):
        problem = _ghosted_strip(comm)
        if name == "world" and comm.size > 1:
            assert problem.mesh.topology.index_map(2).num_ghosts > 0  # really ghosted
        with ds.solve_adaptive(problem, _energy, max_levels=2, weights=weights,
                               verbose=False) as res:
            runs[name] = res.levels
    for p, s in zip(runs["world"], runs["self"], strict=True):
        assert (p.num_cells, p.num_active, p.num_marked) == (s.num_cells, s.num_active,
                                                             s.num_marked), p.level
        assert p.weights == s.weights, p.level
        assert p.J_h == pytest.approx(s.J_h, rel=1e-10), p.level
        rel = estimate_rel(p)
        assert p.eta_p == pytest.approx(s.eta_p, rel=rel), p.level
        assert p.eta == pytest.approx(s.eta, rel=rel), p.level
        assert p.J_low == pytest.approx(s.J_low, rel=rel) and p.J_high == pytest.approx(
            s.J_high, rel=rel), p.level
    assert runs["self"][0].num_active > 0
    if weights == "auto":
        assert runs["self"][0].weights == "local"  # the case this test is about
