"""Finite strain: homogeneous compression of a block on a frictionless rigid plane, exactly.

The block (0, 1)^d is pressed by a prescribed top displacement -c (compression c) onto the rigid
plane y = 0 (z = 0 in 3D); x = 0 (and y = 0 in 3D) are symmetry planes, the other sides free.
The exact state is homogeneous, F = diag(a, s) (diag(a, a, s) in 3D) with s = 1 - c and the
lateral stretch a the root of P_xx(a, s) = 0, written here in closed form for each law and solved
with scipy; the contact force per reference area is lambda = -P_yy (-P_zz in 3D). P1 elements
hold the affine displacement exactly, so the discrete state is the exact one.
"""

import itertools

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from scipy.optimize import brentq

import dwr_signorini as ds
from dwr_signorini import finite_strain_path
from dwr_signorini.semismooth import ConvergenceError
from dwr_signorini.settings import SolverOptions

E, NU = 10.0, 0.3
MU = E / (2 * (1 + NU))
LMBDA = E * NU / ((1 + NU) * (1 - 2 * NU))
CONTACT, TOP, SYM, FREE, SYM2 = 1, 2, 3, 4, 5


def _user_psi(F, mu, lmbda):
    """A compressible law of the test: mu/2 (I_1 - d) - mu ln J + lmbda/2 (J - 1)^2."""
    J = ufl.det(F)
    d = F.ufl_shape[0]
    return mu / 2 * (ufl.tr(F.T * F) - d) - mu * ufl.ln(J) + lmbda / 2 * (J - 1) ** 2


def _principal_stress(law, stretches):
    """The principal first Piola-Kirchhoff stresses of F = diag(stretches), in closed form."""
    lam = np.asarray(stretches, float)
    J = np.prod(lam)
    if law == "neo_hookean":  # P = mu (F - F^-T) + lmbda ln J F^-T
        return MU * (lam - 1 / lam) + LMBDA * np.log(J) / lam
    if law == "svk":  # P = F S, S = 2 mu E + lmbda tr E I
        Ed = (lam**2 - 1) / 2
        return lam * (2 * MU * Ed + LMBDA * np.sum(Ed))
    # the test's psi: P = mu F - mu F^-T + lmbda (J - 1) J F^-T
    return MU * lam - MU / lam + LMBDA * (J - 1) * J / lam


def exact_state(law, c, dim):
    """(a, lambda): the lateral stretch and the contact force per reference area."""
    s = 1.0 - c

    def stretches(a):
        return [a] * (dim - 1) + [s]

    a = brentq(lambda a: _principal_stress(law, stretches(a))[0], 0.5, 3.0, xtol=1e-15)
    return a, -_principal_stress(law, stretches(a))[-1]


MATERIALS = {
    "neo_hookean": ds.NeoHookean,
    "svk": ds.SaintVenantKirchhoff,
    "user": lambda: ds.Hyperelastic(_user_psi),
}


def block_problem(comm, dim, c, material, n=2, rotation=0.0):
    """The compressed block (module docstring); ``rotation`` turns the whole 2D problem."""
    if dim == 2:
        msh = mesh.create_unit_square(comm, n, n, ghost_mode=mesh.GhostMode.none)
    else:
        msh = mesh.create_unit_cube(comm, n, n, n, ghost_mode=mesh.GhostMode.none)
    up = dim - 1

    def classify(x):
        tags = np.full(x.shape[1], FREE, dtype=np.int32)
        tags[np.isclose(x[0], 0.0)] = SYM
        if dim == 3:
            tags[np.isclose(x[1], 0.0)] = SYM2
        tags[np.isclose(x[up], 1.0)] = TOP
        tags[np.isclose(x[up], 0.0)] = CONTACT
        return tags

    fdim = dim - 1
    msh.topology.create_connectivity(fdim, dim)
    facets = mesh.exterior_facet_indices(msh.topology)
    mid = mesh.compute_midpoints(msh, fdim, facets).T
    tags = mesh.meshtags(msh, fdim, facets, classify(mid))
    top = [None] * dim
    top[up] = -c
    sym = [None] * dim
    sym[0] = 0.0
    dirichlet = {TOP: tuple(top), SYM: tuple(sym)}
    if dim == 3:
        dirichlet[SYM2] = (None, 0.0, None)
    normal = [0.0] * dim
    normal[up] = -1.0
    return ds.SignoriniProblem(
        msh, tags, CONTACT, dirichlet=dirichlet, E=E, nu=NU, material=material,
        gap=ds.obstacles.Plane([0.0] * dim, normal),
    )


def displacement_error(u, a, s, dim):
    """Max over the dofs (all ranks) of |u - u_exact|, u_exact = (F - I) x."""
    x = u.function_space.tabulate_dof_coordinates()[:, :dim]
    stretch = np.array([a] * (dim - 1) + [s])
    exact = (stretch - 1.0) * x
    err = np.max(np.abs(u.x.array.reshape(-1, dim) - exact), initial=0.0)
    return MPI.COMM_WORLD.allreduce(err, op=MPI.MAX)


def multiplier_error(lam, value):
    n = lam.function_space.dofmap.index_map.size_local
    err = np.max(np.abs(lam.x.array[:n] - value), initial=0.0)
    return MPI.COMM_WORLD.allreduce(err, op=MPI.MAX)


def print_table(history):
    """The Newton iteration table (pytest -s shows it)."""
    for h in history:
        print(f"  it {h['iteration']:2d}: |A| = {h['num_active']:3d}, changed "
              f"{h['num_changed']:3d}, equilibrium {h['residual_equilibrium']:.3e}, "
              f"NCP {h['residual_ncp']:.3e}")


@pytest.mark.mpi
@pytest.mark.parametrize("law", sorted(MATERIALS))
@pytest.mark.parametrize(
    "c", [0.2, 0.4], ids=["c20", "c40"],
)
def test_homogeneous_compression_2d(law, c):
    a, lam_exact = exact_state(law, c, 2)
    problem = block_problem(MPI.COMM_WORLD, 2, c, MATERIALS[law]())
    with ds.solve_path(problem, None, load_factors=[0.5, 1.0]) as path:
        sol = path.solutions[-1]
        print(f"\n{law}, c = {c}: a = {a:.12f}, lambda = {lam_exact:.12f}, cuts {path.cuts}")
        print_table(sol.history)
        assert displacement_error(sol.u, a, 1 - c, 2) < 1e-8
        assert multiplier_error(sol.lam, lam_exact) < 1e-8 * lam_exact
        assert sol.num_active == sol.disc.num_contact_elements


@pytest.mark.mpi
@pytest.mark.parametrize("law", ["neo_hookean", "svk", "user"])
@pytest.mark.parametrize("c", [0.2, 0.4], ids=["c20", "c40"])
def test_homogeneous_compression_3d(law, c):
    a, lam_exact = exact_state(law, c, 3)
    problem = block_problem(MPI.COMM_WORLD, 3, c, MATERIALS[law](), n=1)
    with ds.solve(problem) as sol:
        print_table(sol.history)
        assert displacement_error(sol.u, a, 1 - c, 3) < 1e-8
        assert multiplier_error(sol.lam, lam_exact) < 1e-8 * lam_exact


def test_quadratic_convergence_once_set_settles():
    """The residuals of the last steps (the set fixed) fall quadratically."""
    problem = block_problem(MPI.COMM_WORLD, 2, 0.2, ds.NeoHookean())
    with ds.solve(problem) as sol:
        print_table(sol.history)
        res = [h["residual_equilibrium"] for h in sol.history if h["num_changed"] == 0]
        big = [r for r in res if r > 1e-13]
        assert len(big) >= 2
        for r0, r1 in itertools.pairwise(big):
            assert r1 < 10 * r0**2 or r1 < 1e-12


def test_refusals():
    comm = MPI.COMM_WORLD
    problem = block_problem(comm, 2, 0.2, ds.NeoHookean())
    msh, tags = problem.mesh, problem.facet_tags
    with pytest.raises(ValueError, match="plane_stress"):
        ds.SignoriniProblem(msh, tags, CONTACT, dirichlet=(TOP,), model="plane_stress",
                            material=ds.NeoHookean(), gap=ds.obstacles.Plane([0, 0], [0, -1]))
    with pytest.raises(ValueError, match="friction"):
        ds.SignoriniProblem(msh, tags, CONTACT, dirichlet=(TOP,), friction=ds.Tresca(0.1),
                            material=ds.NeoHookean(), gap=ds.obstacles.Plane([0, 0], [0, -1]))
    with pytest.raises(ValueError, match=r"obstacles\.Plane"):
        ds.SignoriniProblem(msh, tags, CONTACT, dirichlet=(TOP,), gap=0.1,
                            material=ds.SaintVenantKirchhoff())
    with pytest.raises(TypeError, match="material"):
        ds.SignoriniProblem(msh, tags, CONTACT, dirichlet=(TOP,), material="rubber")
    with ds.solve(problem) as sol:
        with pytest.raises(ValueError, match="stress_fields"):
            ds.stress_fields(sol)
        with pytest.raises(TypeError, match="Solution"):
            ds.contact_summary(sol)
    with pytest.raises(ValueError, match="goal"):
        ds.solve_path(problem, lambda u, lam, m: lam * m.ds_contact, load_factors=[1.0])
    with pytest.raises(ValueError, match="higher_order"):
        ds.solve_adaptive(problem, lambda u, lam, m: lam * m.ds_contact, weights="higher_order")
    with pytest.raises(ValueError, match="method"):
        ds.solve(problem, method="schur")


def test_step_cut_reported():
    """A load step Newton's method fails (here: too few iterations) is halved and reported."""
    problem = block_problem(MPI.COMM_WORLD, 2, 0.4, ds.NeoHookean())
    with pytest.raises(ConvergenceError):
        ds.solve(problem, max_iterations=4)
    with finite_strain_path.solve_path(problem, [1.0], SolverOptions(max_iterations=4)) as path:
        print(f"\ncuts at {path.cuts}, steps {path.steps}")
        assert path.cuts == [1.0, 0.5]
        assert path.steps == [0.25, 0.5, 0.75, 1.0]
        a, lam_exact = exact_state("neo_hookean", 0.4, 2)
        assert displacement_error(path.solutions[-1].u, a, 0.6, 2) < 1e-8
        assert multiplier_error(path.solutions[-1].lam, lam_exact) < 1e-8 * lam_exact


def sheared_block(comm, c, material, rotation=0.0, n=4):
    """The unit square pressed onto y = 0 by its top moved by (c/4, -c): not homogeneous.

    ``rotation`` (radians) turns the whole problem: mesh, obstacle and top displacement.
    """
    msh = mesh.create_unit_square(comm, n, n, ghost_mode=mesh.GhostMode.none)
    msh.topology.create_connectivity(1, 2)
    facets = mesh.exterior_facet_indices(msh.topology)
    mid = mesh.compute_midpoints(msh, 1, facets).T
    values = np.full(len(facets), FREE, dtype=np.int32)
    values[np.isclose(mid[1], 1.0)] = TOP
    values[np.isclose(mid[1], 0.0)] = CONTACT
    tags = mesh.meshtags(msh, 1, facets, values)
    R = np.array([[np.cos(rotation), -np.sin(rotation)], [np.sin(rotation), np.cos(rotation)]])
    msh.geometry.x[:, :2] = msh.geometry.x[:, :2] @ R.T
    top = R @ np.array([c / 4, -c])
    return ds.SignoriniProblem(
        msh, tags, CONTACT, dirichlet={TOP: tuple(top)}, E=E, nu=NU, material=material,
        gap=ds.obstacles.Plane([0.0, 0.0], R @ np.array([0.0, -1.0])),
    )


def contact_force_and_energy(sol, material):
    """|int lam grad d ds| (lam's integral: grad d is the plane's unit normal) and int psi dx."""
    m = sol.disc.m
    force = sol.disc.comm.allreduce(
        fem.assemble_scalar(sol.disc.form(sol.lam * m.ds_contact)), op=MPI.SUM)
    F = ufl.Identity(2) + ufl.grad(sol.u)
    psi = material.energy(F, MU, LMBDA) * m.dx(metadata={"quadrature_degree": 2})
    energy = sol.disc.comm.allreduce(fem.assemble_scalar(fem.form(psi)), op=MPI.SUM)
    return force, energy


@pytest.mark.mpi
def test_newton_matrix_analysed_once():
    """The Newton matrix keeps its pattern across steps and active sets: MUMPS analyses it once.

    A load path of two steps on one system, its active set changing: one symbolic factorisation,
    a numeric one per Newton step (the events PETSc logs on this rank).
    """
    PETSc.Log.begin()
    events = [PETSc.Log.Event(name) for name in ("MatLUFactorSym", "MatLUFactorNum")]
    before = [e.getPerfInfo()["count"] for e in events]
    problem = block_problem(MPI.COMM_WORLD, 2, 0.2, ds.NeoHookean(), n=4)
    with ds.solve_path(problem, None, load_factors=[0.5, 1.0]) as path:
        history = [h for sol in path.solutions for h in sol.history]
        steps = sum(len(sol.history) - 1 for sol in path.solutions)
    symbolic, numeric = (e.getPerfInfo()["count"] - b for e, b in zip(events, before, strict=True))
    assert any(h["num_changed"] > 0 for h in history)
    assert (symbolic, numeric) == (1, steps)


@pytest.mark.mpi
def test_small_load_limit():
    """At 1e-5 of the load the finite-strain state is the linear one to 1e-4 (relative)."""
    comm = MPI.COMM_WORLD
    c = 0.2e-5
    with ds.solve(sheared_block(comm, c, ds.NeoHookean())) as fin, \
            ds.solve(sheared_block(comm, c, ds.LinearElastic())) as lin:
        du = np.max(np.abs(fin.u.x.array - lin.u.x.array), initial=0.0)
        u_max = np.max(np.abs(lin.u.x.array), initial=0.0)
        n = lin.lam.function_space.dofmap.index_map.size_local
        dl = np.max(np.abs(fin.lam.x.array[:n] - lin.lam.x.array[:n]), initial=0.0)
        l_max = np.max(np.abs(lin.lam.x.array[:n]), initial=0.0)
        du, u_max, dl, l_max = (comm.allreduce(v, op=MPI.MAX) for v in (du, u_max, dl, l_max))
        print(f"\nrelative differences: u {du / u_max:.2e}, lambda {dl / l_max:.2e}")
        assert du < 1e-4 * u_max
        assert dl < 1e-4 * l_max
        assert fin.num_active == lin.num_active


@pytest.mark.mpi
def test_frame_invariance():
    """The whole problem turned by 30 degrees: the same contact force and stored energy."""
    comm = MPI.COMM_WORLD
    law = ds.NeoHookean()
    out = []
    for rotation in (0.0, np.pi / 6):
        with ds.solve(sheared_block(comm, 0.2, law, rotation)) as sol:
            out.append(contact_force_and_energy(sol, law))
    (f0, e0), (f1, e1) = out
    print(f"\nforce {f0:.12e} / {f1:.12e}, energy {e0:.12e} / {e1:.12e}")
    assert abs(f1 - f0) < 1e-8 * abs(f0)
    assert abs(e1 - e0) < 1e-8 * abs(e0)


@pytest.mark.mpi
def test_large_sliding():
    """The compressed block pushed along the plane by twice its width: the translated state."""
    comm = MPI.COMM_WORLD
    block = block_problem(comm, 2, 0.2, ds.NeoHookean())
    problem = ds.SignoriniProblem(
        block.mesh, block.facet_tags, CONTACT, dirichlet={TOP: (None, -0.2), SYM: (2.0, None)},
        E=E, nu=NU, material=ds.NeoHookean(), gap=ds.obstacles.Plane([0.0, 0.0], [0.0, -1.0]),
    )
    a, lam_exact = exact_state("neo_hookean", 0.2, 2)
    with ds.solve_path(problem, None, load_factors=[0.25, 0.5, 0.75, 1.0]) as path:
        sol = path.solutions[-1]
        x = sol.u.function_space.tabulate_dof_coordinates()[:, :2]
        exact = np.column_stack([(a - 1) * x[:, 0] + 2.0, -0.2 * x[:, 1]])
        err = comm.allreduce(np.max(np.abs(sol.u.x.array.reshape(-1, 2) - exact)), op=MPI.MAX)
        assert err < 1e-8
        assert multiplier_error(sol.lam, lam_exact) < 1e-8 * lam_exact


@pytest.mark.mpi
def test_disc_obstacle_newton_quadratic():
    """A block pressed onto a rigid disc: the contact Jacobian holds the curvature of the
    distance (its second derivative), so the residuals fall quadratically once the set settles."""
    comm = MPI.COMM_WORLD
    block = block_problem(comm, 2, 0.1, ds.NeoHookean(), n=4)
    problem = ds.SignoriniProblem(
        block.mesh, block.facet_tags, CONTACT, dirichlet={TOP: (None, -0.1), SYM: (0.0, None)},
        E=E, nu=NU, material=ds.NeoHookean(), gap=ds.obstacles.Sphere([0.0, -2.0], 2.0),
    )
    with ds.solve_path(problem, None, load_factors=[0.5, 1.0]) as path:
        sol = path.solutions[-1]
        print_table(sol.history)
        assert 0 < sol.num_active < sol.disc.num_contact_elements
        settled = [h["residual_equilibrium"] for h in sol.history if h["num_changed"] == 0]
        big = [r for r in settled if r > 1e-12]
        assert len(big) >= 2
        for r0, r1 in itertools.pairwise(big):
            assert r1 < 10 * r0**2 or r1 < 1e-12
        # the active facets touch the disc: their gaps vanish to round-off
        G = sol.system.residuals()[1]
        n = sol.lam.function_space.dofmap.index_map.size_local
        active = sol.lam.x.array[:n] > 0
        assert comm.allreduce(float(np.max(np.abs(G[active]), initial=0.0)), op=MPI.MAX) < 1e-12


@pytest.mark.mpi
def test_cylinder_obstacle_newton_quadratic():
    """A cube pressed onto a rigid cylinder (3D): quadratic Newton, active gaps closed."""
    comm = MPI.COMM_WORLD
    block = block_problem(comm, 3, 0.05, ds.NeoHookean(), n=2)
    problem = ds.SignoriniProblem(
        block.mesh, block.facet_tags, CONTACT,
        dirichlet={TOP: (None, None, -0.05), SYM: (0.0, None, None), SYM2: (None, 0.0, None)},
        E=E, nu=NU, material=ds.NeoHookean(),
        gap=ds.obstacles.Cylinder([0.0, 0.0, -2.0], [0.0, 1.0, 0.0], 2.0),
    )
    with ds.solve(problem) as sol:
        print_table(sol.history)
        assert 0 < sol.num_active < sol.disc.num_contact_elements
        settled = [h["residual_equilibrium"] for h in sol.history if h["num_changed"] == 0]
        big = [r for r in settled if r > 1e-12]
        for r0, r1 in itertools.pairwise(big):
            assert r1 < 10 * r0**2 or r1 < 1e-12
        G = sol.system.residuals()[1]
        n = sol.lam.function_space.dofmap.index_map.size_local
        active = sol.lam.x.array[:n] > 0
        assert comm.allreduce(float(np.max(np.abs(G[active]), initial=0.0)), op=MPI.MAX) < 1e-12
