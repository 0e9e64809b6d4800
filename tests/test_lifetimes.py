"""Lifetimes of PETSc objects and options, collective properties, named fallbacks, timing phases.

* A solution owns its Newton system and releases it in ``destroy()`` (or a ``with`` block); the
  options of a solve stay in PETSc's database as long as its solver and leave with it, so every
  re-factorisation (a new active set on every path) still reads them.
* Singular Newton matrices that appear only at a later step are found on all three paths.
* ``-<prefix>...`` options on the command line and ``jit_options`` take effect.
* Nothing a rank-0-only branch reads is collective.
* A problem solved again does not keep the fine meshes of its earlier solves.
* Every timed interval is charged to exactly one phase.
"""

import itertools
import logging
import os
import subprocess
import sys
import textwrap

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import timing
from dwr_signorini.linalg import (
    DenseSchurComplement,
    SchurNewtonSystem,
    iterative_petsc_options,
    mumps,
)
from dwr_signorini.spaces import discretize

from .problems import strip_problem

PATHS = {
    "block": ("block", None),
    "schur-direct": ("schur", None),
    "schur-krylov": ("schur", iterative_petsc_options()),
}


def _options_with(prefix):
    return [k for k in PETSc.Options().getAll() if k.startswith(prefix)]


def _degenerate_box(comm, gap):
    """A 1 x 1 x 1 box clamped on its four sides and pulled down by gravity onto a flat obstacle
    at distance ``gap`` under its bottom (two macro triangles, the contact boundary). The fine
    nodes of the bottom are all clamped except the centre, so both multipliers act on one normal
    displacement: with both active, the Newton matrix and S_AA are singular."""
    msh = mesh.create_box(
        comm, [(0, 0, 0), (1, 1, 1)], [1, 1, 1], mesh.CellType.tetrahedron,
        ghost_mode=mesh.GhostMode.none,
    )

    def classify(x):
        tags = np.full(x.shape[1], ex.DIRICHLET)
        tags[np.isclose(x[2], 1.0)] = ex.NEUMANN
        tags[np.isclose(x[2], 0.0)] = ex.CONTACT
        return tags

    return ds.SignoriniProblem(
        msh, ex.tag_exterior_facets(msh, classify), contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,), E=1.0, nu=0.3, model="3d", body_force=(0.0, 0.0, -1.0),
        gap=gap,
    )


@pytest.mark.mpi
@pytest.mark.parametrize("path", list(PATHS))
def test_dependent_constraints_entering_at_a_later_step_raise(path):
    """Step 0 (from zero) has no active facet: the gap is positive. Free of contact, gravity
    sags the centre by 0.22 > gap, so step 1 activates both facets, whose constraints are
    dependent. Every path must find that singularity at step 1 (the Krylov path through MUMPS's
    null pivots of its preconditioner, which are counted only if ICNTL(24) still reaches the
    factorisation of the second active set) and raise with the history."""
    method, options = PATHS[path]
    comm = MPI.COMM_WORLD
    with ds.solve(_degenerate_box(comm, 1.0), method=method, petsc_options=options) as sol:
        assert sol.num_active == 0  # far obstacle: no contact, the sag is 0.22
        assert -sol.disc.comm.allreduce(sol.u.x.array.min(), op=MPI.MIN) > 0.2
    with pytest.raises(ds.ConvergenceError, match=r"Newton step 1.*singular") as info:
        ds.solve(_degenerate_box(comm, 1e-4), method=method, petsc_options=options)
    assert [h["num_active"] for h in info.value.history] == [0, 2]


@pytest.mark.mpi
@pytest.mark.parametrize("path", list(PATHS))
def test_icntl_24_reaches_every_factorisation(path):
    """The strip problem changes its active set over several Newton steps; the factorisation of
    the last one (the block matrix, or the preconditioner of S_AA, both set up anew for each
    active set) still has null pivot detection on, and the user's ICNTL(14) too."""
    method, options = PATHS[path]
    options = {**(options or {}), "mat_mumps_icntl_14": 55, "schur_mat_mumps_icntl_14": 56}
    with ds.solve(strip_problem(MPI.COMM_WORLD, 16, 4), method=method, petsc_options=options) as s:
        assert len({h["num_active"] for h in s.history}) >= 2  # several active sets
        if path == "schur-krylov":
            factor, workspace = s.system.schur.ksp.getPC().getFactorMatrix(), 56
        else:
            factor, workspace = s.system.ksp.getPC().getFactorMatrix(), 55
        assert factor.getMumpsIcntl(24) == 1
        assert factor.getMumpsIcntl(14) == workspace
        prefix = s.system.prefix
        assert _options_with(prefix)
    assert not _options_with(prefix)


@pytest.mark.mpi
def test_solution_and_result_release_their_objects():
    """``with`` blocks and destroy() (idempotent) remove a solve's options; a given prefix is
    used for the solve, with sub-prefixes for the higher-order solves; an adaptive result
    releases its last level."""
    problem = strip_problem(MPI.COMM_WORLD, 8, 2)
    with ds.solve(problem, petsc_options_prefix="lifetime_") as sol:
        assert sol.system.prefix == "lifetime_"
        assert _options_with("lifetime_pc_type")
        est = ds.estimate(sol, ex.goal_a(-0.5), weights="higher_order")
        assert not _options_with("lifetime_p2_")  # released after the P2 solves
        est.destroy()
        est.destroy()
    sol.destroy()
    assert not _options_with("lifetime_")
    with pytest.raises(ValueError, match="prefix"):
        ds.solve(problem, petsc_options_prefix="no_underscore")
    with ds.solve_adaptive(problem, ex.goal_a(-0.5), max_levels=2, verbose=False) as res:
        prefix = res.solution.system.prefix
        assert _options_with(prefix)
    assert not _options_with(prefix)


@pytest.mark.mpi
def test_a_problem_solved_again_does_not_keep_the_fine_meshes():
    """Each solve refines T_H anew; the data on T_h (its cell tags, the DG0 materials, the
    contact-tag indicators) are the fields of its discretisation, not the problem's, so solving
    one problem many times holds no fine mesh once the solutions are gone. The problem itself
    is frozen data: it holds T_H and nothing per mesh."""
    import gc
    import weakref

    from dwr_signorini.fields import MeshFields

    strip = strip_problem(MPI.COMM_WORLD, 8, 2)
    num_cells = strip.mesh.topology.index_map(2).size_local
    cells = mesh.meshtags(strip.mesh, 2, np.arange(num_cells, dtype=np.int32),
                          np.full(num_cells, 7, dtype=np.int32))
    problem = strip.with_mesh(strip.mesh, strip.facet_tags, cell_tags=cells)
    fine_meshes = []
    for _ in range(3):
        with ds.solve(problem) as sol:
            fine_meshes.append(weakref.ref(sol.disc.mesh))
            fine_meshes.append(weakref.ref(sol.disc.fields))
            assert sol.disc.fields.cell_tags is not None
        del sol
        gc.collect()
    assert all(ref() is None for ref in fine_meshes)
    held = [v for v in vars(problem).values() if isinstance(v, (mesh.Mesh, MeshFields))]
    assert held == [problem.mesh] and problem.cell_tags is cells
    with pytest.raises(AttributeError, match="frozen"):
        problem.cell_tags = None
    # Two discretisations share T_h (for_problem), each with its own fields: T_h stays while
    # one of them lives.
    disc = ds.discretize(problem)
    same = disc.for_problem(problem)
    del disc
    gc.collect()
    assert same.fields.mesh is same.mesh and same.fields.cell_tags is not None
    fine = weakref.ref(same.mesh)
    del same
    gc.collect()
    assert fine() is None


@pytest.mark.mpi
def test_rank_zero_only_reads_are_not_collective():
    """``if comm.rank == 0: print(sol.num_active)`` returns on every rank: the count is computed
    once, in solve(), and is a plain number afterwards."""
    comm = MPI.COMM_WORLD
    with ds.solve(strip_problem(comm, 8, 2)) as sol:
        assert isinstance(sol.num_active, int)
        count = sol.num_active if comm.rank == 0 else None
        assert comm.bcast(count, root=0) == comm.allreduce(int(sol.active.sum()))


def test_command_line_options_reach_the_solver(tmp_path):
    """``-<prefix>ksp_view`` on the command line is read by the solver of that prefix."""
    script = tmp_path / "view.py"
    script.write_text(textwrap.dedent("""
        import sys
        import petsc4py
        petsc4py.init(sys.argv)
        from mpi4py import MPI
        import dwr_signorini as ds
        from tests.problems import strip_problem
        with ds.solve(strip_problem(MPI.COMM_WORLD, 8, 2), petsc_options_prefix="cli_"):
            pass
    """))
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run(
        [sys.executable, str(script), "-cli_ksp_view"], capture_output=True, text=True,
        env=env, cwd=root, timeout=300, check=True,
    ).stdout
    assert "KSP Object: (cli_)" in out
    assert "cholesky" in out or "lu" in out


def test_jit_options_reach_the_compiler(tmp_path):
    """The forms of the Newton system are compiled into the cache directory of jit_options."""
    cache = tmp_path / "jit"
    with ds.solve(strip_problem(MPI.COMM_WORLD, 8, 2), jit_options={"cache_dir": str(cache)}):
        pass
    assert list(cache.rglob("*.c")), "no generated C code in the given cache_dir"
    with pytest.raises(TypeError, match="jit_options"):
        ds.solve(strip_problem(MPI.COMM_WORLD, 8, 2), jit_options="cache")


@pytest.mark.mpi
def test_dense_schur_falls_back_to_solves_with_a_warning(monkeypatch, caplog):
    """Without PETSc's function for entries of the inverse, S comes from multi-RHS solves, with
    a logged warning; it equals S from the entries."""
    disc = discretize(strip_problem(MPI.COMM_WORLD, 8, 2))
    system = SchurNewtonSystem(disc)
    S_entries = system.schur.S
    system.destroy()
    monkeypatch.setattr(mumps, "_INVERSE_FUNCTION", "MatMumpsNoSuchFunction")
    assert not mumps.inverse_entries_available()
    with caplog.at_level(logging.WARNING, logger="dwr_signorini.linalg.schur"):
        system = SchurNewtonSystem(disc)
    assert isinstance(system.schur, DenseSchurComplement)
    assert "MatMumpsGetInverseTranspose was not found" in caplog.text
    if disc.comm.rank == 0:
        assert np.abs(system.schur.S - S_entries).max() <= 1e-12 * np.abs(S_entries).max()
    system.destroy()


def test_null_pivots_raise_when_the_factor_cannot_be_reached():
    """A MUMPS factorisation whose factor is not there (never set up) is an error for the
    null-pivot check, not a count of 0."""
    if not PETSc.Sys.hasExternalPackage("mumps"):
        pytest.skip("PETSc without MUMPS")
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    ksp.getPC().setType("cholesky")
    ksp.getPC().setFactorSolverType("mumps")
    try:
        with pytest.raises(RuntimeError, match="cannot be reached"):
            mumps.null_pivots(ksp)
    finally:
        ksp.destroy()


@pytest.mark.mpi
def test_every_timed_interval_is_charged_to_one_phase():
    """The higher-order solves contain assembly, factorisation and solves: those intervals are
    charged to their own phases and not again to "higher-order solve". The charged segments of
    a solve and estimate are disjoint, and each phase's total grows by its segments' sum."""
    problem = strip_problem(MPI.COMM_WORLD, 8, 2)
    before = timing.snapshot()
    with timing.trace() as segments, ds.solve(problem) as sol:
        ds.estimate(sol, ex.goal_a(-0.5), estimator="eta", weights="higher_order").destroy()
    after = timing.snapshot()
    segments = sorted(segments, key=lambda s: s[1])
    for (_, _, end), (_, start, _) in itertools.pairwise(segments):
        assert start >= end
    phases = {s[0] for s in segments}
    assert {"higher-order solve", "assemble", "factorize", "dual solve"} <= phases
    high = [s for s in segments if s[0] == "higher-order solve"]
    inside = [s for s in segments if high[0][1] <= s[1] and s[2] <= high[-1][2]]
    assert {"assemble", "factorize"} <= {s[0] for s in inside}
    for phase in timing.PHASES:
        charged = sum(e - s for p, s, e in segments if p == phase)
        assert after[phase] - before[phase] == pytest.approx(charged, rel=1e-9, abs=1e-12)
