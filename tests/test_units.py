"""The estimate does not depend on the units (the scale-consistent NCP of dwr_signorini.residuals).

The same body in two unit systems, lengths scaled by s_L and Young's modulus by s_E (no body
force: an indenter, given by its gap, presses the block): displacements scale by s_L, the
contact pressure by s_E, and the goal J = int_GC lambda ds (total contact force in 2D, per unit
thickness) by s_E s_L. So J_h, eta_p, eta, the contact term and every cell indicator must scale
by s_E s_L, on resolved and on unresolved contact (a coarse mesh whose macro facets average the
penetration away, so that no multiplier is active). With the paper's c = 1 they do not: there
lambda + c (u_n - g) adds a pressure to a length.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds

from .helpers import total_force
from .problems import indented_block as _indented_block

S_L, S_E = 1e-3, 1e6  # e.g. mm -> m and MPa -> Pa


def _run(comm, nx, ny, delta, ncp_scale, s_L=1.0, s_E=1.0):
    """J_h, eta_p, eta, contact term; the cell indicators ordered by the cells' midpoints (in
    units of s_L, so that both unit systems list the cells alike); the number of active facets."""
    with ds.solve(_indented_block(comm, nx, ny, delta, s_L, s_E), ncp_scale=ncp_scale) as sol:
        with ds.estimate(sol, total_force) as est:
            fine = sol.disc.mesh
            n = fine.topology.index_map(2).size_local
            mids = mesh.compute_midpoints(fine, 2, np.arange(n, dtype=np.int32))[:, :2] / s_L
            key = np.concatenate(comm.allgather(np.round(mids, 9)))
            indicators = np.concatenate(comm.allgather(est.indicators.x.array[:n].copy()))
            values = {k: getattr(est, k) for k in ("J_h", "eta_p", "eta", "contact_term")}
            order = np.lexsort(key.T)
            return values, indicators[order], sol.num_active


CASES = {"resolved": (32, 12, 0.01), "unresolved": (4, 3, 0.002)}


@pytest.mark.mpi
@pytest.mark.parametrize("case", list(CASES))
def test_estimate_is_invariant_under_a_change_of_units(case):
    comm = MPI.COMM_WORLD
    ref, ind_ref, active = _run(comm, *CASES[case], "physical")
    other, ind_other, active_other = _run(comm, *CASES[case], "physical", S_L, S_E)
    assert active == active_other
    assert (active == 0) == (case == "unresolved")
    scale = S_E * S_L
    assert abs(ref["eta"]) > 0
    for key, value in ref.items():
        assert other[key] / scale == pytest.approx(value, rel=1e-8, abs=1e-8 * abs(ref["eta"])), key
    biggest = np.abs(ind_ref).max()
    assert np.abs(ind_other / scale - ind_ref).max() <= 1e-8 * biggest


@pytest.mark.mpi
def test_unit_one_scale_is_not_invariant_on_unresolved_contact():
    """The paper's c = 1 on the unresolved case: the contact term changes with the units by far
    more than round-off (the reason for the physical default)."""
    comm = MPI.COMM_WORLD
    ref, _, _ = _run(comm, *CASES["unresolved"], 1.0)
    other, _, _ = _run(comm, *CASES["unresolved"], 1.0, S_L, S_E)
    assert abs(other["contact_term"] / (S_E * S_L) - ref["contact_term"]) > 1e-3 * abs(
        ref["contact_term"]
    )
