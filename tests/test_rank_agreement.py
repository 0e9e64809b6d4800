"""Input that differs between ranks is refused on every rank, naming the argument (issue 58).

On 2 ranks (``-m mpi``) each case passes rank-dependent data to one argument; the call must
raise the same ValueError on both ranks, naming the argument and the ranks, instead of mixing
the ranks' answers (E, gap, goal), silently measuring nothing (contact tag) or hanging
(friction law, ``max_levels``). A hang here is the bug (mpi4py's ``-m mpi4py`` aborts both
ranks on an error). Serially the fingerprints themselves are checked: equal data give equal
fingerprints, different data (also a callable with other values) different ones.
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.agreement import fingerprint, probe_points
from tests.problems import top_clamped_tags

COMM = MPI.COMM_WORLD
RANK = COMM.rank


def _mesh():
    msh = mesh.create_rectangle(
        COMM, [(0.0, 0.0), (2.0, 1.0)], [8, 4], ghost_mode=mesh.GhostMode.none
    )
    return msh, top_clamped_tags(msh, 1.0)


def _problem(msh_tags=None, **changes):
    msh, tags = msh_tags or _mesh()
    data = {"contact": ex.CONTACT, "dirichlet": {ex.DIRICHLET: (0.0, -0.01)}, "E": 10.0,
            "nu": 0.3, "gap": 0.0}
    data.update(changes)
    return ds.SignoriniProblem(msh, tags, **data)


def _other_tag_mesh_problem():
    """Rank 1 names the free sides (NEUMANN) as the contact boundary, rank 0 the bottom."""
    return _problem(contact=ex.CONTACT if RANK == 0 else ex.NEUMANN)


PROBLEM_CASES = {
    "E": lambda: _problem(E=10.0 + RANK),
    "gap": lambda: _problem(gap=0.01 * RANK),
    "contact": _other_tag_mesh_problem,
    "friction": lambda: _problem(friction=ds.Tresca(0.1) if RANK == 0 else ds.Coulomb(0.3)),
    "dirichlet": lambda: _problem(dirichlet={ex.DIRICHLET: (0.0, -0.01 * (1 + RANK))}),
    "nu": lambda: _problem(nu=lambda x: 0.3 + 0.01 * RANK * x[0]),
    "boundary_projection": lambda: _problem(
        boundary_projection={ex.NEUMANN: lambda p: p + 0.0 * RANK * p}
        if RANK == 0
        else {ex.NEUMANN: lambda p: p * (1.0 + 1e-9)}
    ),
}


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that differ")
@pytest.mark.parametrize("argument", list(PROBLEM_CASES))
def test_problem_data_differing_between_ranks(argument):
    with pytest.raises(ValueError) as info:
        PROBLEM_CASES[argument]()
    text = str(info.value)
    assert text.startswith(f"SignoriniProblem: {argument} (rank 0 | rank 1") and "differs" in text
    assert COMM.allgather(text) == [text] * COMM.size


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that differ")
def test_max_levels_differing_between_ranks():
    problem = _problem()
    with pytest.raises(ValueError, match=r"solve_adaptive: max_levels \(rank 0 \| rank 1\)"):
        ds.solve_adaptive(problem, ex.goal_a(0.5), max_levels=2 + RANK, verbose=False)


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that differ")
def test_path_settings_differing_between_ranks():
    msh_tags = _mesh()
    problems = [_problem(msh_tags, dirichlet={ex.DIRICHLET: (0.0, -d)}) for d in (0.005, 0.01)]
    with pytest.raises(ValueError, match=r"solve_path: estimator \(rank 0 \| rank 1\)"):
        ds.solve_path(problems, ex.goal_a(0.5), estimator="eta" if RANK == 0 else "eta_p",
                      verbose=False)


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that differ")
def test_goal_differing_between_ranks():
    problem = _problem()
    with ds.solve(problem) as sol:
        def goal(u, lam, m):
            return (1.0 + RANK) * lam * m.ds_contact

        with pytest.raises(ValueError, match=r"estimate: goal \(rank 0 \| rank 1\) differs"):
            ds.estimate(sol, goal)


@pytest.mark.mpi
def test_same_data_on_every_rank_passes():
    """The same data, callables included, pass on any number of ranks (and solve)."""
    problem = _problem(E=lambda x: 10.0 + x[0], gap=ds.obstacles.Plane((0.0, 0.0), (0.0, -1.0)),
                       friction=ds.Tresca(0.1))
    with ds.solve(problem) as sol:
        assert sol.newton_iterations > 0


def test_fingerprints():
    msh, _ = _mesh()
    x = ufl.SpatialCoordinate(msh)
    points = probe_points(msh)
    assert points.shape == (5, 2)
    assert np.all(points >= 0.0) and np.all(points <= [2.0, 1.0])

    def same(a, b, numeric=False):
        return fingerprint(a, x, points, numeric) == fingerprint(b, x, points, numeric)

    assert same({3: (0.0, None)}, {3: (0.0, None)})
    assert not same({3: (0.0, None)}, {3: (None, 0.0)})
    assert not same(10.0, 10.000000000001)
    assert same(lambda y: 1 + y[0], lambda y: y[0] + 1.0)  # the same values
    assert not same(lambda y: 1 + y[0], lambda y: 1 + y[1])
    assert not same(ds.Tresca(0.1), ds.Coulomb(0.1))
    assert not same(ds.Tresca(0.1), ds.Tresca(0.2))
    assert not same(ds.obstacles.Sphere((0.0, 2.0), 1.0), ds.obstacles.Sphere((0.0, 2.0), 1.1))
    assert not same(ds.ContactPair(slave=3, master=4), ds.ContactPair(slave=4, master=3))
    assert same({4: lambda p: 2 * p}, {4: lambda p: p + p}, numeric=True)
    assert not same({4: lambda p: 2 * p}, {4: lambda p: 3 * p}, numeric=True)


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that differ")
def test_solver_and_estimate_options_differing_between_ranks():
    problem = _problem()
    with pytest.raises(ValueError, match=r"solve: max_iterations \(rank 0 \| rank 1\) differs"):
        ds.solve(problem, max_iterations=20 + RANK)
    with ds.solve(problem) as sol:
        with pytest.raises(ValueError, match=r"estimate: estimator \(rank 0 \| rank 1\)"):
            ds.estimate(sol, ex.goal_a(0.5), estimator="eta" if RANK == 0 else "eta_p")
