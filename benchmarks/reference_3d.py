"""Reference values of J in 3D from J_h alone, and the effectivity of the estimates against them.

Two 3D problems:

* ``obstacle``: the paper's example 5.3 (``examples.obstacle_problem``, goal ``goal_obstacle``);
* ``indentation``: a block ``[-1, 1]^2 x [-1, 0]`` clamped at the bottom, pressed at its top by a
  sphere of radius 2 lowered by 0.005 (paraboloid gap), E = 1e3, nu = 0.3, goal the total contact
  force ``int_GC lambda ds`` (the case of the trust issue).

For each, three independent sequences of refinement from the same macro mesh: uniform levels,
an adaptive run (eta, fixed fraction, all edges of a marked cell) and an adaptive run with
another rule (eta, ``refinement_rule="longest_edge"``, ``growth=2``). Each sequence's J_h is
extrapolated to N -> infinity from its last three levels, J_h = J + C N^(-q), with q fitted (no
estimate enters, which would make checking the estimate circular); the uncertainty of a
sequence is the distance of its extrapolated value from its last J_h, or, where its last three
J_h are not monotone (no asymptotic regime yet), the larger of its last two changes. The
reference is the extrapolation with the smallest uncertainty; its uncertainty is the largest of
that and the distance to every other sequence's value beyond that one's own uncertainty. Then
Ieff = (J_ref - J_h) / estimate for every level whose error is at least 10 times the
reference's uncertainty. Tables to stdout, JSON to
``benchmarks/results/`` (a run of some problems replaces theirs in an existing file)::

    scripts/fenicsx mpirun -n 2 python3 benchmarks/reference_3d.py --problems indentation
    scripts/fenicsx mpirun -n 2 python3 benchmarks/reference_3d.py --problems obstacle \\
        --max-cells 1500000
    scripts/fenicsx python3 benchmarks/reference_3d.py --quick      # small, for checking
    scripts/fenicsx python3 benchmarks/reference_3d.py \\
        --tables-from benchmarks/results/reference_3d.json      # tables again, from a run
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex


def indentation_problem(comm: MPI.Comm, n: int) -> ds.SignoriniProblem:
    """The indentation on n x n x n/2 boxes (:func:`dwr_signorini.cases.indentation_problem`)."""
    return cases.indentation_problem(comm, n)


#: The references as weights_3d.py stored them beside its runs (problem -> run in that file).
_WEIGHTS_RUNS = {"indentation": "indentation, 8 x 8 x 4", "obstacle": "example 5.3, 1 x 4 x 4"}


def stored_reference(name: str, results: Path = Path("benchmarks/results")) -> tuple[float, float]:
    """(J_ref, uncertainty) of problem ``name`` ("indentation" or "obstacle") from a run of this
    script: ``reference_3d.json`` if this machine has one, else the committed copy of the same
    values that ``weights_3d.py`` stores with its runs (``weights_3d.json``)."""
    own = results / "reference_3d.json"
    if own.exists():
        ref = json.loads(own.read_text())[name]
        return ref["J_ref"], ref["uncertainty"]
    run = json.loads((results / "weights_3d.json").read_text())["runs"][_WEIGHTS_RUNS[name]]
    return run["J_ref"], run["uncertainty"]


total_force = cases.goal_total_force


def extrapolate(N: list[float], J: list[float]) -> tuple[float, float, float]:
    """J and q of J_h = J + C N^(-q) through the last three points; the uncertainty |J - J_last|.

    q solves (J2 - J1) / (J3 - J2) = (N1^-q - N2^-q) / (N2^-q - N3^-q) by bisection on
    (0.05, 4); without a sign-consistent fit the last value is returned with the larger of the
    last two changes as its uncertainty.
    """
    (n1, n2, n3), (j1, j2, j3) = N[-3:], J[-3:]
    d1, d2 = j2 - j1, j3 - j2
    if d1 == 0 or d2 == 0 or d1 * d2 < 0:
        return j3, max(abs(d1), abs(d2)), float("nan")

    def residual(q: float) -> float:
        return (n1**-q - n2**-q) / (n2**-q - n3**-q) - d1 / d2

    lo, hi = 0.05, 4.0
    if residual(lo) * residual(hi) > 0:
        return j3, max(abs(d1), abs(d2)), float("nan")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if residual(lo) * residual(mid) <= 0:
            hi = mid
        else:
            lo = mid
    q = 0.5 * (lo + hi)
    C = d2 / (n3**-q - n2**-q)
    J_inf = j3 - C * n3**-q
    return J_inf, abs(J_inf - j3), q


def sequences(fraction: float) -> dict[str, dict[str, Any]]:
    """The independent sequences of refinement: their ``solve_adaptive`` options."""
    return {
        "uniform": {"refinement": "uniform"},
        "adaptive": {"refinement": "adaptive", "fraction": fraction},
        "longest_edge": {"refinement": "adaptive", "refinement_rule": "longest_edge",
                         "growth": 2.0},
    }


def run(problem: ds.SignoriniProblem, goal: Any, name: str, options: dict[str, Any],
        levels: int, max_cells: int) -> list[dict[str, Any]]:
    tic = time.perf_counter()
    with ds.solve_adaptive(problem, goal, max_levels=levels, max_cells=max_cells,
                           verbose=True, **options) as res:
        rows = [r.as_dict() for r in res.levels]
    if MPI.COMM_WORLD.rank == 0:
        print(f"  {name}: {len(rows)} levels in {time.perf_counter() - tic:.1f} s", flush=True)
    return rows


def reference(runs: dict[str, list[dict[str, Any]]]) -> tuple[float, float, str, dict]:
    """J_ref and its uncertainty from the sequences' J_h (see the module docstring)."""
    ext = {}
    for ref, rows in runs.items():
        N = [float(r["dofs"]) for r in rows]
        J = [r["J_h"] for r in rows]
        # Fewer than three levels: no extrapolation, an unknown (infinite) uncertainty.
        ext[ref] = extrapolate(N, J) if len(rows) >= 3 else (J[-1], float("inf"), float("nan"))
    best = min(ext, key=lambda k: ext[k][1])
    J_ref = ext[best][0]
    # Every other sequence's disagreement beyond its own uncertainty widens the reference's.
    U = max([ext[best][1]] + [abs(J_ref - J) - u for k, (J, u, _) in ext.items() if k != best])
    return J_ref, U, best, ext


def table(runs: dict[str, list[dict[str, Any]]], J_ref: float, U: float) -> list[dict]:
    """Per level: the error against J_ref and Ieff where the reference can judge it."""
    out = []
    for ref, rows in runs.items():
        for r in rows:
            err = J_ref - r["J_h"]
            judged = np.isfinite(U) and U > 0 and abs(err) >= 10 * U
            out.append({**r, "refinement": ref, "error": err,
                        "ieff": err / r["eta"] if judged and r["eta"] else None})
    return out


def print_table(name: str, J_ref: float, U: float, best: str, ext: dict, rows: list) -> None:
    others = ", ".join(f"{k} {J:.6e} +- {u:.1e}" for k, (J, u, _) in ext.items())
    print(f"\n{name}: J_ref = {J_ref:.6e} +- {U:.1e} (from the {best} sequence; {others})")
    print(f"{'run':>12} {'L':>2} {'cells':>8} {'J_h':>13} {'eta':>11} {'R_A':>10} "
          f"{'J_ref - J_h':>12} {'Ieff':>7} {'time':>7}")
    for t in rows:
        ieff = f"{t['ieff']:7.3f}" if t["ieff"] is not None else "      -"
        print(f"{t['refinement']:>12} {t['level']:2d} {t['cells']:8d} {t['J_h']:13.6e} "
              f"{t['eta']:11.3e} {t['R_A']:10.2e} {t['error']:12.3e} {ieff} "
              f"{t['time_cumulative']:7.1f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="obstacle,indentation")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--max-cells", type=int, default=800_000)
    parser.add_argument("--output", type=Path, default=Path("benchmarks/results"))
    parser.add_argument("--tables-from", type=Path, default=None,
                        help="recompute reference and tables from the levels of this JSON")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    setups = {
        "obstacle": (lambda: ex.obstacle_problem(comm, (1, 4, 4)), ex.goal_obstacle(), 0.05),
        "indentation": (lambda: indentation_problem(comm, 4 if args.quick else 8), total_force,
                        0.05),
    }
    max_cells = 60_000 if args.quick else args.max_cells
    old = json.loads(args.tables_from.read_text()) if args.tables_from else None
    summary: dict[str, Any] = {"num_processes": comm.size}
    for name in args.problems.split(","):
        if old is not None:
            runs: dict[str, list[dict[str, Any]]] = {}
            for t in old[name]["levels"]:
                runs.setdefault(t["refinement"], []).append(t)
        else:
            build, goal, fraction = setups[name]
            if comm.rank == 0:
                print(f"\n{name}", flush=True)
            runs = {}
            for ref, options in sequences(fraction).items():
                cumulative, rows = 0.0, []
                for r in run(build(), goal, ref, options, 16, max_cells):
                    cumulative += r["time"]["total"]
                    rows.append({"level": r["level"], "cells": r["num_cells"],
                                 "dofs": r["num_dofs"], "J_h": r["J_h"], "eta": r["eta"],
                                 "R_A": r["active_set_remainder"],
                                 "time_cumulative": cumulative})
                runs[ref] = rows
        J_ref, U, best, ext = reference(runs)
        rows = table(runs, J_ref, U)
        summary[name] = {"J_ref": J_ref, "uncertainty": U, "from": best,
                         "max_cells": max_cells if old is None else old[name].get("max_cells"),
                         "extrapolations": {k: {"J": v[0], "uncertainty": v[1], "q": v[2]}
                                            for k, v in ext.items()},
                         "levels": rows}
        if comm.rank == 0:
            print_table(name, J_ref, U, best, ext, rows)
    if comm.rank == 0 and old is None:
        args.output.mkdir(parents=True, exist_ok=True)
        path = args.output / ("reference_3d_quick.json" if args.quick else "reference_3d.json")
        # The problems of this run replace theirs in an earlier file; the others stay.
        if path.exists():
            summary = {**json.loads(path.read_text()), **summary}
        path.write_text(json.dumps(summary, indent=1))
        print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
