"""3D levels of up to millions of DoFs on the Krylov path: time per phase, memory, K-solve ratio.

Levels of :func:`~dwr_signorini.solve_adaptive` with ``method="krylov"`` (each Newton step and
the dual one GMRES on the saddle-point system with one GAMG cycle of K per iteration, see
:mod:`dwr_signorini.linalg.krylov`) or ``--method krylov-schur`` (``method="schur"`` with
``iterative_petsc_options()``: CG on S_AA with a CG + GAMG solve of K per iteration), on
example 5.3 (macro mesh n x 4n x 4n) or the indentation of ``reference_3d.py`` (n x n x n/2),
uniform or adaptive (growth 2). Nothing of the size of K is factored. A line per level: DoFs,
Newton steps, the weights of the estimate, seconds per phase, the level's total, one CG + GAMG
solve of K on the same mesh (``ref``, set-up included, ``--ref``) and the ratio, the peak
memory of the largest rank and of all ranks, and the share of the fine cells on the rank that
holds most; ``benchmarks/results/large_3d_<problem>_np<N>.json``. ``--log`` prints every
Newton step (active facets, changes, residuals).
The same command runs on any number of ranks::

    scripts/fenicsx mpirun -n 2 python3 benchmarks/large_3d.py                  # 146k, 1.1M DoFs
    scripts/fenicsx mpirun -n 2 python3 benchmarks/large_3d.py --n 2            # a check in seconds
    scripts/fenicsx mpirun -n 2 python3 benchmarks/large_3d.py --problem indentation \\
        --refinement adaptive --n 16 --levels 5
    scripts/fenicsx python3 benchmarks/large_3d.py --levels 1 --n 14            # 1.1M DoFs, 1 rank
"""

from __future__ import annotations

import argparse
import json
import logging
import resource
import time
from pathlib import Path

from mpi4py import MPI

from bench_levels import krylov_reference_times
from reference_3d import indentation_problem, total_force

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.linalg import iterative_petsc_options
from dwr_signorini.timing import PHASES, snapshot

METHODS = {
    "krylov": {"method": "krylov"},
    "krylov-schur": {"method": "schur", "petsc_options": iterative_petsc_options()},
}


def build(comm: MPI.Comm, name: str, n: int) -> tuple[ds.SignoriniProblem, object]:
    """The problem and its goal."""
    if name == "obstacle":
        return ex.obstacle_problem(comm, n=(n, 4 * n, 4 * n)), ex.goal_obstacle()
    return indentation_problem(comm, n), total_force


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", default="obstacle", choices=("obstacle", "indentation"))
    parser.add_argument("--n", type=int, default=7, help="the macro mesh (see above)")
    parser.add_argument("--levels", type=int, default=2)
    parser.add_argument("--refinement", default="uniform", choices=("uniform", "adaptive"))
    parser.add_argument("--method", default="krylov", choices=tuple(METHODS))
    parser.add_argument("--weights", default="auto")
    parser.add_argument("--ref", action="store_true",
                        help="also time one CG + GAMG solve of K per level (the ratio)")
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    parser.add_argument("--log", action="store_true",
                        help="print every Newton step (sets, changes, residuals) on rank 0")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.log and comm.rank == 0:
        logging.basicConfig(format="  %(message)s")
        logging.getLogger("dwr_signorini.newton").setLevel(logging.INFO)
    problem, goal = build(comm, args.problem, args.n)
    rows: list[dict] = []
    last = [snapshot(), time.perf_counter()]

    def callback(record: ds.LevelRecord, sol: ds.Solution, est: ds.Estimate) -> None:
        now = snapshot()
        total = comm.allreduce(time.perf_counter() - last[1], op=MPI.MAX)
        phases = {k: comm.allreduce(now[k] - last[0][k], op=MPI.MAX) for k in PHASES}
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0**2  # GiB
        tdim = sol.disc.mesh.topology.dim
        owned = comm.allgather(sol.disc.mesh.topology.index_map(tdim).size_local)
        row = {
            "problem": args.problem, "refinement": args.refinement, "method": sol.method,
            "level": record.level, "cells": record.num_cells, "dofs": record.num_dofs,
            "num_active": record.num_active, "newton": record.newton_iterations,
            "krylov_iterations": getattr(sol.system, "iterations", None),
            "weights": record.weights, "J_h": record.J_h, "J_low": record.J_low,
            "J_high": record.J_high, "total_s": total, "ranks": comm.size,
            "peak_GiB_max_rank": comm.allreduce(rss, op=MPI.MAX),
            "peak_GiB_all_ranks": comm.allreduce(rss, op=MPI.SUM),
            "cells_largest_rank_share": max(owned) / sum(owned),
            **{f"{k}_s": v for k, v in phases.items() if v > 0},
        }
        if args.ref:
            row["ref_s"] = krylov_reference_times(sol)[0]
            row["ratio"] = total / row["ref_s"]
        rows.append(row)
        if comm.rank == 0:
            print(json.dumps(row), flush=True)
        last[0], last[1] = snapshot(), time.perf_counter()

    adaptive = {"growth": 2.0} if args.refinement == "adaptive" else {}
    ds.solve_adaptive(problem, goal, refinement=args.refinement, max_levels=args.levels,
                      weights=args.weights, callback=callback, verbose=True,
                      **adaptive, **METHODS[args.method]).destroy()
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        path = args.output / f"large_3d_{args.problem}_np{comm.size}.json"
        path.write_text(json.dumps({"levels": rows, "args": {
            k: str(v) for k, v in vars(args).items()}}, indent=1))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
