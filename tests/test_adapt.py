"""Acceptance tests of the adaptive loop ``solve_adaptive`` (paper Sections 5.2 and 5.3).

Truth used here is independent of the code under test:

* the location of the singularities of Example 5.2 (the corners where the clamped edge meets the
  free edges, and the end of the active contact zone read off the active set) and of the boundary
  of the contact zone of Example 5.3 (read off the active set);
* the paper's reference value J_ref of Example 5.2 (extrapolated by the authors from another code),
  with an uncertainty that covers its known bias: the paper remarks that its last errors look too
  small because of J_ref, and ``benchmarks/bar_reference.py`` puts J about 7e-6 (relative) above
  it, so 2e-5 is used. Only levels whose error is >= 10 times that are compared with it.
  One test also compares with our own reference, ``benchmarks/results/bar_reference.json``
  (written by ``benchmarks/bar_reference.py`` from runs up to 2M cells; skipped if missing);
* theory: the optimal adaptive rate N^-1 of P1 elements in 2D, and a slower uniform rate (the
  corner singularities); the definitions of fixed-fraction and Doerfler marking, recomputed here
  from the patch indicators, and the patches recomputed geometrically;
* invariants (uniform refinement multiplies the cells by 2^d, the stopping rules, files equal to
  the records) and serial against parallel runs.

Run ``-m mpi`` under ``mpirun -n 2 python3 -m mpi4py -m pytest`` for the parallel checks.
"""

import csv
import json
import math
import os
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import geometry, io, mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.linalg import iterative_petsc_options
from dwr_signorini.marking import mark, patch_indicators
from dwr_signorini.spaces import refine_marked

from . import fem_compat
from .problems import estimate_rel

TRI, QUAD = mesh.CellType.triangle, mesh.CellType.quadrilateral
TET, HEX = mesh.CellType.tetrahedron, mesh.CellType.hexahedron

#: The paper's reference value of Example 5.2 and the uncertainty we grant it (see docstring).
J_PAPER = ex.BAR_J_REF
U_PAPER = 2.0e-5 * J_PAPER
#: Our own reference (written by benchmarks/bar_reference.py; the test using it skips without).
OWN_REFERENCE = Path(__file__).resolve().parents[1] / "benchmarks/results/bar_reference.json"

#: Singular points of Example 5.2: the two ends of the clamped edge y = 0.
CORNERS = np.array([[0.0, 0.0], [0.05, 0.0]])
#: Levels 0-2 are pre-asymptotic (the paper's Table 3 has Ieff 1.96 and 1.39 there).
FIRST_ASYMPTOTIC_LEVEL = 3


# --------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------


def bar_problem(comm=MPI.COMM_WORLD, nx=4, ny=16, cell_type=TRI):
    """Example 5.2: the bar, plane stress, pushed towards the obstacle by a volume force."""
    return ex.bar_problem(comm, nx, ny, cell_type)


def obstacle_problem(comm=MPI.COMM_WORLD, n=(1, 4, 4), cell_type=TET):
    """Example 5.3 on a coarse box; on the fine mesh (one uniform refinement) B is resolved."""
    return ex.obstacle_problem(comm, n, cell_type)


def allgather(comm, values):
    """Concatenation of the local arrays of all ranks (on every rank)."""
    return np.concatenate([np.asarray(v) for v in comm.allgather(np.asarray(values))])


def owned_cells(msh):
    return np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)


def cell_midpoints(msh):
    return mesh.compute_midpoints(msh, msh.topology.dim, owned_cells(msh))


def triangle_areas(msh):
    """Areas of the owned triangles from their vertex coordinates."""
    nodes = mesh.entities_to_geometry(msh, 2, owned_cells(msh), False)
    x = msh.geometry.x[nodes][:, :, :2]
    a, b = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    return 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def contact_facets(sol):
    """Vertex coordinates of the owned macro contact facets and whether each is active."""
    sub = sol.disc.contact_mesh
    dim = sub.topology.dim
    n = sub.topology.index_map(dim).size_local
    active = np.asarray(sol.active[:n], dtype=bool)
    if n == 0:  # a rank without contact facets (entities_to_geometry would fail on it)
        return np.zeros((0, dim + 1, 3)), active
    nodes = mesh.entities_to_geometry(sub, dim, np.arange(n, dtype=np.int32), False)
    return sub.geometry.x[nodes], active


def contact_transition_y(sol):
    """y of the end of the active contact zone of Example 5.2: the lowest active contact point."""
    x, active = contact_facets(sol)
    low = x[active][:, :, 1].min(axis=1) if active.any() else np.zeros(0)
    values = allgather(sol.disc.comm, low)
    assert values.size > 0, "no active contact facet: the bar does not touch the obstacle"
    return float(values.min())


def bar_singular_points(sol):
    """The two corners of the clamped edge and the end of the active contact zone."""
    return np.vstack([CORNERS, [[0.05, contact_transition_y(sol)]]])


def distance_to(points, x):
    """Distance of every row of x (2D coordinates) to the nearest of ``points``."""
    return np.min(np.linalg.norm(x[:, None, :2] - points[None, :, :2], axis=2), axis=1)


def fitted_slope(N, E):
    """Least-squares slope of log E against log N."""
    return float(np.polyfit(np.log(np.asarray(N, float)), np.log(np.asarray(E, float)), 1)[0])


def errors_against(levels, J, U):
    """(level, N, E_rel, Ieff) of the levels whose error is at least 10 times the uncertainty U."""
    out = []
    for r in levels:
        err = J - r.J_h
        if abs(err) >= 10.0 * U:
            out.append((r.level, r.num_cells, abs(err) / abs(J), err / r.eta))
    return out


def read_csv_rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def assert_on_all_ranks(comm, ok, what=""):
    """Assert a rank-local condition everywhere, so that no rank is left alone in a collective."""
    oks = comm.allgather(bool(ok))
    assert all(oks), (what, oks)


def row_mismatches(row, record, timings=True):
    """Keys where a CSV row (strings) or JSON row differs from the record, float for float.

    Timings are measured on each rank and the files hold rank 0's: compare them there only.
    """
    bad = []
    for key, value in record.as_dict().items():
        if isinstance(value, dict):
            for sub, v in value.items():
                got = row[f"{key}_{sub}"] if f"{key}_{sub}" in row else row[key][sub]
                if timings and float(got) != v:
                    bad.append(f"{key}_{sub}")
        elif value is None:
            if row[key] not in (None, ""):
                bad.append(key)
        elif isinstance(value, (str, bool)):  # CSV holds str(value), JSON the value
            if row[key] not in (value, str(value)):
                bad.append(key)
        elif isinstance(value, int):
            if int(row[key]) != value:
                bad.append(key)
        elif float(row[key]) != value:
            bad.append(key)
    return bad


def assert_rows_match(comm, rows, records):
    bad = [row_mismatches(row, rec, timings=comm.rank == 0) for row, rec in zip(rows, records,
                                                                                strict=True)]
    assert_on_all_ranks(comm, not any(bad), bad)


# --------------------------------------------------------------------------------------------------
# Shared runs (module scope: computed once, also under mpirun)
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def adaptive_bar():
    """9 adaptive levels of Example 5.2 (512 ... ~140k cells), as in the paper's Table 3.

    The callback records, per level, the singular points and the global position of the macro
    cell with the largest |patch indicator|.
    """
    comm = MPI.COMM_WORLD
    per_level = []

    def callback(record, sol, est):
        disc = sol.disc
        eta_K = patch_indicators(disc, est.indicators.x.array)
        mids = mesh.compute_midpoints(disc.macro_mesh, 2, np.arange(len(eta_K), dtype=np.int32))
        all_eta = allgather(comm, np.abs(eta_K))
        all_mid = allgather(comm, mids[:, :2]).reshape(-1, 2)
        per_level.append({"points": bar_singular_points(sol),
                          "largest": all_mid[np.argmax(all_eta)]})

    res = ds.solve_adaptive(bar_problem(comm), ex.goal_bar(), refinement="adaptive", fraction=0.2,
                            max_levels=9, exact=J_PAPER, callback=callback, verbose=False)
    return res, per_level


@pytest.fixture(scope="module")
def uniform_bar():
    """5 uniform levels of Example 5.2 (512 ... 131072 cells)."""
    return ds.solve_adaptive(bar_problem(), ex.goal_bar(), refinement="uniform", max_levels=5,
                             exact=J_PAPER, verbose=False)


# --------------------------------------------------------------------------------------------------
# Example 5.2: where the refinement goes, rates, effectivity
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_bar_largest_indicator_sits_at_a_singularity(adaptive_bar):
    """On every level the patch with the largest |indicator| is at a corner or the contact end."""
    _, per_level = adaptive_bar
    for level, info in enumerate(per_level):
        d = distance_to(info["points"], info["largest"][None, :])[0]
        assert d < 0.01, (level, info)


@pytest.mark.mpi
def test_bar_refinement_concentrates_at_corners_and_contact_end(adaptive_bar):
    """Final mesh: smallest cells at the corners, dense cells at all three singular points."""
    res, _ = adaptive_bar
    sol = res.solution
    comm = sol.disc.comm
    fine = sol.disc.mesh
    mid = allgather(comm, cell_midpoints(fine)[:, :2]).reshape(-1, 2)
    h = allgather(comm, fine.h(2, owned_cells(fine)))
    area = allgather(comm, triangle_areas(fine))
    assert area.sum() == pytest.approx(0.05 * 0.2, rel=1e-12)
    points = bar_singular_points(sol)
    assert 0.15 < points[2, 1] < 0.2  # the contact zone ends inside Gamma_C

    # The smallest cells lie at the two corners of the clamped edge.
    smallest = h <= 2.0 * h.min()
    assert distance_to(CORNERS, mid[smallest]).max() < 0.005

    # Cells near each singular point are much denser and smaller than far from all of them
    # (away from y = 0.05 too, the edge of the goal region B, which is also refined).
    dist = distance_to(points, mid)
    far = (dist > 0.03) & (np.abs(mid[:, 1] - 0.05) > 0.01)
    far_density = far.sum() / area[far].sum()
    h0 = np.hypot(0.05 / 8, 0.2 / 32)  # diameter of the initial fine cells
    for p in points:
        near = np.linalg.norm(mid - p, axis=1) < 0.0025
        assert near.sum() / area[near].sum() > 5.0 * far_density, p
        assert np.median(h[near]) < 0.5 * np.median(h[far]), p
        assert h[near].min() < h0 / 8, p  # refined at least three times

    # On Gamma_C the shortest facets are at the end of the active zone, not inside it.
    x, active = contact_facets(sol)
    y = allgather(comm, x[:, :, 1].mean(axis=1))
    length = allgather(comm, np.abs(x[:, 1, 1] - x[:, 0, 1]))
    at_end = np.abs(y - points[2, 1]) < 0.0025
    inside = allgather(comm, active) & (y > points[2, 1] + 0.02)
    assert at_end.any() and inside.any()
    assert length[at_end].min() < 0.5 * length[inside].min()


def test_bar_adaptive_error_decays_like_one_over_n(adaptive_bar, uniform_bar):
    """Adaptive: E_rel ~ N^-1 (optimal for P1); uniform: slower, and worse at equal cost."""
    res, _ = adaptive_bar
    ok = errors_against(res.levels, J_PAPER, U_PAPER)
    ok = [e for e in ok if e[0] >= FIRST_ASYMPTOTIC_LEVEL][-4:]
    assert len(ok) >= 3, ok
    slope = fitted_slope([e[1] for e in ok], [e[2] for e in ok])
    assert abs(slope + 1.0) <= 0.2, (slope, ok)

    uni = errors_against(uniform_bar.levels, J_PAPER, U_PAPER)[-3:]
    assert len(uni) == 3 and uni[-1][0] == uniform_bar.levels[-1].level, uni
    slope_uniform = fitted_slope([e[1] for e in uni], [e[2] for e in uni])
    assert slope_uniform > -0.9, (slope_uniform, uni)  # reduced by the corner singularities
    assert slope_uniform > slope + 0.1, (slope_uniform, slope)
    # The adaptive run reaches the finest uniform error with fewer cells.
    N_u, E_u = uni[-1][1], uni[-1][2]
    assert any(e[1] < N_u / 2 and e[2] < E_u for e in ok), (ok, uni[-1])


def test_bar_effectivity_index(adaptive_bar):
    """Ieff in [0.8, 1.25] on every asymptotic level that J_ref can judge."""
    res, _ = adaptive_bar
    ok = [e for e in errors_against(res.levels, J_PAPER, U_PAPER)
          if e[0] >= FIRST_ASYMPTOTIC_LEVEL]
    assert len(ok) >= 3, ok
    for level, _, _, ieff in ok:
        assert 0.8 <= ieff <= 1.25, (level, ieff)


def own_reference():
    """Our reference with its own uncertainty, if benchmarks/bar_reference.py wrote one (not a
    --quick run); otherwise the paper's value with the margin granted to it."""
    if OWN_REFERENCE.exists():
        data = json.loads(OWN_REFERENCE.read_text())
        if not data.get("quick"):
            return data["J_ref"], data["uncertainty"]
    return J_PAPER, U_PAPER


def test_bar_rate_and_effectivity_against_own_reference(adaptive_bar):
    """Against our reference (if computed): slope ~ -1, Ieff in [0.8, 1.25] where it can judge."""
    J_ref, U = own_reference()
    assert abs(J_ref - J_PAPER) <= U_PAPER  # the two references agree within the granted margin
    res, _ = adaptive_bar
    ok = [e for e in errors_against(res.levels, J_ref, U) if e[0] >= FIRST_ASYMPTOTIC_LEVEL]
    assert len(ok) >= 4, ok
    last = ok[-4:]
    slope = fitted_slope([e[1] for e in last], [e[2] for e in last])
    assert abs(slope + 1.0) <= 0.2, (slope, last)
    for level, _, _, ieff in ok:
        assert 0.8 <= ieff <= 1.25, (level, ieff)


# --------------------------------------------------------------------------------------------------
# Stopping rules and uniform refinement
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_max_levels_and_tol_stop_the_loop(capsys):
    """tol stops the loop once the interval for J is at most 2 tol wide (converged); a run that
    ends at max_levels first says it did not converge."""
    goal = ex.goal_bar()
    full = ds.solve_adaptive(bar_problem(), goal, max_levels=4, verbose=False)
    assert [r.level for r in full.levels] == [0, 1, 2, 3]
    assert not full.converged  # no tol
    half = [(r.J_high - r.J_low) / 2 for r in full.levels]
    assert half[2] < half[1] < half[0]
    tol = math.sqrt(half[1] * half[2])  # between the half-widths of levels 1 and 2
    stopped = ds.solve_adaptive(bar_problem(), goal, max_levels=4, tol=tol, verbose=False)
    assert len(stopped.levels) == 3 and stopped.converged
    last = stopped.levels[-1]
    assert last.J_high - last.J_low <= 2 * tol
    assert all(r.J_high - r.J_low > 2 * tol for r in stopped.levels[:-1])
    assert stopped.levels[-1].num_marked == 0  # nothing marked after the last level
    for a, b in zip(stopped.levels, full.levels[:3], strict=True):
        # Each run partitions its own mesh: in parallel the numbering, hence round-off, differ.
        assert a.num_cells == b.num_cells
        assert a.J_h == pytest.approx(b.J_h, rel=1e-12)
    one = ds.solve_adaptive(bar_problem(), goal, max_levels=4, tol=1.01 * half[0], verbose=False)
    assert len(one.levels) == 1 and one.converged
    assert len(ds.solve_adaptive(bar_problem(), goal, max_levels=1, verbose=False).levels) == 1
    capsys.readouterr()
    short = ds.solve_adaptive(bar_problem(), goal, max_levels=2, tol=1e-3 * half[1])
    assert not short.converged and len(short.levels) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert "not converged" in capsys.readouterr().out


@pytest.mark.mpi
def test_max_cells_is_respected(adaptive_bar):
    res, _ = adaptive_bar
    cells = [r.num_cells for r in res.levels]
    max_cells = (cells[3] + cells[4]) // 2
    capped = ds.solve_adaptive(bar_problem(), ex.goal_bar(), max_levels=10, max_cells=max_cells,
                               verbose=False)
    assert [r.num_cells for r in capped.levels] == cells[:4]  # the next level would exceed it
    assert all(r.num_cells <= max_cells for r in capped.levels)
    # Uniform: 512 * 4^k cells; the cap stops before the first level above it.
    uniform = ds.solve_adaptive(bar_problem(), ex.goal_bar(), refinement="uniform",
                                max_levels=10, max_cells=512 * 16, verbose=False)
    assert [r.num_cells for r in uniform.levels] == [512, 2048, 8192]


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("build", "factor", "contact_factor"),
    [
        pytest.param(lambda: bar_problem(nx=2, ny=8), 4, 2, id="triangles"),
        pytest.param(lambda: bar_problem(nx=2, ny=8, cell_type=QUAD), 4, 2, id="quadrilaterals"),
        pytest.param(lambda: obstacle_problem(n=(1, 2, 2)), 8, 4, id="tetrahedra"),
        pytest.param(lambda: obstacle_problem(n=(1, 2, 2), cell_type=HEX), 8, 4, id="hexahedra"),
    ],
)
def test_uniform_refinement_multiplies_cells(build, factor, contact_factor):
    problem = build()
    tdim = problem.mesh.topology.dim
    n0 = problem.mesh.topology.index_map(tdim).size_global
    goal = ex.goal_bar() if tdim == 2 else ex.goal_obstacle()
    res = ds.solve_adaptive(problem, goal, refinement="uniform", max_levels=3, verbose=False)
    assert len(res.levels) == 3
    for k, r in enumerate(res.levels):
        assert r.num_macro_cells == n0 * factor**k
        assert r.num_cells == n0 * factor ** (k + 1)  # the fine mesh halves the macro mesh
        assert r.num_marked == 0
    for a, b in zip(res.levels[:-1], res.levels[1:], strict=True):
        assert b.num_contact_elements == contact_factor * a.num_contact_elements
    # The loop takes each level's T_h as the next T_H: the same as refining T_H twice.
    macro = problem
    for _ in range(2):
        macro, _ = refine_marked(macro, None)
    J_h = ds.estimate(ds.solve(macro), goal, estimator="eta_p").J_h
    assert J_h == pytest.approx(res.levels[-1].J_h, rel=1e-10, abs=0.0)


# --------------------------------------------------------------------------------------------------
# Marking: recomputed from the patch indicators
# --------------------------------------------------------------------------------------------------


def geometric_patch_sums(disc, indicators):
    """Sum of the fine indicators over the fine cells whose midpoint lies in each macro cell."""
    macro, tdim = disc.macro_mesh, disc.macro_mesh.topology.dim
    mid = cell_midpoints(disc.mesh)
    tree = fem_compat.bb_tree(macro, tdim, owned_cells(macro))
    candidates = geometry.compute_collisions_points(tree, mid)
    hits = geometry.compute_colliding_cells(macro, candidates, mid)
    one = np.all(np.diff(hits.offsets) == 1)  # each midpoint lies in exactly one macro cell
    assert_on_all_ranks(disc.comm, one, "fine cell midpoints in several macro cells")
    owner = hits.array[hits.offsets[:-1]]
    return np.bincount(owner, weights=indicators[: len(mid)], minlength=len(owned_cells(macro)))


def check_marking(disc, indicators, strategy, fraction, record):
    """The marked macro cells are the fewest / ceil(fraction N) ones with the largest |eta_K|."""
    comm = disc.comm
    eta_K = patch_indicators(disc, indicators)
    geo = geometric_patch_sums(disc, indicators)
    scale = np.abs(indicators).sum() + 1e-300
    assert_on_all_ranks(comm, np.allclose(eta_K, geo, rtol=0, atol=1e-12 * scale), "patches")
    marked = mark(disc, indicators, strategy, fraction)
    is_marked = np.zeros(len(eta_K), dtype=bool)
    is_marked[marked] = True
    a = allgather(comm, np.abs(eta_K))
    m = allgather(comm, is_marked)
    assert m.sum() == record.num_marked  # the loop used this marking
    assert a[m].min() >= a[~m].max()  # the largest ones (ties included)
    order = np.sort(a)[::-1]
    threshold = a[m].min()
    ties = np.sum(a == threshold)
    if strategy == "fixed_fraction":
        k = math.ceil(fraction * a.size)
    else:
        total = a.sum()
        assert a[m].sum() >= fraction * total * (1 - 1e-12)
        k = int(np.argmax(np.cumsum(order) >= fraction * total * (1 - 1e-12))) + 1
    assert k <= m.sum() <= k + ties - 1, (strategy, k, m.sum(), ties)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("strategy", "fraction"),
    [("doerfler", 0.5), ("doerfler", 0.8), ("fixed_fraction", 0.2), ("fixed_fraction", 0.37)],
)
def test_marking_follows_its_definition(strategy, fraction):
    seen = []

    def callback(record, sol, est):
        if record.level < 3:  # the last level marks nothing
            check_marking(sol.disc, est.indicators.x.array, strategy, fraction, record)
        seen.append(record.num_marked)

    res = ds.solve_adaptive(bar_problem(), ex.goal_bar(), strategy=strategy, fraction=fraction,
                            max_levels=4, callback=callback, verbose=False)
    assert len(seen) == 4 and all(n > 0 for n in seen[:3]) and seen[3] == 0
    cells = [r.num_macro_cells for r in res.levels]
    assert all(np.diff(cells) > 0), cells


# --------------------------------------------------------------------------------------------------
# Output directory
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_output_dir_rows_and_fields(mpi_tmp_path):
    out = mpi_tmp_path / "run"
    res = ds.solve_adaptive(bar_problem(), ex.goal_bar(), max_levels=3, exact=J_PAPER,
                            output_dir=out, verbose=False)
    MPI.COMM_WORLD.Barrier()
    comm = MPI.COMM_WORLD
    for r in res.levels:
        for suffix in ("", "_contact"):
            assert (out / f"level_{r.level:02d}{suffix}.xdmf").is_file()
            assert (out / f"level_{r.level:02d}{suffix}.h5").is_file()
        with io.XDMFFile(comm, out / f"level_{r.level:02d}.xdmf", "r") as xdmf:
            msh = xdmf.read_mesh()
        assert msh.topology.index_map(2).size_global == r.num_cells
    rows = read_csv_rows(out / "adaptive.csv")
    data = json.loads((out / "adaptive.json").read_text())
    assert len(rows) == len(data["levels"]) == len(res.levels) == 3
    assert_rows_match(comm, rows, res.levels)
    assert_rows_match(comm, data["levels"], res.levels)
    assert data["meta"]["refinement"] == "adaptive"
    res.to_csv(out / "again.csv")  # the result's own writers give the same table
    res.to_json(out / "again.json")
    comm.Barrier()
    assert read_csv_rows(out / "again.csv") == rows
    assert json.loads((out / "again.json").read_text())["levels"] == data["levels"]
    uniform = ds.solve_adaptive(bar_problem(), ex.goal_bar(), refinement="uniform", max_levels=2,
                                output_dir=out, verbose=False)
    assert len(read_csv_rows(out / "uniform.csv")) == len(uniform.levels) == 2
    assert len(read_csv_rows(out / "adaptive.csv")) == 3  # the other table is untouched


@pytest.mark.mpi
def test_result_writers_use_the_mesh_communicator(mpi_tmp_path):
    """A run on COMM_SELF (one per rank) writes its own table on every rank."""
    rank = MPI.COMM_WORLD.rank
    res = ds.solve_adaptive(bar_problem(MPI.COMM_SELF), ex.goal_bar(), max_levels=2,
                            verbose=False)
    res.to_csv(mpi_tmp_path / f"self_{rank}.csv")
    res.to_json(mpi_tmp_path / f"self_{rank}.json")
    written = (mpi_tmp_path / f"self_{rank}.csv").is_file() and (
        mpi_tmp_path / f"self_{rank}.json").is_file()
    assert all(MPI.COMM_WORLD.allgather(written))


@pytest.mark.mpi
def test_interrupted_run_keeps_finished_levels(mpi_tmp_path):
    out = mpi_tmp_path / "interrupted"
    records = []

    def callback(record, sol, est):
        records.append(record)
        if record.level == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        ds.solve_adaptive(bar_problem(), ex.goal_bar(), max_levels=5, output_dir=out,
                          callback=callback, verbose=False)
    MPI.COMM_WORLD.Barrier()
    rows = read_csv_rows(out / "adaptive.csv")
    data = json.loads((out / "adaptive.json").read_text())
    assert 2 <= len(rows) <= 3 and 2 <= len(data["levels"]) <= 3
    comm = MPI.COMM_WORLD
    assert_rows_match(comm, rows[:2], records[:2])
    assert_rows_match(comm, data["levels"][:2], records[:2])
    assert (out / "level_01.xdmf").is_file()


def _unwritable_dir(tmp_path):
    """A directory in which this process cannot create files (checked by trying), or None."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    for candidate in (locked, Path("/proc/sys")):
        try:
            (candidate / "probe").touch()
        except OSError:
            return candidate
        (candidate / "probe").unlink()
    return None


@pytest.mark.parametrize("case", ["file", "below_file", "unwritable"])
def test_bad_output_dir_is_rejected_and_nothing_created(tmp_path, case):
    target = tmp_path / "a_file"
    target.write_text("keep me")
    if case == "file":
        out = target
    elif case == "below_file":
        out = target / "results"
    else:
        parent = _unwritable_dir(tmp_path)
        if parent is None:
            pytest.skip("no directory here is unwritable for this process")
        out = parent / "dwr_signorini_test_out"
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(ValueError, match="output_dir"):
        ds.solve_adaptive(bar_problem(), ex.goal_bar(), max_levels=2, output_dir=out,
                          verbose=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert target.read_text() == "keep me"
    assert not out.exists() or out == target
    if (tmp_path / "locked").exists():
        (tmp_path / "locked").chmod(0o700)


# --------------------------------------------------------------------------------------------------
# Serial against parallel
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_parallel_run_matches_serial():
    """Same marked cells, cell counts and J_h on COMM_WORLD as on one process."""
    goal = ex.goal_bar()
    par = ds.solve_adaptive(bar_problem(MPI.COMM_WORLD), goal, max_levels=6, verbose=False)
    ser = ds.solve_adaptive(bar_problem(MPI.COMM_SELF), goal, max_levels=6, verbose=False)
    assert len(par.levels) == len(ser.levels) == 6
    for p, s in zip(par.levels, ser.levels, strict=True):
        assert p.num_marked == s.num_marked, p.level
        assert (p.num_cells, p.num_macro_cells, p.num_contact_elements, p.num_dofs) == (
            s.num_cells, s.num_macro_cells, s.num_contact_elements, s.num_dofs), p.level
        assert p.num_active == s.num_active, p.level
        assert p.J_h == pytest.approx(s.J_h, rel=1e-9), p.level
        assert p.weights == s.weights, p.level
        assert p.eta == pytest.approx(s.eta, rel=estimate_rel(p)), p.level


# --------------------------------------------------------------------------------------------------
# Example 5.3 (3D)
# --------------------------------------------------------------------------------------------------


def contact_zone_radius(sol):
    """Radius of the active contact zone around (x2, x3) = (0.25, 0.25) on x1 = 0.25."""
    x, active = contact_facets(sol)
    rho = np.hypot(x[..., 1] - 0.25, x[..., 2] - 0.25).mean(axis=1)
    values = allgather(sol.disc.comm, rho[active])
    assert values.size > 0, "no active contact facet"
    return float(values.max())


def distance_to_contact_boundary(x, radius):
    """Distance of points to the circle {x1 = 0.25, |(x2, x3) - (0.25, 0.25)| = radius}."""
    rho = np.hypot(x[:, 1] - 0.25, x[:, 2] - 0.25)
    return np.hypot(x[:, 0] - 0.25, rho - radius)


@pytest.mark.mpi
def test_3d_refinement_concentrates_at_contact_zone_boundary():
    comm = MPI.COMM_WORLD
    stats = []

    def callback(record, sol, est):
        disc = sol.disc
        radius = contact_zone_radius(sol)
        assert 0.1 < radius < 0.3  # the obstacle touches the body inside z < 0.25
        marked = mark(disc, est.indicators.x.array, "fixed_fraction", 0.1)
        mids = cell_midpoints(disc.macro_mesh)
        d_all = allgather(comm, distance_to_contact_boundary(mids, radius))
        d_marked = allgather(comm, distance_to_contact_boundary(mids[marked], radius))
        stats.append((record.level, d_marked, d_all))

    res = ds.solve_adaptive(obstacle_problem(comm), ex.goal_obstacle(), fraction=0.1,
                            max_levels=3, callback=callback, verbose=False)
    assert len(res.levels) == 3
    assert all(math.isfinite(r.J_h) and math.isfinite(r.eta) for r in res.levels)
    for level, d_marked, d_all in stats[1:]:  # level 0 has 8 macro contact facets only
        assert np.median(d_marked) < 0.5 * np.median(d_all), level
        assert np.mean(d_marked < 0.1) > 0.5, level


def tetrahedron_volumes(msh, cells):
    if len(cells) == 0:
        return np.zeros(0)
    x = msh.geometry.x[mesh.entities_to_geometry(msh, 3, cells, False)]
    return np.abs(np.linalg.det(x[:, 1:] - x[:, :1])) / 6.0


@pytest.mark.slow
@pytest.mark.parametrize("weights", [
    "hierarchical",
    pytest.param("auto", marks=pytest.mark.xfail(strict=True, reason=(
        "with the P2 weights on the band around the contact zone on the unresolved levels, "
        "level 4 marks 37.7 % of its cells within 0.1 of the contact-zone boundary (a band of "
        "7.6 % of the volume: 5.0 times its share), under the 40 % asked; the other levels "
        "0.47-0.86"))),
])
def test_3d_longer_run_refines_the_contact_zone_boundary(weights):
    """Six levels (~130k cells): every level marks mostly within 0.1 of the contact-zone boundary.

    That band holds under a tenth of the volume, but at least 40 % of the marked cells and at
    least four times its volume fraction; |C(w_h)(xi_h)| keeps falling after its peak. With
    the P2 weights of the whole mesh on every level (``"hierarchical"``), and with ``"auto"``.
    """
    comm = MPI.COMM_WORLD
    stats = []

    def callback(record, sol, est):
        disc = sol.disc
        radius = contact_zone_radius(sol)
        cells = owned_cells(disc.macro_mesh)
        mids = cell_midpoints(disc.macro_mesh)
        marked = mark(disc, est.indicators.x.array, "fixed_fraction", 0.05)
        band = distance_to_contact_boundary(mids, radius) < 0.1
        vol = tetrahedron_volumes(disc.macro_mesh, cells)
        in_band = allgather(comm, band[marked])
        band_volume = comm.allreduce(vol[band].sum()) / comm.allreduce(vol.sum())
        stats.append((record.level, float(np.mean(in_band)), band_volume))

    res = ds.solve_adaptive(obstacle_problem(comm), ex.goal_obstacle(), fraction=0.05,
                            max_levels=6, callback=callback, verbose=False, weights=weights)
    assert len(res.levels) == 6
    for level, marked_share, band_volume in stats[:-1]:
        assert band_volume < 0.1, (level, band_volume)
        assert marked_share >= 0.4 and marked_share >= 4 * band_volume, stats
    c = np.abs([r.contact_term for r in res.levels])
    peak = int(np.argmax(c))
    assert peak <= 1 and np.all(np.diff(c[peak:]) < 0) and c[-1] < 1e-2 * c[peak], c


def test_3d_contact_term_decreases():
    """C(w_h)(xi_h) decays fast once the contact zone is resolved (paper, Section 5.3)."""
    res = ds.solve_adaptive(obstacle_problem(), ex.goal_obstacle(), fraction=0.05, max_levels=5,
                            verbose=False)
    c = np.abs([r.contact_term for r in res.levels])
    peak = int(np.argmax(c))
    assert peak <= 1, c
    assert np.all(np.diff(c[peak:]) < 0), c
    assert c[-1] < 0.05 * c[peak], c


# --------------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_adaptive_on_quadrilaterals_is_rejected():
    with pytest.raises(ValueError, match="simplex"):
        ds.solve_adaptive(bar_problem(cell_type=QUAD), ex.goal_bar(), refinement="adaptive",
                          verbose=False)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"fraction": 0.0}, "fraction"),
        ({"fraction": -0.1}, "fraction"),
        ({"fraction": 1.5}, "fraction"),
        ({"fraction": math.nan}, "fraction"),
        ({"max_levels": 0}, "max_levels"),
        ({"max_levels": -1}, "max_levels"),
        ({"strategy": "maximum"}, "strategy"),
        ({"estimator": "eta_d"}, "estimator"),
        ({"weights": "quadratic"}, "weights"),
        ({"refinement": "red"}, "refinement"),
        ({"method": "lu"}, "method"),
    ],
)
def test_bad_options_are_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ds.solve_adaptive(bar_problem(nx=2, ny=8), ex.goal_bar(), verbose=False, **kwargs)


def test_bad_options_create_no_output(tmp_path):
    out = tmp_path / "never"
    with pytest.raises(ValueError, match="fraction"):
        ds.solve_adaptive(bar_problem(nx=2, ny=8), ex.goal_bar(), fraction=0.0, output_dir=out,
                          verbose=False)
    assert not out.exists()
    assert os.listdir(tmp_path) == []


@pytest.mark.mpi
@pytest.mark.parametrize("solver", ["direct", "krylov"])
def test_schur_path_gives_the_same_adaptive_run(solver):
    """method="schur" reproduces the block path level by level: with K factored once per level
    (to round-off), and with CG + GAMG on K and CG on S_AA (to the Krylov tolerances; one more
    Newton step per level, the accurate solve of the settled active set)."""
    solvers = {"direct": (None, 1e-10, 0), "krylov": (iterative_petsc_options(), 1e-7, 1)}
    options, tol, extra = solvers[solver]
    runs = [
        ds.solve_adaptive(
            bar_problem(), ex.goal_bar(), max_levels=3, verbose=False, method=m, petsc_options=o
        )
        for m, o in (("block", None), ("schur", options))
    ]
    assert runs[1].meta["method"] == "schur"
    for a, b in zip(*(r.levels for r in runs), strict=True):
        assert (a.num_cells, a.num_active, a.newton_iterations + extra, a.num_marked) == (
            b.num_cells,
            b.num_active,
            b.newton_iterations,
            b.num_marked,
        )
        assert np.isclose(a.J_h, b.J_h, rtol=tol)
        assert np.isclose(a.eta, b.eta, rtol=1000 * tol)
