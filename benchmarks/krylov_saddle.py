"""One Newton step of the two Krylov paths, in CG + GAMG solves of K.

For example 5.3 (macro mesh n x 4n x 4n) and the 3D indentation of ``reference_3d.py`` (n x n x
n/2), the converged active set is found once (``method="schur"``, K factored), and then, on the
same mesh and active set, one Newton step from zero is timed loosely (the tolerances of the
steps before the active set settles) and accurately:

* ``krylov``: :class:`~dwr_signorini.linalg.krylov.KrylovNewtonSystem`, GMRES on the
  saddle-point system with one GAMG cycle of K per iteration (``--alphas`` also tries other
  scales of its Schur approximation);
* ``krylov-schur``: :class:`~dwr_signorini.linalg.schur.SchurNewtonSystem` with
  ``iterative_petsc_options()``, CG on S_AA with a CG + GAMG solve of K per iteration;

against ``ref``, one CG + GAMG solve of K to 1e-10 from zero with the same options (its set-up
printed apart). Set-up of each path (multigrid, S_hat) printed apart too. Writes
``benchmarks/results/krylov_saddle[_np<N>].json``::

    scripts/fenicsx python3 benchmarks/krylov_saddle.py
    scripts/fenicsx python3 benchmarks/krylov_saddle.py --n-3d 3 --n-indent 8 --alphas 1,2,3,4,8
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
from reference_3d import indentation_problem

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.linalg import KrylovNewtonSystem, SchurNewtonSystem, krylov
from dwr_signorini.linalg.nullspace import rigid_body_modes
from dwr_signorini.linalg.options import OptionsScope, iterative_petsc_options, unique_prefix
from dwr_signorini.spaces import discretize


def reference_solve(sol: ds.Solution) -> tuple[float, float, int]:
    """(set-up, solve, iterations) of one CG + GAMG solve of K = [f - N^T lam] from zero."""
    system = sol.system
    comm = system.disc.comm
    scope = OptionsScope(unique_prefix(), iterative_petsc_options())
    ksp = PETSc.KSP().create(comm)
    nullspace = rigid_body_modes(system.V, system.n_u)
    K = system.K
    K.setNearNullSpace(nullspace)
    b, x, lam = K.createVecRight(), K.createVecRight(), system.N.createVecLeft()
    try:
        scope.apply(ksp)
        ksp.setOperators(K)
        lam.array_w[:] = system.split(system.x)[1]
        system.NT.mult(lam, b)
        b.aypx(-1.0, system.f)
        comm.barrier()
        tic = time.perf_counter()
        ksp.setUp()
        setup = time.perf_counter() - tic
        tic = time.perf_counter()
        ksp.solve(b, x)
        return setup, time.perf_counter() - tic, ksp.getIterationNumber()
    finally:
        for obj in (ksp, nullspace, b, x, lam):
            obj.destroy()
        scope.destroy()


def time_step(cls: type, disc, active: np.ndarray, loose: bool) -> tuple[float, float, int]:
    """(set-up, step, iterations) of one Newton step from zero of a new system of ``cls``."""
    comm = disc.comm
    options = iterative_petsc_options() if cls is SchurNewtonSystem else None
    comm.barrier()
    tic = time.perf_counter()
    system = cls(disc, options)
    setup = time.perf_counter() - tic
    try:
        system.set_loose(loose)
        comm.barrier()
        tic = time.perf_counter()
        system.solve_active(active)
        step = time.perf_counter() - tic
        iterations = system.iterations if cls is KrylovNewtonSystem else system.schur.iterations
        return setup, step, iterations
    finally:
        system.destroy()


def measure(name: str, problem: ds.SignoriniProblem, alphas: list[float]) -> list[dict]:
    """The rows of one problem."""
    disc = discretize(problem)
    comm = disc.comm
    rows = []
    with ds.solve(disc, method="schur") as sol:
        setup_ref, ref, its_ref = reference_solve(sol)
        active = sol.system.active.copy()
        base = {"problem": name, "dofs": disc.num_dofs, "num_active": sol.num_active,
                "ranks": comm.size, "ref_setup": setup_ref, "ref": ref, "ref_its": its_ref}
    paths = [("krylov-schur", SchurNewtonSystem, krylov.ALPHA)]
    paths += [("krylov", KrylovNewtonSystem, alpha) for alpha in alphas]
    default = krylov.ALPHA
    for path, cls, alpha in paths:
        krylov.ALPHA = alpha
        for loose in (True, False):
            setup, step, its = time_step(cls, disc, active, loose)
            rows.append({**base, "path": path, "alpha": alpha if cls is KrylovNewtonSystem
                         else None, "loose": loose, "setup": setup, "step": step,
                         "iterations": its, "step_per_ref": step / ref})
            if comm.rank == 0:
                r = rows[-1]
                print(f"{name:12s} {r['dofs']:9d} {r['num_active']:6d} {path:13s} "
                      f"{'' if r['alpha'] is None else r['alpha']:>5} "
                      f"{'loose' if loose else 'full':6s} {setup:8.2f} {step:8.2f} {its:6d} "
                      f"{ref:7.2f} {its_ref:4d} {setup_ref:7.2f} {step / ref:8.2f}", flush=True)
    krylov.ALPHA = default
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-3d", type=int, default=7, help="example 5.3 on n x 4n x 4n boxes")
    parser.add_argument("--n-indent", type=int, default=16, help="the indentation on n x n x n/2")
    parser.add_argument("--alphas", default=str(krylov.ALPHA))
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    alphas = [float(a) for a in args.alphas.split(",")]
    if comm.rank == 0:
        print(f"{'problem':12s} {'DoFs':>9s} {'|A|':>6s} {'path':13s} {'alpha':>5s} "
              f"{'step':6s} {'set-up':>8s} {'solve':>8s} {'its':>6s} {'ref':>7s} {'its':>4s} "
              f"{'ref set-up':>7s} {'solve/ref':>8s}")
    n = args.n_3d
    rows = measure("example 5.3", ex.obstacle_problem(comm, (n, 4 * n, 4 * n)), alphas)
    rows += measure("indentation", indentation_problem(comm, args.n_indent), alphas)
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        tag = "" if comm.size == 1 else f"_np{comm.size}"
        path = args.output / f"krylov_saddle{tag}.json"
        path.write_text(json.dumps(rows, indent=1))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
