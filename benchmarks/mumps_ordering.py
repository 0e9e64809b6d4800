"""Which fill-reducing ordering MUMPS should use: seconds of one factorisation + solve of K.

For the stiffness matrix K of example 5.1 (2D, triangles) and example 5.3 (3D, tetrahedra), one
MUMPS LU factorisation + solve with its default ordering (ICNTL(7)=7, automatic: METIS here),
METIS (5) and AMD (0); the best of ``--repeat`` runs, and the ratio to the default. It justifies
the dimension-dependent default of :func:`dwr_signorini.newton.default_petsc_options`::

    scripts/fenicsx python3 benchmarks/mumps_ordering.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/mumps_ordering.py
"""

from __future__ import annotations

import argparse
import time

from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.newton import NewtonSystem, clear_options, set_options
from dwr_signorini.spaces import discretize

ORDERINGS = {"default (7)": None, "METIS (5)": 5, "AMD (0)": 0}


def factor_time(K: PETSc.Mat, f: PETSc.Vec, ordering: int | None, repeat: int) -> float:
    """Best wall-clock seconds (max over ranks) of a fresh MUMPS LU factorisation + solve."""
    best = float("inf")
    for _ in range(repeat):
        ksp = PETSc.KSP().create(K.getComm())
        options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
        if ordering is not None:
            options["mat_mumps_icntl_7"] = ordering
        names = set_options(ksp, "dwr_signorini_ordering_", options)
        x = f.duplicate()
        K.getComm().tompi4py().Barrier()
        tic = time.perf_counter()
        ksp.setOperators(K)
        ksp.setUp()
        ksp.solve(f, x)
        elapsed = K.getComm().tompi4py().allreduce(time.perf_counter() - tic, op=MPI.MAX)
        best = min(best, elapsed)
        ksp.destroy()
        clear_options(names)
        x.destroy()
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-2d", type=int, default=64, help="macro mesh 3n x 2n (198k DoFs)")
    parser.add_argument("--n-3d", type=int, default=7, help="macro mesh n x 4n x 4n (146k DoFs)")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    msh, tags = ex.analytic_2d_mesh(comm, 3 * args.n_2d, 2 * args.n_2d,
                                    cell_type=mesh.CellType.triangle)
    problems = {
        "2D (5.1)": ds.SignoriniProblem(msh, tags, contact=ex.CONTACT,
                                        dirichlet=(ex.DIRICHLET,), E=10.0, nu=0.3),
        "3D (5.3)": ex.obstacle_problem(comm, n=(args.n_3d, 4 * args.n_3d, 4 * args.n_3d)),
    }
    if comm.rank == 0:
        print(f"{'mesh':>10} {'DoFs':>9} {'ordering':>12} {'seconds':>9} {'/ default':>9}")
    for name, problem in problems.items():
        system = NewtonSystem(discretize(problem))
        times = {key: factor_time(system.K, system.f, value, args.repeat)
                 for key, value in ORDERINGS.items()}
        for key, seconds in times.items():
            if comm.rank == 0:
                print(f"{name:>10} {system.K.getSize()[0]:>9} {key:>12} {seconds:9.3f} "
                      f"{seconds / times['default (7)']:9.2f}", flush=True)
        system.destroy()


if __name__ == "__main__":
    main()
