"""A finite-strain load path from an earlier path's state: pressed, then slid, exactly.

The block of tests/test_finite_strain.py is pressed by 20 % (first path), then, from that state,
its symmetry side is moved by twice its width along the plane (second path): the exact end state
is the homogeneous compression translated by 2 (frictionless contact, large sliding). Each
requested factor reports its Newton steps, cuts and time through the callback.
"""

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import cases

from .test_finite_strain import (
    CONTACT,
    NU,
    SYM,
    TOP,
    E,
    block_problem,
    exact_state,
    multiplier_error,
)


@pytest.mark.mpi
def test_press_then_slide_from_state():
    comm = MPI.COMM_WORLD
    press = block_problem(comm, 2, 0.2, ds.NeoHookean())
    slide = ds.SignoriniProblem(
        press.mesh, press.facet_tags, CONTACT, dirichlet={TOP: (None, -0.2), SYM: (2.0, None)},
        E=E, nu=NU, material=ds.NeoHookean(), gap=ds.obstacles.Plane([0.0, 0.0], [0.0, -1.0]),
    )
    a, lam_exact = exact_state("neo_hookean", 0.2, 2)
    seen = []
    with ds.solve_path(press, None, load_factors=[0.5, 1.0]) as pressed:
        start = pressed.solutions[-1]
        with ds.solve_path(slide, None, load_factors=[0.25, 0.5, 0.75, 1.0],
                           initial_guess=start,
                           callback=lambda rec, sol, est: seen.append((rec, est))) as path:
            sol = path.solutions[-1]
            x = sol.u.function_space.tabulate_dof_coordinates()[:, :2]
            exact = np.column_stack([(a - 1) * x[:, 0] + 2.0, -0.2 * x[:, 1]])
            err = comm.allreduce(float(np.max(np.abs(sol.u.x.array.reshape(-1, 2) - exact))),
                                 op=MPI.MAX)
            # the first slide step starts pressed: the contact stays closed, nothing lifts off
            first = path.solutions[0]
            print(f"\nslid by 2: |u - u_exact| = {err:.2e}; steps "
                  + ", ".join(f"t={r.factor} newton={r.newton_iterations} cuts={r.cuts}"
                              for r in path.records))
            assert err < 1e-8
            assert multiplier_error(sol.lam, lam_exact) < 1e-8 * lam_exact
            assert multiplier_error(first.lam, lam_exact) < 1e-8 * lam_exact
    assert [r.factor for r, _ in seen] == [0.25, 0.5, 0.75, 1.0]
    assert all(est is None and r.newton_iterations >= 1 and r.seconds > 0 for r, est in seen)
    assert [r.steps[-1] for r, _ in seen] == [0.25, 0.5, 0.75, 1.0]


def test_start_with_loads_refused():
    comm = MPI.COMM_WORLD
    press = block_problem(comm, 2, 0.2, ds.NeoHookean())
    loaded = ds.SignoriniProblem(
        press.mesh, press.facet_tags, CONTACT, dirichlet={TOP: (None, -0.2), SYM: (0.0, None)},
        E=E, nu=NU, material=ds.NeoHookean(), body_force=(0.0, -0.1),
        gap=ds.obstacles.Plane([0.0, 0.0], [0.0, -1.0]),
    )
    with ds.solve_path(press, None, load_factors=[1.0]) as pressed:
        with pytest.raises(ValueError, match="without body force"):
            ds.solve_path(loaded, None, load_factors=[1.0], initial_guess=pressed.solutions[-1])
        with pytest.raises(TypeError, match="FiniteStrainSolution"):
            ds.solve_path(press, None, load_factors=[1.0], initial_guess=(1, 2))


@pytest.mark.mpi
def test_clamped_top_ranks_agree():
    """A vector-valued Dirichlet condition (the rubber cylinder's plate, both components) whose
    dofs the partition splits: the contact force on all ranks equals the one-process solve's
    (each rank solves that too)."""
    forces = []
    for comm in (MPI.COMM_SELF, MPI.COMM_WORLD):
        press, _ = cases.rubber_cylinder_problems(
            cases.rubber_cylinder_mesh(comm, h_contact=0.2, h=0.3), approach=0.1)
        with ds.solve_path(press, None, load_factors=[0.5, 1.0]) as path:
            forces.append(cases.measure_contact(path.solutions[-1]).force)
    print(f"\ncontact force: one process {forces[0]:.14f}, all {forces[1]:.14f}")
    assert forces[0] > 0.01
    assert abs(forces[1] - forces[0]) < 1e-9 * forces[0]
