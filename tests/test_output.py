"""Output users open (issue 58, item 6): stress fields, time series, VTX, a solve's log line.

* ``ds.stress_fields``: a block pressed uniformly by p on a rigid flat, free to expand sideways
  (a roller on one side), carries the uniform stress sigma_yy = -p (sigma_zz = -p in 3D), which
  P1 displacements contain: the DG0 Cauchy stress equals it to round-off, and the von Mises
  stress is p sqrt(1 - nu + nu^2) in plane strain (sigma_zz = -nu p), p in plane stress and 3D.
* A load path with ``output_dir`` is one time series, ``path.xdmf`` / ``path_contact.xdmf``,
  Time = 0, 1, 2 for the three steps, u, lambda, sigma and von Mises in it; an adaptive path adds
  each refined mesh to the file and refers each step's fields to its own mesh. An adaptive
  run's levels hold sigma and von Mises too. Where dolfinx has ADIOS2 the VTX files exist.
* ``ds.solve`` logs one INFO line on rank 0 (``dwr_signorini.newton``).
"""

import logging
import math
import xml.etree.ElementTree as ET

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import compat
from dwr_signorini import examples as ex
from tests.problems import tag_by_midpoint, top_clamped_tags

pytestmark = pytest.mark.mpi

COMM = MPI.COMM_WORLD
BOTTOM, SIDES, TOP, LEFT = 1, 2, 4, 5
E, NU, P = 10.0, 0.3, 0.2


def _tags(msh):
    """LEFT at x = 0, BOTTOM at height 0, TOP at height 1, SIDES elsewhere."""
    up = msh.geometry.dim - 1
    return tag_by_midpoint(msh, SIDES, ((LEFT, lambda x: np.isclose(x[0], 0.0)),
                                        (BOTTOM, lambda x: np.isclose(x[up], 0.0)),
                                        (TOP, lambda x: np.isclose(x[up], 1.0))))


def pressed(model):
    """The unit square (cube) pressed by p on top, on the plane y = 0 (z = 0), a roller x = 0."""
    if model == "3d":
        msh = mesh.create_unit_cube(COMM, 2, 2, 2, ghost_mode=mesh.GhostMode.none)
        # the y-motion held on the side y = 0 as well (a roller there): SIDES carries it
        dirichlet = {LEFT: (0.0, None, None)}
        load = {TOP: (0.0, 0.0, -P)}
    else:
        msh = mesh.create_unit_square(COMM, 3, 3, ghost_mode=mesh.GhostMode.none)
        dirichlet, load = {LEFT: (0.0, None)}, {TOP: (0.0, -P)}
    tags = _tags(msh)
    if model == "3d":  # the face y = 0: a roller u_y = 0 (tag 6)
        fdim = msh.topology.dim - 1
        mid = mesh.compute_midpoints(msh, fdim, tags.indices)
        values = tags.values.copy()
        values[np.isclose(mid[:, 1], 0.0) & (values == SIDES)] = 6
        tags = mesh.meshtags(msh, fdim, tags.indices, values)
        dirichlet[6] = (None, 0.0, None)
    problem = ds.SignoriniProblem(msh, tags, contact=BOTTOM, dirichlet=dirichlet, E=E, nu=NU,
                                  model=model, traction=load, gap=0.0)
    disc = ds.discretize(problem)
    lam0 = fem.Function(disc.Q)
    lam0.x.array[:] = 1.0  # only the contact holds the block up
    return ds.solve(disc, initial_guess=(fem.Function(disc.V), lam0))


@pytest.mark.parametrize("model, factor", [
    ("plane_strain", math.sqrt(1 - NU + NU**2)), ("plane_stress", 1.0), ("3d", 1.0)])
def test_stress_of_a_uniformly_pressed_block(model, factor):
    with pressed(model) as sol:
        sigma, vm = ds.stress_fields(sol)
        gdim = sol.disc.mesh.geometry.dim
        exact = np.zeros((gdim, gdim))
        exact[-1, -1] = -P
        values = sigma.x.array.reshape(-1, gdim, gdim)
        assert values.shape[0] > 0 or COMM.size > 1
        assert np.max(np.abs(values - exact), initial=0.0) <= 1e-10 * P
        assert np.max(np.abs(vm.x.array - factor * P), initial=0.0) <= 1e-10 * P
        assert sigma.name == "sigma" and vm.name == "von_mises"


def _times(path, grid):
    """The Time values of the temporal collection ``grid`` of an XDMF file, and their meshes."""
    root = ET.parse(path).getroot()
    for collection in root.iter("Grid"):
        if collection.get("Name") == grid and collection.get("GridType") == "Collection":
            out = []
            for g in collection.findall("Grid"):
                include = next(c for c in g if c.tag.endswith("include"))  # xi:include
                out.append((float(g.find("Time").get("Value")), include.get("xpointer")))
            return out
    raise AssertionError(f"no time series {grid} in {path}")


def _bp_steps(path):
    """The number of steps of a BP4 file: its index md.idx has a 64-byte header and 64 bytes
    per step (ADIOS2's BP4 format)."""
    return ((path / "md.idx").stat().st_size - 64) // 64


def _strip(comm, nx=8):
    msh = mesh.create_rectangle(comm, [(0.0, 0.0), (2.0, 1.0)], [nx, 4],
                                ghost_mode=mesh.GhostMode.none)
    return msh, top_clamped_tags(msh, 1.0)


def _path(depths):
    msh, tags = _strip(COMM)
    return [ds.SignoriniProblem(msh, tags, contact=ex.CONTACT,
                                dirichlet={ex.DIRICHLET: (0.0, -d)}, E=E, nu=NU, gap=0.0)
            for d in depths]


def _force(u, lam, m):
    return lam * m.ds_contact


@pytest.mark.parametrize("adaptive", [False, True])
def test_load_path_is_one_time_series(mpi_tmp_path, adaptive):
    out = mpi_tmp_path / f"adaptive_{adaptive}"
    with ds.solve_path(_path([0.01, 0.02, 0.03]), _force, adaptive=adaptive, output_dir=out,
                       verbose=False, history=False):
        pass
    COMM.barrier()
    assert not list(out.glob("level_*"))
    for name in ("u", "sigma", "von_mises", "indicators"):
        series = _times(out / "path.xdmf", name)
        assert [t for t, _ in series] == [0.0, 1.0, 2.0]
    contact = _times(out / "path_contact.xdmf", "lambda")
    assert [t for t, _ in contact] == [0.0, 1.0, 2.0]
    meshes = [m for _, m in _times(out / "path.xdmf", "u")]
    if adaptive:  # every step on its refined mesh, each written once
        assert [m.split("'")[1] for m in meshes] == ["mesh", "mesh_1", "mesh_2"]
    else:
        assert len(set(meshes)) == 1
    if compat.has_vtx():
        if adaptive:  # a new file from each refined mesh on
            names = ["path_p1.bp", "path_p1_01.bp", "path_p1_02.bp", "path_contact_dg0_02.bp"]
            steps = [1, 1, 1, 1]
        else:  # one file per element, the three steps in it
            names = ["path_p1.bp", "path_dg0.bp", "path_contact_dg0.bp"]
            steps = [3, 3, 3]
        assert [_bp_steps(out / n) for n in names] == steps


def test_adaptive_levels_hold_the_stress(mpi_tmp_path):
    msh, tags = _strip(COMM)
    problem = ds.SignoriniProblem(msh, tags, contact=ex.CONTACT,
                                  dirichlet={ex.DIRICHLET: (0.0, -0.02)}, E=E, nu=NU, gap=0.0)
    with ds.solve_adaptive(problem, _force, max_levels=2, output_dir=mpi_tmp_path,
                           verbose=False):
        pass
    COMM.barrier()
    for level in (0, 1):
        for name in ("u", "sigma", "von_mises"):
            assert _times(mpi_tmp_path / f"level_{level:02d}.xdmf", name) == [
                (float(level), "xpointer(/Xdmf/Domain/Grid[@Name='mesh'][1]/*[self::Topology"
                 " or self::Geometry])")]
    if compat.has_vtx():
        assert (mpi_tmp_path / "level_01_p1.bp").is_dir()


def test_solve_logs_one_line(caplog):
    msh, tags = _strip(COMM, 4)
    problem = ds.SignoriniProblem(msh, tags, contact=ex.CONTACT,
                                  dirichlet={ex.DIRICHLET: (0.0, -0.02)}, E=E, nu=NU, gap=0.0)
    with caplog.at_level(logging.INFO, logger="dwr_signorini.newton"):
        with ds.solve(problem) as sol:
            steps = sol.newton_iterations
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("solve: ")]
    if COMM.rank == 0:
        assert len(lines) == 1 and f"{steps} Newton steps" in lines[0], lines
    else:
        assert lines == []
