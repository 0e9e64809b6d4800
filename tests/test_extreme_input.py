"""Bad input across the public API names the argument and its fix and leaves no output behind;
interrupted adaptive runs (KeyboardInterrupt, SIGKILL) keep every finished level."""

import csv
import json
import os
import signal
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import io, mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

from .problems import TRI, block

DIRICHLET, NEUMANN, CONTACT = ex.DIRICHLET, ex.NEUMANN, ex.CONTACT


# --------------------------------------------------------------------------------------------------
# 6. Bad input across the public API
# --------------------------------------------------------------------------------------------------


def _bad_problem_args(msh, tags):
    _, other_tags = block(MPI.COMM_WORLD, 2, 2)
    cells = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
    return [
        ("contact-tag-missing", {"contact": 7}, ValueError, r"contact tag 7.*tags present"),
        ("dirichlet-tag-missing", {"dirichlet": (9,)}, ValueError, r"dirichlet tag 9"),
        ("no-dirichlet", {"dirichlet": ()}, ValueError, r"dirichlet.*at least one"),
        ("tags-not-meshtags", {"facet_tags": np.array([1, 2])}, TypeError, r"facet_tags"),
        (
            "cell-tags",
            {"facet_tags": mesh.meshtags(msh, 2, cells, np.full_like(cells, 3))},
            ValueError,
            r"facet_tags.*cell tags",
        ),
        ("other-mesh-tags", {"facet_tags": other_tags}, ValueError, r"facet_tags.*another mesh"),
        ("mesh-not-mesh", {"mesh": "mesh.msh"}, TypeError, r"mesh must be a dolfinx"),
        ("nu-half", {"nu": 0.5}, ValueError, r"nu.*incompressible.*0\.499"),
        ("E-zero", {"E": 0.0}, ValueError, r"E \(Young's modulus\).*> 0"),
        ("E-string", {"E": "210e9"}, TypeError, r"E must be a real number"),
        ("gap-nan", {"gap": float("nan")}, ValueError, r"gap must be finite"),
        ("gap-vector", {"gap": lambda x: x}, ValueError, r"gap must return a UFL scalar"),
        ("gap-numpy", {"gap": lambda x: np.sin(x[0])}, TypeError, r"gap.*ufl functions"),
        ("body-force-shape", {"body_force": lambda x: x[0]}, ValueError, r"body_force.*vector"),
        ("model-unknown", {"model": "axisymmetric"}, ValueError, r"model must be one of"),
        ("traction-not-dict", {"traction": [(0.0, 1.0)]}, TypeError, r"traction must be a dict"),
        ("contact-float", {"contact": 3.0}, TypeError, r"contact must be an integer"),
    ]


def test_bad_problem_input_names_argument_and_fix():
    msh, tags = block(MPI.COMM_WORLD, 4, 4)
    cases = _bad_problem_args(msh, tags)
    assert len(cases) >= 15
    for _name, change, error, match in cases:
        args = {"mesh": msh, "facet_tags": tags, "contact": CONTACT, "dirichlet": (DIRICHLET,)}
        args.update(change)
        with pytest.raises(error, match=match):
            ds.SignoriniProblem(**args)


@pytest.fixture(scope="module")
def small_problem():
    return ex.analytic_problem(MPI.COMM_WORLD, 6, 4, TRI)


def test_bad_solve_and_estimate_input(small_problem):
    for kwargs, error, match in [
        ({"max_iterations": 0}, ValueError, "max_iterations"),
        ({"rtol": -1.0}, ValueError, "rtol"),
        ({"ncp_scale": 0.0}, ValueError, "ncp_scale"),
        ({"ncp_scale": "paper"}, ValueError, "ncp_scale"),
        ({"petsc_options": [("pc_type", "lu")]}, TypeError, "petsc_options must be a dict"),
        ({"initial_guess": (1.0,)}, TypeError, "initial_guess"),
    ]:
        with pytest.raises(error, match=match):
            ds.solve(small_problem, **kwargs)
    sol = ds.solve(small_problem)
    goal = ex.goal_a(-0.5)
    other = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    for args, kwargs, error, match in [
        ((goal,), {"estimator": "eta_d"}, ValueError, "estimator must be one of"),
        ((goal,), {"weights": "p2"}, ValueError, "weights must be one of"),
        ((lambda u, lam, m: ufl.inner(u, u),), {}, TypeError, "must return a UFL form"),
        (
            (lambda u, lam, m: ufl.inner(u, u) * ufl.dx(domain=other),),
            {},
            ValueError,
            "another mesh",
        ),
    ]:
        with pytest.raises(error, match=match):
            ds.estimate(sol, *args, **kwargs)


ADAPTIVE_BAD = [
    pytest.param({"fraction": -0.1}, ValueError, "fraction", id="negative-fraction"),
    pytest.param({"fraction": 1.5}, ValueError, "fraction", id="fraction-above-one"),
    pytest.param({"max_levels": 0}, ValueError, "max_levels", id="max-levels-zero"),
    pytest.param({"strategy": "maximum"}, ValueError, "strategy must be", id="unknown-strategy"),
    pytest.param(
        {"refinement": "red-green"}, ValueError, "refinement must be", id="unknown-refinement"
    ),
    pytest.param({"estimator": "eta_s"}, ValueError, "estimator must be", id="unknown-estimator"),
    pytest.param({"weights": "p3"}, ValueError, "weights must be", id="unknown-weights"),
    pytest.param({"goal": 1.0}, TypeError, "goal must be a callable", id="goal-not-callable"),
    pytest.param({"exact": float("nan")}, ValueError, "exact", id="exact-nan"),
    pytest.param({"output_dir": "FILE"}, ValueError, "output_dir", id="output-dir-is-a-file"),
    pytest.param(
        {"output_dir": "FILE/out"}, ValueError, "output_dir", id="output-dir-under-a-file"
    ),
    pytest.param(
        {"goal": lambda u, lam, m: 1.0},
        TypeError,
        "UFL form",
        id="goal-not-a-form",
    ),
    pytest.param(
        {"goal": "OTHER_MESH"},
        ValueError,
        "another mesh",
        id="goal-other-mesh",
    ),
]


@pytest.mark.mpi
@pytest.mark.parametrize(("change", "error", "match"), ADAPTIVE_BAD)
def test_bad_adaptive_input_leaves_no_output_dir(small_problem, mpi_tmp_path, change, error, match):
    """solve_adaptive rejects bad input naming the argument, and the output directory it was
    given does not exist afterwards (nothing half-written)."""
    out = mpi_tmp_path / "run"
    afile = mpi_tmp_path / "a_file"
    if MPI.COMM_WORLD.rank == 0:
        afile.write_text("not a directory\n")
    MPI.COMM_WORLD.Barrier()
    kwargs = {"goal": ex.goal_a(-0.5), "max_levels": 2, "output_dir": out, "verbose": False}
    kwargs.update(change)
    if kwargs["output_dir"] == "FILE":
        kwargs["output_dir"] = out = afile
    elif kwargs["output_dir"] == "FILE/out":
        kwargs["output_dir"] = out = afile / "out"
    if kwargs["goal"] == "OTHER_MESH":
        other = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
        kwargs["goal"] = lambda u, lam, m: ufl.inner(u, u) * ufl.dx(domain=other)
    with pytest.raises(error, match=match):
        ds.solve_adaptive(small_problem, **kwargs)
    MPI.COMM_WORLD.Barrier()
    if out == afile:
        assert afile.read_text() == "not a directory\n"
    else:
        assert not out.exists()


# --------------------------------------------------------------------------------------------------
# 7. Interrupted adaptive runs keep every finished level
# --------------------------------------------------------------------------------------------------


def check_finished_levels(out, num_levels):
    """CSV and JSON rows of levels 0 .. num_levels-1 complete and consistent; their XDMF/HDF5
    fields exist and their meshes read back with the recorded number of cells."""
    with open(out / "adaptive.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(out / "adaptive.json") as fh:
        table = json.load(fh)
    assert len(rows) >= num_levels and len(table["levels"]) >= num_levels
    for k in range(num_levels):
        row, record = rows[k], table["levels"][k]
        assert int(row["level"]) == record["level"] == k
        required = ("num_cells", "num_contact_elements", "J_h", "eta_p", "eta", "estimate")
        assert all(row[key] != "" for key in required), row
        assert float(row["J_h"]) == record["J_h"]
        for suffix, cells in (("", "num_cells"), ("_contact", "num_contact_elements")):
            xdmf = out / f"level_{k:02d}{suffix}.xdmf"
            assert xdmf.exists() and xdmf.with_suffix(".h5").exists()
            grids = ET.parse(xdmf).getroot().iter("Grid")
            name = next(g.get("Name") for g in grids if g.find("Topology") is not None)
            with io.XDMFFile(MPI.COMM_SELF, xdmf, "r") as fh:
                msh = fh.read_mesh(name=name)
            assert msh.topology.index_map(msh.topology.dim).size_global == int(row[cells])
    return rows, table


@pytest.mark.mpi
def test_keyboard_interrupt_keeps_finished_levels(small_problem, mpi_tmp_path):
    """Ctrl-C (KeyboardInterrupt from the callback after level 1) propagates, and the rows and
    fields of levels 0 and 1 are intact and readable."""
    out = mpi_tmp_path / "interrupted"

    def callback(record, sol, est):
        if record.level == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        ds.solve_adaptive(
            small_problem,
            ex.goal_a(-0.5),
            max_levels=5,
            output_dir=out,
            callback=callback,
            verbose=False,
        )
    MPI.COMM_WORLD.Barrier()
    if MPI.COMM_WORLD.rank == 0:
        rows, table = check_finished_levels(out, 2)
        assert len(rows) == len(table["levels"]) == 2
    MPI.COMM_WORLD.Barrier()


_KILLED_RUN = textwrap.dedent(
    """
    import sys
    from mpi4py import MPI
    import dwr_signorini as ds
    from dwr_signorini import examples as ex

    problem = ex.analytic_problem(MPI.COMM_WORLD, 6, 4, ex.CellType.triangle)
    ds.solve_adaptive(problem, ex.goal_a(-0.5), max_levels=12, output_dir=sys.argv[1])
    """
)


@pytest.mark.serial
def test_sigkill_keeps_finished_levels(tmp_path):
    """A run killed with SIGKILL right after it printed level 1's progress line: the rows and
    fields of levels 0 and 1 are intact (CSV appended and fsynced per level, JSON replaced
    atomically, one XDMF/HDF5 pair per level and field set)."""
    script = tmp_path / "run.py"
    script.write_text(_KILLED_RUN)
    out = tmp_path / "killed"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_COMM_WORLD", "PMIX"))}
    proc = subprocess.Popen(
        [sys.executable, str(script), str(out)], stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        for line in proc.stdout:
            if line.startswith("level  1"):
                os.kill(proc.pid, signal.SIGKILL)
                break
    finally:
        proc.stdout.close()
        returncode = proc.wait(timeout=120)
    assert returncode == -signal.SIGKILL, "the run ended before it could be killed"
    check_finished_levels(out, 2)
