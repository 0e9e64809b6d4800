"""Unresolved contact is seen: the estimate is of the size of the error from the first level on.

A block indented by a disc (``problems.indented_block``) on a 4 x 3 macro mesh: the contact
zone is narrower than a macro facet, so on the first levels the integrated gap of every macro
facet is positive and no multiplier is active, J_h = 0, although the disc penetrates the body
pointwise. The goal is the total contact force. The reference value comes from J_h alone (the
finest of 12 adaptive levels, its uncertainty the change from the level before), not from any
estimate; on every level whose error is at least 10 times that uncertainty the interval for J
must contain it, and the estimate must have an effectivity in [1/3, 3], the levels without
contact and the first ones with it included.
"""

from mpi4py import MPI

import pytest

import dwr_signorini as ds

from .helpers import total_force
from .problems import indented_block


def _crossing(errors: list[float], k: int) -> bool:
    """Whether J_h passes close to J at level k: its error is below a third of both neighbours'.

    There an error is small by cancellation, and no estimate can have the effectivity of the
    levels around it.
    """
    inner = 0 < k < len(errors) - 1
    return inner and abs(errors[k]) < min(abs(errors[k - 1]), abs(errors[k + 1])) / 3


@pytest.fixture(scope="module")
def unresolved_run():
    """The adaptive run of the defaults from a level that misses the contact: its judged levels
    (error >= 10 x the reference's uncertainty), their errors and the reference."""
    comm = MPI.COMM_WORLD
    with ds.solve_adaptive(indented_block(comm, 4, 3, 0.002), total_force, max_levels=12,
                           verbose=False) as res:
        levels = res.levels
    J = [r.J_h for r in levels]
    reference, uncertainty = J[-1], abs(J[-1] - J[-2])
    errors = [reference - r.J_h for r in levels]
    judged = [r for r in levels[:-2] if abs(errors[r.level]) >= 10 * uncertainty]
    return levels, judged, errors, reference, uncertainty


def test_unresolved_contact_is_estimated_and_bracketed_on_every_level(unresolved_run):
    """With the defaults (weights="auto"): the interval contains the reference on every judged
    level, and the interval's centre has effectivities in [1/3, 3] on every judged level but a
    crossing (measured 1.22, 0.57, 2.24, 0.60, 0.38, 0.57, 0.93, 0.73)."""
    levels, judged, errors, reference, uncertainty = unresolved_run
    assert uncertainty < 1e-4 * reference
    assert levels[0].num_active == 0 and levels[0].J_h == 0.0  # the contact is missed
    assert [r.level for r in judged][:3] == [0, 1, 2]  # the unresolved levels are judged
    assert any(r.num_active > 0 for r in judged[:3])  # and the first one with contact
    assert any(not r.resolved for r in judged)  # some computed with P2 weights
    assert len(judged) >= 6
    for r in judged:
        assert r.J_low <= reference <= r.J_high, (r.level, r.J_low, reference, r.J_high)
        if _crossing(errors, r.level):
            continue
        centre = 0.5 * (r.J_low + r.J_high) - r.J_h
        assert 1 / 3 <= errors[r.level] / centre <= 3, (r.level, errors[r.level] / centre)


def test_unresolved_estimate_effectivity(unresolved_run):
    """The estimate's effectivity in [1/3, 3] on every judged level but a crossing. Measured
    1.62, 0.76, 2.99, 0.80, 0.51, 0.77, 1.10, 0.87: level 2, the first with contact (2 active
    facets), 2.99 with the P2 weights on the band around the contact zone; it was 3.85 with the
    P2 weights of the whole mesh (a strict xfail then), and 2.19 while rho* was compiled as one
    kernel whose facet integrals of degrees 1, 8, 2, 8 on Gamma_C assembled to another sum."""
    _, judged, errors, _, _ = unresolved_run
    for r in judged:
        if not _crossing(errors, r.level):
            ieff = errors[r.level] / r.estimate
            assert 1 / 3 <= ieff <= 3, (r.level, ieff)


@pytest.mark.parametrize("ncp_scale", [1.0])
def test_paper_scale_misses_the_unresolved_contact(ncp_scale):
    """With the paper's c = 1 (E = 10 here) the same first level is estimated at a fortieth of
    its error: the reason for the physical default."""
    comm = MPI.COMM_WORLD
    with ds.solve(indented_block(comm, 4, 3, 0.002), ncp_scale=ncp_scale) as sol:
        with ds.estimate(sol, total_force) as est:
            physical_sol = ds.solve(indented_block(comm, 4, 3, 0.002))
            with physical_sol, ds.estimate(physical_sol, total_force) as physical:
                assert est.J_h == physical.J_h == 0.0
                assert 0 < est.eta < physical.eta / 10
