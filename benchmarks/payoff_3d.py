"""Where adaptivity pays in 3D: error against cumulative wall-clock time, adaptive and uniform.

For the 3D indentation of ``reference_3d.py`` (goal: the total contact force) and the paper's
example 5.3, a uniform run to about 300k fine cells and adaptive runs, all with
``solve_adaptive``'s defaults (in 3D: Doerfler's criterion with theta = 0.3, at most twice the
cells per level; ``weights="auto"``) and the default linear solver (``method=None``). The error
of every level is measured against the reference value of ``reference_3d.py`` (from J_h alone,
with its uncertainty U; :func:`reference_3d.stored_reference`). The package's answer on a level
is J_h, with the interval [J_low, J_high]; the table gives its width over the error. The script
prints, per problem:

* a table per level: cells, DoFs, J_h, J_ref - J_h, the level's time and the cumulative time;
* the target: the error of the uniform run's finest level; the first level of each adaptive run
  whose error is below it (``nominal``) and below it by more than the reference can doubt
  (``decided``: ``|e| + U < |e_uniform| - U``), with its cumulative time against the uniform
  run's (the goal of the 3D issue: <= 1/3);

and writes ``benchmarks/results/payoff_3d.json`` and the plot ``payoff_3d.png`` (error against
cumulative time, with the reference's uncertainty as a band)::

    scripts/fenicsx mpirun -n 2 python3 benchmarks/payoff_3d.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/payoff_3d.py --problems indentation
    scripts/fenicsx python3 benchmarks/payoff_3d.py --tables-from benchmarks/results/payoff_3d.json

Every process compiles its forms at its first solve: a level-0 solve of each problem runs first,
untimed, so that the runs' times do not include the JIT compilation.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mpi4py import MPI

from reference_3d import indentation_problem, stored_reference, total_force

import dwr_signorini as ds
from dwr_signorini import examples as ex

RESULTS = Path("benchmarks/results")


def setups(comm: MPI.Comm) -> dict[str, dict[str, Any]]:
    """Per problem: the goal and the runs, each (macro mesh builder, solve_adaptive options)."""
    # solve_adaptive's defaults: in 3D Doerfler, theta = 0.3, growth <= 2; weights "auto"
    adaptive = {"refinement": "adaptive"}
    return {
        "indentation": {
            "goal": total_force,
            "runs": {
                # n = 12: uniform levels of 41k and 332k fine cells
                "uniform (12 x 12 x 6)": (lambda: indentation_problem(comm, 12),
                                          {"refinement": "uniform", "max_levels": 2}),
                "adaptive (8 x 8 x 4)": (lambda: indentation_problem(comm, 8),
                                         {**adaptive, "max_cells": 400_000}),
                "adaptive (12 x 12 x 6)": (lambda: indentation_problem(comm, 12),
                                           {**adaptive, "max_cells": 400_000}),
            },
        },
        "obstacle": {
            "goal": ex.goal_obstacle(),
            "runs": {
                # 768, 6,144, 49,152 and 393,216 fine cells
                "uniform (1 x 4 x 4)": (lambda: ex.obstacle_problem(comm, (1, 4, 4)),
                                        {"refinement": "uniform", "max_levels": 4}),
                "adaptive (1 x 4 x 4)": (lambda: ex.obstacle_problem(comm, (1, 4, 4)),
                                         {**adaptive, "max_cells": 500_000}),
            },
        },
    }


def run(build: Callable[[], ds.SignoriniProblem], goal: Any, options: dict[str, Any],
        J_ref: float) -> list[dict[str, Any]]:
    """One run: per level cells, DoFs, J_h, error, time of the level and cumulative time."""
    options = {"max_levels": 12, **options}
    rows, cumulative = [], 0.0
    with ds.solve_adaptive(build(), goal, verbose=False, **options) as res:
        for r in res.levels:
            cumulative += r.time["total"]
            rows.append({"level": r.level, "cells": r.num_cells, "dofs": r.num_dofs,
                         "J_h": r.J_h, "estimate": r.estimate, "error": J_ref - r.J_h,
                         "J_low": r.J_low, "J_high": r.J_high, "weights": r.weights,
                         "width_over_error": (r.J_high - r.J_low) / abs(J_ref - r.J_h),
                         "time_level": r.time["total"], "time_cumulative": cumulative,
                         "converged": res.converged})
    return rows


def payoff(runs: dict[str, list[dict[str, Any]]], U: float) -> dict[str, Any]:
    """The uniform run's finest error and, per adaptive run, when it gets below it.

    ``nominal``: the first level whose |J_ref - J_h| is below the target; ``decided``: the first
    whose error is below it by more than the reference can doubt (|e| + U < target - U).
    """
    uniform = next(rows for name, rows in runs.items() if name.startswith("uniform"))
    target = abs(uniform[-1]["error"])
    t_uniform = uniform[-1]["time_cumulative"]
    out: dict[str, Any] = {"target_error": target, "uniform_time": t_uniform,
                           "uniform_cells": uniform[-1]["cells"], "adaptive": {}}

    def reached(r: dict[str, Any] | None) -> dict[str, Any] | None:
        if r is None:
            return None
        return {"level": r["level"], "cells": r["cells"], "time": r["time_cumulative"],
                "time_ratio": r["time_cumulative"] / t_uniform,
                "width_over_error": r.get("width_over_error")}

    for name, rows in runs.items():
        if not name.startswith("uniform"):
            out["adaptive"][name] = {
                "nominal": reached(next((r for r in rows if abs(r["error"]) < target), None)),
                "decided": reached(next((r for r in rows if abs(r["error"]) + U < target - U),
                                        None)),
            }
    return out


def report(name: str, J_ref: float, U: float, runs: dict[str, list[dict[str, Any]]],
           result: dict[str, Any]) -> None:
    print(f"\n{name}: J_ref = {J_ref:.6g} +- {U:.2g}")
    print(f"{'run':>24} {'L':>2} {'cells':>9} {'DoFs':>8} {'J_h':>12} {'J_ref - J_h':>12} "
          f"{'J_low':>12} {'J_high':>12} {'w/e':>6} {'t_level':>8} {'t_cum':>8}")
    for run_name, rows in runs.items():
        for r in rows:
            print(f"{run_name:>24} {r['level']:2d} {r['cells']:9d} {r['dofs']:8d} "
                  f"{r['J_h']:12.6g} {r['error']:12.4g} {r.get('J_low', math.nan):12.6g} "
                  f"{r.get('J_high', math.nan):12.6g} {r.get('width_over_error', math.nan):6.2f} "
                  f"{r['time_level']:8.2f} {r['time_cumulative']:8.2f}")
    print(f"target: |J_ref - J_h| = {result['target_error']:.4g} of the uniform level of "
          f"{result['uniform_cells']:,} cells, reached after {result['uniform_time']:.1f} s")
    for run_name, a in result["adaptive"].items():
        for kind in ("decided", "nominal"):
            r = a[kind]
            if r is not None:
                print(f"  {run_name}, {kind}: level {r['level']} ({r['cells']:,} cells) after "
                      f"{r['time']:.1f} s, {r['time_ratio']:.2f} of the uniform run's time, "
                      f"interval {r.get('width_over_error') or math.nan:.2f} x its error wide")
            else:
                print(f"  {run_name}, {kind}: not reached within the run")


def plot(results: dict[str, Any], path: Path) -> None:
    from dwr_signorini.viz.canvas import new_figure, save_figure

    fig = new_figure((5.2 * len(results), 4.2))
    for k, (name, data) in enumerate(results.items()):
        ax = fig.add_subplot(1, len(results), k + 1)
        for i, (run_name, rows) in enumerate(data["runs"].items()):
            style = "s-" if run_name.startswith("uniform") else "o-"
            ax.loglog([r["time_cumulative"] for r in rows],
                      [max(abs(r["error"]), 1e-12) for r in rows], style, color=f"C{i}",
                      label=run_name)
        ax.axhline(data["uncertainty"], color="k", ls=":", lw=1,
                   label="uncertainty of J_ref")
        ax.axhline(data["payoff"]["target_error"], color="0.5", ls="--", lw=1,
                   label="uniform run's finest error")
        ax.set_xlabel("cumulative wall-clock time [s]")
        ax.set_ylabel("|J_ref - J_h|")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    save_figure(fig, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", default="indentation,obstacle")
    parser.add_argument("--output", type=Path, default=RESULTS)
    parser.add_argument("--tables-from", type=Path, default=None,
                        help="print the tables and redraw the plot from the JSON of a run")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.tables_from is not None:
        old = json.loads(args.tables_from.read_text())
        results = {k: v for k, v in old.items() if k != "num_processes"}
        for name, data in results.items():
            data["payoff"] = payoff(data["runs"], data["uncertainty"])
            if comm.rank == 0:
                report(name, data["J_ref"], data["uncertainty"], data["runs"], data["payoff"])
        if comm.rank == 0:
            plot(results, args.tables_from.with_suffix(".png"))
        return
    results: dict[str, Any] = {}
    for name in args.problems.split(","):
        setup = setups(comm)[name]
        J_ref, U = stored_reference(name)
        # JIT compilation, untimed: one level of the first run's problem
        build, _ = next(iter(setup["runs"].values()))
        ds.solve_adaptive(build(), setup["goal"], max_levels=1, verbose=False).destroy()
        runs = {}
        for run_name, (build, options) in setup["runs"].items():
            runs[run_name] = run(build, setup["goal"], options, J_ref)
            if comm.rank == 0:
                last = runs[run_name][-1]
                print(f"{name}, {run_name}: {len(runs[run_name])} levels, "
                      f"{last['cells']:,} cells, {last['time_cumulative']:.1f} s", flush=True)
        result = payoff(runs, U)
        results[name] = {"J_ref": J_ref, "uncertainty": U, "runs": runs, "payoff": result}
        if comm.rank == 0:
            report(name, J_ref, U, runs, result)
    if comm.rank == 0:
        args.output.mkdir(parents=True, exist_ok=True)
        (args.output / "payoff_3d.json").write_text(json.dumps(
            {"num_processes": comm.size, **results}, indent=1, default=_json_default))
        plot(results, args.output / "payoff_3d.png")
        print(f"\nwrote {args.output / 'payoff_3d.json'} and payoff_3d.png")


def _json_default(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    raise TypeError(f"not JSON serialisable: {value!r}")


if __name__ == "__main__":
    main()
