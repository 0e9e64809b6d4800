"""One 2D solve and estimate per contact law, the smoke test of ``make test-quick``.

The block of the friction guide (a block pressed onto a rigid cylinder and sheared, 238 macro
triangles), frictionless, with Tresca's and with Coulomb's law: Newton converges, the contact
zone is found, the law holds facet by facet, and the estimate is finite and inside its interval.
The thorough checks of each law are in test_primal, test_friction and test_coulomb.
"""

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import examples as ex

pytestmark = pytest.mark.mpi

S, MU = 0.2, 0.3


def contact_force(u, lam, m):
    return lam * m.ds_contact


def friction_force(u, lam, m, lam_t):
    return lam_t * m.ds_contact


def _problem(law):
    block = ex.friction_problem(MPI.COMM_WORLD)          # its mesh and tags, another law
    return ds.SignoriniProblem(
        block.mesh, block.facet_tags, contact=ex.CONTACT,
        dirichlet={ex.DIRICHLET: (0.01, -0.02)}, E=10.0, nu=0.3,
        gap=ex.friction_gap(1.0), friction=law)


def _owned(function):
    n = function.function_space.dofmap.index_map.size_local
    return function.x.array[:n]


@pytest.mark.parametrize("law", ["frictionless", "tresca", "coulomb"])
def test_solve_and_estimate(law):
    comm = MPI.COMM_WORLD
    friction = {"frictionless": None, "tresca": ds.Tresca(S), "coulomb": ds.Coulomb(MU)}[law]
    goal = contact_force if friction is None else friction_force
    with ds.solve(_problem(friction)) as sol, ds.estimate(sol, goal) as est:
        assert 1 <= sol.newton_iterations <= 20
        assert 0 < sol.num_active < sol.disc.comm.allreduce(len(_owned(sol.lam)), op=MPI.SUM)
        lam = _owned(sol.lam)
        assert comm.allreduce(float(lam.min(initial=0.0)), op=MPI.MIN) >= -1e-10
        if friction is not None:
            lam_t = np.abs(_owned(sol.lam_t))
            bound = S if law == "tresca" else MU * np.maximum(lam, 0.0)
            excess = float(np.max(lam_t - bound, initial=0.0))
            assert comm.allreduce(excess, op=MPI.MAX) <= 1e-8
            assert sol.num_stick > 0 and sol.num_slip > 0
        J_low, J_high = est.interval
        assert all(np.isfinite([est.J_h, est.eta_p, est.eta, J_low, J_high]))
        assert est.J_h != 0.0 and est.eta != 0.0
        assert J_low <= est.J_h + est.eta <= J_high
