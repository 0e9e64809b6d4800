"""The P2 weights on the band around the contact zone against those of the whole mesh, in 3D.

One 3D level (example 5.3 from ``n x 4n x 4n`` macro boxes, or the 3D indentation of
``reference_3d.py`` from ``n x n x n/2``), solved once; then its estimate with each of the given
weights on the same solution, timed (the slower rank), with eta, the interval and whether it
holds the reference of ``reference_3d.py`` (``stored_reference``), and the time against the
solve's::

    scripts/fenicsx python3 benchmarks/band_weights_cost.py --problem obstacle --n 4 \\
        --weights local higher_order
    scripts/fenicsx mpirun -n 2 python3 benchmarks/band_weights_cost.py --problem indentation \\
        --n 16 --weights local
"""

from __future__ import annotations

import argparse
import time

from mpi4py import MPI

from reference_3d import indentation_problem, stored_reference, total_force

import dwr_signorini as ds
from dwr_signorini import examples as ex


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", choices=("obstacle", "indentation"), default="obstacle")
    parser.add_argument("--n", type=int, default=4)
    parser.add_argument("--weights", nargs="+", default=["local", "higher_order"])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.problem == "obstacle":
        n = args.n
        problem, goal = ex.obstacle_problem(comm, (n, 4 * n, 4 * n)), ex.goal_obstacle()
    else:
        problem, goal = indentation_problem(comm, args.n), total_force
    J_ref, _ = stored_reference(args.problem)
    tic = time.perf_counter()
    sol = ds.solve(problem)
    t_solve = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
    cells = sol.disc.mesh.topology.index_map(3).size_global
    dofs = sol.disc.V.dofmap.index_map.size_global * sol.disc.V.dofmap.index_map_bs
    if comm.rank == 0:
        print(f"{args.problem}, n = {args.n}, {comm.size} rank(s): {cells:,} cells, {dofs:,} "
              f"DoFs, method {sol.method}, solve {t_solve:.2f} s, J_ref {J_ref:.6g}")
        print(f"{'weights':>13} {'eta':>12} {'J_low':>11} {'J_high':>11} {'holds':>5} "
              f"{'estimate [s]':>12} {'/ solve':>7}", flush=True)
    for weights in args.weights:
        tic = time.perf_counter()
        with ds.estimate(sol, goal, weights=weights) as est:
            t = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
            lo, hi = est.interval
        if comm.rank == 0:
            print(f"{weights:>13} {est.eta:+12.5e} {lo:11.6g} {hi:11.6g} "
                  f"{'yes' if lo <= J_ref <= hi else 'NO':>5} {t:12.2f} {t / t_solve:7.2f}",
                  flush=True)
    sol.destroy()


if __name__ == "__main__":
    main()
