"""Alternative linear solvers give the same results as the reference direct block solve.

* FGMRES + Schur field split + GAMG (``fieldsplit_petsc_options``) on the block matrix.
* ``method="schur"`` with a direct solver of K: K factored once per mesh, the Newton steps and
  the dual problem through the dense S = N K^-1 N^T.
* ``method="schur"`` with ``iterative_petsc_options``: K by CG + GAMG, S_AA by CG matrix-free.

Each is compared with the block path run independently on the same discretisation.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import cases, hierarchical
from dwr_signorini import examples as ex
from dwr_signorini.dual import solve_dual
from dwr_signorini.goal import GoalForms
from dwr_signorini.linalg import (
    METHODS,
    DenseSchurComplement,
    KrylovNewtonSystem,
    KrylovSchurComplement,
    NewtonSystem,
    SchurNewtonSystem,
    choose_method,
    fieldsplit_petsc_options,
    iterative_petsc_options,
    schur,
)
from dwr_signorini.spaces import discretize

from .problems import cycling_cantilever, indented_block, strip_problem


@pytest.mark.mpi
def test_iterative_fieldsplit_matches_direct_3d():
    """FGMRES + Schur field split + GAMG reproduces the MUMPS solution, dual and estimate."""
    problem = ex.obstacle_problem(MPI.COMM_WORLD, (2, 8, 8))
    msh = problem.mesh
    results = []
    for opts in (None, fieldsplit_petsc_options()):
        sol = ds.solve(problem, petsc_options=opts)
        est = ds.estimate(sol, ex.goal_obstacle(), petsc_options=opts)
        local = fem.assemble_scalar(fem.form(sol.u[0] ** 2 * sol.disc.m.dx))
        norm = np.sqrt(msh.comm.allreduce(local, op=MPI.SUM))
        results.append((sol.num_active, est.J_h, est.eta, norm))
    (a0, J0, e0, n0), (a1, J1, e1, n1) = results
    assert a0 == a1 and a0 > 0
    assert np.isclose(J1, J0, rtol=1e-7)
    assert np.isclose(n1, n0, rtol=1e-7)
    assert np.isclose(e1, e0, rtol=1e-5)


# --------------------------------------------------------------------------------------------------
# method="schur" (dense S from the factors of K, or CG on S_AA with GAMG on K) against block
# --------------------------------------------------------------------------------------------------


SCHUR_CASES = {
    "strip-2d-tri": (lambda comm: strip_problem(comm, 32, 8), ex.goal_a(-0.5)),
    "obstacle-3d-tet": (lambda comm: ex.obstacle_problem(comm, (2, 8, 8)), ex.goal_obstacle()),
    "tresca-2d-tri": (lambda comm: ex.friction_problem(comm, s=0.05), ex.goal_friction_force()),
    "indentation-3d-tet": (
        lambda comm: cases.indentation_problem(comm, 8, depth=0.02), cases.goal_total_force
    ),
}


def _settled(history):
    """The history without the record that found the active set settled after loose steps
    (the accurate solve of the same set follows it)."""
    return [h for h in history if not (h["loose"] and h["iteration"] and not h["num_changed"])]


def _relative_difference(comm, a, b):
    """||a - b|| / ||a|| over all ranks' owned entries."""
    num = comm.allreduce(float(np.sum((a - b) ** 2)), op=MPI.SUM)
    den = comm.allreduce(float(np.sum(a**2)), op=MPI.SUM)
    return np.sqrt(num / den)


#: Solvers of K on the Schur path: relative tolerance of the comparison with the block path
#: (round-off for the direct solver, the Krylov tolerances 1e-10 for the iterative one).
SCHUR_SOLVERS = {"direct": (None, 1e-10), "krylov": (iterative_petsc_options(), 1e-8)}

#: The paths compared with the block path: (method, petsc_options, relative tolerance).
PATHS = {**{f"schur-{k}": ("schur", *v) for k, v in SCHUR_SOLVERS.items()},
         "krylov": ("krylov", None, 1e-8)}


@pytest.mark.mpi
@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize("case", list(SCHUR_CASES))
def test_path_matches_block_path(case, path):
    """The linear solvers of the Newton steps give the same iterates (active sets, Newton
    steps, u, lambda), the same dual solution (y, xi) and estimate, up to their tolerance:
    the Schur path with K factored or solved by CG, and the saddle-point GMRES of "krylov"."""
    build, goal = SCHUR_CASES[case]
    method, options, tol = PATHS[path]
    comm = MPI.COMM_WORLD
    disc = discretize(build(comm))  # one mesh and numbering: in parallel the partition may vary
    runs = {}
    for name, opts in (("block", None), (method, options)):
        sol = ds.solve(disc, method=name, petsc_options=opts)
        z = solve_dual(sol.system, GoalForms(goal, sol.u, sol.lam, sol.disc, sol.lam_t))
        runs[name] = (sol, z)
    (s0, z0), (s1, z1) = runs["block"], runs[method]
    solver = "direct" if path == "schur-direct" else "krylov"
    assert s1.method == ("schur" if solver == "direct" else "krylov")
    if method == "schur":
        assert isinstance(s1.system.schur, KrylovSchurComplement) == (solver == "krylov")
    else:
        assert type(s1.system) is KrylovNewtonSystem
    assert type(s0.system) is NewtonSystem
    n_u, n_lam = s0.system.n_u, s0.system.algebra.n_q
    assert s0.num_active > 0
    assert s0.num_active < comm.allreduce(n_lam, op=MPI.SUM)  # a genuine inactive set too
    # The Krylov path takes loose steps until the active set settles, then solves that set
    # once more, accurately.
    extra = int(solver == "krylov")
    assert [h["loose"] for h in s1.history] == [bool(extra)] * (len(s1.history) - 1) + [False]
    assert s1.newton_iterations == s0.newton_iterations + extra
    assert [h["num_active"] for h in _settled(s1.history)] == [h["num_active"] for h in s0.history]
    assert comm.allreduce(bool(np.array_equal(s1.active, s0.active)), op=MPI.LAND)
    assert comm.allreduce(bool(np.array_equal(s1.system.free, s0.system.free)), op=MPI.LAND)
    pairs = {
        "u": (s0.u.x.array[:n_u], s1.u.x.array[:n_u]),
        "lam": (s0.stacked(), s1.stacked()),
        "y": (z0.y.x.array[:n_u], z1.y.x.array[:n_u]),
        "xi": (s0.stacked(z0.multipliers), s1.stacked(z1.multipliers)),
    }
    if s0.lam_t is not None:  # friction: slipping facets, whose lam_t is on the right-hand side
        assert s0.num_slip > 0 and comm.allreduce(bool(np.any(s0.system.free)), op=MPI.LOR)
    for name, (ref, other) in pairs.items():
        assert _relative_difference(comm, ref, other) < tol, name
    # The estimator takes the dual solution through Solution.system on either path.
    est0, est1 = ds.estimate(s0, goal), ds.estimate(s1, goal)
    assert np.isclose(est1.J_h, est0.J_h, rtol=tol)
    assert est1.weights == est0.weights
    for a, b in ((est0.eta, est1.eta), (est0.eta_p, est1.eta_p)):
        assert abs(b - a) <= _estimate_tolerance(est0, 100 * tol * abs(a))


def _estimate_tolerance(est, tol):
    """How far two solver paths' estimates may differ: ``tol``, or with the hierarchical P2
    weights (an FGMRES to HIERARCHICAL_RTOL from each path's P1 factors) 10 x that tolerance of
    the size of the terms |rho| + |rho*| + |C| (measured 1.2e-5 of eta on the 3D obstacle's
    Krylov path, where the factored weights agree to 1e-8)."""
    if est.weights != "hierarchical":
        return tol
    scale = abs(est.rho) + abs(est.rho_star or 0.0) + abs(est.contact_term)
    return max(tol, 10 * hierarchical.HIERARCHICAL_RTOL * scale)


@pytest.mark.mpi
@pytest.mark.parametrize("case", list(SCHUR_CASES))
def test_schur_complement_from_mumps_inverse_entries(case, monkeypatch):
    """S = N_C (K^-1)_CC N_C^T from MUMPS's entries of the inverse equals S from full solves
    with the columns of N^T, and the factors of K still solve K x = f afterwards (the call
    changes MUMPS's solve controls, which must be restored). Small blocks of columns, so that
    S is summed over several requests."""
    from petsc4py import PETSc

    monkeypatch.setattr(schur, "SCHUR_BLOCK_ENTRIES", 1000)
    build, _ = SCHUR_CASES[case]
    comm = MPI.COMM_WORLD
    system = SchurNewtonSystem(discretize(build(comm)))
    assert isinstance(system.schur, DenseSchurComplement)
    S, S_solves = system.schur.S, system.schur.compute_by_solves()
    if comm.rank == 0:
        assert S.shape == (system.n_lam_global,) * 2
        assert np.abs(S - S_solves).max() <= 1e-12 * np.abs(S_solves).max()
    x, r = system.K.createVecRight(), system.K.createVecLeft()
    system.ksp.solve(system.f, x)
    system.K.mult(x, r)
    r.axpy(-1.0, system.f)
    assert r.norm(PETSc.NormType.INFINITY) <= 1e-10 * system.f.norm(PETSc.NormType.INFINITY)
    for vec in (x, r):
        vec.destroy()
    system.destroy()


@pytest.mark.mpi
@pytest.mark.parametrize("solver", list(SCHUR_SOLVERS))
def test_schur_path_with_least_index_safeguard(solver):
    """Active-set cycling and the least-index safeguard: the same solution on both paths, the
    same iterates until the sets repeat."""
    options, tol = SCHUR_SOLVERS[solver]
    disc = discretize(cycling_cantilever(MPI.COMM_WORLD))
    s0 = ds.solve(disc)
    s1 = ds.solve(disc, method="schur", petsc_options=options)
    first = next(h["iteration"] for h in s0.history if h["safeguard"])
    assert any(h["safeguard"] for h in s1.history)
    if solver == "direct":  # exact steps: the same iterates throughout
        for key in ("num_active", "num_changed", "safeguard"):
            assert [h[key] for h in s1.history] == [h[key] for h in s0.history], key
    else:  # the same sets until they repeat; the loose steps then turn accurate, and the
        # cycle, a cycle of exact steps, repeats under them before the safeguard takes it
        for key in ("num_active", "num_changed"):
            assert [h[key] for h in s1.history[:first]] == [h[key] for h in s0.history[:first]]
        assert not any(h["safeguard"] for h in s1.history if h["loose"])
    n_u = s0.system.n_u
    assert _relative_difference(disc.comm, s0.u.x.array[:n_u], s1.u.x.array[:n_u]) < tol


@pytest.mark.mpi
def test_accurate_steps_do_not_count_the_sets_of_loose_steps_as_cycles():
    """The set rule of the semi-smooth Newton loop, driven by hand: loose steps visit X, then
    Y, where they settle; Y is solved again accurately, whose iterate asks for X. That is the
    correction of a loose step, not a cycle: X is taken whole. A set that accurate steps
    themselves repeat (Y) still sets off the least-index rule. A repeat among loose steps makes
    the following steps accurate instead."""
    from dwr_signorini.semismooth import NewtonLoop

    disc = discretize(strip_problem(MPI.COMM_WORLD, 8, 2))
    system = NewtonSystem(disc)
    loop = NewtonLoop(system, 1e-8, 20)
    n = len(system.active)
    X = np.zeros(n, dtype=bool)
    X[: n // 2] = True
    Y = X.copy()
    Y[n // 2 :] = True  # X and Y differ on every rank that owns rows
    free = np.zeros(n)

    def step(it, wanted, resolve=False):
        loop.history.append({"num_active": 0, "safeguard": False})
        loop.resolve = resolve
        loop.switching = wanted != loop.previous if loop.previous is not None else wanted
        new, new_free, _ = loop.next_set(it, wanted, free)
        loop.previous, loop.previous_free = new, new_free
        return new

    assert np.array_equal(step(0, X), X)  # loose
    assert np.array_equal(step(1, Y), Y)  # loose, settles on Y
    assert np.array_equal(step(2, Y, resolve=True), Y)  # Y again, accurately
    assert np.array_equal(step(3, X), X)  # back to X: no safeguard
    assert loop.safeguard_since is None
    back = step(4, Y)  # accurate steps repeat Y: least-index rule, one row changes
    assert loop.safeguard_since == 4
    changed = MPI.COMM_WORLD.allreduce(int((back != X).sum()), op=MPI.SUM)
    assert changed == 1
    loop.destroy()

    # loose steps that repeat a set (X, Y, X): the loop solves accurately from then on and
    # takes X whole; a repeat among the accurate steps (Y, X again) is a cycle
    loop = NewtonLoop(system, 1e-8, 20)
    loop.loose = True  # as on the Krylov path (a direct solve is never loose)
    assert np.array_equal(step(0, X), X)
    assert np.array_equal(step(1, Y), Y)
    assert np.array_equal(step(2, X), X)
    assert not loop.loose and loop.safeguard_since is None
    assert np.array_equal(step(3, Y), Y)
    back = step(4, X)
    assert loop.safeguard_since == 4
    assert MPI.COMM_WORLD.allreduce(int((back != Y).sum()), op=MPI.SUM) == 1
    loop.destroy()
    system.destroy()


def test_schur_path_bad_input(monkeypatch):
    """Unknown method; no solve with K; too many multipliers for the dense S (not for CG);
    multigrid options on the block path."""
    problem = strip_problem(MPI.COMM_WORLD, 8, 2)
    with pytest.raises(
        ValueError, match=r"method must be one of \('block', 'schur', 'krylov'\) or None"
    ):
        ds.solve(problem, method="Schur")
    with pytest.raises(ValueError, match=r"method='schur'.*pc_type 'lu'.*'sor'"):
        ds.solve(problem, method="schur", petsc_options={"ksp_type": "preonly", "pc_type": "sor"})
    with pytest.raises(ValueError, match=r"multigrid.*method='krylov'"):
        ds.solve(problem, petsc_options=iterative_petsc_options())
    monkeypatch.setattr(schur, "SCHUR_MAX_MULTIPLIERS", 3)
    with pytest.raises(ValueError, match=r"SCHUR_MAX_MULTIPLIERS = 3.*method='block'"):
        ds.solve(problem, method="schur")
    sol = ds.solve(problem, method="schur", petsc_options=iterative_petsc_options())
    assert sol.num_active > 0


@pytest.mark.mpi
@pytest.mark.parametrize("method", METHODS)
def test_forward_solve_with_the_last_newton_matrix(method):
    """solve_forward (through the transposed solve) solves A x = b for the Newton matrix
    A = [[K, N^T], [-D_A N, D_I M]] of the last step, applied here from its pieces, for a right
    -hand side with inactive rows, and gives back the last step from its own right-hand side."""
    comm = MPI.COMM_WORLD
    with ds.solve(strip_problem(comm, 16, 4), method=method) as sol:
        system = sol.system
        active = system.active
        assert comm.allreduce(int(active.sum())) > 0 and comm.allreduce(int((~active).sum())) > 0
        b, x = system.x.duplicate(), system.x.duplicate()
        rng = np.random.default_rng(comm.rank)
        b.array_w[:] = rng.standard_normal(len(b.array))
        for bc in system.bcs:
            bc.set(b.array_w[: system.n_u], alpha=0.0)
        system.solve_forward(b, x)
        u, lam = (system.K.createVecRight() for _ in range(2))
        u.array_w[:] = system.split(x)[0]
        lam_vec, n_u = system.N.createVecLeft(), system.N.createVecLeft()
        lam_vec.array_w[:] = system.split(x)[1]
        system.K.mult(u, lam)
        force = system.K.createVecRight()
        system.N.multTranspose(lam_vec, force)
        system.N.mult(u, n_u)
        residual_u = lam.array + force.array - system.split(b)[0]
        residual_lam = (np.where(active, -n_u.array, system.M.array * system.split(x)[1])
                        - system.split(b)[1])
        for res, rhs in ((residual_u, system.split(b)[0]), (residual_lam, system.split(b)[1])):
            scale = comm.allreduce(float(np.max(np.abs(rhs), initial=0.0)), MPI.MAX)
            assert comm.allreduce(float(np.max(np.abs(res), initial=0.0)), MPI.MAX) < 1e-8 * scale

        system.write(b, system.f.array, np.where(active, -system.g.array, 0.0))
        system.solve_forward(b, x)
        for ours, step in zip(system.split(x), system.split(system.x), strict=True):
            scale = comm.allreduce(float(np.max(np.abs(step), initial=0.0)), MPI.MAX)
            assert comm.allreduce(float(np.max(np.abs(ours - step), initial=0.0)),
                                  MPI.MAX) <= 1e-9 * scale
        for vec in (b, x, u, lam, lam_vec, n_u, force):
            vec.destroy()


def test_dual_needs_a_solved_system():
    """The dual problem transposes the last Newton step: none yet is an error on both paths."""
    problem = strip_problem(MPI.COMM_WORLD, 8, 2)
    sol = ds.solve(problem)
    goal = GoalForms(ex.goal_a(-0.5), sol.u, sol.lam, sol.disc)
    for cls in (NewtonSystem, SchurNewtonSystem):
        system = cls(sol.disc)
        with pytest.raises(RuntimeError, match="has not been solved"):
            solve_dual(system, goal)
        system.destroy()


@pytest.mark.mpi
@pytest.mark.parametrize("method", [m for m in METHODS if m != "krylov"])  # the factored ones
def test_solver_options_reach_mumps_and_are_removed(method):
    """Options read only at the factorisation (mat_mumps_*) reach MUMPS: AMF ordering on 2D
    meshes by default, the user's choice over it; they stay in PETSc's database while the
    solution lives and none is left after its destroy()."""
    from petsc4py import PETSc

    problem = strip_problem(MPI.COMM_WORLD, 8, 2)
    for options, ordering, workspace in (
        (None, 2, None),
        ({"mat_mumps_icntl_7": 5, "mat_mumps_icntl_14": 70}, 5, 70),
    ):
        sol = ds.solve(problem, petsc_options=options, method=method)
        factor = sol.system.ksp.getPC().getFactorMatrix()
        assert factor.getMumpsIcntl(7) == ordering
        if workspace is not None:
            assert factor.getMumpsIcntl(14) == workspace
        prefix = sol.system.prefix
        assert PETSc.Options().getInt(prefix + "mat_mumps_icntl_7") == ordering
        sol.destroy()
        assert not [k for k in PETSc.Options().getAll() if k.startswith(prefix)]


@pytest.mark.mpi
def test_higher_order_weights_on_the_krylov_schur_path():
    """The P2 dual and primal of weights="higher_order" are solved like the primal problem (here
    CG on S_AA with GAMG on the P2 K) and give the block path's estimate."""
    comm = MPI.COMM_WORLD
    disc = discretize(ex.obstacle_problem(comm, (2, 8, 8)))
    goal = ex.goal_obstacle()
    estimates = []
    for method, options in (("block", None), ("schur", iterative_petsc_options())):
        sol = ds.solve(disc, method=method, petsc_options=options)
        est = ds.estimate(sol, goal, weights="higher_order", petsc_options=options)
        estimates.append((est.eta, est.eta_p))
    assert np.allclose(estimates[1], estimates[0], rtol=1e-6)


@pytest.mark.mpi
def test_symmetric_newton_matrix_solves_the_newton_step_and_its_transpose():
    """The block path factors the symmetric A_s (LDL^T) of A = L A_s. With A written out as in
    the paper, [K, N^T; -D_A N, D_I M], its step solves A x = [f; -D_A g] and the dual solve
    A^T z = r, for an active set with active and inactive rows."""
    from petsc4py import PETSc

    sol = ds.solve(strip_problem(MPI.COMM_WORLD, 16, 4))
    system, comm = sol.system, sol.disc.comm
    active = system.active
    assert 0 < comm.allreduce(int(active.sum())) < comm.allreduce(active.size)
    factor = system.ksp.getPC().getFactorMatrix()
    assert (system.ksp.getPC().getType(), factor.getMumpsInfog(20) > 0) == ("cholesky", True)
    assert system.A.isSymmetric(0.0)

    # A = [K, N^T; -D_A N, D_I M], from the assembled pieces.
    A = system.A0.copy()
    sign = A.createVecLeft()
    sign.array_w[: system.n_u] = 1.0
    sign.array_w[system.n_u :] = np.where(active, -1.0, 0.0)
    A.diagonalScale(L=sign)
    diagonal = A.getDiagonal()
    diagonal.array_w[system.n_u :] = np.where(active, 0.0, system.M.array)
    A.setDiagonal(diagonal)

    b = A.createVecLeft()
    b.array_w[: system.n_u] = system.f.array
    b.array_w[system.n_u :] = np.where(active, -system.g.array, 0.0)
    residual = b.duplicate()
    A.mult(system.x, residual)
    residual.axpy(-1.0, b)
    assert residual.norm() <= 1e-12 * b.norm()

    r = b.duplicate()
    r.setRandom(PETSc.Random().create(comm))
    z = b.duplicate()
    system.solve_transpose(r, z)
    A.multTranspose(z, residual)
    residual.axpy(-1.0, r)
    assert residual.norm() <= 1e-10 * r.norm()
    for obj in (A, sign, diagonal, b, residual, r, z):
        obj.destroy()


def test_choose_method_rule():
    """The dense Schur path for 3D problems of 100k-200k DoFs with at most 1000 multipliers and
    for 2D solves from zero of at least 20k DoFs, the Krylov path in 3D from 200k DoFs or where
    a factorisation does not fit, the block path otherwise."""
    assert choose_method(3, 150_000, 512) == "schur"
    assert choose_method(3, 150_000, 1510) == "block"
    assert choose_method(3, 50_000, 100) == "block"
    # from 200k DoFs in 3D: the Krylov path (measured faster), not for nonsymmetric laws
    assert choose_method(3, 216_000, 512) == "krylov"
    assert choose_method(3, 265_000, 1510) == "krylov"
    assert choose_method(3, 265_000, 1510, symmetric=False) == "block"
    assert choose_method(2, 789_000, 128) == "block"
    assert choose_method(2, 789_000, 128, cold_start=True) == "schur"
    assert choose_method(2, 10_000, 128, cold_start=True) == "block"
    # where a factorisation does not fit: the Krylov path, if the law is symmetric
    assert choose_method(3, 216_000, 512, fits=False) == "krylov"
    assert choose_method(3, 265_000, 1510, fits=False) == "krylov"
    assert choose_method(3, 265_000, 1510, fits=False, symmetric=False) == "block"


@pytest.mark.mpi
def test_method_none_follows_the_rule_and_the_options(monkeypatch):
    """method=None picks by choose_method (here made to pick the Schur path for a small 3D
    problem), the block path whenever petsc_options are given, and an explicit method wins;
    the chosen path gives the block path's solution."""
    import dwr_signorini.linalg as linalg

    monkeypatch.setattr(linalg, "AUTO_SCHUR_MIN_DOFS", 0)
    disc = discretize(ex.obstacle_problem(MPI.COMM_WORLD, (1, 4, 4)))
    with ds.solve(disc) as auto, ds.solve(disc, method="block") as block:
        assert auto.method == "schur" and isinstance(auto.system, SchurNewtonSystem)
        assert block.method == "block" and type(block.system) is NewtonSystem
        n_u = block.system.n_u
        diff = _relative_difference(disc.comm, block.u.x.array[:n_u], auto.u.x.array[:n_u])
        assert diff < 1e-10
    with ds.solve(disc, petsc_options={"mat_mumps_icntl_14": 50}) as given:
        assert given.method == "block"


@pytest.mark.mpi
def test_method_none_takes_the_krylov_path_where_a_factorisation_does_not_fit(monkeypatch):
    """With less memory per rank than MUMPS's analysis predicts for K, method=None takes the
    Krylov path (Solution.method, LevelRecord.method), which gives the factored path's J_h,
    eta_p and eta to the Krylov tolerances; with ample memory it factors as before."""
    from dwr_signorini.linalg import memory

    monkeypatch.setattr(memory, "PROBE_MIN_DOFS", 0)  # probe this small mesh
    comm = MPI.COMM_WORLD
    problem = ex.obstacle_problem(comm, (2, 8, 8))
    disc = discretize(problem)
    goal = ex.goal_obstacle()
    with ds.solve(disc, method="block") as factored:
        _, need, _ = memory.factorization_fits(factored.system.K, 3)
    assert need > 0
    runs = {}
    for budget in (need // 10, 10**6 * need):
        with monkeypatch.context() as patch:
            patch.setattr(memory, "MEMORY_BUDGET", budget)
            if budget > need:  # the rough estimate from the size fits: no analysis
                patch.setattr(memory, "predicted_factor_memory", _not_called)
            with ds.solve(disc) as sol:
                est = ds.estimate(sol, goal, weights="patch")
                runs[sol.method] = (est.J_h, est.eta_p, est.eta)
    assert set(runs) == {"krylov", "block"}
    assert np.allclose(runs["krylov"], runs["block"], rtol=1e-7)
    monkeypatch.setattr(memory, "MEMORY_BUDGET", need // 10)
    result = ds.solve_adaptive(problem, goal, max_levels=1, weights="patch")
    assert [rec.method for rec in result.levels] == ["krylov"]
    assert "(krylov)" in _level_line(result.levels[0])


@pytest.mark.mpi
def test_krylov_path_that_does_not_converge_says_so_and_leaves_no_options():
    """A GMRES of the saddle-point system stopped early (its options under the solve's prefix,
    ``saddle_``) is a ConvergenceError naming it, and no option of the solve is left behind."""
    from petsc4py import PETSc

    problem = ex.obstacle_problem(MPI.COMM_WORLD, (1, 4, 4))
    with pytest.raises(ds.ConvergenceError, match=r"GMRES on the saddle-point system did not "
                       r"converge \(KSP reason -3, 2 iterations\)"):
        ds.solve(problem, method="krylov", petsc_options={"saddle_ksp_max_it": 2},
                 petsc_options_prefix="krylov_failure_")
    assert not [k for k in PETSc.Options().getAll() if k.startswith("krylov_failure_")]


def _not_called(*args):
    raise AssertionError("MUMPS's analysis was run where the size alone decided")


def _level_line(record) -> str:
    """The progress line of a level, as rank 0 shows it."""
    from dwr_signorini.report import progress_line

    return progress_line(record)


@pytest.mark.mpi
def test_predicted_factor_memory_bounds_what_mumps_then_uses():
    """MUMPS's prediction from its analysis alone (INFOG(16)) is at least the memory the
    factorisation then takes (INFOG(21), the most on a rank) and within twice it, and it
    grows with the mesh."""
    from dwr_signorini.linalg import memory

    comm = MPI.COMM_WORLD
    predicted = []
    for n in (1, 2):
        with ds.solve(ex.obstacle_problem(comm, (n, 4 * n, 4 * n)), method="schur") as sol:
            factor = sol.system.ksp.getPC().getFactorMatrix()
            used = factor.getMumpsInfog(21) * 10**6
            predicted.append(memory.predicted_factor_memory(sol.system.K, 3))
            assert used <= predicted[-1] <= 2 * used
    assert predicted[1] > 2 * predicted[0]


def test_available_memory_reads_the_node_and_the_container(tmp_path, monkeypatch):
    """The budget per rank is the smaller of MemAvailable and the control group's remainder,
    shared by the ranks on the node; MEMORY_BUDGET overrides it."""
    from dwr_signorini.linalg import memory

    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       24000000 kB\nMemAvailable:   20000000 kB\n")
    assert memory._meminfo_available(meminfo) == 20000000 * 1024
    assert memory._meminfo_available(tmp_path / "missing") is None
    (tmp_path / "memory.max").write_text("max\n")
    assert memory._cgroup_available(tmp_path) is None
    (tmp_path / "memory.max").write_text("8000000000\n")
    (tmp_path / "memory.current").write_text("3000000000\n")
    assert memory._cgroup_available(tmp_path) == 5_000_000_000
    monkeypatch.setattr(memory, "_meminfo_available", lambda: 20000000 * 1024)
    monkeypatch.setattr(memory, "_cgroup_available", lambda: 5_000_000_000)
    assert memory.available_memory(MPI.COMM_SELF) == 5_000_000_000
    monkeypatch.setattr(memory, "MEMORY_BUDGET", 123)
    assert memory.available_memory(MPI.COMM_SELF) == 123


def _kkt_matrix(n: int = 6000, m: int = 3000):
    """A nonsingular symmetric indefinite [[D, B^T], [B, 0]], D = 0 on the first m rows.

    The zero diagonal entries are stored, as in the Newton matrix.

    B has full row rank (an entry on the "diagonal" k and three random columns per row), D > 0
    elsewhere, so the matrix is nonsingular; its zero diagonal makes MUMPS delay pivots beyond
    the analysis' estimate when the pivot threshold is high and no extra workspace is allowed.
    """
    from petsc4py import PETSc

    rng = np.random.default_rng(1)
    cols = rng.integers(0, n, size=(m, 3))
    d, b = 1 + rng.random(n), 1 + rng.random((m, 4))  # the same values on every rank
    A = PETSc.Mat().createAIJ([n + m, n + m], nnz=12, comm=MPI.COMM_WORLD)
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    lo, hi = A.getOwnershipRange()
    for i in range(lo, min(hi, n)):  # explicit zeros on the first m, as the Newton matrix has
        A.setValue(i, i, d[i] if i >= m else 0.0, addv=True)
    for k in range(m):
        for j, v in zip((k, *cols[k]), b[k], strict=True):
            for row, col in ((n + k, j), (j, n + k)):
                if lo <= row < hi:
                    A.setValue(row, col, v, addv=True)
    A.assemble()
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    return A


@pytest.mark.mpi
def test_mumps_workspace_retry():
    """``linalg.mumps.set_up``: a factorisation that runs out of workspace (INFOG(1) = -9) is
    repeated with more (ICNTL(14)), and the solve is then exact; a plain set-up of the same
    matrix fails, and the user's option is back in the database afterwards."""
    from petsc4py import PETSc

    from dwr_signorini.linalg.mumps import mumps_failure, set_up
    from dwr_signorini.linalg.options import OptionsScope

    A = _kkt_matrix()
    options = {"ksp_type": "preonly", "pc_type": "cholesky", "pc_factor_mat_solver_type": "mumps",
               "mat_mumps_icntl_14": 0, "mat_mumps_cntl_1": 0.5}
    x_exact, b = A.createVecs()
    x_exact.setRandom()
    A.mult(x_exact, b)
    for retry in (False, True):
        scope = OptionsScope("dwr_signorini_test_workspace_", options=options)
        ksp = PETSc.KSP().create(MPI.COMM_WORLD)
        scope.apply(ksp)
        if retry:
            set_up(ksp, A)
        else:
            ksp.setOperators(A)
            ksp.setUp()
        x = b.duplicate()
        ksp.solve(b, x)
        if retry:
            assert ksp.getConvergedReason() > 0
            assert ksp.getPC().getFactorMatrix().getMumpsIcntl(14) >= 100
            x.axpy(-1.0, x_exact)
            assert x.norm() < 1e-6 * x_exact.norm()
        else:
            assert ksp.getConvergedReason() < 0
            assert "workspace was too small" in mumps_failure(ksp)
        assert PETSc.Options().getInt("dwr_signorini_test_workspace_mat_mumps_icntl_14") == 0
        for obj in (ksp, x):
            obj.destroy()
        scope.destroy()
    for obj in (A, x_exact, b):
        obj.destroy()


@pytest.mark.mpi
def test_newton_steps_reusing_factors_match_factoring(monkeypatch):
    """The block path's steps solved with the factors of an earlier step and a low-rank
    (Woodbury) correction give the same J_h, estimates and Newton iterations as factoring
    every step, on adaptive levels of example 5.3 where the last steps change a few facets;
    the dual problem after such a step is solved the same way."""
    from dwr_signorini.linalg.factor import FactoredNewtonSystem, ReusePolicy

    runs = {}
    for name, fraction in (("factor", 0.0), ("reuse", 1e9)):  # never / whenever possible
        monkeypatch.setattr(FactoredNewtonSystem, "reuse", ReusePolicy(fraction=fraction))
        counts = []
        res = ds.solve_adaptive(
            ex.obstacle_problem(MPI.COMM_WORLD, (1, 4, 4)), ex.goal_obstacle(), growth=2.0,
            max_levels=5, verbose=False, method="block",
            callback=lambda r, sol, est, counts=counts: counts.append(
                (sol.system.factorizations, sol.system.reused)),
        )
        runs[name] = (res.levels, counts)
        res.destroy()
    (factored, f_counts), (reused, r_counts) = runs["factor"], runs["reuse"]
    assert all(r == 0 for _, r in f_counts)
    assert sum(r for _, r in r_counts) >= 2, r_counts
    assert sum(f for f, _ in r_counts) < sum(f for f, _ in f_counts)
    for a, b in zip(factored, reused, strict=True):
        assert (a.num_cells, a.newton_iterations, a.num_active) == (
            b.num_cells, b.newton_iterations, b.num_active)
        assert b.J_h == pytest.approx(a.J_h, rel=1e-11)
        assert b.weights == a.weights
        # the hierarchical P2 weights (an FGMRES to HIERARCHICAL_RTOL from each path's factors)
        # agree to that tolerance: measured 1.1e-5 of eta on a level of this run
        rel = 10 * hierarchical.HIERARCHICAL_RTOL if a.weights == "hierarchical" else 1e-8
        assert b.eta == pytest.approx(a.eta, rel=rel, abs=1e-10 * abs(a.J_h))


@pytest.mark.mpi
@pytest.mark.parametrize("s_E", [1.0, 1e-6])
def test_stiffness_norm_is_the_largest_row_sum_off_the_dirichlet_rows(s_E):
    """||K||_inf without the Dirichlet rows, against the rows summed off the dofs of the bcs.

    With the unit modulus scale PETSc's norm answers (rows sum to more than 1); with 1e-6 every
    coupled row sums to less than the Dirichlet rows' 1, and the rows are summed instead.
    """
    from dwr_signorini.algebra import ContactAlgebra

    disc = discretize(indented_block(MPI.COMM_WORLD, 4, 3, 0.002, s_E=s_E))
    algebra = ContactAlgebra(disc)
    try:
        free = fem.Function(disc.V)
        free.x.array[:] = 1.0
        for bc in disc.bcs:
            bc.set(free.x.array)
        rows, _, values = algebra.K.getValuesCSR()
        row_sums = np.add.reduceat(np.abs(values), rows[:-1])
        coupled = free.x.array[: len(row_sums)] == 1.0
        comm = MPI.COMM_WORLD
        counts = comm.allreduce(np.array([coupled.sum(), (~coupled).sum()]), op=MPI.SUM)
        assert counts.min() > 0  # both kinds of rows are there
        expected = comm.allreduce(float(row_sums[coupled].max(initial=0.0)), op=MPI.MAX)
        assert (expected > 1.0) == (s_E == 1.0)
        assert np.isclose(algebra.stiffness_norm(), expected, rtol=1e-14, atol=0)
    finally:
        algebra.destroy()


@pytest.mark.mpi
def test_woodbury_update_with_kept_columns_solves_the_changed_matrix():
    """``lowrank``: the columns kept per changed row are those of A_new - A_old, and the update
    solves A_new x = b as a factorisation of A_new does, also for a second set of changes that
    reuses the first set's columns and adds only its new rows."""
    from petsc4py import PETSc

    from dwr_signorini.linalg.lowrank import FactorColumns, WoodburyUpdate

    comm = MPI.COMM_WORLD
    with ds.solve(indented_block(comm, 16, 6, 0.02), method="block") as sol:
        system = sol.system
        q_start = sol.disc.Q.dofmap.index_map.local_range[0]
        assert sol.disc.num_contact_elements >= 8 and sol.num_active >= 2
        active0 = sol.active.copy()

        def flipped(globals_):
            own = np.isin(q_start + np.arange(active0.size), globals_)
            active = active0 ^ own
            first = system.A.getOwnershipRange()[0] + system.n_u
            rows = np.concatenate(comm.allgather(first + np.flatnonzero(own)))
            return active, np.sort(rows).astype(np.int64)

        def factored(A):
            ksp = PETSc.KSP().create(comm)
            ksp.setOperators(A)
            ksp.setType("preonly")
            ksp.getPC().setType("lu")
            ksp.getPC().setFactorSolverType("mumps")
            ksp.setUp()
            return ksp

        A_old = system.newton_matrix(active0)
        ksp_old = factored(A_old)
        columns = FactorColumns(ksp_old, A_old)
        b = A_old.createVecLeft()
        b.array_w[:] = np.random.default_rng(comm.rank).random(b.getLocalSize())
        for changed, new in (([0, 1, 2, 3], [0, 1, 2, 3]), ([0, 1, 2, 3, 6, 7], [6, 7])):
            active, rows = flipped(changed)
            assert len(columns.missing(rows)) == len(new)
            A_new = system.newton_matrix(active)
            update = WoodburyUpdate(columns, A_new, rows)
            x, x_direct = A_new.createVecRight(), A_new.createVecRight()
            update.solve(b, x)
            ksp_new = factored(A_new)
            ksp_new.solve(b, x_direct)
            x.axpy(-1.0, x_direct)
            assert x.norm() <= 1e-9 * x_direct.norm()
            D = A_new.copy()
            D.axpy(-1.0, A_old)
            e, column = D.createVecRight(), D.createVecLeft()
            for row in rows:
                e.set(0.0)
                if e.getOwnershipRange()[0] <= row < e.getOwnershipRange()[1]:
                    e.setValue(int(row), 1.0)
                e.assemble()
                D.mult(e, column)
                assert np.array_equal(columns.d[:, columns.index[int(row)]], column.array_r)
            for obj in (A_new, x, x_direct, ksp_new, D, e, column):
                obj.destroy()
            update.destroy()
        for obj in (A_old, ksp_old, b):
            obj.destroy()
        columns.destroy()
