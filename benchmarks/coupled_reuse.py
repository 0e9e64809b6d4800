"""Factor reuse on the coupled (nonsymmetric) Newton path: row updates against factorisations.

The first ``--steps`` steps of the Cattaneo-Mindlin path (``cases.cattaneo_mindlin_path``,
Coulomb friction) on the default mesh refined ``--refinements`` times uniformly, solved by
``ds.solve_path`` (patch weights, no history chain) twice: with the defaults (a step whose matrix
differs from the factored one in few rows is solved by a row update of the old factors,
``linalg.lowrank.RowUpdate``) and with ``linalg.factor.ReusePolicy(fraction=-1)`` (every Newton
step factored). Prints per step the Newton steps, factorisations and reused steps, J_h, and the time
per phase of each run::

    scripts/fenicsx mpirun -n 2 python3 benchmarks/coupled_reuse.py
"""

from __future__ import annotations

import argparse
import time

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.linalg.factor import FactoredNewtonSystem, ReusePolicy
from dwr_signorini.refine import refine_marked
from dwr_signorini.timing import snapshot


def run(comm: MPI.Comm, refinements: int, steps: int) -> tuple[list, dict, float]:
    """One path: per step (Newton steps, factorisations, reused, J_h), phase times, total."""
    problems = cases.cattaneo_mindlin_path(comm)
    for _ in range(refinements):
        refined, _ = refine_marked(problems[0], None)
        problems = [p.with_mesh(refined.mesh, refined.facet_tags, refined.cell_tags)
                    for p in problems]
    rows = []

    def record(rec, sol, est):
        rows.append((rec.num_cells, sol.newton_iterations, sol.system.factorizations,
                     sol.system.reused, rec.J_h))

    before, tic = snapshot(), time.perf_counter()
    ds.solve_path(problems[:steps], ex.goal_friction_force(), weights="patch", history=False,
                  callback=record, verbose=False).destroy()
    total = time.perf_counter() - tic
    after = snapshot()
    phases = {k: after[k] - before[k] for k in after if after[k] - before[k] > 0.05}
    return rows, phases, total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--refinements", type=int, default=3)
    parser.add_argument("--steps", type=int, default=3)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    default = FactoredNewtonSystem.reuse
    for name, policy in (("row updates", default), ("every step factored", ReusePolicy(-1.0))):
        FactoredNewtonSystem.reuse = policy
        rows, phases, total = run(comm, args.refinements, args.steps)
        if comm.rank == 0:
            print(f"{name}: {total:.1f} s, cells {rows[0][0]}")
            for k, (_, newton, factored, reused, J_h) in enumerate(rows):
                print(f"  step {k}: Newton {newton:2d}  factorisations {factored:2d}  "
                      f"reused {reused:2d}  J_h {J_h:.12e}")
            print("  " + ", ".join(f"{k} {v:.1f} s" for k, v in phases.items()), flush=True)
    FactoredNewtonSystem.reuse = default


if __name__ == "__main__":
    main()
