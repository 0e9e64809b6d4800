"""Coulomb's semi-smooth Newton method from zero on a sweep of exact problems, and along paths.

Three tables, each printed as it goes and written to ``<output>/friction_robustness.json``:

1. **The sweep** (``tests/friction_cases.py``): the exact uniform patch tests (stick ratios
   0.05-0.999, slip ratios 1.001-100, mu 0.01, 0.3, 0.9, 2, triangles, quadrilaterals,
   tetrahedra, hexahedra, two shear directions in 3D), one ``ds.solve`` from zero each, with
   Coulomb's law and with Tresca's law of threshold s = mu lambda_n (the same solution):
   Newton steps, time, the error against the exact solution (max of lambda_n, lambda_t, slip,
   relative). Above the uniqueness bound of the discrete problem (mu = 2 > 0.958) an error of
   order 1 means another solution of the discrete problem (``tests/test_coulomb_sweep.py``).
2. **Cattaneo-Mindlin paths**: the Newton steps per load step of ``solve_path`` on the 2D and
   3D problems of ``examples`` (press, then shear in steps), and the one-step solves from zero.
3. **The cost per Newton step** of Coulomb's law against Tresca's on the same mesh (the sheared
   block on a cylinder, threshold s = mu lambda_n of the frictionless solution's mean), best of
   ``--repeat``.

::

    scripts/fenicsx python3 benchmarks/friction_robustness.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/friction_robustness.py
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.io import write_json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests import friction_cases as fc


def say(comm: MPI.Comm, text: str) -> None:
    """Print on rank 0, at once."""
    if comm.rank == 0:
        print(text, flush=True)


def sweep_table(comm: MPI.Comm, quick: bool) -> list[dict]:
    """Table 1: every case of the sweep with Coulomb's and Tresca's law."""
    rows = []
    say(comm, f"{'case':36s} {'law':8s} {'cells':>6s} {'ranks':>5s} {'steps':>5s} "
              f"{'time [s]':>8s} {'error':>8s}")
    for case in fc.sweep(quick=quick):
        lam_n = case.exact()["lam_n"]
        for law in (ds.Coulomb(case.mu), ds.Tresca(case.mu * lam_n)):
            problem = case.problem(comm, law)
            comm.barrier()
            tic = time.perf_counter()
            try:
                with ds.solve(problem, rtol=1e-10) as sol:
                    elapsed = time.perf_counter() - tic
                    steps = sol.newton_iterations
                    error = max(fc.errors(case, sol).values())
            except ds.ConvergenceError:
                elapsed, steps, error = time.perf_counter() - tic, -1, float("nan")
            cells = comm.allreduce(problem.mesh.topology.index_map(
                problem.mesh.topology.dim).size_local, op=MPI.SUM)
            row = {"case": case.label, "law": law.name, "mu": case.mu, "ratio": case.ratio,
                   "cells": cells, "ranks": comm.size, "steps": steps,
                   "time": comm.allreduce(elapsed, op=MPI.MAX), "error": error}
            rows.append(row)
            say(comm, f"{case.label:36s} {law.name:8s} {cells:6d} {comm.size:5d} "
                      f"{steps:5d} {row['time']:8.3f} {error:8.1e}")
    for law in ("coulomb", "tresca"):
        for bound in ("below", "above"):
            part = [r for r in rows if r["law"] == law and (r["mu"] < 1.0) == (bound == "below")]
            steps = [r["steps"] for r in part]
            if not part:
                continue
            exact = sum(r["error"] <= 1e-8 for r in part)
            failed = sum(s < 0 for s in steps)
            say(comm, f"{law} mu {bound} the bound: {len(part)} cases, {failed} failed, "
                      f"{exact} exact to 1e-8, Newton steps median "
                      f"{statistics.median(steps):g}, max {max(steps)}")
    return rows


def path_table(comm: MPI.Comm, steps: int) -> list[dict]:
    """Table 2: Newton steps per load step of the Cattaneo-Mindlin paths; one-step solves."""
    rows = []
    goal = ex.goal_friction_force()
    for dim, build in ((2, cases.cattaneo_mindlin_path), (3, cases.cattaneo_mindlin_path_3d)):
        problems = build(comm, steps=steps)
        counts: list[int] = []

        def record(rec, sol, est, counts=counts):
            counts.append(sol.newton_iterations)

        tic = time.perf_counter()
        with ds.solve_path(problems, goal, callback=record, verbose=False, weights="patch"):
            pass
        elapsed = time.perf_counter() - tic
        shear = counts[1:]
        say(comm, f"Cattaneo-Mindlin {dim}D path, {steps} shear steps: Newton steps per load "
                  f"step {counts} (shear steps: median {statistics.median(shear):g}, max "
                  f"{max(shear)}, {sum(counts) / len(counts):.2f} a step), {elapsed:.1f} s")
        tic = time.perf_counter()
        with ds.solve(build(comm, steps=1)[-1]) as sol:
            one = sol.newton_iterations
        say(comm, f"Cattaneo-Mindlin {dim}D in one step from zero: {one} Newton steps, "
                  f"{time.perf_counter() - tic:.1f} s")
        rows.append({"dim": dim, "path_steps": counts, "one_step": one, "time": elapsed})
    return rows


def cost_table(comm: MPI.Comm, scales: list[int], repeat: int) -> list[dict]:
    """Table 3: the time per Newton step of Coulomb's law against Tresca's, one mesh each."""
    rows = []
    mu = 0.3
    say(comm, f"{'mesh':>10s} {'law':8s} {'steps':>5s} {'solve [s]':>9s} {'per step [s]':>12s}")
    for scale in scales:
        base = ex.friction_problem(comm, nx=17 * scale, ny=7 * scale)
        with ds.solve(ds.SignoriniProblem(
            base.mesh, base.facet_tags, contact=ex.CONTACT, dirichlet=base.dirichlet_values,
            E=10.0, nu=0.3, gap=base.gap,
        )) as free:
            n_q = free.system.algebra.n_q
            active = free.active
            mean = comm.allreduce(float(np.sum(free.lam.x.array[:n_q][active])), op=MPI.SUM)
            s = mu * mean / max(free.num_active, 1)
        per_step = {}
        for law in (ds.Coulomb(mu), ds.Tresca(s)):
            problem = ds.SignoriniProblem(
                base.mesh, base.facet_tags, contact=ex.CONTACT,
                dirichlet=base.dirichlet_values, E=10.0, nu=0.3, gap=base.gap, friction=law,
            )
            best = None
            for _ in range(repeat):
                comm.barrier()
                tic = time.perf_counter()
                with ds.solve(problem) as sol:
                    elapsed = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
                    n = sol.newton_iterations
                best = elapsed if best is None else min(best, elapsed)
            per_step[law.name] = best / n
            say(comm, f"{17 * scale:4d}x{7 * scale:<5d} {law.name:8s} {n:5d} {best:9.3f} "
                      f"{best / n:12.4f}")
            rows.append({"scale": scale, "law": law.name, "steps": n, "time": best})
        say(comm, f"  Coulomb / Tresca per Newton step: "
                  f"{per_step['coulomb'] / per_step['tresca']:.2f}")
    return rows


def main() -> None:
    """Run the three tables (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="mu = 0.3, triangles and tets")
    parser.add_argument("--path-steps", type=int, default=10, help="shear steps of the paths")
    parser.add_argument("--scales", default="1,2,4", help="the cost table's meshes 17n x 7n")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    out = {
        "sweep": sweep_table(comm, args.quick),
        "paths": path_table(comm, args.path_steps),
        "cost": cost_table(comm, [int(s) for s in args.scales.split(",")], args.repeat),
    }
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        write_json(args.output / f"friction_robustness_np{comm.size}.json", out)


if __name__ == "__main__":
    main()
