"""Coulomb friction and load paths (dwr_signorini.laws.Coulomb, dwr_signorini.path) against truth.

* mu = 0 is the frictionless problem, to round-off (2D and 3D); the patch tests of Tresca's law
  with Coulomb's threshold are in tests/test_friction.py and tests/test_friction_3d.py;
* the dual solution: adjoint consistency of the nonsymmetric Newton matrix for a linear goal
  (J(w_h) = z_h . F, F the last step's right-hand side), and the derivative of the friction force
  with respect to a load against finite differences of re-solved problems;
* load paths: a path that stays fully stuck ends where a single step does (the problem is then
  linear); where the contact zone grows under partial slip the path matters; shearing and
  unshearing leaves a residual tangential traction (hysteresis) that a stuck body has not;
* global sliding of a block on an inclined plane: it holds below the force ratio
  F / G = (tan(alpha) + mu) / (1 - mu tan(alpha)) and has no equilibrium above it;
* serial = 2 ranks on a load path.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex

from .friction_cases import BOTTOM, SIDES, TOP, block_tags
from .helpers import (
    dual_against_finite_differences,
    global_max,
    global_sum,
    linear_friction_goal,
    with_body_force,
)

LEFT, RIGHT = SIDES[:2]

COMM = MPI.COMM_WORLD
MU_F = 0.3


def cylinder(comm=COMM, mu=MU_F, top=(0.01, -0.02), dim=2, **kwargs):
    """The sheared block on a cylinder (examples.friction_problem) with Coulomb friction."""
    base = ex.friction_problem(comm, dim=dim, **kwargs)
    moved = top if dim == 2 else (top[0], 0.0, top[1])
    return ds.SignoriniProblem(
        base.mesh, base.facet_tags, contact=ex.CONTACT, dirichlet={ex.DIRICHLET: moved},
        E=10.0, nu=0.3, gap=base.gap, friction=ds.Coulomb(mu),
    )


def path(tops, comm=COMM, mu=MU_F):
    """One problem per top displacement, on one mesh."""
    first = cylinder(comm, mu, tops[0])
    return [first] + [
        ds.SignoriniProblem(first.mesh, first.facet_tags, contact=ex.CONTACT,
                            dirichlet={ex.DIRICHLET: top}, E=10.0, nu=0.3, gap=first.gap,
                            friction=first.law)
        for top in tops[1:]
    ]


def final_state(problems, goal=None):
    """(u, lam, lam_t) arrays and the records of a path's last step."""
    out = {}

    def keep(record, sol, est):
        out["state"] = [f.x.array.copy() for f in (sol.u, sol.lam, sol.lam_t)]

    goal = goal or ex.goal_friction_force()
    with ds.solve_path(problems, goal, callback=keep, verbose=False) as res:
        return out["state"], res.steps


# --------------------------------------------------------------------------------------------------
# Limits
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("dim", [2, 3])
def test_zero_friction_is_frictionless(dim):
    """mu = 0: lambda_t = 0 and (u, lambda_n) the frictionless solution to round-off."""
    coulomb = cylinder(mu=0.0, dim=dim, **({"nx": 6, "ny": 3, "radius": 4.0} if dim == 3 else {}))
    free = ds.SignoriniProblem(
        coulomb.mesh, coulomb.facet_tags, contact=ex.CONTACT,
        dirichlet=coulomb.dirichlet_values, E=10.0, nu=0.3, gap=coulomb.gap,
    )
    with ds.solve(coulomb, rtol=1e-12) as a, ds.solve(free, rtol=1e-12) as b:
        assert a.num_active > 0 and a.num_active == b.num_active
        assert global_max(a.u.x.array - b.u.x.array) <= 1e-10 * global_max(b.u.x.array)
        assert global_max(a.lam.x.array - b.lam.x.array) <= 1e-10 * global_max(b.lam.x.array)
        assert global_max(a.lam_t.x.array) == 0.0


# --------------------------------------------------------------------------------------------------
# The dual problem: the transposed nonsymmetric Newton matrix
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_adjoint_consistency_for_a_linear_goal():
    """With the final sets the primal map is linear, A w_h = F (F = [f; h], h the multiplier
    rows of the last Newton step's right-hand side, coupled rows included); the dual solves
    A^T z_h = J', so for a linear goal J(w_h) = z_h . F to round-off (1e-10)."""
    with ds.solve(cylinder(), rtol=1e-12) as sol, ds.estimate(sol, linear_friction_goal) as est:
        assert est.goal_is_linear and sol.num_stick > 0 and sol.num_slip > 0
        s = sol.system
        xi = sol.stacked(est.dual.multipliers)
        xi_1 = np.where(s.active, xi * s.c_n, xi)  # solve_dual's map of the constrained rows
        h = s.b.array[s.n_u:]
        y = est.dual.y.x.array[: s.n_u]
        total = global_sum(y @ s.f.array) + global_sum(xi_1 @ h)
        assert total == pytest.approx(est.J_h, rel=1e-10, abs=0.0)
        coupled = np.zeros(len(h), dtype=bool)
        for cp in s.couplings:
            coupled[cp.rows[:, 1:].ravel()] = True
        assert global_sum(coupled.sum()) == sol.num_slip  # the slipping facets' rows


@pytest.mark.mpi
def test_dual_is_the_derivative_of_J_against_finite_differences():
    """d/de J(w_h(e)) for the body force (e, 0) at e = 0, by central differences of re-solved
    problems (whose sets do not change), equals z_h . [int e_x . v; 0]: the dual sees the
    coupling of the slipping facets' tangential rows to lambda_n."""
    goal = ex.goal_friction_force()

    def solve(eps):
        return ds.solve(with_body_force(cylinder(), (eps, 0.0)), rtol=1e-12)

    def same_sets(other, sol):
        assert sol.num_slip > 0
        assert np.array_equal(other.system.active, sol.system.active)

    predicted, fd = dual_against_finite_differences(solve, goal, lambda v: v[0], same_sets)
    assert abs(predicted) > 1e-3
    assert fd == pytest.approx(predicted, rel=1e-6)


# --------------------------------------------------------------------------------------------------
# Load paths
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_a_path_that_stays_stuck_ends_where_one_step_does():
    """Press and shear a block on a flat rigid plane in proportion, in one step and in ten:
    every facet in contact and stuck on every step, the problem is linear and the end states
    agree to 1e-10."""
    msh = mesh.create_unit_square(COMM, 6, 6, ghost_mode=mesh.GhostMode.none)
    tags = block_tags(msh, height=1.0)

    def problem(k, n):
        return ds.SignoriniProblem(
            msh, tags, contact=BOTTOM, dirichlet={TOP: (0.01 * k / n, -0.01 * k / n)}, E=10.0,
            nu=0.3, gap=0.0, friction=ds.Coulomb(10.0))

    goal = ex.goal_friction_force()
    one, steps_one = final_state([problem(1, 1)], goal)
    ten, steps_ten = final_state([problem(k, 10) for k in range(1, 11)], goal)
    n_contact = steps_one[0].num_contact_elements
    assert all(r.num_stick == n_contact for r in steps_one + steps_ten)
    for a, b in zip(one, ten, strict=True):
        assert global_max(a - b) <= 1e-10 * global_max(a)


@pytest.mark.mpi
def test_partial_slip_makes_the_path_matter():
    """On the cylinder, pressing and shearing in proportion in one step or in ten ends in
    different states: points that come into contact late stick where they arrive."""
    one, _ = final_state(path([(0.01, -0.02)]))
    ten, steps = final_state(path([(0.001 * k, -0.002 * k) for k in range(1, 11)]))
    assert any(r.num_slip > 0 and r.num_stick > 0 for r in steps)
    lam_t_one, lam_t_ten = one[2], ten[2]
    assert global_max(lam_t_one - lam_t_ten) >= 0.02 * global_max(lam_t_one)


@pytest.mark.mpi
def test_shear_and_unshear_leave_a_residual_traction():
    """Press, shear (partial slip), shear back to zero: a tangential traction stays locked in
    (hysteresis); the same path with mu = 100 (stuck throughout) returns to the pressed state,
    lambda_t = 0 where it was 0 after pressing (to 1e-10 of its peak)."""
    tops = [(0.0, -0.02), (0.005, -0.02), (0.01, -0.02), (0.005, -0.02), (0.0, -0.02)]
    peaks, ends, pressed = {}, {}, {}
    for mu in (MU_F, 100.0):
        states = []

        def keep(record, sol, est, states=states):
            states.append(sol.lam_t.x.array.copy())

        with ds.solve_path(path(tops, mu=mu), ex.goal_friction_force(), callback=keep,
                           verbose=False) as res:
            if mu == MU_F:
                assert res.steps[2].num_slip > 0
        pressed[mu], peaks[mu], ends[mu] = states[0], states[2], states[-1]
    locked = global_max(ends[MU_F] - pressed[MU_F])
    assert locked >= 0.1 * global_max(peaks[MU_F] - pressed[MU_F])
    assert global_max(ends[100.0] - pressed[100.0]) <= 1e-10 * global_max(peaks[100.0])


@pytest.mark.mpi
def test_serial_and_parallel_paths_agree():
    """A three-step path with partial slip on COMM_WORLD and on COMM_SELF: the same sets,
    J_h and estimates to round-off."""
    tops = [(0.0, -0.02), (0.005, -0.02), (0.01, -0.02)]
    runs = {}
    for name, comm in (("world", COMM), ("self", MPI.COMM_SELF)):
        with ds.solve_path(path(tops, comm=comm), ex.goal_friction_force(), weights="patch",
                           verbose=False) as res:
            runs[name] = res.steps
    for p, s in zip(runs["world"], runs["self"], strict=True):
        assert (p.num_active, p.num_stick, p.num_slip) == (s.num_active, s.num_stick,
                                                           s.num_slip)
        assert p.J_h == pytest.approx(s.J_h, rel=1e-10)
        assert p.eta == pytest.approx(s.eta, rel=1e-8, abs=1e-14)
    assert runs["self"][-1].num_slip > 0


# --------------------------------------------------------------------------------------------------
# Global sliding on an inclined plane
# --------------------------------------------------------------------------------------------------


def incline_path(pushes, alpha, mu, press=0.01, comm=COMM):
    """A square block on an incline of angle alpha, in the incline's frame (contact y = 0), its
    top clamped to a plate that moves down by ``press`` and sideways by each push (global
    directions: horizontal e_h = (cos alpha, -sin alpha), vertical e_v = (sin alpha,
    cos alpha)). The plate's force on the block has the horizontal part F and the downward
    part G; in full slip up the slope F / G = (tan alpha + mu) / (1 - mu tan alpha)."""
    msh = mesh.create_unit_square(comm, 6, 6, ghost_mode=mesh.GhostMode.none)
    tags = block_tags(msh, height=1.0)
    e_h = np.array([math.cos(alpha), -math.sin(alpha)])
    e_v = np.array([math.sin(alpha), math.cos(alpha)])
    return [
        ds.SignoriniProblem(
            msh, tags, contact=BOTTOM, E=10.0, nu=0.3, gap=0.0, friction=ds.Coulomb(mu),
            dirichlet={TOP: tuple(float(c) for c in push * e_h - press * e_v)},
            traction={t: (0.0, 0.0) for t in (LEFT, RIGHT)},
        )
        for push in pushes
    ]


@pytest.mark.mpi
def test_global_sliding_force_on_an_incline():
    """Push the plate sideways step by step: while a facet sticks, the plate's force ratio
    F / G stays below r* = (tan(alpha) + mu) / (1 - mu tan(alpha)); once every facet slips it
    is r* (to 1e-10: statics and Coulomb's law on every facet), so the steps bracket the
    sliding force. F, G from the contact resultants (Lambda_t, Lambda_n) = int (lambda_t,
    lambda_n): F = Lambda_t cos(alpha) + Lambda_n sin(alpha), G = Lambda_n cos(alpha) -
    Lambda_t sin(alpha)."""
    alpha, mu = 0.2, MU_F
    r_star = (math.tan(alpha) + mu) / (1 - mu * math.tan(alpha))
    pushes = [0.0, 0.01, 0.02, 0.025, 0.03, 0.04, 0.06]
    rows = []

    def resultants(record, sol, est):
        n = sol.system.algebra.n_q
        M = sol.system.M.array[:n]
        lam_n, lam_t = (global_sum(M @ f.x.array[:n]) for f in (sol.lam, sol.lam_t))
        F = lam_t * math.cos(alpha) + lam_n * math.sin(alpha)
        G = lam_n * math.cos(alpha) - lam_t * math.sin(alpha)
        rows.append((record.num_stick, record.num_slip, F / G))

    with ds.solve_path(incline_path(pushes, alpha, mu), ex.goal_friction_force(),
                       callback=resultants, weights="patch", verbose=False):
        pass
    stuck = [r for s, _, r in rows if s > 0]
    sliding = [r for s, _, r in rows if s == 0]
    assert stuck and sliding, rows
    assert rows[0][2] < r_star and all(r < r_star * (1 - 1e-6) for r in stuck), rows
    assert all(abs(r - r_star) <= 1e-10 * r_star for r in sliding), rows
    assert [s > 0 for s, _, _ in rows] == sorted([s > 0 for s, _, _ in rows], reverse=True)


# --------------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------------


def test_bad_paths_are_rejected_by_name():
    one = path([(0.0, -0.02)])[0]
    other = cylinder()  # another mesh
    goal = ex.goal_friction_force()
    with pytest.raises(ValueError, match="problems is empty"):
        ds.solve_path([], goal)
    with pytest.raises(TypeError, match="problems must be a sequence"):
        ds.solve_path(one, goal)
    with pytest.raises(ValueError, match=r"problems\[1\] lives on another mesh"):
        ds.solve_path([one, other], goal)
    tresca = ds.SignoriniProblem(one.mesh, one.facet_tags, contact=ex.CONTACT,
                                 dirichlet=one.dirichlet_values, E=10.0, nu=0.3, gap=one.gap,
                                 friction=ds.Tresca(0.1))
    with pytest.raises(ValueError, match=r"problems\[1\] has another contact boundary or "
                                         "contact law"):
        ds.solve_path([one, tresca], goal)
    with pytest.raises(TypeError, match="goal must be a callable"):
        ds.solve_path([one, one], [goal])
    with pytest.raises(TypeError, match="adaptive must be True or False"):
        ds.solve_path([one], goal, adaptive="yes")


# --------------------------------------------------------------------------------------------------
# Adaptivity along a path: the history on the refined mesh
# --------------------------------------------------------------------------------------------------


def _slip_integral(disc, u):
    """int_GC u . t ds on the fine mesh of ``disc`` (collective)."""
    m = disc.m
    t = ufl.as_vector((-m.n[1], m.n[0]))
    return disc.comm.allreduce(
        fem.assemble_scalar(fem.form(ufl.dot(u, t) * m.ds_contact)), op=MPI.SUM)


@pytest.mark.mpi
def test_refined_path_carries_the_history_exactly():
    """adaptive=True: the step after a refinement measures its slip from the previous step's
    displacement interpolated onto the refined mesh, which is exact (nested P1): int u_old . t
    over Gamma_C is the old step's to round-off. The refined path ends nearer to the same path
    solved on the refined mesh from the start than the path that never refines."""
    tops = [(0.0, -0.02), (0.005, -0.02), (0.01, -0.02)]
    slips, carried = [], []

    def record(rec, sol, est):
        slips.append(_slip_integral(sol.disc, sol.u))
        if sol.disc.u_old is not None:
            carried.append(_slip_integral(sol.disc, sol.disc.u_old))

    goal = ex.goal_friction_force()
    with ds.solve_path(path(tops), goal, adaptive=True, callback=record,
                       verbose=False) as res:
        refined = [r.J_h for r in res.steps]
        assert [r.level for r in res.steps] == [0, 1, 2]
        assert res.steps[1].num_cells > res.steps[0].num_cells
        fine = res.problem
    assert carried == pytest.approx(slips[:-1], rel=1e-12, abs=1e-15)
    coarse = final_state(path(tops))[1]
    on_fine = final_state([p.with_mesh(fine.mesh, fine.facet_tags) for p in path(tops)])[1]
    assert abs(refined[-1] - on_fine[-1].J_h) < abs(coarse[-1].J_h - on_fine[-1].J_h)


@pytest.mark.mpi
def test_path_writes_its_table_and_fields(mpi_tmp_path, capsys):
    """output_dir: path.csv and path.json with one row per step, the fields per step; verbose:
    one progress line per step on rank 0."""
    import json

    tops = [(0.0, -0.02), (0.01, -0.02)]
    with ds.solve_path(path(tops), ex.goal_friction_force(), output_dir=mpi_tmp_path) as res:
        assert len(res.steps) == 2
    COMM.barrier()
    lines = (mpi_tmp_path / "path.csv").read_text().splitlines()
    assert len(lines) == 3 and "J_low" in lines[0] and "step" in lines[0]
    data = json.loads((mpi_tmp_path / "path.json").read_text())
    assert [r["step"] for r in data["levels"]] == [0, 1]
    assert data["meta"]["law"] == "Coulomb(0.3)"
    assert any(p.suffix in (".xdmf", ".bp") for p in mpi_tmp_path.iterdir())
    out = capsys.readouterr().out
    assert out.count("step ") == (2 if COMM.rank == 0 else 0)


# --------------------------------------------------------------------------------------------------
# The error the history carries
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_history_goal_is_the_derivative_of_J_in_u_old():
    """The sensitivity of a step's J to the previous step's displacement (path.history_goal),
    L(v), against central differences of the step re-solved from u_old + e v (the sets do
    not change): to 1e-6."""
    from dwr_signorini.path import history_goal

    p0, p1 = path([(0.0, -0.02), (0.005, -0.02)])
    goal = ex.goal_friction_force()
    disc0 = ds.discretize(p0)
    sol0 = ds.solve(disc0, rtol=1e-12)
    v = fem.Function(disc0.V)
    v.interpolate(lambda x: np.vstack([1e-3 * np.sin(np.pi * x[0]), 1e-3 * x[0] * x[1]]))

    def step(shift):
        disc = disc0.for_problem(p1)
        u_old = fem.Function(disc0.V)
        u_old.x.array[:] = sol0.u.x.array + shift * v.x.array
        disc.set_u_old(u_old)
        return ds.solve(disc, rtol=1e-12)

    eps = 1e-4
    with step(0.0) as sol1, ds.estimate(sol1, goal, estimator="eta_p") as est1:
        assert sol1.num_stick > 0
        L = history_goal(sol1, est1)
        m = sol1.disc.m
        lam_t = sol1.lam_t
        predicted = COMM.allreduce(
            fem.assemble_scalar(sol1.disc.form(L(v, sol1.lam, m, lam_t))), op=MPI.SUM)
        values = []
        for sign in (1.0, -1.0):
            with step(sign * eps) as other:
                assert np.array_equal(other.system.active, sol1.system.active)
                with ds.estimate(other, goal, estimator="eta_p") as e:
                    values.append(e.J_h)
    sol0.destroy()
    fd = (values[0] - values[1]) / (2 * eps)
    assert abs(predicted) > 1e-3 * abs(est1.J_h)
    assert fd == pytest.approx(predicted, rel=1e-6)


@pytest.mark.slow
def test_cycling_slip_sets_are_broken(monkeypatch):
    """A Coulomb path whose first shear step cycled with the plain set rule (Cattaneo-Mindlin,
    nu = 0.2, contact facets of 0.0025: the slip directions of a few facets alternated, which
    Murty's rule, changing one row per step, did not break) converges to the tolerance on both
    steps: a slip that reverses passes through stick (:func:`dwr_signorini.laws.reversing`),
    and damped steps remain behind it. (Every step factored and MUMPS ordering with AMD, the
    conditions under which the path was found to cycle.)"""
    from dwr_signorini.linalg.factor import FactoredNewtonSystem, ReusePolicy

    monkeypatch.setattr(FactoredNewtonSystem, "reuse", ReusePolicy(fraction=-1.0))
    problems = cases.cattaneo_mindlin_path(COMM, nu=0.2, h_contact=0.0025)[:2]
    residuals = []

    def record(rec, sol, est):
        residuals.append(sol.history[-1]["residual_ncp"])

    with ds.solve_path(problems, ex.goal_friction_force(), weights="patch", history=False,
                       callback=record, verbose=False,
                       petsc_options={"mat_mumps_icntl_7": 0}):
        pass
    assert len(residuals) == 2
    assert max(residuals) <= 1e-8


def test_for_problem_refuses_another_mesh_or_tags():
    """Discretization.for_problem shares the meshes: a problem on another mesh is refused, by
    name; on the same mesh the spaces are the same objects."""
    one, two = path([(0.0, -0.02), (0.01, -0.02)])
    disc = ds.discretize(one)
    same = disc.for_problem(two)
    assert same.V is disc.V and same.Q is disc.Q and same.problem is two
    with pytest.raises(ValueError, match="for_problem: the problem must live on this"):
        disc.for_problem(cylinder())
    with pytest.raises(TypeError, match="u_old must be a dolfinx Function"):
        same.set_u_old(np.zeros(3))


@pytest.mark.mpi
def test_factor_reuse_gives_the_factored_solution(monkeypatch):
    """The nonsymmetric path's row updates of old factors (linalg.lowrank.RowUpdate), taken
    on every step where they can be: the path's states and estimates equal those of a
    factorisation per Newton step (1e-9), with fewer factorisations."""
    from dwr_signorini.linalg.factor import FactoredNewtonSystem, ReusePolicy

    tops = [(0.0, -0.02), (0.005, -0.02), (0.01, -0.02)]
    runs = {}
    for name, fraction in (("reuse", 1e9), ("factor", -1.0)):
        monkeypatch.setattr(FactoredNewtonSystem, "reuse", ReusePolicy(fraction=fraction))
        counts = []

        def record(rec, sol, est, counts=counts):
            counts.append((sol.system.factorizations, sol.system.reused))

        with ds.solve_path(path(tops), ex.goal_friction_force(), callback=record,
                           weights="patch", verbose=False) as res:
            runs[name] = ([f.x.array.copy() for f in (res.solution.u, *res.solution.multipliers)],
                          [(r.J_h, r.eta) for r in res.steps], counts)
    (a, steps_a, counts_a), (b, steps_b, counts_b) = runs["reuse"], runs["factor"]
    for x, y in zip(a, b, strict=True):
        assert global_max(x - y) <= 1e-9 * global_max(y)
    for (J1, e1), (J2, e2) in zip(steps_a, steps_b, strict=True):
        assert J1 == pytest.approx(J2, rel=1e-9, abs=1e-15)
        assert e1 == pytest.approx(e2, rel=1e-6, abs=1e-12)
    assert sum(r for _, r in counts_a) > 0 and all(r == 0 for _, r in counts_b)
    assert sum(f for f, _ in counts_a) < sum(f for f, _ in counts_b)
