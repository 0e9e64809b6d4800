"""Errors under MPI (issue 34): raised on one rank, raised on every rank; nothing left behind.

* :mod:`dwr_signorini.collective` on its own: the same exception, naming where it came from,
  on every rank, also an instance of the original type.
* User code and one-rank failures of the package raised on the *last* rank only (rank 1 of 2;
  serially rank 0): in this process (``-m mpi`` on 2 ranks: a hang here would be the bug), and
  as ``mpirun -n 2`` subprocesses with a timeout (``tests/mpi_scenarios.py``), where a hang is
  a failure.
* After each failure path of ``solve``, ``estimate`` and ``solve_adaptive``: PETSc's options
  database and the live PETSc objects as before the call, and the next good solve under the
  same options prefix gives the result of the good solve before.
* Faults: a 2-rank adaptive run killed by SIGTERM or SIGINT keeps every finished level in the
  CSV and JSON tables with its fields readable; the line that says why a run stopped.
"""

import csv
import gc
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
from dolfinx import io

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import io as ds_io
from dwr_signorini.collective import CollectiveError, call_collectively, on_root
from dwr_signorini.linalg import NewtonSystem
from tests.problems import strip_problem

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "tests" / "mpi_scenarios.py"
COMM = MPI.COMM_WORLD
LAST = COMM.size - 1


def fail_on_last_rank(what="user code"):
    if COMM.rank == LAST:
        raise ValueError(f"{what} fails on rank {LAST} only")


def contact_force(u, lam, m):
    return lam * m.ds_contact


def live_petsc_objects():
    """PETSc objects that are alive (not destroyed) and reachable from Python."""
    gc.collect()
    PETSc.garbage_cleanup(COMM)
    return sum(1 for o in gc.get_objects() if isinstance(o, PETSc.Object) and o.handle)


@pytest.fixture(scope="module")
def reference():
    """The displacement norm of a good solve of the strip (8 x 2)."""
    with ds.solve(strip_problem(COMM, 8, 2)) as sol:
        return sol.u.x.petsc_vec.norm()


# -- the guard on its own ---------------------------------------------------------------------


@pytest.mark.mpi
def test_error_on_one_rank_is_raised_on_every_rank():
    with pytest.raises(CollectiveError) as info:
        call_collectively(COMM, "the user's f", fail_on_last_rank, "f")
    err = info.value
    assert isinstance(err, ValueError)  # the original type, too
    assert err.where == "the user's f" and err.ranks == (LAST,)
    assert err.error_type == "ValueError" and "fails on rank" in err.error_message
    assert str(err).startswith("the user's f raised ValueError")
    assert COMM.allgather(str(err)) == [str(err)] * COMM.size  # the same on every rank
    if COMM.size > 1:
        assert f"on rank {LAST} of {COMM.size}" in str(err)
    assert (err.__cause__ is not None) == (COMM.rank == LAST)
    assert call_collectively(COMM, "g", lambda a: a + 1, 1) == 2


@pytest.mark.mpi
def test_only_the_outermost_guard_communicates():
    """A rank that fails before an inner guard, which the other rank reaches: no mismatch."""
    def outer():
        fail_on_last_rank("outer")
        return call_collectively(COMM, "inner", lambda: 1)

    with pytest.raises(ValueError, match=r"^outer raised ValueError") as info:
        call_collectively(COMM, "outer", outer)
    assert info.value.where == "outer"
    assert COMM.allreduce(1) == COMM.size  # the ranks are still in step
    assert call_collectively(COMM, "outer", lambda: call_collectively(COMM, "inner", int)) == 0


@pytest.mark.mpi
def test_an_exception_type_that_cannot_be_pickled_keeps_its_name():
    class LocalError(Exception):
        pass

    def fail():
        if COMM.rank == LAST:
            raise LocalError("local")

    with pytest.raises(CollectiveError, match="h raised LocalError") as info:
        call_collectively(COMM, "h", fail)
    assert isinstance(info.value, RuntimeError)


@pytest.mark.mpi
def test_a_failed_write_on_rank_zero_is_raised_on_every_rank(mpi_tmp_path):
    target = mpi_tmp_path / "missing_dir" / "table.csv"
    with pytest.raises(FileNotFoundError, match=r"to_csv.*raised FileNotFoundError"):
        on_root(COMM, f"to_csv({str(target)!r})", ds_io.write_csv, target, [{"a": 1}])


# -- user code and package failures on the last rank, in this process ------------------------


@pytest.mark.mpi
def test_goal_raising_on_one_rank(reference):
    def goal(u, lam, m):
        fail_on_last_rank("the goal")
        return contact_force(u, lam, m)

    with ds.solve(strip_problem(COMM, 8, 2)) as sol:
        before = PETSc.Options().getAll()
        with pytest.raises(ValueError, match="goal raised ValueError"):
            ds.estimate(sol, goal)
        assert PETSc.Options().getAll() == before
        ds.estimate(sol, contact_force).destroy()  # the solution is still usable


@pytest.mark.mpi
@pytest.mark.parametrize("name", ["E", "nu", "gap", "body_force", "dirichlet"])
def test_data_callable_raising_on_one_rank_when_assembled(name, reference):
    """The callable passes the problem's check, then raises on the last rank in the solve."""
    good = strip_problem(COMM, 8, 2)
    values = {"E": lambda x: 0 * x[0] + ex.ANALYTIC_MATERIAL.E,
              "nu": lambda x: 0 * x[0] + ex.ANALYTIC_MATERIAL.nu,
              "gap": good.gap, "body_force": lambda x: (0 * x[0], -1.0 + 0 * x[0]),
              "dirichlet": lambda x: (0 * x[0], 0 * x[0])}
    armed = []

    def later_fails(x):
        if armed:
            fail_on_last_rank(name)
        return values[name](x)

    kw = {"contact": ex.CONTACT, "dirichlet": (ex.DIRICHLET,), "E": ex.ANALYTIC_MATERIAL.E,
          "nu": ex.ANALYTIC_MATERIAL.nu, "body_force": (0.0, -1.0), "gap": good.gap}
    kw[name] = {ex.DIRICHLET: later_fails} if name == "dirichlet" else later_fails
    problem = ds.SignoriniProblem(good.mesh, good.facet_tags, **kw)
    armed.append(True)
    before, objects = PETSc.Options().getAll(), live_petsc_objects()
    with pytest.raises(ValueError, match=rf"{name}(\[1\])? raised ValueError"):
        ds.solve(problem)
    assert PETSc.Options().getAll() == before
    assert live_petsc_objects() == objects


@pytest.mark.mpi
def test_boundary_projection_raising_on_one_rank():
    """Raised when the problem is built: the projection is tried on T_H's vertices there."""
    problem = strip_problem(COMM, 8, 2)
    before = PETSc.Options().getAll()
    with pytest.raises(ValueError, match=r"boundary_projection\[2\] raised ValueError"):
        ds.SignoriniProblem(
            problem.mesh, problem.facet_tags, contact=ex.CONTACT, dirichlet=(ex.DIRICHLET,),
            body_force=(0.0, -1.0), gap=problem.gap,
            boundary_projection={ex.NEUMANN: lambda p: fail_on_last_rank("projection") or p},
        )
    assert PETSc.Options().getAll() == before


@pytest.mark.mpi
def test_callback_raising_on_one_rank_releases_the_run():
    before, objects = PETSc.Options().getAll(), live_petsc_objects()
    with pytest.raises(ValueError, match="callback raised ValueError"):
        ds.solve_adaptive(strip_problem(COMM, 8, 2), contact_force, max_levels=3,
                          verbose=False, callback=lambda *_: fail_on_last_rank("callback"))
    assert PETSc.Options().getAll() == before
    assert live_petsc_objects() == objects


@pytest.mark.mpi
def test_a_table_that_rank_zero_cannot_write(mpi_tmp_path, monkeypatch):
    def no_space(path, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ds_io, "write_json", no_space)
    before = PETSc.Options().getAll()
    with pytest.raises(OSError, match=r"writing adaptive.csv raised OSError.*No space left"):
        ds.solve_adaptive(strip_problem(COMM, 8, 2), contact_force, max_levels=2,
                          verbose=False, output_dir=mpi_tmp_path / "full")
    assert PETSc.Options().getAll() == before


@pytest.mark.mpi
def test_a_linear_solve_failing_on_one_rank_first(monkeypatch, reference):
    """A MUMPS failure that one rank reports (here: after its solve, on the last rank only)."""
    solve_active = NewtonSystem.solve_active

    def mumps_fails(self, active, free=None, couplings=None):
        solve_active(self, active, free, couplings)
        if COMM.rank == LAST:
            raise PETSc.Error(76)

    monkeypatch.setattr(NewtonSystem, "solve_active", mumps_fails)
    before, objects = PETSc.Options().getAll(), live_petsc_objects()
    with pytest.raises(ds.ConvergenceError, match=r"Newton step 0: linear solve failed"):
        ds.solve(strip_problem(COMM, 8, 2), method="block")
    assert PETSc.Options().getAll() == before
    assert live_petsc_objects() == objects


@pytest.mark.mpi
def test_a_dual_solve_failing_on_one_rank(monkeypatch):
    solve_transpose = NewtonSystem.solve_transpose

    def fails(self, rhs, z):
        solve_transpose(self, rhs, z)
        if COMM.rank == LAST:
            raise PETSc.Error(76)

    with ds.solve(strip_problem(COMM, 8, 2), method="block") as sol:
        monkeypatch.setattr(NewtonSystem, "solve_transpose", fails)
        with pytest.raises(PETSc.Error, match="the dual solve raised Error"):
            ds.estimate(sol, contact_force)


# -- nothing left behind: each failure path, then a good solve under the same prefix ----------


def _solve_fails(problem, prefix, case):
    if case == "misspelt-option":
        ds.solve(problem, {"pc_type": "lux"}, petsc_options_prefix=prefix)
    elif case == "no-convergence":
        ds.solve(problem, {"pc_type": "lu"}, max_iterations=1, petsc_options_prefix=prefix)
    elif case == "singular":  # LU without MUMPS's pivoting on the saddle-point matrix
        ds.solve(problem, {"pc_type": "lu", "pc_factor_mat_solver_type": "petsc"},
                 petsc_options_prefix=prefix)
    elif case == "schur-misspelt-option":
        ds.solve(problem, {"pc_type": "lux"}, method="schur", petsc_options_prefix=prefix)
    elif case == "schur-krylov-rejected-option":  # the CG on S_AA reads <prefix>schur_...
        PETSc.Options()[prefix + "schur_ksp_type"] = "cgg"
        try:
            ds.solve(problem, ds.linalg.iterative_petsc_options(), method="schur",
                     petsc_options_prefix=prefix)
        finally:
            del PETSc.Options()[prefix + "schur_ksp_type"]
    elif case == "estimate-higher-order":
        with ds.solve(problem, petsc_options_prefix=prefix) as sol:
            ds.estimate(sol, contact_force, weights="higher_order",
                        petsc_options={"pc_type": "lux"})
    elif case == "estimate-goal":
        with ds.solve(problem, petsc_options_prefix=prefix) as sol:
            ds.estimate(sol, lambda u, lam, m: 1 / 0)
    elif case == "adaptive-options":
        ds.solve_adaptive(problem, contact_force, max_levels=2, verbose=False,
                          petsc_options={"pc_type": "lux"})
    elif case == "adaptive-goal-at-level-1":
        levels = []

        def goal(u, lam, m):
            levels.append(1)
            if len(levels) > 1:
                raise RuntimeError("the goal fails on level 1")
            return contact_force(u, lam, m)

        ds.solve_adaptive(problem, goal, max_levels=3, verbose=False)


#: Each failure path and the error it raises.
FAILURES = {
    "misspelt-option": r"petsc_options .*PETSc rejected.*lux",
    "no-convergence": r"no convergence in max_iterations=1",
    "singular": r"Newton step 0: linear solve failed",
    "schur-misspelt-option": r"petsc_options .*PETSc rejected.*lux",
    "schur-krylov-rejected-option": r"petsc_options \(prefix '.*_schur_'\).*cgg",
    "estimate-higher-order": r"petsc_options \(prefix '.*_p2_'\).*lux",
    "estimate-goal": r"goal raised ZeroDivisionError",
    "adaptive-options": r"petsc_options .*PETSc rejected.*lux",
    "adaptive-goal-at-level-1": r"goal raised RuntimeError.*level 1",
}


@pytest.mark.mpi
@pytest.mark.parametrize(("case", "pattern"), FAILURES.items(), ids=list(FAILURES))
def test_a_failure_leaves_options_and_objects_as_before(case, pattern, reference):
    problem = strip_problem(COMM, 8, 2)
    prefix = f"issue34_{case.replace('-', '_')}_"
    before, objects = PETSc.Options().getAll(), live_petsc_objects()
    with pytest.raises((ValueError, RuntimeError, ArithmeticError), match=pattern):
        _solve_fails(problem, prefix, case)
    assert PETSc.Options().getAll() == before
    assert live_petsc_objects() == objects
    with ds.solve(problem, petsc_options_prefix=prefix) as sol:  # as in a fresh process
        assert sol.u.x.petsc_vec.norm() == pytest.approx(reference, rel=1e-12)


# -- subprocesses: 2 ranks, a failure on rank 1 only, a timeout -------------------------------


def _mpirun():
    if COMM.size > 1:
        pytest.skip("launches its own processes")
    mpirun = shutil.which("mpirun") or shutil.which("mpiexec")
    if mpirun is None:
        pytest.skip("no mpirun")
    return mpirun


def _start(args, **kwargs):
    cmd = [_mpirun(), "-n", "2", sys.executable, str(SCENARIOS), *map(str, args)]
    return subprocess.Popen(cmd, cwd=ROOT, env=dict(os.environ), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kwargs)


@pytest.mark.serial
@pytest.mark.parametrize(("where", "message"), [
    ("goal", "goal raised ValueError on rank 1 of 2: the goal fails on rank 1 only"),
    ("body_force", "body_force must be a callable x -> UFL vector with 2 components"),
    ("callback", "callback raised ValueError on rank 1 of 2: the callback fails on rank 1"),
    ("to_csv", "raised FileNotFoundError on rank 0 of 2"),
])
def test_two_ranks_error_on_rank_one_only_no_hang(where, message, tmp_path):
    proc = _start(["raise", where, tmp_path])
    try:
        out, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"mpirun -n 2 hung on an error on one rank ({where}):\n{out}\n{err}")
    assert proc.returncode == 0, f"{out}\n{err}"
    lines = sorted(line for line in out.splitlines() if line.startswith("rank "))
    assert [line[:6] for line in lines] == ["rank 0", "rank 1"], out
    assert all(message in line and "options left: []" in line for line in lines), out
    assert lines[0][len("rank 0"):] == lines[1][len("rank 1"):]  # the same error on both


# -- faults: a 2-rank run killed by a signal during a level ------------------------------------


def _rows(path):
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.serial
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_two_rank_run_killed_by_a_signal_keeps_finished_levels(sig, tmp_path):
    out = tmp_path / "killed"
    proc = _start(["run", out], start_new_session=True)
    try:
        deadline = time.monotonic() + 240
        while len(_rows(out / "adaptive.csv")) < 3:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the run wrote no three levels in 240 s"
            time.sleep(0.05)
        os.kill(proc.pid, sig)  # mpirun passes the signal on to both ranks
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode != 0  # killed, not finished
    rows = _rows(out / "adaptive.csv")
    data = json.loads((out / "adaptive.json").read_text())
    # The JSON is rewritten after each level's CSV row: a signal between the two leaves it one
    # level behind (OutputDirectory.append); every level it has is the CSV's.
    assert 3 <= len(rows) < 30 and len(data["levels"]) in (len(rows), len(rows) - 1)
    assert [int(r["level"]) for r in rows] == list(range(len(rows)))
    for row, level in zip(rows[: len(data["levels"])], data["levels"], strict=True):
        assert float(row["J_h"]) == pytest.approx(level["J_h"], rel=1e-12)
        assert int(row["num_cells"]) == level["num_cells"]
        for suffix in ("", "_contact"):  # every finished level's fields can be read back
            with io.XDMFFile(MPI.COMM_SELF, out / f"level_{level['level']:02d}{suffix}.xdmf",
                             "r") as xdmf:
                msh = xdmf.read_mesh(name="mesh")
            assert msh.topology.index_map(msh.topology.dim).size_global > 0


# -- why a run stopped, in one line -------------------------------------------------------------


@pytest.mark.mpi
def test_a_run_says_in_one_line_why_it_stopped(capsys):
    problem = strip_problem(COMM, 8, 2)
    res = ds.solve_adaptive(problem, contact_force, max_levels=2)
    assert res.stopped_by == "max_levels" and not res.converged
    capped = ds.solve_adaptive(strip_problem(COMM, 8, 2), contact_force, max_levels=5,
                               max_cells=200)
    assert capped.stopped_by == "max_cells" and len(capped.levels) == 1
    assert capped.next_cells > 200
    tol = ds.solve_adaptive(strip_problem(COMM, 8, 2), contact_force, max_levels=2, tol=1e-30)
    out = [line for line in capsys.readouterr().out.splitlines() if not line.startswith("level")]
    if COMM.rank == 0:
        assert out == [
            "stopped after 2 levels: max_levels = 2 reached; no tol given, so no convergence "
            "test",
            f"stopped after 1 level: max_cells = 200 reached (the next level would have "
            f"{capped.next_cells} cells); no tol given, so no convergence test",
            out[2],
        ]
        assert out[2].startswith("not converged: J_high - J_low = ")
        assert out[2].endswith("> 2 tol = 2.000e-30 after 2 levels: max_levels = 2 reached")
    for r in (res, capped, tol):
        r.destroy()
    assert np.isfinite(tol.levels[-1].J_h)


@pytest.mark.mpi
def test_a_failure_in_the_p2_set_up_leaves_nothing_behind(monkeypatch):
    """The hierarchical P2 solver fails after its algebra and prolongation exist: they are
    destroyed at once (not left to the garbage collector), the error reaches the caller, and
    the solution stays usable."""
    from dwr_signorini import hierarchical

    made = []

    class Recorded(hierarchical.ContactAlgebra):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    def fails(K2):
        raise RuntimeError("smoother failed")

    def goal(u, lam, m):
        return lam * m.ds_contact

    with ds.solve(strip_problem(COMM, 8, 2)) as sol:
        with ds.estimate(sol, goal, weights="patch") as est:
            good = est.eta
        monkeypatch.setattr(hierarchical, "ContactAlgebra", Recorded)
        monkeypatch.setattr(hierarchical, "_smoother", fails)
        with pytest.raises(RuntimeError, match="smoother failed"):
            ds.estimate(sol, goal, weights="hierarchical")
        assert len(made) == 1
        assert all(getattr(made[0], name) is None for name in ("K", "N", "NT", "f", "M", "g"))
        monkeypatch.undo()
        with ds.estimate(sol, goal, weights="patch") as est:
            assert est.eta == good

