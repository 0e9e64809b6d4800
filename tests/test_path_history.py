"""The error a load path's history carries (dwr_signorini.path): one backward sweep.

* the default ``history="last"`` gives the last step the terms of the backward chain of history
  goals, here computed independently (the steps solved one by one from the same warm starts,
  the chain estimated step by step with ``history_goal`` and ``estimate``): to 1e-10, and so
  does the chain after every step (``history="every"``, the behaviour of ``history=True``);
* its cost: the default runs one history estimate per earlier step in total (n - 1 for n
  steps), the chain after every step n (n - 1) / 2;
* the path's history estimates reuse what each step's own estimate made that does not depend
  on the goal (:mod:`dwr_signorini.estimate_parts`: the P2 system factored once per step, or
  its two-level set-up, the primal weights, the compiled forms), and their terms are those of
  fresh estimates to 1e-10, for the patch, factored P2 and hierarchical P2 weights;
* serially and on 2 ranks (the chain's terms are reduced over the ranks).
"""

from mpi4py import MPI

import pytest
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import estimate_parts
from dwr_signorini import examples as ex
from dwr_signorini import path_history as path_module
from dwr_signorini.linalg import memory
from dwr_signorini.path_history import history_goal

COMM = MPI.COMM_WORLD
TOPS = [(0.0, -0.02), (0.004, -0.02), (0.008, -0.02), (0.012, -0.021)]


def sheared_path(comm=COMM, law=None):
    """The block on a cylinder (examples.friction_problem), Coulomb friction (or ``law``),
    pressed then sheared in three steps: partial slip, so the history's goals do not vanish."""
    base = ex.friction_problem(comm, nx=12, ny=6)
    return [
        ds.SignoriniProblem(base.mesh, base.facet_tags, contact=ex.CONTACT,
                            dirichlet={ex.DIRICHLET: top}, E=10.0, nu=0.3, gap=base.gap,
                            friction=ds.Coulomb(0.3) if law is None else law)
        for top in TOPS
    ]


def copies(sol):
    """A warm start: copies of the solution's u and multipliers."""
    out = []
    for f in (sol.u, *sol.multipliers):
        g = fem.Function(f.function_space)
        g.x.array[:] = f.x.array
        out.append(g)
    return tuple(out)


def reference_chain(problems, goal, weights="auto"):
    """The last step's own interval, and its history terms by the chain written out:
    (estimate, low, high) per earlier step, last first, the ends relative to the history goal's
    J_h (as path.history_estimates). Every estimate is a fresh one: its own reconstruction, P2
    solves and forms, nothing kept with the solutions."""
    sols, disc = [], None
    try:
        for p in problems:
            disc = ds.discretize(p) if disc is None else disc.for_problem(p)
            disc.set_u_old(sols[-1].u if sols else None)
            sols.append(ds.solve(disc, initial_guess=copies(sols[-1]) if sols else None))
        assert all(sol.estimate_parts is None for sol in sols)
        ests = [ds.estimate(sols[-1], goal, weights=weights)]
        terms = []
        for k in range(len(sols) - 2, -1, -1):
            ests.append(ds.estimate(sols[k], history_goal(sols[k + 1], ests[-1]),
                                    weights=weights))
            low, high = ests[-1].interval
            terms.append((ests[-1].value, low - ests[-1].J_h, high - ests[-1].J_h))
        own = ests[0].interval
        for e in ests:
            e.destroy()
        return own, terms
    finally:
        for s in sols:
            s.destroy()


def counted_path(monkeypatch, problems, goal, history):
    """The path's step records and the number of history estimates it ran."""
    calls = []

    def counting(*args, **kwargs):
        calls.append(1)
        return ds.estimate(*args, **kwargs)

    monkeypatch.setattr(path_module, "estimate", counting)
    with ds.solve_path(problems, goal, history=history, verbose=False) as res:
        return res.steps, len(calls)


@pytest.mark.mpi
def test_last_step_history_is_the_chain_in_one_sweep(monkeypatch):
    problems, goal = sheared_path(), ex.goal_friction_force()
    n = len(problems)
    own, terms = reference_chain(problems, goal)
    eta = sum(t[0] for t in terms)
    low, high = sum(t[1] for t in terms), sum(t[2] for t in terms)
    assert abs(eta) > 1e-12 and all(t[0] != 0.0 for t in terms)  # a chain that carries error
    steps, calls = counted_path(monkeypatch, problems, goal, None)
    assert calls == n - 1
    assert [s.eta_history for s in steps[:-1]] == [None] * (n - 1)
    every, calls_every = counted_path(monkeypatch, problems, goal, "every")
    assert calls_every == n * (n - 1) // 2
    assert all(s.eta_history is not None for s in every[1:])
    for last in (steps[-1], every[-1]):
        assert last.eta_history == pytest.approx(eta, rel=1e-10, abs=1e-16)
        assert last.J_low == pytest.approx(own[0] + low, rel=1e-10, abs=1e-16)
        assert last.J_high == pytest.approx(own[1] + high, rel=1e-10, abs=1e-16)
    for name in ("eta_history", "estimate", "J_low", "J_high", "J_best"):
        assert getattr(steps[-1], name) == pytest.approx(getattr(every[-1], name), rel=1e-10,
                                                         abs=1e-16)


@pytest.mark.mpi
def test_history_modes_are_checked():
    problems = sheared_path()[:2]
    for bad, error in (("all", ValueError), (1, TypeError)):
        with pytest.raises(error, match="history must be"):
            ds.solve_path(problems, ex.goal_friction_force(), history=bad, verbose=False)
    with pytest.raises(ValueError, match="adaptive path"):
        ds.solve_path(problems, ex.goal_friction_force(), adaptive=True, history="last",
                      verbose=False)


@pytest.mark.mpi
@pytest.mark.parametrize("budget", [None, 1], ids=["memory", "no-memory"])
@pytest.mark.parametrize(("law", "weights", "solver"), [
    (None, "higher_order", "FactoredP2"),
    (ds.Tresca(0.1), "hierarchical", "HierarchicalP2"),
])
def test_history_reuses_each_steps_p2_solver(monkeypatch, law, weights, solver, budget):
    """With P2 weights the history's estimates reuse each step's P2 solver: one per step in
    total (n, against 2 n - 1 for fresh estimates), and terms equal to the fresh chain's; with
    a memory budget of 1 byte no solver is kept (2 n - 1 made), the terms the same."""
    problems, goal = sheared_path(law=law), ex.goal_friction_force()
    n = len(problems)
    made = []
    cls = getattr(estimate_parts, solver)
    original = cls.__init__

    def counting(self, *args, **kwargs):
        made.append(1)
        original(self, *args, **kwargs)

    own, terms = reference_chain(problems, goal, weights)
    assert len(terms) == n - 1 and all(t[0] != 0.0 for t in terms)
    monkeypatch.setattr(cls, "__init__", counting)
    monkeypatch.setattr(memory, "MEMORY_BUDGET", budget)
    with ds.solve_path(problems, goal, weights=weights, verbose=False) as res:
        last = res.steps[-1]
        assert res.solution.estimate_parts is None  # released with the path's end
        assert res.estimate.reconstructor.V2h is not None  # the last estimate keeps its own
    assert len(made) == (n if budget is None else 2 * n - 1)
    assert last.eta_history == pytest.approx(sum(t[0] for t in terms), rel=1e-10, abs=1e-16)
    assert last.J_low == pytest.approx(own[0] + sum(t[1] for t in terms), rel=1e-10, abs=1e-16)
    assert last.J_high == pytest.approx(own[1] + sum(t[2] for t in terms), rel=1e-10,
                                        abs=1e-16)
