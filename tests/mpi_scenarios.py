"""Scenarios that tests/test_collective.py runs as ``mpirun -n 2 python3 tests/mpi_scenarios.py``.

A test that only one rank fails cannot run inside ``mpirun ... -m pytest``: if the package let
the other rank wait in a collective, the test run would hang. Run as subprocesses with a
timeout, a hang is a failure instead.

``python3 tests/mpi_scenarios.py raise <where>``: user code (or a rank-0 write) raises on the
last rank only; every rank prints one line ``rank <r>: <type>: <message>`` for the exception it
got (or ``rank <r>: no exception``) and the options left in PETSc's database.

``python3 tests/mpi_scenarios.py run <output_dir>``: an adaptive run of many levels into
``output_dir``, for a test to interrupt with a signal.
"""

import sys
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import dwr_signorini as ds
from dwr_signorini import examples as ex
from tests.problems import strip_problem

COMM = MPI.COMM_WORLD
LAST = COMM.size - 1


def fail_here(what):
    if COMM.rank == LAST:
        raise ValueError(f"{what} fails on rank {LAST} only")


def goal(u, lam, m):
    fail_here("the goal")
    return lam * m.ds_contact


def body_force(x):
    fail_here("the body force")
    return (0.0 * x[0], -1.0 + 0.0 * x[0])


def raise_in(where, tmp):
    """Make ``where`` fail on the last rank only."""
    problem = strip_problem(COMM, 8, 2)
    if where == "goal":
        with ds.solve(problem) as sol:
            ds.estimate(sol, goal)
    elif where == "body_force":
        kw = {"contact": ex.CONTACT, "dirichlet": (ex.DIRICHLET,), "body_force": body_force}
        ds.SignoriniProblem(problem.mesh, problem.facet_tags, **kw)
    elif where == "callback":
        ds.solve_adaptive(problem, lambda u, lam, m: lam * m.ds_contact, max_levels=2,
                          verbose=False, callback=lambda *_: fail_here("the callback"))
    elif where == "to_csv":
        with ds.solve_adaptive(problem, lambda u, lam, m: lam * m.ds_contact, max_levels=1,
                               verbose=False) as result:
            result.to_csv(Path(tmp) / "no" / "such" / "directory" / "table.csv")


def main():
    mode, arg = sys.argv[1], sys.argv[2]
    if mode == "run":
        problem = ex.bar_problem(COMM, 4, 16)
        ds.solve_adaptive(problem, ex.goal_bar(), max_levels=30, output_dir=arg, verbose=True)
        return
    tmp = sys.argv[3] if len(sys.argv) > 3 else "."
    before = PETSc.Options().getAll()
    try:
        raise_in(arg, tmp)
        line = "no exception"
    except Exception as err:
        line = f"{type(err).__name__}: {err}".replace("\n", " | ")
    left = sorted(set(PETSc.Options().getAll()) - set(before))
    # One write of the whole line: print's separate write of the newline let mpirun forward
    # the two ranks' lines run together ("... []rank 0: ...").
    sys.stdout.write(f"rank {COMM.rank}: {line} || options left: {left}\n")
    sys.stdout.flush()
    np.testing.assert_equal(left, [])


if __name__ == "__main__":
    main()
