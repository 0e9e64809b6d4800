"""Coverage of the interval for J: does [J_low, J_high] contain a reference, and how wide is it?

Runs ``solve_adaptive`` with its defaults (``weights="auto"``; fraction 0.2 in 2D, in 3D Doerfler
with theta = 0.3 and at most twice the cells per level) and, for the 3D problems, the uniform
sequence too, and judges every level against a reference value of J obtained without any
estimate:

* ``analytic``: example 5.1 on triangles, goal J_a1, against its exact value
  (``examples.exact_J_a``, quadrature of the exact solution);
* ``block``: the 2D block indented by a disc of ``tests/problems.py`` (whose first levels miss
  the contact), goal the contact force, against the finest J_h of a longer adaptive run
  (fraction 0.2, patch weights: its J_h alone), whose last change is the uncertainty;
* ``bar``: example 5.2, goal of the paper, against the paper's J_ref (5.934693870188e-6); the
  uncertainty is its distance to ``bar_reference.json``'s extrapolations plus their own;
* ``friction``: the friction demo's problem (Tresca, ``examples.friction_problem``), goal the
  friction force, adaptive and uniform, against the finest J_h of a longer adaptive run (12
  levels, 1.6M cells, patch weights), whose last change is the uncertainty;
* ``friction3d``: the friction demo's 3D problem (a block on a sphere, Tresca with s = 0.1,
  ``FRICTION_DEFAULTS_3D``), goal the friction force along x, adaptive and uniform, against the
  finest J_h of a longer adaptive run (growth 2, 8 levels), whose last change is the
  uncertainty;
* ``obstacle``, ``indentation8``, ``indentation12``: example 5.3 from 1 x 4 x 4 boxes and the
  3D indentation of ``reference_3d.py`` from 8 x 8 x 4 and 12 x 12 x 6 boxes, against the
  references of ``reference_3d.py`` (from J_h alone; ``reference_3d.stored_reference``).

A level is judged when its error is at least 10 times the reference's uncertainty. Per level:
J_h, the interval, whether it contains J_ref, its width over the error, the effectivity of its
centre (J_ref - J_h) / (centre - J_h), which weights the level used and whether its contact set
counted as resolved, and the times of the solve and of the estimate. JSON to
``benchmarks/results/interval_coverage.json`` (a run of some problems replaces theirs)::

    scripts/fenicsx python3 benchmarks/interval_coverage.py --problems analytic block bar
    scripts/fenicsx mpirun -n 2 python3 benchmarks/interval_coverage.py --problems friction
    scripts/fenicsx mpirun -n 2 python3 benchmarks/interval_coverage.py --problems friction3d
    scripts/fenicsx mpirun -n 2 python3 benchmarks/interval_coverage.py \\
        --problems obstacle indentation8 indentation12
    scripts/fenicsx python3 benchmarks/interval_coverage.py --tables-from \\
        benchmarks/results/interval_coverage.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from mpi4py import MPI

from dolfinx.mesh import CellType
from reference_3d import indentation_problem, stored_reference, total_force

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.viz import plot_interval
from tests.problems import indented_block

RESULTS = Path("benchmarks/results")
OUTPUT = RESULTS / "interval_coverage.json"

#: Example 5.2's reference value in the paper (Section 5.2).
BAR_PAPER_J_REF = 5.934693870188204e-06


def _force(u, lam, m):
    return lam * m.ds_contact


def _bar_reference() -> tuple[float, float]:
    ours = json.loads((RESULTS / "bar_reference.json").read_text())
    return BAR_PAPER_J_REF, ours["uncertainty"] + abs(ours["J_ref"] - BAR_PAPER_J_REF)


def _block_reference(comm: MPI.Comm, levels: int) -> tuple[float, float]:
    """The finest J_h of a longer adaptive run of the block; its last change as uncertainty."""
    with ds.solve_adaptive(indented_block(comm, 4, 3, 0.002), _force, fraction=0.2,
                           weights="patch", max_levels=levels, verbose=False) as res:
        J = [r.J_h for r in res.levels]
    return J[-1], abs(J[-1] - J[-2])


def _friction_reference(comm: MPI.Comm, levels: int) -> tuple[float, float]:
    """The finest J_h of a longer adaptive run of the friction problem; its last change."""
    with ds.solve_adaptive(ex.friction_problem(comm), ex.goal_friction_force(), fraction=0.2,
                           weights="patch", max_levels=levels, max_cells=4_000_000,
                           verbose=False) as res:
        J = [r.J_h for r in res.levels]
    return J[-1], abs(J[-1] - J[-2])


def _friction_3d(comm: MPI.Comm) -> ds.SignoriniProblem:
    """The friction demo's 3D problem."""
    d = ex.FRICTION_DEFAULTS_3D
    return ex.friction_problem(comm, nx=d["nx"], ny=d["ny"], radius=d["radius"], s=d["s"], dim=3)


def _friction_3d_reference(comm: MPI.Comm, levels: int) -> tuple[float, float]:
    """The finest J_h of a longer adaptive run of the 3D friction problem; its last change."""
    with ds.solve_adaptive(_friction_3d(comm), ex.goal_friction_force(), weights="patch",
                           growth=2.0, max_levels=levels, verbose=True) as res:
        J = [r.J_h for r in res.levels]
    return J[-1], abs(J[-1] - J[-2])


def problems(comm: MPI.Comm, quick: bool) -> dict[str, dict[str, Any]]:
    """Per problem: builder, goal, reference (a callable), levels, and whether to run uniform."""
    return {
        "analytic": dict(
            build=lambda: ex.analytic_problem(comm, 12, 8, CellType.triangle),
            goal=ex.goal_a(-0.5), reference=lambda: (ex.exact_J_a(-0.5), 0.0),
            levels=4 if quick else 7, uniform=False),
        "block": dict(
            build=lambda: indented_block(comm, 4, 3, 0.002), goal=_force,
            reference=lambda: _block_reference(comm, 8 if quick else 13),
            levels=6 if quick else 12, uniform=False),
        "bar": dict(
            build=lambda: ex.bar_problem(comm), goal=ex.goal_bar(), reference=_bar_reference,
            levels=4 if quick else 9, uniform=False),
        "friction": dict(
            build=lambda: ex.friction_problem(comm), goal=ex.goal_friction_force(),
            reference=lambda: _friction_reference(comm, 8 if quick else 12),
            levels=5 if quick else 8, uniform=True),
        "friction3d": dict(
            build=lambda: _friction_3d(comm), goal=ex.goal_friction_force(),
            reference=lambda: _friction_3d_reference(comm, 6 if quick else 8),
            levels=4 if quick else 6, uniform=True),
        "obstacle": dict(
            build=lambda: ex.obstacle_problem(comm, (1, 4, 4)), goal=ex.goal_obstacle(),
            reference=lambda: stored_reference("obstacle"),
            levels=3 if quick else 8, uniform=True),
        "indentation8": dict(
            build=lambda: indentation_problem(comm, 8), goal=total_force,
            reference=lambda: stored_reference("indentation"),
            levels=2 if quick else 6, uniform=True),
        "indentation12": dict(
            build=lambda: indentation_problem(comm, 12), goal=total_force,
            reference=lambda: stored_reference("indentation"),
            levels=2 if quick else 5, uniform=True),
    }


def judge(levels: list[dict[str, Any]], J_ref: float, U: float) -> list[dict[str, Any]]:
    """Each level's error, coverage, width / error and centre effectivity against J_ref."""
    rows = []
    for r in levels:
        error = J_ref - r["J_h"]
        centre = 0.5 * (r["J_low"] + r["J_high"]) - r["J_h"]
        rows.append({
            "level": r["level"], "num_cells": r["num_cells"], "dofs": r["num_dofs"],
            "J_h": r["J_h"],
            "J_low": r["J_low"], "J_high": r["J_high"], "error": error,
            "judged": abs(error) >= 10 * U,
            "covered": r["J_low"] <= J_ref <= r["J_high"],
            "width_over_error": (r["J_high"] - r["J_low"]) / abs(error) if error else None,
            "ieff_centre": error / centre if centre else None,
            "eta": r["eta"], "eta_p": r["eta_p"], "R_A": r["active_set_remainder"],
            "weights": r["weights"], "resolved": r["resolved"],
            "t_solve": r["time"]["solve"],
            "t_estimate": r["time"]["dual"] + r["time"]["estimate"],
            "t_total": r["time"]["total"],
        })
    return rows


def run(comm: MPI.Comm, setup: dict[str, Any], refinement: str, max_cells: int) -> list[dict]:
    with ds.solve_adaptive(setup["build"](), setup["goal"], refinement=refinement,
                           max_levels=setup["levels"], max_cells=max_cells,
                           verbose=comm.rank == 0) as res:
        return res.rows()


def print_table(name: str, J_ref: float, U: float, runs: dict[str, list[dict]]) -> None:
    print(f"\n{name}: J_ref = {J_ref:.8g} +- {U:.2g}")
    print(f"{'run':>9} {'L':>2} {'cells':>9} {'J_h':>12} {'J_low':>12} {'J_high':>12} "
          f"{'error':>10} {'judged':>6} {'in':>3} {'w/e':>6} {'Ieff_c':>7} {'weights':>12} "
          f"{'res':>3} {'t_sol':>6} {'t_est':>6}")
    for refinement, rows in runs.items():
        for r in rows:
            w = r["width_over_error"]
            ic = r["ieff_centre"]
            print(f"{refinement:>9} {r['level']:2d} {r['num_cells']:9d} {r['J_h']:12.6g} "
                  f"{r['J_low']:12.6g} {r['J_high']:12.6g} {r['error']:+10.3e} "
                  f"{'yes' if r['judged'] else 'no':>6} {'yes' if r['covered'] else 'NO':>3} "
                  f"{w if w is not None else float('nan'):6.2f} "
                  f"{ic if ic is not None else float('nan'):7.3f} {r['weights']:>12} "
                  f"{'y' if r['resolved'] else 'n':>3} {r['t_solve']:6.2f} "
                  f"{r['t_estimate']:6.2f}")


#: The problems' names in the Markdown table.
LABELS = {"analytic": "5.1, J_a1 (exact)", "bar": "5.2", "block": "2D indented block",
          "obstacle": "5.3", "indentation8": "indentation 8x8x4",
          "indentation12": "indentation 12x12x6", "friction": "Tresca friction"}


#: The weights as the table names them: P2 on the band around the contact zone, P2 on all T_h.
WEIGHT_LABELS = {"patch": "patch", "local": "P2 band"}


def print_markdown(problems: dict[str, Any]) -> None:
    """The judged levels of every problem as one Markdown table (benchmarks/README.md)."""
    print("| problem | run | L | cells | J_h | [J_low, J_high] | J_ref - J_h | contains "
          "| width / error | Ieff of the centre | weights |")
    print("|---|---|---:|---:|---:|---|---:|---|---:|---:|---|")
    for name, p in problems.items():
        for refinement, rows in p["runs"].items():
            for r in rows:
                if not r["judged"] or (refinement == "uniform" and r["level"] == 0):
                    continue  # (a uniform run's level 0 is the adaptive one's)
                weights = WEIGHT_LABELS.get(r["weights"], "P2")
                print(f"| {LABELS.get(name, name)} | {refinement} | {r['level']} "
                      f"| {r['num_cells']:,} | {r['J_h']:.6g} "
                      f"| [{r['J_low']:.6g}, {r['J_high']:.6g}] | {r['error']:+.2e} "
                      f"| {'yes' if r['covered'] else 'NO'} | {r['width_over_error']:.2f} "
                      f"| {r['ieff_centre']:.2f} | {weights} |")


def plot(name: str, result: dict[str, Any]) -> None:
    """J_h and its interval per level against the reference: ``interval_<name>.png``."""
    path = RESULTS / f"interval_{name}.png"
    # The range of the levels after the first, whose intervals would flatten the others.
    later = [r for rows in result["runs"].values() for r in rows[1:]]
    lo = min([r["J_low"] for r in later] + [result["J_ref"]])
    hi = max([r["J_high"] for r in later] + [result["J_ref"]])
    plot_interval(result["runs"], path, reference=result["J_ref"],
                  title=f"{name}: J(w_h) and the interval [J_low, J_high]",
                  ylim=(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)) if later else None)
    print(f"wrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=["analytic", "block", "bar"])
    parser.add_argument("--max-cells", type=int, default=800_000)
    parser.add_argument("--quick", action="store_true", help="few levels, for checking")
    parser.add_argument("--tables-from", type=Path, help="print the tables of a JSON file")
    parser.add_argument("--markdown", action="store_true",
                        help="with --tables-from: the judged levels as one Markdown table")
    parser.add_argument("--output", type=Path, default=OUTPUT)
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    if args.tables_from is not None and args.markdown:
        print_markdown(json.loads(args.tables_from.read_text())["problems"])
        return
    if args.tables_from is not None:
        for name, p in json.loads(args.tables_from.read_text())["problems"].items():
            print_table(name, p["J_ref"], p["uncertainty"], p["runs"])
            plot(name, p)
        return
    setups = problems(comm, args.quick)
    unknown = sorted(set(args.problems) - set(setups))
    if unknown:
        parser.error(f"unknown problems {unknown}; choose from {sorted(setups)}")
    results = {}
    for name in args.problems:
        setup = setups[name]
        J_ref, U = setup["reference"]()
        kinds = ("adaptive", "uniform") if setup["uniform"] else ("adaptive",)
        runs = {k: judge(run(comm, setup, k, args.max_cells), J_ref, U) for k in kinds}
        results[name] = {"J_ref": J_ref, "uncertainty": U, "runs": runs}
        if comm.rank == 0:
            print_table(name, J_ref, U, runs)
            plot(name, results[name])
    if comm.rank == 0 and not args.quick:
        data = {"problems": {}}
        if args.output.exists():
            data = json.loads(args.output.read_text())
        data["num_processes"] = comm.size
        data["problems"].update(results)
        args.output.write_text(json.dumps(data, indent=1))


if __name__ == "__main__":
    main()
