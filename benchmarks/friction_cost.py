"""What Tresca friction costs against the frictionless problem on the same meshes.

The sheared block on a cylinder of ``dwr_signorini.examples.friction_problem`` (the friction
demo), with Tresca's law and without friction (the same data, ``friction=None``), on uniform
refinements of its macro mesh: per mesh, the Newton steps from a zero start, the time of the
solve, per Newton step, and the time of the estimate (eta with the patch weights, so that both
estimates do the same work; ``weights="auto"`` may pick P2 weights for one and not the
other) of a goal each problem has (the normal contact force), the best of ``--repeat`` runs.
The ratio columns are Tresca over frictionless, measured in the same run. With ``--dim 3`` the
block on a sphere (``FRICTION_DEFAULTS_3D``, macro mesh 6n x 6n x 3n), where Tresca's Newton
matrix is not symmetric (LU, a factorisation per step) and the frictionless one is factored by
LDL^T with factor reuse (``--method block``) or solved by the package's default::

    scripts/fenicsx python3 benchmarks/friction_cost.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/friction_cost.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/friction_cost.py --dim 3 --scales 1,2,3 \
        --method block
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.io import write_json


def problems(comm: MPI.Comm, scale: int, dim: int = 2) -> dict[str, ds.SignoriniProblem]:
    """The friction demo's problem on a macro mesh ``scale`` times finer, with and without."""
    if dim == 2:
        tresca = ex.friction_problem(comm, nx=17 * scale, ny=7 * scale)
    else:
        d = ex.FRICTION_DEFAULTS_3D
        tresca = ex.friction_problem(comm, nx=d["nx"] * scale, ny=d["ny"] * scale,
                                     radius=d["radius"], dim=3)
    free = ds.SignoriniProblem(
        tresca.mesh, tresca.facet_tags, contact=ex.CONTACT, dirichlet=tresca.dirichlet_values,
        E=10.0, nu=0.3, gap=tresca.gap,
    )
    return {"frictionless": free, "tresca": tresca}


def normal_force(u, lam, m):
    return lam * m.ds_contact


def measure(problem: ds.SignoriniProblem, repeat: int, method: str | None = None
            ) -> dict[str, float]:
    """Best-of-``repeat`` seconds of the solve and the estimate, and the Newton steps."""
    best: dict[str, float] = {}
    for _ in range(repeat):
        comm = problem.mesh.comm
        comm.Barrier()
        tic = time.perf_counter()
        sol = ds.solve(problem, method=method)
        t_solve = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
        tic = time.perf_counter()
        est = ds.estimate(sol, normal_force, weights="patch")
        t_est = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
        row = {"dofs": sol.disc.num_dofs, "newton": sol.newton_iterations, "solve": t_solve,
               "per_step": t_solve / max(sol.newton_iterations, 1), "estimate": t_est,
               "method": sol.method}
        est.destroy()
        sol.destroy()
        if not best or row["solve"] < best["solve"]:
            best = row
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scales", default="1,2,4,8", help="macro mesh 17n x 7n")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--dim", type=int, choices=(2, 3), default=2)
    parser.add_argument("--method", choices=("block", "schur"), default=None,
                        help="the frictionless problem's linear solver (default: the package's)")
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    for p in problems(comm, 1, args.dim).values():  # JIT, once
        measure(p, 1)
    rows = []
    if comm.rank == 0:
        print(f"{'dofs':>9} {'law':>12} {'newton':>6} {'solve [s]':>9} {'per step':>9} "
              f"{'estimate':>9} {'method':>6} | {'solve':>6} {'step':>6} {'est.':>6}")
    for scale in (int(s) for s in args.scales.split(",")):
        result = {
            law: measure(p, args.repeat, args.method if law == "frictionless" else None)
            for law, p in problems(comm, scale, args.dim).items()
        }
        for law, r in result.items():
            ratio = {k: r[k] / result["frictionless"][k] for k in ("solve", "per_step",
                                                                   "estimate")}
            rows.append({"scale": scale, "law": law, **r, **{f"ratio_{k}": v
                                                              for k, v in ratio.items()}})
            if comm.rank == 0:
                print(f"{r['dofs']:9d} {law:>12} {r['newton']:6d} {r['solve']:9.3f} "
                      f"{r['per_step']:9.3f} {r['estimate']:9.3f} {r['method']:>6} | "
                      f"{ratio['solve']:6.2f} {ratio['per_step']:6.2f} {ratio['estimate']:6.2f}",
                      flush=True)
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        suffix = "" if args.dim == 2 else "_3d"
        write_json(args.output / f"friction_cost{suffix}_np{comm.size}.json",
                   {"ranks": comm.size, "rows": rows})


if __name__ == "__main__":
    main()
