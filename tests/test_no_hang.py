"""A mistake in a call that frees problems raises and exits instead of hanging (issue 48).

``ds.solve_path([make(d) for d in loads])`` with the goal forgotten raises a TypeError while the
list of problems, and with it the last reference to each mesh, dies. The problems' checks and
solves must leave no mpi4py state on the meshes' communicators: its delete callback, run by the
C++ destructor while the exception propagates, used to fail and leave the process waiting on a
lock for ever (:func:`dwr_signorini.collective.shadow`). The call runs in a subprocess, serially
and on 2 ranks, with a timeout, so a regression fails the test instead of hanging the suite.
"""

import os
import shutil
import signal
import subprocess
import sys
import textwrap

from mpi4py import MPI

import pytest

pytestmark = [
    pytest.mark.serial,
    pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="launches its own processes"),
]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

SCRIPT = textwrap.dedent("""
    import sys

    from mpi4py import MPI

    from dolfinx import mesh

    import dwr_signorini as ds
    from dwr_signorini import examples as ex


    def make(d):
        msh = mesh.create_rectangle(MPI.COMM_WORLD, [(0.0, 0.0), (4.0, 1.0)], [8, 2],
                                    ghost_mode=mesh.GhostMode.none)
        problem = ds.SignoriniProblem(msh, ex.tag_block_facets(msh, 1.0),
                                      contact=ex.CONTACT, dirichlet={ex.DIRICHLET: (0.0, -d)},
                                      gap=0.0)
        if sys.argv[1] == "solved":  # the solve's reductions ran on the processes of the mesh
            ds.solve(problem).destroy()
        return problem


    def main():
        ds.solve_path([make(d) for d in (0.01, 0.02)])


    try:
        main()
    except TypeError as err:
        sys.stdout.write(f"raised: {err}\\n")  # one write: the ranks' lines do not interleave
        sys.stdout.flush()
    else:
        print("no error", flush=True)
    main()
""")


def _run(tmp_path, nprocs, variant):
    script = tmp_path / "forgotten_goal.py"
    script.write_text(SCRIPT)
    cmd = [sys.executable, str(script), variant]
    if nprocs > 1:
        mpirun = shutil.which("mpirun") or shutil.which("mpiexec")
        if mpirun is None:
            pytest.skip("no mpirun")
        cmd = [mpirun, "-n", str(nprocs), *cmd]
    env = {**os.environ, "PYTHONPATH": ROOT + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, cwd=ROOT, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # mpirun and its ranks: nothing is left waiting
        out, err = proc.communicate()
        pytest.fail(f"the call hangs on {nprocs} rank(s): {out!r} {err!r}")
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


@pytest.mark.parametrize("variant", ["built", "solved"])
@pytest.mark.parametrize("nprocs", [1, 2])
def test_forgotten_goal_raises_and_exits(tmp_path, nprocs, variant):
    """Caught, the TypeError is printed and the script goes on; uncaught, the process exits with
    status 1 and its traceback (on every rank), and mpi4py reports no failed callback. The
    problems are only built, or also solved once (their solutions destroyed)."""
    proc = _run(tmp_path, nprocs, variant)
    out, err = proc.stdout, proc.stderr
    assert out.count("raised: solve_path() missing 1 required positional argument: 'goal'") \
        == nprocs, out + err
    assert proc.returncode != 0
    assert err.count("TypeError: solve_path() missing 1 required positional argument") \
        == nprocs, err
    assert "commlock" not in err and "SystemError" not in err, err
