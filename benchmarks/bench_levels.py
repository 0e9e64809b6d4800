"""Price every phase of a level against one factorisation + solve of the stiffness matrix K.

For example 5.1 (``2d``), example 5.3 (``3d``) and the 3D indentation of
``reference_3d.py`` (``indent``: a block pressed by a sphere, goal the contact force), over
uniform and adaptive levels, this prints and writes a table of DoFs, Newton iterations and
seconds per phase (assembly, factorisations, Newton solves, dual solve, reconstructions,
indicators, marking, refinement, output), next to the time of one MUMPS factorisation + solve of
K alone on the same mesh (``ref``, in memory the process has not used before, like the level's
own factorisation; ``ref_warm``, the same repeated), the ratios total/ref and total/ref_warm, and
the peak memory. ``--methods`` takes ``block``, ``schur`` (the dense Schur complement),
``auto`` (``method=None``: the package's choice, :func:`dwr_signorini.linalg.choose_method`) and
``krylov`` (``method="krylov"``: each step one saddle-point GMRES with a multigrid cycle of K
per iteration) and ``krylov-schur`` (``method="schur"`` with ``iterative_petsc_options()``: CG on
S_AA with a CG + GAMG solve of K per iteration); the ``ref`` of both is one CG + GAMG solve of
K with the same options and the rigid body modes, set-up included. It first prints
how long filling memory takes the first time and again: where the first time is costly (a
sandbox), ``ref`` and ``ref_warm`` differ. After each level (outside its time) it measures the
machine's parallel capacity (``capacity``, :func:`parallel_capacity`): a speed-up on 2 ranks
needs a second free core. Run it with 1 and with 2 ranks; ``--summary`` then prints the
speed-ups (``--phases-from DOFS``: per phase, for the levels of at least DOFS DoFs)::

    scripts/fenicsx python3 benchmarks/bench_levels.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/bench_levels.py
    scripts/fenicsx python3 benchmarks/bench_levels.py --summary

Timings on a shared or virtual machine vary from run to run; ``--run k`` numbers the tables of
repeated runs (each in a new process, so that ``ref`` is again in memory not used before), and
``--summary`` then prints the median of each column over them::

    for k in 1 2 3; do
        scripts/fenicsx python3 benchmarks/bench_levels.py --examples 2d --run $k
    done
"""

from __future__ import annotations

import argparse
import csv
import resource
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
from dolfinx import mesh
from mumps_ordering import factor_times
from reference_3d import indentation_problem, total_force

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.linalg import default_petsc_options, iterative_petsc_options
from dwr_signorini.linalg.nullspace import rigid_body_modes
from dwr_signorini.timing import PHASES, snapshot

COLUMNS = ("assemble", "factorize", "newton solve", "dual solve", "goal", "higher-order solve",
           "reconstruct", "indicators", "mark", "refine", "discretize", "transfer", "output")


def krylov_reference_times(sol: ds.Solution) -> tuple[float, float]:
    """Seconds of one CG + GAMG solve of K (set-up included), twice: the ``ref`` of ``krylov``.

    The right-hand side is the load the solution's displacement carries, f - N^T lambda_h (f
    alone is zero where the contact loads the body, and CG would stop at once).
    """
    system = sol.system
    nullspace = rigid_body_modes(system.V, system.n_u)
    system.K.setNearNullSpace(nullspace)
    load, lam = system.f.duplicate(), system.N.createVecLeft()
    lam.array_w[:] = system.split(system.x)[1]
    system.NT.mult(lam, load)
    load.aypx(-1.0, system.f)
    (first, _), (second, _) = factor_times(system.K, load, iterative_petsc_options(), repeat=2)
    for obj in (nullspace, load, lam):
        obj.destroy()
    return first, second


def reference_times(sol: ds.Solution) -> tuple[float, float]:
    """Seconds of one MUMPS factorisation + solve of K alone (fresh KSP, same matrix, same options).

    Run twice, max over ranks. The first run allocates its factors in memory the process has not
    touched before, as the Newton factorisation of every new level does and as a standalone run
    would (``ref``). The second reuses that memory (``ref_warm``). Where first touches are costly
    (in this sandbox up to 2.3 s per GiB, see :func:`first_touch_seconds_per_gib`) the two differ.
    """
    # The same direct solver as the Newton steps' (ordering chosen by dimension).
    options = default_petsc_options(sol.disc.mesh.topology.dim)
    (first, _), (second, _) = factor_times(sol.system.K, sol.system.f, options, repeat=2)
    return first, second


def first_touch_seconds_per_gib(comm: MPI.Comm, gib: float = 0.5) -> tuple[float, float]:
    """Seconds per GiB to fill memory the process never used before, and to fill it again."""
    n = int(gib * 2**30) // 8
    seconds = []
    for _ in range(2):
        tic = time.perf_counter()
        a = np.ones(n)
        seconds.append(time.perf_counter() - tic)
        del a
    return tuple(comm.allreduce(t, op=MPI.MAX) / gib for t in seconds)


def parallel_capacity(comm: MPI.Comm, size: int = 300, repeat: int = 40) -> float:
    """How many ranks' worth of compute the machine gives now: ranks x t_alone / t_together.

    Rank 0 multiplies two dense matrices ``repeat`` times alone (the other ranks sleep, polling
    a non-blocking barrier: no busy wait), then all ranks do the same at once. On an idle
    machine with a core per rank this is about the number of ranks; where other work shares the
    cores it is less, and it bounds the speed-up any phase can reach at that moment (1 on one
    rank).
    """
    a = np.random.default_rng(0).random((size, size))

    def work() -> float:
        tic = time.perf_counter()
        for _ in range(repeat):
            a @ a
        return time.perf_counter() - tic

    work()  # warm up
    alone = work() if comm.rank == 0 else 0.0
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(1e-3)
    together = comm.allreduce(work(), op=MPI.MAX)
    return comm.size * comm.bcast(alone, root=0) / together


def problem_2d(comm: MPI.Comm, n: int) -> tuple[ds.SignoriniProblem, object]:
    return ex.analytic_problem(comm, 3 * n, 2 * n, mesh.CellType.triangle), ex.goal_a(-0.5)


def problem_3d(comm: MPI.Comm, n: int) -> tuple[ds.SignoriniProblem, object]:
    return ex.obstacle_problem(comm, (2 * n, 8 * n, 8 * n)), ex.goal_obstacle()


def problem_indent(comm: MPI.Comm, n: int) -> tuple[ds.SignoriniProblem, object]:
    return indentation_problem(comm, n), total_force


PROBLEMS = {"2d": problem_2d, "3d": problem_3d, "indent": problem_indent}
METHOD_ARGUMENTS = {
    "block": {"method": "block"},
    "schur": {"method": "schur"},
    "auto": {"method": None},
    "krylov": {"method": "krylov"},
    "krylov-schur": {"method": "schur", "petsc_options": iterative_petsc_options()},
}


def run(
    example: str, refinement: str, levels: int, start: int, comm: MPI.Comm, method: str,
    growth: float | None = None, weights: str = "auto",
) -> list[dict]:
    problem, goal = PROBLEMS[example](comm, start)
    rows: list[dict] = []
    last = [snapshot(), time.perf_counter()]

    def callback(record: ds.LevelRecord, sol: ds.Solution, est: ds.Estimate) -> None:
        now = snapshot()
        wall = time.perf_counter() - last[1]
        phases = {k: comm.allreduce(now[k] - last[0][k], op=MPI.MAX) for k in PHASES}
        measure = krylov_reference_times if method.startswith("krylov") else reference_times
        ref, ref_warm = measure(sol)
        peak = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, op=MPI.MAX)
        capacity = parallel_capacity(comm)
        total = comm.allreduce(wall, op=MPI.MAX)
        row = {
            "example": example, "refinement": refinement, "method": method, "ranks": comm.size,
            "used": sol.method, "weights": record.weights,
            "level": record.level, "cells": record.num_cells, "dofs": record.num_dofs,
            "newton": record.newton_iterations,
            # factorisations of the Newton matrix and steps solved with earlier factors (the
            # block path's reuse decisions follow MUMPS's counts, which differ with the ranks)
            "factored": getattr(sol.system, "factorizations", ""),
            "reused": getattr(sol.system, "reused", ""),
            **{k: phases[k] for k in COLUMNS},
            "total": total, "ref": ref, "ratio": total / ref, "ref_warm": ref_warm,
            "ratio_warm": total / ref_warm, "peak_MiB": peak / 1024.0, "capacity": capacity,
        }
        # The primal solve: assembly, factorisations and Newton solves (solve()).
        primal = phases["assemble"] + phases["factorize"] + phases["newton solve"]
        row["dual/primal"] = phases["dual solve"] / primal
        row["est/primal"] = (phases["reconstruct"] + phases["indicators"]) / primal
        rows.append(row)
        if comm.rank == 0:
            print(" ".join(f"{_fmt(row[k])}" for k in HEADER), flush=True)
        last[0], last[1] = snapshot(), time.perf_counter()

    adaptive = {"growth": growth} if growth and refinement == "adaptive" else {"fraction": 0.2}
    ds.solve_adaptive(
        problem, goal, refinement=refinement, max_levels=levels, callback=callback,
        verbose=False, weights=weights, **adaptive, **METHOD_ARGUMENTS[method],
    ).destroy()
    return rows


HEADER = ("example", "refinement", "method", "used", "weights", "level", "cells", "dofs", "newton",
          "factored", "reused",
          "assemble", "factorize", "newton solve", "dual solve", "higher-order solve", "goal",
          "reconstruct", "indicators", "mark", "refine", "total", "ref", "ratio", "ref_warm",
          "ratio_warm", "dual/primal", "est/primal",
          "peak_MiB", "capacity")


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:12.4f}" if value < 1e4 else f"{value:12.1f}"
    return f"{value!s:>12}"


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = sorted({(r["example"], r["refinement"], r["method"]) for r in rows})
    fig, axes = plt.subplots(1, len(groups), figsize=(5 * len(groups), 4), squeeze=False)
    for ax, key in zip(axes[0], groups, strict=True):
        sel = [r for r in rows if (r["example"], r["refinement"], r["method"]) == key]
        dofs = [r["dofs"] for r in sel]
        for col in ("assemble", "factorize", "newton solve", "dual solve", "reconstruct",
                    "indicators", "refine", "total", "ref"):
            values = [max(r[col], 1e-6) for r in sel]
            style = "k--" if col == "ref" else ("k-" if col == "total" else "-o")
            ax.loglog(dofs, values, style, label=col, markersize=3)
        ax.set_title(f"{key[0]} {key[1]} {key[2]} ({sel[0]['ranks']} rank(s))")
        ax.set_xlabel("DoFs")
        ax.set_ylabel("seconds per level")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _runs(out: Path, ranks: int) -> list[dict]:
    """The tables of the runs with ``ranks`` ranks: ``bench_levels_np<ranks>_run<k>.csv``, or
    if there are none, the single ``bench_levels_np<ranks>.csv``."""
    paths = sorted(out.glob(f"bench_levels_np{ranks}_run*.csv")) or sorted(
        out.glob(f"bench_levels_np{ranks}.csv")
    )
    if not paths:
        raise FileNotFoundError(f"no bench_levels_np{ranks}*.csv in {out}")
    tables = []
    for path in paths:
        with open(path) as fh:
            tables.append(
                {(r["example"], r["refinement"], r["method"], r["level"]): r
                 for r in csv.DictReader(fh)}
            )
    return tables


def _median(tables: list[dict], key: tuple, column: str) -> float:
    return float(np.median([float(t[key][column]) for t in tables if key in t]))


def summary(out: Path) -> None:
    """Speed-up of 2 ranks over 1 and the ratios of each level, from the CSV files.

    With several runs per rank count (``--run``), every column is the median over the runs.
    ratio1/ratio2: total/ref with 1/2 ranks; warm1/warm2: total/ref_warm; dual/pr and est/pr:
    dual solve and estimator (reconstructions + indicators) against the primal solve (assembly,
    factorisations and Newton solves), 1 rank.
    """
    tables = {np_: _runs(out, np_) for np_ in (1, 2)}
    print(f"runs: {len(tables[1])} with 1 rank, {len(tables[2])} with 2 ranks (medians)")
    print(f"{'example':>8} {'refinement':>10} {'method':>6} {'level':>5} {'dofs':>9} "
          f"{'newton':>6} {'t1':>9} {'t2':>9} {'speed-up':>9} {'ratio1':>7} {'ratio2':>7} "
          f"{'warm1':>7} {'warm2':>7} {'dual/pr':>7} {'est/pr':>7}")
    for key, r1 in tables[1][0].items():
        if not all(key in t for t in tables[2]):
            continue
        one = {c: _median(tables[1], key, c) for c in
               ("total", "ratio", "ratio_warm", "dual/primal", "est/primal")}
        two = {c: _median(tables[2], key, c) for c in ("total", "ratio", "ratio_warm")}
        print(f"{key[0]:>8} {key[1]:>10} {key[2]:>6} {key[3]:>5} {r1['dofs']:>9} "
              f"{r1['newton']:>6} {one['total']:9.3f} {two['total']:9.3f} "
              f"{one['total'] / two['total']:9.2f} {one['ratio']:7.2f} {two['ratio']:7.2f} "
              f"{one['ratio_warm']:7.2f} {two['ratio_warm']:7.2f} {one['dual/primal']:7.3f} "
              f"{one['est/primal']:7.3f}")


def phase_summary(out: Path, min_dofs: int) -> None:
    """Per phase, 1 rank against 2, of the levels of at least ``min_dofs`` DoFs (medians).

    Prints t1, t2 and the speed-up t1/t2 of every phase that takes at least 0.05 s on 1 rank,
    of ``other`` (the level's time outside the named phases: the callback, the search for the
    marking fraction's refinement, Python between phases) and of the level, with the parallel
    capacity (:func:`parallel_capacity`) the 2-rank runs measured after each level, and the
    spread (min-max over the runs) of the level's time.
    """
    tables = {np_: _runs(out, np_) for np_ in (1, 2)}
    for key, r1 in tables[1][0].items():
        if int(r1["dofs"]) < min_dofs or not all(key in t for t in tables[2]):
            continue
        totals = {np_: [float(t[key]["total"]) for t in tables[np_] if key in t] for np_ in (1, 2)}
        capacity = [float(t[key].get("capacity") or "nan") for t in tables[2]]
        print(f"{key[0]} {key[1]} level {key[3]}, {r1['dofs']} DoFs: level {min(totals[1]):.2f}-"
              f"{max(totals[1]):.2f} s (1 rank), {min(totals[2]):.2f}-{max(totals[2]):.2f} s "
              f"(2 ranks), capacity of the 2-rank runs {', '.join(f'{c:.2f}' for c in capacity)}")
        print(f"  {'phase':>18} {'t1':>8} {'t2':>8} {'speed-up':>8}")
        rest = {np_: _median(tables[np_], key, "total") for np_ in (1, 2)}
        for phase in COLUMNS:
            t = {np_: _median(tables[np_], key, phase) for np_ in (1, 2)}
            for np_ in (1, 2):
                rest[np_] -= t[np_]
            if t[1] >= 0.05:
                print(f"  {phase:>18} {t[1]:8.3f} {t[2]:8.3f} {t[1] / max(t[2], 1e-9):8.2f}")
        print(f"  {'other':>18} {rest[1]:8.3f} {rest[2]:8.3f} {rest[1] / max(rest[2], 1e-9):8.2f}")
        t = {np_: _median(tables[np_], key, "total") for np_ in (1, 2)}
        print(f"  {'level':>18} {t[1]:8.3f} {t[2]:8.3f} {t[1] / t[2]:8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", default="2d,3d")
    parser.add_argument("--refinements", default="uniform,adaptive")
    parser.add_argument("--levels-2d", type=int, default=6)
    parser.add_argument("--levels-3d", type=int, default=3)
    parser.add_argument("--adaptive-levels-2d", type=int, default=9)
    # Level 4 of the adaptive 3D run has 1.35M DoFs: its direct factorisation needs ~43 GB.
    parser.add_argument("--adaptive-levels-3d", type=int, default=4)
    parser.add_argument("--start-2d", type=int, default=4, help="macro mesh 3n x 2n")
    parser.add_argument("--start-3d", type=int, default=1, help="macro mesh 2n x 8n x 8n")
    parser.add_argument("--levels-indent", type=int, default=2)
    parser.add_argument("--adaptive-levels-indent", type=int, default=4)
    parser.add_argument("--start-indent", type=int, default=8, help="macro mesh n x n x n/2")
    parser.add_argument("--growth", type=float, default=None,
                        help="growth= of the adaptive runs (default: fraction 0.2)")
    parser.add_argument("--methods", default="block",
                        help="Newton linear algebra, comma-separated: block, schur, auto, krylov, "
                             "krylov-schur")
    parser.add_argument("--weights", default="auto",
                        help="weights= of the estimate (auto: patch, P2 where unresolved)")
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    parser.add_argument("--run", type=int, default=None,
                        help="number of this run: writes bench_levels_np<ranks>_run<k>.csv")
    parser.add_argument("--summary", action="store_true",
                        help="print the table of the runs written before (medians over runs)")
    parser.add_argument("--phases-from", type=int, default=None, metavar="DOFS",
                        help="with --summary: also the speed-up per phase of the levels of at "
                             "least DOFS DoFs")
    args = parser.parse_args()
    if args.summary:
        summary(args.output)
        if args.phases_from is not None:
            phase_summary(args.output, args.phases_from)
        return
    comm = MPI.COMM_WORLD
    fresh, again = first_touch_seconds_per_gib(comm)
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        print(f"filling memory: {fresh:.3f} s/GiB the first time, {again:.3f} s/GiB again")
        print(" ".join(f"{h:>12}" for h in HEADER), flush=True)
    rows: list[dict] = []
    for example in args.examples.split(","):
        for refinement in args.refinements.split(","):
            uniform = refinement == "uniform"
            levels = getattr(args, ("" if uniform else "adaptive_") + f"levels_{example}")
            start = getattr(args, f"start_{example}")
            for method in args.methods.split(","):
                rows += run(example, refinement, levels, start, comm, method, args.growth,
                            args.weights)
    if comm.rank == 0:
        suffix = "" if args.run is None else f"_run{args.run}"
        path = args.output / f"bench_levels_np{comm.size}{suffix}.csv"
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        plot(rows, args.output / f"bench_levels_np{comm.size}{suffix}.png")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
