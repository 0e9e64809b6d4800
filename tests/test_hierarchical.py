"""The hierarchical P2 dual (``weights="hierarchical"``) against the directly solved P2 dual.

The truth is the dual of ``weights="higher_order"``: the P2 system with Lambda_H and the final
active set, factored and solved directly. :mod:`dwr_signorini.hierarchical` solves the same
system by FGMRES with a two-level preconditioner, so to a tight tolerance it must reproduce its
solution, and eta_p with it; to the default tolerance the estimate must stay close. Contact
problems in 2D (the strip, whose contact boundary both ranks share on 2 processes; example 5.1
on quadrilaterals, where the edge unknowns of Q2 include the cell centres) and 3D (example 5.3),
serially and on 2 ranks.
"""

import itertools

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import hierarchical
from dwr_signorini import weights as auto_weights
from dwr_signorini.dual import solve_dual
from dwr_signorini.estimator import _higher_order_solutions
from dwr_signorini.goal import GoalForms
from dwr_signorini.hierarchical import hierarchical_solutions
from dwr_signorini.reconstruction import Reconstructor

from .helpers import total_force
from .problems import indented_block, strip_problem

pytestmark = pytest.mark.mpi


def _norm(f: fem.Function) -> float:
    n = f.function_space.dofmap.index_map.size_local * f.function_space.dofmap.index_map_bs
    return np.sqrt(f.function_space.mesh.comm.allreduce(float(f.x.array[:n] @ f.x.array[:n])))


def _difference(a: fem.Function, b: fem.Function) -> float:
    d = fem.Function(a.function_space)
    d.x.array[:] = a.x.array - b.x.array
    return _norm(d) / _norm(b)


def _with_law(problem: ds.SignoriniProblem, law) -> ds.SignoriniProblem:
    return problem.with_mesh(problem.mesh, problem.facet_tags, law=law)


def _friction_3d(comm: MPI.Comm) -> ds.SignoriniProblem:
    """The sheared block on a sphere of tests/test_friction_3d.py, on 4 x 4 x 2 boxes."""
    return ex.friction_problem(comm, nx=4, ny=2, dim=3, radius=4.0, s=0.2)


def _stick_and_slip(sol) -> None:
    """A frictional case has both stick and slip facets (the coupled rows are the slip's)."""
    if sol.stick is not None:
        assert sol.num_stick > 0 and sol.num_slip > 0, (sol.num_stick, sol.num_slip)


CASES = {
    "strip 2D": (lambda comm: strip_problem(comm, 16, 4), total_force),
    "example 5.1, quadrilaterals": (
        lambda comm: ex.analytic_problem(comm, 6, 4, mesh.CellType.quadrilateral),
        ex.goal_a(-0.5),
    ),
    "example 5.3": (lambda comm: ex.obstacle_problem(comm, (1, 4, 4)), ex.goal_obstacle()),
    "Tresca friction 2D": (lambda comm: ex.friction_problem(comm), ex.goal_friction_force()),
    # coupled Newton rows: a slipping facet's tangential row couples its normal multiplier
    "Coulomb friction 2D": (lambda comm: _with_law(ex.friction_problem(comm), ds.Coulomb(0.3)),
                            ex.goal_friction_force()),
    "Coulomb friction 3D": (lambda comm: _with_law(_friction_3d(comm), ds.Coulomb(0.3)),
                            ex.goal_friction_force()),
    "Tresca friction 3D": (lambda comm: _friction_3d(comm), ex.goal_friction_force()),
    # nu = 0.49: the P1 coarse space locks, the smoother carries the divergence-free modes
    "nearly incompressible Hertz block": (
        lambda comm: indented_block(comm, 24, 11, 0.01, nu=0.49), total_force,
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_iterative_p2_dual_equals_the_factored_one(case):
    build, goal = CASES[case]
    comm = MPI.COMM_WORLD
    with ds.solve(build(comm)) as sol:
        assert comm.allreduce(int(sol.system.active.sum())) > 0
        _stick_and_slip(sol)
        forms = GoalForms(goal, sol.u, sol.lam, sol.disc, sol.tangential or None)
        z = solve_dual(sol.system, forms)
        rec = Reconstructor(sol.disc)
        try:
            z2, w2 = _higher_order_solutions(sol, forms, rec, True, None)
            errors, primal = [], []
            for rtol in (1e-2, 1e-8):
                zk, (uk, lamk) = hierarchical_solutions(sol, forms, z, rec.V2h, True, rtol=rtol)
                pairs = zip(zk.multipliers, z2.multipliers, strict=True)
                errors.append((_difference(zk.y, z2.y), max(_difference(a, b) for a, b in pairs)))
                pairs = zip(lamk, w2[1], strict=True)
                primal.append((_difference(uk, w2[0]), max(_difference(a, b) for a, b in pairs)))
        finally:
            rec.destroy()
    assert errors[1][0] < errors[0][0] and primal[1][0] < primal[0][0]
    assert errors[1][0] < 1e-6 and errors[1][1] < 1e-6, errors
    assert primal[1][0] < 1e-6 and primal[1][1] < 1e-6, primal


@pytest.mark.parametrize("case", CASES)
def test_hierarchical_estimate_approaches_higher_order(case, monkeypatch):
    """eta_p and eta to a tight tolerance equal those of the factored P2 solutions, and to the
    default one (a relative residual of 1e-4) are within 1e-3 of them (measured: at most
    3.6e-4, on a level of the strip)."""
    build, goal = CASES[case]
    rel = 10 * hierarchical.HIERARCHICAL_RTOL
    comm = MPI.COMM_WORLD
    with ds.solve(build(comm)) as sol:
        with ds.estimate(sol, goal, weights="higher_order") as high:
            with ds.estimate(sol, goal, weights="hierarchical") as hier:
                monkeypatch.setattr(hierarchical, "HIERARCHICAL_RTOL", 1e-8)
                with ds.estimate(sol, goal, weights="hierarchical") as many:
                    pass
    assert many.eta_p == pytest.approx(high.eta_p, rel=1e-6)
    assert many.eta == pytest.approx(high.eta, rel=1e-6)
    assert hier.J_h == high.J_h
    assert hier.eta_p == pytest.approx(high.eta_p, rel=rel)
    assert hier.eta == pytest.approx(high.eta, rel=rel)


def test_hierarchical_weights_on_the_krylov_path(monkeypatch):
    """With the Newton steps by the saddle-point GMRES (method="krylov", its coarse steps solved
    only to the loose tolerance) the hierarchical weights give the factored P2 estimate: within
    1 % to the default tolerance, 1e-6 to a tight one."""
    comm = MPI.COMM_WORLD
    disc = ds.discretize(ex.obstacle_problem(comm, (1, 4, 4)))
    goal = ex.goal_obstacle()
    with ds.solve(disc, method="block") as sol:
        with ds.estimate(sol, goal, weights="higher_order") as high:
            pass
    with ds.solve(disc, method="krylov") as sol:
        assert sol.method == "krylov"
        with ds.estimate(sol, goal, weights="hierarchical") as hier:
            pass
        monkeypatch.setattr(hierarchical, "HIERARCHICAL_RTOL", 1e-8)
        with ds.estimate(sol, goal, weights="hierarchical") as many:
            pass
    assert hier.eta == pytest.approx(high.eta, rel=1e-2)
    assert many.eta == pytest.approx(high.eta, rel=1e-6)
    assert many.eta_p == pytest.approx(high.eta_p, rel=1e-6)


def test_adaptive_run_with_hierarchical_weights():
    """solve_adaptive refines by the hierarchical indicators; on every level eta is that of the
    factored P2 solutions on the same solution within 10 x the P2 residual's tolerance of the
    size of its terms |rho| + |rho*| + |C| (measured 4.3e-5, 6.8e-5, 2.3e-5 of it; on level 1
    eta is small against its terms, and the difference 1.3e-3 of eta itself)."""
    comm = MPI.COMM_WORLD
    levels = []

    def check(record, sol, est):
        with ds.estimate(sol, total_force, weights="higher_order") as high:
            scale = abs(high.rho) + abs(high.rho_star) + abs(high.contact_term)
            levels.append((record.level, est.weights, est.eta, high.eta, scale))

    with ds.solve_adaptive(strip_problem(comm, 16, 4), total_force, weights="hierarchical",
                           max_levels=3, verbose=False, callback=check) as res:
        cells = [r.num_cells for r in res.levels]
    assert all(a < b for a, b in itertools.pairwise(cells)), cells
    assert len(levels) == 3
    for level, weights, eta, eta_high, scale in levels:
        assert weights == "hierarchical"
        assert abs(eta - eta_high) <= 10 * hierarchical.HIERARCHICAL_RTOL * scale, level


@pytest.mark.parametrize(("case", "kind"), [
    ("Tresca friction 2D", "hierarchical"), ("Coulomb friction 2D", "hierarchical"),
    ("Coulomb friction 3D", "higher_order"), ("Tresca friction 3D", "higher_order"),
])
def test_auto_takes_hierarchical_weights_for_coupled_rows_in_2d_only(case, kind):
    """The P2 weights of weights="auto" (weights.p2_kind): the two-level solver for a symmetric
    law and for coupled rows in 2D, where it was the faster; the factored P2 system for coupled
    rows in 3D, where it was not (weights.HIERARCHICAL_COUPLED_DIMS)."""
    build, _ = CASES[case]
    with ds.solve(build(MPI.COMM_WORLD)) as sol:
        assert auto_weights.p2_kind(sol) == kind
