"""An installed package works outside the checkout: ``pip install .`` of a copy of the sources,
imported from a directory that knows nothing of the checkout, finds the gmsh scripts its
examples and cases build their meshes from (``dwr_signorini.meshes``, the checkout's
``meshes/``)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.serial

OUTSIDE = """
import sys
from mpi4py import MPI
import dwr_signorini
from dwr_signorini import cases
from dwr_signorini.cases.load_path import MESHES
from dwr_signorini.meshes import hertz_2d

msh, cell_tags, facet_tags = cases.cattaneo_mindlin_mesh(MPI.COMM_SELF, h_contact=0.1, h=0.4)
print(dwr_signorini.__file__)
print(MESHES)
print(hertz_2d.__file__)
print(msh.topology.index_map(2).size_local, len(facet_tags.find(cases.CM_CONTACT)))
"""


def test_installed_examples_find_their_meshes(tmp_path):
    if subprocess.run([sys.executable, "-m", "pip", "--version"], capture_output=True,
                      check=False).returncode != 0:
        pytest.skip("pip is not available in this environment")
    source = tmp_path / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    for name in ("dwr_signorini", "meshes"):
        shutil.copytree(ROOT / name, source / name, symlinks=True,
                        ignore=shutil.ignore_patterns("__pycache__", "*.msh"))
    site = tmp_path / "site"
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
         "--no-index", "--no-cache-dir", "--target", str(site), str(source)],
        capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (site / "dwr_signorini" / "meshes" / "cattaneo_2d.py").is_file()
    assert not (site / "dwr_signorini" / "meshes").is_symlink()
    shutil.rmtree(source)                       # nothing may refer back to the sources
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    proc = subprocess.run([sys.executable, "-c", OUTSIDE], cwd=work, env=env,
                          capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    package, meshes, script, sizes = proc.stdout.strip().splitlines()[-4:]
    for path in (package, meshes, script):
        assert Path(path).resolve().is_relative_to(site.resolve()), path
        assert not Path(path).resolve().is_relative_to(ROOT), path
    cells, contact = map(int, sizes.split())
    assert cells > 0 and contact > 0
