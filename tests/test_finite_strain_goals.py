"""Goal quantities at finite strain: m.F(u), m.P(u) and m.cauchy(u) against exact states.

The homogeneous compression of tests/test_finite_strain.py (F = diag(a, s), a from its scalar
equation) has a constant P = diag(0, -lambda) and Cauchy stress sigma = P F^T / det F =
diag(0, -lambda / a); goals written with ``m.P`` and ``m.cauchy`` must give these values to
round-off. The trace of the Cauchy stress is invariant under a rotation of the whole problem; the
linear material's P and Cauchy stress are Hooke's sigma(u).
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini.goal import GoalForms

from .test_finite_strain import (
    CONTACT,
    MATERIALS,
    NU,
    SYM,
    TOP,
    E,
    _principal_stress,
    block_problem,
    exact_state,
    sheared_block,
)


def goal_value(sol, goal):
    """J(u_h, lambda_H) as the package evaluates a goal (collective)."""
    return GoalForms(goal, sol.u, sol.lam, sol.disc).value()


@pytest.mark.mpi
@pytest.mark.parametrize("law", sorted(MATERIALS))
def test_homogeneous_compression_goals(law):
    """The mean of P_yy, sigma_yy, sigma_xx and F_yy over Omega (|Omega| = 1): exact."""
    c = 0.3
    a, lam_exact = exact_state(law, c, 2)
    problem = block_problem(MPI.COMM_WORLD, 2, c, MATERIALS[law]())
    with ds.solve_path(problem, None, load_factors=[0.5, 1.0]) as path:
        sol = path.solutions[-1]
        values = {
            "P_yy": goal_value(sol, lambda u, lam, m: m.P(u)[1, 1] * m.dx),
            "P_xx": goal_value(sol, lambda u, lam, m: m.P(u)[0, 0] * m.dx),
            "sigma_yy": goal_value(sol, lambda u, lam, m: m.cauchy(u)[1, 1] * m.dx),
            "sigma_xx": goal_value(sol, lambda u, lam, m: m.cauchy(u)[0, 0] * m.dx),
            "F_yy": goal_value(sol, lambda u, lam, m: m.F(u)[1, 1] * m.dx),
            "force": goal_value(sol, lambda u, lam, m: lam * m.ds_contact),
        }
    exact = {"P_yy": -lam_exact, "P_xx": 0.0, "sigma_yy": -lam_exact / a, "sigma_xx": 0.0,
             "F_yy": 1.0 - c, "force": lam_exact}
    print(f"\n{law}: " + ", ".join(f"{k} {values[k]:.12f} ({exact[k]:.12f})" for k in exact))
    for key, value in exact.items():
        assert abs(values[key] - value) < 1e-8 * lam_exact, key


def test_first_piola_per_cell_tag():
    """E per cell tag: P of a prescribed affine field is the closed form with each tag's E.

    Every law's P is linear in (mu, lambda), so E doubled (nu kept) doubles P.
    """
    comm = MPI.COMM_WORLD
    block = block_problem(comm, 2, 0.2, ds.NeoHookean(), n=4)
    msh = block.mesh
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    left = mesh.compute_midpoints(msh, tdim, cells)[:, 0] < 0.5
    cell_tags = mesh.meshtags(msh, tdim, cells, np.where(left, 1, 2).astype(np.int32))
    stretches = (1.1, 0.8)
    for law in sorted(MATERIALS):
        problem = ds.SignoriniProblem(
            msh, block.facet_tags, CONTACT, dirichlet={TOP: (None, -0.2), SYM: (0.0, None)},
            E={1: E, 2: 2 * E}, nu=NU, cell_tags=cell_tags, material=MATERIALS[law](),
            gap=ds.obstacles.Plane([0.0, 0.0], [0.0, -1.0]),
        )
        disc = ds.discretize(problem)
        u = fem.Function(disc.V)
        u.interpolate(lambda x: np.vstack([(stretches[0] - 1) * x[0], (stretches[1] - 1) * x[1]]))
        m = disc.m
        P_yy = [comm.allreduce(fem.assemble_scalar(fem.form(m.P(u)[1, 1] * m.dx(tag))),
                               op=MPI.SUM) for tag in (1, 2)]
        exact = _principal_stress(law, stretches)[1] / 2  # each tag is half of Omega
        print(f"\n{law}: P_yy over the tags {P_yy}, exact {exact:.12f} and twice that")
        assert abs(P_yy[0] - exact) < 1e-10 * abs(exact)
        assert abs(P_yy[1] - 2 * exact) < 1e-10 * abs(exact)


@pytest.mark.mpi
def test_cauchy_trace_frame_invariant():
    """The problem turned by 30 degrees: the same int tr(sigma) dx and int det F dx."""
    comm = MPI.COMM_WORLD
    out = []
    for rotation in (0.0, np.pi / 6):
        with ds.solve(sheared_block(comm, 0.2, ds.NeoHookean(), rotation)) as sol:
            out.append([goal_value(sol, lambda u, lam, m: ufl.tr(m.cauchy(u)) * m.dx),
                        goal_value(sol, lambda u, lam, m: ufl.det(m.F(u)) * m.dx)])
    (t0, j0), (t1, j1) = out
    print(f"\nint tr(sigma) {t0:.12e} / {t1:.12e}, int det F {j0:.12e} / {j1:.12e}")
    assert abs(t0) > 1e-2  # a stressed state, not a trivial zero
    assert abs(t1 - t0) < 1e-8 * abs(t0)
    assert abs(j1 - j0) < 1e-8 * abs(j0)


@pytest.mark.parametrize("model", ["plane_strain", "plane_stress"])
def test_linear_material_is_hooke(model):
    """LinearElastic: m.P(u) and m.cauchy(u) are m.sigma(u), m.F(u) is I + grad u."""
    problem = sheared_block(MPI.COMM_WORLD, 0.01, ds.LinearElastic())
    problem = ds.SignoriniProblem(
        problem.mesh, problem.facet_tags, CONTACT, dirichlet={TOP: (0.0025, -0.01)}, E=E, nu=NU,
        model=model, gap=ds.obstacles.Plane([0.0, 0.0], [0.0, -1.0]),
    )
    with ds.solve(problem) as sol:
        m = sol.disc.m
        sigma = m.sigma(sol.u)
        diff = sum(goal_value(sol, lambda u, lam, m, f=f: ufl.inner(f(u) - sigma, f(u) - sigma)
                              * m.dx) for f in (m.P, m.cauchy))
        size = goal_value(sol, lambda u, lam, m: ufl.inner(sigma, sigma) * m.dx)
        grad = goal_value(sol, lambda u, lam, m: ufl.inner(
            m.F(u) - ufl.Identity(2) - ufl.grad(u), m.F(u) - ufl.Identity(2) - ufl.grad(u))
            * m.dx)
    assert size > 1e-6
    assert diff == 0.0  # the same stress
    assert grad < 1e-20 * size  # round-off of F - I - grad u
