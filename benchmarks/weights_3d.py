"""Estimates with patch, hierarchical and higher-order weights on 3D levels, against references.

Adaptive runs (eta with patch weights, fraction 0.05, all edges of a marked cell) of the 3D
indentation of ``reference_3d.py`` (block ``[-1, 1]^2 x [-1, 0]``, sphere of radius 2 lowered by
0.005, contact radius about 0.1, goal the total contact force) from the macro meshes 8 x 8 x 4
and 12 x 12 x 6, whose first levels miss the contact zone or find it on too many facets, and of
example 5.3 from its 1 x 4 x 4 macro mesh. On every level the script estimates the error three
times from the same solution: with the default patch weights, with ``weights="hierarchical"``
(the P2 solutions computed iteratively, the Newton factors as coarse level) and with
``weights="higher_order"`` (the same P2 solutions by a factorisation), and measures them against
the reference values of ``benchmarks/results/reference_3d.json`` (from J_h alone; run
``reference_3d.py`` first). It prints per level:

* cells, active macro facets, J_h, the error J_ref - J_h;
* eta, its effectivity Ieff = (J_ref - J_h) / eta, eta_p and its effectivity, for each weight;
* R_A and ``(|eta| + |R_A|) / |e|``, the stopping quantity of ``solve_adaptive``, against the
  error (patch weights);
* the time of each estimate.

and writes ``benchmarks/results/weights_3d.json``::

    scripts/fenicsx mpirun -n 2 python3 benchmarks/weights_3d.py
    scripts/fenicsx python3 benchmarks/weights_3d.py --tables-from \\
        benchmarks/results/weights_3d.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from mpi4py import MPI

from reference_3d import indentation_problem, total_force

import dwr_signorini as ds
from dwr_signorini import examples as ex

RESULTS = Path("benchmarks/results")


def runs(comm: MPI.Comm) -> dict[str, tuple[str, Any, Any, int]]:
    """Per run: the problem's key in reference_3d.json, the problem builder, goal and levels."""
    return {
        "indentation, 8 x 8 x 4": ("indentation", lambda: indentation_problem(comm, 8),
                                   total_force, 3),
        "indentation, 12 x 12 x 6": ("indentation", lambda: indentation_problem(comm, 12),
                                     total_force, 2),
        "example 5.3, 1 x 4 x 4": ("obstacle", lambda: ex.obstacle_problem(comm, (1, 4, 4)),
                                   ex.goal_obstacle(), 6),
    }


WEIGHTS = ("patch", "hierarchical", "higher_order")


def run(comm: MPI.Comm, problem: ds.SignoriniProblem, goal: Any, levels: int,
        J_ref: float) -> list[dict[str, Any]]:
    """One adaptive run; at every level the estimates of the same solution with every weight."""
    rows: list[dict[str, Any]] = []

    def measure(record: ds.LevelRecord, sol: ds.Solution, est: ds.Estimate) -> None:
        error = J_ref - est.J_h
        row: dict[str, Any] = {"level": record.level, "cells": record.num_cells,
                               "active": record.num_active, "J_h": est.J_h, "error": error,
                               "stop_ratio": (abs(est.eta) + abs(est.active_set_remainder))
                               / abs(error)}
        for weights in WEIGHTS:
            tic = time.perf_counter()
            e = est if weights == "patch" else ds.estimate(sol, goal, weights=weights)
            t = record.time["estimate"] if weights == "patch" else time.perf_counter() - tic
            row[weights] = {"eta": e.eta, "eta_p": e.eta_p, "R_A": e.active_set_remainder,
                            "rho": e.rho, "rho_star": e.rho_star, "contact": e.contact_term,
                            "ieff": error / e.eta, "ieff_p": error / e.eta_p,
                            "time": comm.allreduce(t, op=MPI.MAX)}
            if e is not est:
                e.destroy()
        rows.append(row)
        print_row(comm, row)

    with ds.solve_adaptive(problem, goal, fraction=0.05,
                           max_levels=levels, verbose=False, callback=measure):
        pass
    return rows


HEADER = (f"{'L':>2} {'cells':>8} {'act':>4} {'J_h':>8} {'J_ref-J_h':>10} {'R_A':>9} "
          f"{'stop/e':>6}" + "".join(f" | {w[:12]:>12} {'Ieff':>6} {'eta_p':>9} {'Ieff':>6} "
                                     f"{'t':>6}" for w in WEIGHTS))


def print_row(comm: MPI.Comm, r: dict[str, Any]) -> None:
    if comm.rank != 0:
        return
    line = (f"{r['level']:2d} {r['cells']:8d} {r['active']:4d} {r['J_h']:8.5f} "
            f"{r['error']:+10.4f} {r['patch']['R_A']:+9.4f} {r['stop_ratio']:6.2f}")
    for w in WEIGHTS:
        e = r[w]
        line += (f" | {e['eta']:+12.4f} {e['ieff']:6.2f} {e['eta_p']:+9.4f} "
                 f"{e['ieff_p']:6.2f} {e['time']:6.2f}")
    print(line, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tables-from", type=Path, help="print the tables of a written JSON")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.tables_from is not None:
        data = json.loads(args.tables_from.read_text())
    else:
        references = json.loads((RESULTS / "reference_3d.json").read_text())
        data = {"num_processes": comm.size, "runs": {}}
        for name, (key, build, goal, levels) in runs(comm).items():
            J_ref, U = references[key]["J_ref"], references[key]["uncertainty"]
            if comm.rank == 0:
                print(f"\n{name}: J_ref = {J_ref:.6g} +- {U:.2g}\n{HEADER}", flush=True)
            data["runs"][name] = {"J_ref": J_ref, "uncertainty": U,
                                  "levels": run(comm, build(), goal, levels, J_ref)}
        if comm.rank == 0:
            RESULTS.mkdir(parents=True, exist_ok=True)
            (RESULTS / "weights_3d.json").write_text(json.dumps(data, indent=1))
        return
    for name, r in data["runs"].items():
        if comm.rank == 0:
            print(f"\n{name}: J_ref = {r['J_ref']:.6g} +- {r['uncertainty']:.2g}\n{HEADER}")
        for row in r["levels"]:
            print_row(comm, row)


if __name__ == "__main__":
    main()
