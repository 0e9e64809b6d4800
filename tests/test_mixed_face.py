"""A face sheared by a prescribed displacement and pressed by a traction (issue 48, part 4).

``dirichlet={TOP: (d, None)}, traction={TOP: (0.0, -p)}`` on the unit square with nu = 0 (plane
strain), frictionless contact with the rigid plane y = 0 on the bottom and free sides. The exact
solution is the uniform state

    u = (d, -p y / E),   sigma = diag(0, -p),   lambda = p on the whole bottom,

which P1 displacements and P0 multipliers contain, so the discrete solution equals it to round-off:
the traction acts on the free component of the top face, the prescribed one takes d. Only the
contact holds the block up, so the Newton iteration starts with the contact active. With Tresca
friction (s < mu d) the block slides and carries the uniform shear stress s (second test).
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh

import dwr_signorini as ds
from tests.problems import tag_by_midpoint

pytestmark = pytest.mark.mpi

BOTTOM, SIDES, TOP, RIGHT = 1, 2, 4, 5
E, P, D, S = 10.0, 0.3, 0.05, 0.1


def block(comm, friction=None, p=P, dirichlet=None, on=None):
    """The block pressed by p (``on``: a problem whose mesh and tags to reuse, for a path)."""
    msh, tags = (on.mesh, on.facet_tags) if on is not None else _square(comm)
    # With Tresca's s the sliding block carries the shear stress s: the sides carry sigma n.
    sides = {SIDES: (0.0, -S), RIGHT: (0.0, S)} if friction is not None else {}
    return ds.SignoriniProblem(
        msh, tags, contact=BOTTOM, dirichlet=dirichlet or {TOP: (D, None)}, E=E, nu=0.0,
        model="plane_strain", traction={TOP: (0.0, -p), **sides}, gap=0.0, friction=friction,
    )


def _square(comm):
    msh = mesh.create_unit_square(comm, 6, 6, ghost_mode=mesh.GhostMode.none)
    return msh, tag_by_midpoint(msh, SIDES, ((RIGHT, lambda x: np.isclose(x[0], 1.0)),
                                             (BOTTOM, lambda x: np.isclose(x[1], 0.0)),
                                             (TOP, lambda x: np.isclose(x[1], 1.0))))


def test_shear_by_displacement_press_by_traction():
    problem = block(MPI.COMM_WORLD)
    disc = ds.discretize(problem)
    lam0 = fem.Function(disc.Q)
    lam0.x.array[:] = 1.0  # contact active from the start: nothing else holds the block up
    with ds.solve(disc, initial_guess=(fem.Function(disc.V), lam0)) as sol:
        V = sol.u.function_space
        x = V.tabulate_dof_coordinates()
        u = sol.u.x.array.reshape(-1, 2)
        exact = np.stack([np.full(len(x), D), -P * x[:, 1] / E], axis=1)
        scale = max(D, P / E)
        assert np.max(np.abs(u - exact), initial=0.0) <= 1e-10 * scale
        lam = sol.lam.x.array
        assert np.max(np.abs(lam - P), initial=0.0) <= 1e-10 * P
        num_lam = MPI.COMM_WORLD.allreduce(lam.size)
        assert num_lam > 0


def test_tresca_block_slides_under_the_prescribed_shear():
    """Tresca's s = 0.1 < mu d: the block slides in +x, the friction stress is s everywhere.

    sigma = [[0, s], [s, -p]], u = (d - s / mu + s y / mu, -p y / E) with mu = E / 2 (nu = 0),
    lambda = p, |lambda_t| = s on the whole bottom; the sides carry sigma n = (0, -+s).
    """
    problem = block(MPI.COMM_WORLD, ds.Tresca(S))
    disc = ds.discretize(problem)
    guess = [fem.Function(disc.Q) for _ in range(2)]
    guess[0].x.array[:] = 1.0
    with ds.solve(disc, initial_guess=(fem.Function(disc.V), *guess)) as sol:
        x = sol.u.function_space.tabulate_dof_coordinates()
        u = sol.u.x.array.reshape(-1, 2)
        mu = E / 2
        exact = np.stack([D - S / mu + S * x[:, 1] / mu, -P * x[:, 1] / E], axis=1)
        assert np.max(np.abs(u - exact), initial=0.0) <= 1e-10 * D
        assert np.max(np.abs(sol.lam.x.array - P), initial=0.0) <= 1e-10 * P
        assert np.max(np.abs(np.abs(sol.lam_t.x.array) - S), initial=0.0) <= 1e-10 * S
