"""Time the dense Schur complement S = N K^-1 N^T of ``method="schur"`` two ways, on one mesh.

* entries of the inverse: S = N_C (K^-1)_CC N_C^T with (K^-1)_CC from MUMPS (ICNTL(30)), the
  default with MUMPS (:func:`dwr_signorini.linalg.mumps.mumps_inverse_entries`);
* solves: K X = N^T by multi-right-hand-side solves with the factors of K (the path for other
  direct solvers).

Both are timed on the same factors of K; ``factor`` is one factorisation + solve of K alone
(fresh solver, same options), for comparison. Also printed: the largest difference of the two
S relative to max |S|::

    scripts/fenicsx python3 benchmarks/schur_complement.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/schur_complement.py
"""

from __future__ import annotations

import argparse
import time

from mpi4py import MPI

import numpy as np
from bench_levels import problem_2d, problem_3d
from mumps_ordering import factor_times

from dwr_signorini import linalg
from dwr_signorini.spaces import Discretization


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="2d:64,3d:4", help="example:n, macro mesh sizes")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print(f"{'mesh':>6} {'DoFs':>9} {'n_lam':>6} {'factor':>8} {'entries':>8} "
              f"{'solves':>8} {'solves/entries':>14} {'max diff':>9}", flush=True)
    for case in args.cases.split(","):
        example, n = case.split(":")
        make = problem_2d if example == "2d" else problem_3d
        problem, _ = make(comm, int(n))
        disc = Discretization(problem)
        system = linalg.SchurNewtonSystem(disc)
        options = linalg.default_petsc_options(disc.mesh.topology.dim)
        seconds = {"factor": factor_times(system.K, system.f, options, repeat=1)[0][0]}
        schur = system.schur
        results = {}
        for name, method in (("entries", schur.compute_from_inverse_entries),
                             ("solves", schur.compute_by_solves)):
            comm.Barrier()
            tic = time.perf_counter()
            results[name] = method()
            seconds[name] = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
        if comm.rank == 0:
            S, T = results["entries"], results["solves"]
            diff = np.abs(S - T).max() / np.abs(T).max()
            print(f"{example:>6} {system.K.getSize()[0]:>9} {schur.n:>6} {seconds['factor']:8.2f} "
                  f"{seconds['entries']:8.2f} {seconds['solves']:8.2f} "
                  f"{seconds['solves'] / seconds['entries']:14.2f} {diff:9.1e}", flush=True)
        system.destroy()


if __name__ == "__main__":
    main()
