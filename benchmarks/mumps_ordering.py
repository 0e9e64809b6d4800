"""Which factorisation and ordering MUMPS should use: seconds of one factorisation + solve.

For the stiffness matrix K of example 5.1 (2D, triangles) and example 5.3 (3D, tetrahedra), one
MUMPS LDL^T factorisation + solve with its default ordering (ICNTL(7)=7, automatic: METIS here),
METIS (5), AMD (0) and AMF (2), and its LU with the ordering that
:func:`dwr_signorini.linalg.default_petsc_options` chooses; then, for the symmetric form of the
block Newton matrix of the last Newton step (method "block", see
:meth:`dwr_signorini.linalg.NewtonSystem.newton_matrix`), LDL^T against LU with that ordering,
and LDL^T with each ordering.
The best of ``--repeat`` runs, the ratio to the first row of the matrix, and MUMPS's factor
entries. It justifies the defaults of ``default_petsc_options``::

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
from dwr_signorini.linalg.mumps import mumps_factor, mumps_failure, set_up
from dwr_signorini.linalg.options import OptionsScope, default_petsc_options
from dwr_signorini.spaces import discretize

ORDERINGS = {"default (7)": {}, "METIS (5)": {"mat_mumps_icntl_7": 5},
             "AMD (0)": {"mat_mumps_icntl_7": 0}, "AMF (2)": {"mat_mumps_icntl_7": 2}}
FACTORISATIONS = {"LDL^T": {"pc_type": "cholesky"}, "LU": {"pc_type": "lu"}}


def factor_times(
    K: PETSc.Mat, f: PETSc.Vec, options: dict, repeat: int
) -> list[tuple[float, int]]:
    """``repeat`` fresh factorisations (or preconditioner set-ups) + solves of K with ``options``.

    Returns:
        For each: the seconds (max over ranks) and the factor entries (MUMPS's INFOG(20),
        estimated by the analysis; 0 for a solver that is not MUMPS).

    Raises:
        RuntimeError: A solve did not converge.
    """
    runs = []
    x = f.duplicate()
    for _ in range(repeat):
        ksp = PETSc.KSP().create(K.getComm())
        scope = OptionsScope("dwr_signorini_ordering_", options=options)
        scope.apply(ksp)
        K.getComm().tompi4py().Barrier()
        tic = time.perf_counter()
        set_up(ksp, K)  # as the Newton steps: more MUMPS workspace where the estimate fell short
        ksp.solve(f, x)
        elapsed = K.getComm().tompi4py().allreduce(time.perf_counter() - tic, op=MPI.MAX)
        if ksp.getConvergedReason() <= 0:
            why = mumps_failure(ksp) or "not a MUMPS failure"
            raise RuntimeError(
                f"the solve with K failed (KSP reason {ksp.getConvergedReason()}; {why})"
            )
        factor = mumps_factor(ksp)
        runs.append((elapsed, 0 if factor is None else factor.getMumpsInfog(20)))
        # A reference to the factor held past ksp.destroy() keeps MUMPS's memory alive.
        del factor
        ksp.destroy()
        scope.destroy()
    x.destroy()
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-2d", type=int, default=64, help="macro mesh 3n x 2n (198k DoFs)")
    parser.add_argument("--n-3d", type=int, default=7, help="macro mesh n x 4n x 4n (146k DoFs)")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--meshes", default="2d,3d", help="which of 2d, 3d")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    problems = {}
    if "2d" in args.meshes:
        problems["2D (5.1)"] = ex.analytic_problem(comm, 3 * args.n_2d, 2 * args.n_2d,
                                                   mesh.CellType.triangle)
    if "3d" in args.meshes:
        n = args.n_3d
        problems["3D (5.3)"] = ex.obstacle_problem(comm, n=(n, 4 * n, 4 * n))
    if comm.rank == 0:
        print(f"{'mesh':>10} {'matrix':>7} {'DoFs':>9} {'option':>26} {'seconds':>9} "
              f"{'/ first':>9} {'factor entries':>14}")
    for name, problem in problems.items():
        sol = ds.solve(discretize(problem), method="block")  # K and the block matrix A
        tdim = problem.mesh.topology.dim
        chosen = default_petsc_options(tdim)
        rows = [("K", sol.system.K, f"LDL^T, ordering {key}", default_petsc_options() | value)
                for key, value in ORDERINGS.items()]
        rows.append(("K", sol.system.K, "LU, chosen ordering", chosen | FACTORISATIONS["LU"]))
        rows += [("Newton", sol.system.A, f"{key}, chosen ordering", chosen | value)
                 for key, value in FACTORISATIONS.items()]
        rows += [("Newton", sol.system.A, f"LDL^T, ordering {key}", default_petsc_options() | value)
                 for key, value in ORDERINGS.items()]
        first = {}
        for matrix_name, matrix, label, options in rows:
            rhs = matrix.createVecLeft()
            rhs.set(1.0)
            runs = factor_times(matrix, rhs, options, args.repeat)
            seconds, entries = min(t for t, _ in runs), runs[0][1]
            rhs.destroy()
            first.setdefault(matrix_name, seconds)
            if comm.rank == 0:
                print(f"{name:>10} {matrix_name:>7} {matrix.getSize()[0]:>9} {label:>26} "
                      f"{seconds:9.3f} {seconds / first[matrix_name]:9.2f} {entries:14d}",
                      flush=True)
        sol.system.destroy()


if __name__ == "__main__":
    main()
