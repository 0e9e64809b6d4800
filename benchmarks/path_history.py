"""The error a load path's history carries: one backward sweep against a chain after every step.

The 2D Cattaneo-Mindlin path (``cases.cattaneo_mindlin_path``: a press step, then ``--steps``
shear steps, Coulomb friction, nu = 0.49, the default weights) on the default mesh refined
``--refinements`` times uniformly, solved by ``ds.solve_path`` three times in one run: with
``history="every"`` (the chain of history goals after every step, the default before: k
estimates at step k), with the default ``history="last"`` (one backward sweep after the last
step: one estimate per earlier step in total) and with ``history=False``. Prints the path's
time of each run, the history's share of it, and the largest difference of the last step's
history terms (``eta_history``, ``J_low``, ``J_high``) between the first two runs::

    scripts/fenicsx python3 benchmarks/path_history.py --steps 8 --refinements 1
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.refine import refine_marked

RUNS = (("every step (before)", "every"), ("last step, one sweep (default)", None),
        ("no history", False))


def problems_of(comm: MPI.Comm, steps: int, refinements: int) -> list[ds.SignoriniProblem]:
    """The path's problems on the default mesh refined ``refinements`` times."""
    problems = cases.cattaneo_mindlin_path(comm, steps=steps)
    for _ in range(refinements):
        refined, _ = refine_marked(problems[0], None)
        problems = [p.with_mesh(refined.mesh, refined.facet_tags, refined.cell_tags)
                    for p in problems]
    return problems


def run(problems: list[ds.SignoriniProblem], history: Any) -> dict[str, Any]:
    """One path: its total time, the history's time, and the last step's record."""
    tic = time.perf_counter()
    with ds.solve_path(problems, ex.goal_friction_force(), history=history,
                       verbose=False) as res:
        steps = res.steps
    return {"total": time.perf_counter() - tic, "cells": steps[-1].num_cells,
            "history": sum(s.time["history"] for s in steps), "last": steps[-1]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=8, help="shear steps (steps + 1 problems)")
    parser.add_argument("--refinements", type=int, default=0)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    problems = problems_of(comm, args.steps, args.refinements)
    out = {name: run(problems, history) for name, history in RUNS}
    if comm.rank != 0:
        return
    old, new = (out[name]["last"] for name, _ in RUNS[:2])
    diff = max(abs(getattr(old, k) - getattr(new, k)) for k in ("eta_history", "J_low", "J_high"))
    print(f"{len(problems)} steps, {out[RUNS[0][0]]['cells']} cells, {comm.size} process(es)")
    print(f"last step: estimate {new.estimate:.6e}, eta_history {new.eta_history:.6e}, "
          f"interval [{new.J_low:.6e}, {new.J_high:.6e}]; max |old - new| of its history "
          f"terms {diff:.1e}")
    for name, _ in RUNS:
        r = out[name]
        print(f"  {name:32s} path {r['total']:7.1f} s   history {r['history']:6.1f} s")


if __name__ == "__main__":
    main()
