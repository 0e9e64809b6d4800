"""The estimate along a Coulomb load path: effectivity and coverage on every step and level.

The 2D Cattaneo-Mindlin path (``cases.cattaneo_mindlin_path``: a cylinder pressed onto a
rigid flat, then sheared in steps, Coulomb friction) is solved with ``ds.solve_path`` on a
sequence of meshes, each the uniform refinement of the last (the arc projected onto the circle).
The goal of every step is the friction force Q = int_GC lambda_t. The reference of each step is
the J_h of the finest mesh, its uncertainty the change from the mesh before (from J_h alone, no
estimate). A step of a level is judged when its error is at least 10 times that uncertainty;
for each: J_h, the interval, whether it contains the reference, its width over the error, and
the effectivity of eta, (J_ref - J_h) / eta (eta of the step's own residuals; the interval
includes the error the history carries, ``StepRecord.eta_history``, on every step:
``history="every"``). Also per step: Newton
steps and the times of the solve and of the estimate (the cost per step).

    scripts/fenicsx mpirun -n 2 python3 benchmarks/path_effectivity.py
    scripts/fenicsx python3 benchmarks/path_effectivity.py --tables-from \\
        benchmarks/results/path_effectivity.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.refine import refine_marked

RESULTS = Path("benchmarks/results")
OUTPUT = RESULTS / "path_effectivity.json"


def paths(
    comm: MPI.Comm, levels: int, weights: str, nu: float | None = None
) -> list[list[dict[str, Any]]]:
    """The path's step records on ``levels`` meshes, each the uniform refinement of the last."""
    problems = cases.cattaneo_mindlin_path(comm, **({} if nu is None else {"nu": nu}))
    runs = []
    for level in range(levels):
        with ds.solve_path(problems, ex.goal_friction_force(), weights=weights,
                           history="every", verbose=False) as res:
            rows = [r.as_dict() for r in res.steps]
        if comm.rank == 0:
            print(f"level {level}: {rows[0]['num_cells']} cells, "
                  f"{sum(r['time']['total'] for r in rows):.1f} s", flush=True)
        runs.append(rows)
        if level < levels - 1:
            refined, _ = refine_marked(problems[0], None)
            problems = [p.with_mesh(refined.mesh, refined.facet_tags, refined.cell_tags)
                        for p in problems]
    return runs


def judge(
    runs: list[list[dict[str, Any]]], reference: list[tuple[float, float]] | None = None
) -> list[dict[str, Any]]:
    """Each step of each level against the reference (J_ref, uncertainty) per step.

    Without ``reference``: the finest level's J_h, its change from the level before as the
    uncertainty, and the two finest levels are not judged.
    """
    if reference is None:
        reference = [(ref["J_h"], abs(ref["J_h"] - prev["J_h"]))
                     for ref, prev in zip(runs[-1], runs[-2], strict=True)]
        runs = runs[:-2]
    out = []
    for level, rows in enumerate(runs):
        for r, (J_ref, unc) in zip(rows, reference, strict=True):
            err = J_ref - r["J_h"]
            out.append({
                "level": level, "step": r["step"], "cells": r["num_cells"], "J_h": r["J_h"],
                "J_low": r["J_low"], "J_high": r["J_high"], "J_ref": J_ref, "uncertainty": unc,
                "error": err, "eta": r["eta"], "weights": r["weights"],
                "ieff": err / r["eta"] if r["eta"] else float("inf"),
                "judged": abs(err) >= 10 * unc,
                "covers": r["J_low"] - unc <= J_ref <= r["J_high"] + unc,
                "width_over_error": (r["J_high"] - r["J_low"]) / abs(err) if err else None,
                "newton": r["newton_iterations"], "num_stick": r["num_stick"],
                "num_slip": r["num_slip"], "t_solve": r["time"]["solve"],
                "t_estimate": r["time"]["dual"] + r["time"]["estimate"],
            })
    return out


def table(rows: list[dict[str, Any]]) -> str:
    """The Markdown table of the judged and unjudged steps."""
    lines = ["| level | step | cells | J_h | [J_low, J_high] | J_ref - J_h | Ieff(eta) | "
             "covers | width / error | stick/slip | Newton | solve | estimate |",
             "|---:|---:|---:|---:|---|---:|---:|---|---:|---|---:|---:|---:|"]
    for r in rows:
        mark = "" if r["judged"] else " (not judged)"
        width = "" if r["width_over_error"] is None else f"{r['width_over_error']:.2f}"
        lines.append(
            f"| {r['level']} | {r['step']} | {r['cells']:,} | {r['J_h']:.5e} | "
            f"[{r['J_low']:.5e}, {r['J_high']:.5e}] | {r['error']:.2e}{mark} | "
            f"{r['ieff']:.2f} | {'yes' if r['covers'] else 'NO'} | {width} | "
            f"{r['num_stick']}/{r['num_slip']} | {r['newton']} | {r['t_solve']:.2f} s | "
            f"{r['t_estimate']:.2f} s |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, default=5)
    parser.add_argument("--weights", default="auto")
    parser.add_argument("--tables-from", type=Path, default=None)
    parser.add_argument("--reference", type=Path, default=None,
                        help="a JSON of an earlier run: its finest J_h per step as J_ref, the "
                        "change from the level before as the uncertainty (all levels judged)")
    parser.add_argument("--nu", type=float, default=None, help="Poisson's ratio")
    parser.add_argument("--output", type=Path, default=OUTPUT)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.tables_from is not None:
        data = json.loads(args.tables_from.read_text())
    else:
        runs = paths(comm, args.levels, args.weights, args.nu)
        reference = None
        if args.reference is not None:
            J = json.loads(args.reference.read_text())["J_h"]
            reference = [(a, abs(a - b)) for a, b in zip(J[-1], J[-2], strict=True)]
        data = {"levels": args.levels, "weights": args.weights, "processes": comm.size,
                "nu": args.nu, "reference_from": str(args.reference),
                "rows": judge(runs, reference), "references": [r["J_h"] for r in runs[-1]],
                "J_h": [[r["J_h"] for r in rows] for rows in runs],
                "cells": [rows[0]["num_cells"] for rows in runs],
                "eta": [[r["eta"] for r in rows] for rows in runs],
                "time": [[r["time"]["total"] for r in rows] for rows in runs]}
        if comm.rank == 0:
            args.output.parent.mkdir(parents=True, exist_ok=True)
            args.output.write_text(json.dumps(data, indent=1))
    if comm.rank == 0:
        print(table(data["rows"]))
        judged = [r for r in data["rows"] if r["judged"]]
        if judged:
            ieff = [r["ieff"] for r in judged]
            print(f"judged {len(judged)}: Ieff in [{min(ieff):.2f}, {max(ieff):.2f}], "
                  f"covered {sum(r['covers'] for r in judged)}/{len(judged)}")


if __name__ == "__main__":
    main()
