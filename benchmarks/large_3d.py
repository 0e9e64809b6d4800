"""Example 5.3 on a 3D mesh of about 1M DoFs, solved and estimated with the iterative option.

Two uniform levels of :func:`~dwr_signorini.solve_adaptive` with ``method="schur"`` and
:func:`~dwr_signorini.newton.iterative_petsc_options` (K by CG with GAMG and the rigid body
modes, S_AA = (N K^-1 N^T)_AA by CG applied matrix-free): no factorisation of K is made. The
first level warm-starts the second. Prints a line per
level with DoFs, Newton iterations, seconds per phase and the peak memory summed over the
ranks, and writes ``benchmarks/results/large_3d.json``::

    scripts/fenicsx mpirun -n 2 python3 benchmarks/large_3d.py            # 1.1M DoFs
    scripts/fenicsx mpirun -n 2 python3 benchmarks/large_3d.py --n 2      # 30k DoFs, a check
    scripts/fenicsx mpirun -n 2 python3 benchmarks/large_3d.py --levels 1 [--no-loose-steps]
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import newton
from dwr_signorini.newton import iterative_petsc_options
from dwr_signorini.timing import PHASES, snapshot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=7,
                        help="first macro mesh n x 4n x 4n (x6 tetrahedra); the last level's fine "
                             "mesh has (8n+1)(32n+1)^2 vertices")
    parser.add_argument("--levels", type=int, default=2)
    parser.add_argument("--no-loose-steps", action="store_true",
                        help="solve every Newton step to the full tolerances (for comparison)")
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.no_loose_steps:
        newton.LOOSE_RTOL = tuple(iterative_petsc_options()["ksp_rtol"] for _ in range(2))
    problem = ex.obstacle_problem(comm, n=(args.n, 4 * args.n, 4 * args.n))
    rows: list[dict] = []
    last = [snapshot(), time.perf_counter()]

    def callback(record: ds.LevelRecord, sol: ds.Solution, est: ds.Estimate) -> None:
        now = snapshot()
        phases = {k: comm.allreduce(now[k] - last[0][k], op=MPI.MAX) for k in PHASES}
        peak = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, op=MPI.SUM)
        row = {
            "level": record.level, "cells": record.num_cells, "dofs": record.num_dofs,
            "newton": record.newton_iterations, "J_h": record.J_h, "eta": record.eta,
            "total_s": comm.allreduce(time.perf_counter() - last[1], op=MPI.MAX),
            "peak_GiB_all_ranks": peak / 1024.0**2, "ranks": comm.size,
            **{f"{k}_s": v for k, v in phases.items() if v > 0},
        }
        rows.append(row)
        if comm.rank == 0:
            print(json.dumps(row), flush=True)
        last[0], last[1] = snapshot(), time.perf_counter()

    ds.solve_adaptive(problem, ex.goal_obstacle(), refinement="uniform", max_levels=args.levels,
                      method="schur", petsc_options=iterative_petsc_options(), callback=callback,
                      verbose=True)
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        with open(args.output / "large_3d.json", "w") as fh:
            json.dump({"levels": rows, "petsc_options": iterative_petsc_options(),
                       "loose_rtol": newton.LOOSE_RTOL}, fh, indent=1)


if __name__ == "__main__":
    main()
