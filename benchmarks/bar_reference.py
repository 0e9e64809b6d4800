"""Our own reference value of J for the bar example (Section 5.2 of the paper), with an uncertainty.

The paper's reference value J_ref = 5.934693870188204e-6 was extrapolated from uniform refinement,
and the paper itself remarks that its last errors look too small because of it. This script
computes a reference independently of that number, from three kinds of runs on meshes far finer
than those of Table 3:

1. uniform refinement up to ~2M cells, extrapolated by Richardson with the convergence rate fitted
   to the last three levels (the uniform rate is reduced by the corner singularities, so it is
   estimated, not assumed);
2. adaptive refinement driven by eta with the patch weights (the paper's), up to ~2M cells:
   (a) extrapolation of the last two levels with the optimal adaptive rate N^-1, and
   (b) the corrected value J_h + eta of the finest level;
3. adaptive refinement driven by eta with ``weights="higher_order"`` (dual and primal in P2),
   up to ~1M cells: the same two estimates (a) and (b).

The reference value is the median of these five estimates. Its uncertainty is the larger of
(i) the largest distance of an estimate from the median and (ii) the largest "drift" of an
extrapolation, i.e. how much it moved when the finest level was added (the extrapolation from the
previous levels minus the one from the last levels). Everything goes to
``benchmarks/results/bar_reference.json`` (and the tables of the runs to CSV files next to it).

Usage (serial; about 6-8 minutes on one core)::

    scripts/fenicsx python3 benchmarks/bar_reference.py
    scripts/fenicsx python3 benchmarks/bar_reference.py --quick     # a smoke test, seconds
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import statistics
import time
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.io import write_csv

RESULTS = Path(__file__).resolve().parent / "results"
JSON_NAME = "bar_reference.json"


def run(comm: MPI.Comm, refinement: str, weights: str, max_cells: int) -> list[dict[str, Any]]:
    """One run of ``solve_adaptive`` until the next level would exceed ``max_cells``."""
    res = ds.solve_adaptive(
        ex.bar_problem(comm), ex.goal_bar(), refinement=refinement, fraction=0.2,
        strategy="fixed_fraction", max_levels=40, max_cells=max_cells, estimator="eta",
        weights=weights, verbose=True,
    )
    return res.rows()


def richardson_fitted(N: np.ndarray, J: np.ndarray) -> tuple[float, float]:
    """J* and the rate p from J_i = J* - C N_i^-p through three levels (any ratios of N)."""
    d1, d2 = J[1] - J[0], J[2] - J[1]
    if d1 == 0 or d2 / d1 <= 0:
        return math.nan, math.nan
    target = d2 / d1

    def ratio(p: float) -> float:  # (N2^-p - N1^-p) / (N1^-p - N0^-p), decreasing in p
        a, b, c = N ** (-p)
        return (c - b) / (b - a)

    lo, hi = 1e-3, 10.0
    if not ratio(hi) < target < ratio(lo):
        return math.nan, math.nan
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ratio(mid) > target else (lo, mid)
    p = 0.5 * (lo + hi)
    C = d2 / (N[1] ** -p - N[2] ** -p)
    return float(J[2] + C * N[2] ** -p), float(p)


def extrapolate_rate(N: np.ndarray, J: np.ndarray, p: float = 1.0) -> float:
    """J* from the last two levels with J = J* - C N^-p for a given rate p."""
    C = (J[1] - J[0]) / (N[0] ** -p - N[1] ** -p)
    return float(J[1] + C * N[1] ** -p)


def estimates_of(name: str, rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """The estimates of J(w) that a run gives, with their drift."""
    N = np.array([r["num_cells"] for r in rows], dtype=float)
    J = np.array([r["J_h"] for r in rows])
    eta = np.array([r["eta"] for r in rows])
    out: dict[str, dict[str, Any]] = {}
    if name == "uniform":
        if len(rows) >= 4:
            value, p = richardson_fitted(N[-3:], J[-3:])
            prev, p_prev = richardson_fitted(N[-4:-1], J[-4:-1])
            out["uniform_richardson"] = {
                "value": value, "drift": abs(value - prev), "rate": p, "previous": prev,
                "previous_rate": p_prev, "cells": int(N[-1]),
                "how": "Richardson with the rate fitted to the last three uniform levels "
                       "(J_h = J - C N^-p); drift = change against the previous three levels",
            }
        return out
    if len(rows) >= 3:
        value = extrapolate_rate(N[-2:], J[-2:])
        prev = extrapolate_rate(N[-3:-1], J[-3:-1])
        fitted, p = richardson_fitted(N[-3:], J[-3:])
        out[f"{name}_extrapolated"] = {
            "value": value, "drift": abs(value - prev), "previous": prev, "cells": int(N[-1]),
            "fitted_rate_last3": p, "fitted_richardson_last3": fitted,
            "how": "last two adaptive levels extrapolated with the optimal rate N^-1; drift = "
                   "change against the extrapolation of the two levels before",
        }
    out[f"{name}_corrected"] = {
        "value": float(J[-1] + eta[-1]), "drift": None, "previous": float(J[-2] + eta[-2]),
        "cells": int(N[-1]), "eta": float(eta[-1]),
        "how": "J_h + eta on the finest adaptive level",
    }
    return out


def combine(estimates: dict[str, dict[str, Any]]) -> tuple[float, float, float]:
    """Median of the estimates, uncertainty (spread and drifts) and the plain spread."""
    values = [e["value"] for e in estimates.values() if math.isfinite(e["value"])]
    ref = statistics.median(values)
    spread = max(abs(v - ref) for v in values)
    drifts = [e["drift"] for e in estimates.values() if e["drift"] is not None]
    drifts = [d for d in drifts if math.isfinite(d)]
    return ref, max([spread, *drifts]), max(values) - min(values)


def print_table(name: str, rows: list[dict[str, Any]], ref: float) -> None:
    print(f"\n{name}: {len(rows)} levels (E_rel and Ieff against our reference {ref:.10e})")
    print(f"{'L':>3} {'M_Omega':>9} {'J_h':>20} {'eta':>11} {'J_h + eta':>20} {'E_rel':>10} "
          f"{'Ieff':>7} {'time [s]':>9}")
    for r in rows:
        err = ref - r["J_h"]
        print(f"{r['level']:3d} {r['num_cells']:9d} {r['J_h']:20.13e} {r['eta']:11.4e} "
              f"{r['J_h'] + r['eta']:20.13e} {abs(err) / abs(ref):10.3e} {err / r['eta']:7.3f} "
              f"{r['time']['total']:9.2f}")


def compute_reference(
    comm: MPI.Comm,
    uniform_max_cells: int = 2_200_000,
    adaptive_max_cells: int = 2_200_000,
    higher_order_max_cells: int = 1_100_000,
    quick: bool = False,
) -> dict[str, Any]:
    """Run the three sequences and combine their estimates (collective; printing on rank 0)."""
    rank0 = comm.rank == 0
    t0 = time.perf_counter()
    runs: dict[str, list[dict[str, Any]]] = {}
    wall: dict[str, float] = {}
    for name, refinement, weights, max_cells in (
        ("uniform", "uniform", "patch", uniform_max_cells),
        ("adaptive_patch", "adaptive", "patch", adaptive_max_cells),
        ("adaptive_higher_order", "adaptive", "higher_order", higher_order_max_cells),
    ):
        if rank0:
            print(f"\n=== {name}: refinement={refinement}, weights={weights}, "
                  f"max_cells={max_cells}", flush=True)
        tic = time.perf_counter()
        runs[name] = run(comm, refinement, weights, max_cells)
        wall[name] = time.perf_counter() - tic

    estimates: dict[str, dict[str, Any]] = {}
    for name, rows in runs.items():
        estimates.update(estimates_of(name, rows))
    ref, uncertainty, spread = combine(estimates)
    return {
        "example": "paper Section 5.2 (bar), J(u) = int_B grad u : grad u dx, B = [0, 0.05]^2",
        "J_ref": ref,
        "uncertainty": uncertainty,
        "relative_uncertainty": uncertainty / abs(ref),
        "spread": spread,
        "method": (
            "median of five estimates: uniform refinement with Richardson extrapolation "
            "(rate fitted to the last three levels), and for adaptive runs driven by eta with "
            "patch and with higher-order weights, the extrapolation of the last two levels with "
            "the rate N^-1 and the corrected value J_h + eta of the finest level; uncertainty = "
            "max(largest distance of an estimate from the median, largest drift of an "
            "extrapolation when its finest level was added)"
        ),
        "quick": quick,
        "estimates": estimates,
        "paper_J_ref": ex.BAR_J_REF,
        "paper_minus_ours": ex.BAR_J_REF - ref,
        "runs": {name: {"wall_seconds": wall[name], "levels": rows} for name, rows in runs.items()},
        "runtime_seconds": time.perf_counter() - t0,
        "num_processes": comm.size,
        "dolfinx": __import__("dolfinx").__version__,
        "python": platform.python_version(),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }


def report(data: dict[str, Any]) -> None:
    """Print the tables of the runs and the estimates."""
    ref, uncertainty = data["J_ref"], data["uncertainty"]
    for name, run_data in data["runs"].items():
        print_table(name, run_data["levels"], ref)
    print("\nEstimates of J(w):")
    print(f"{'method':>34} {'value':>20} {'- reference':>12} {'drift':>10} {'cells':>9}")
    for key, e in data["estimates"].items():
        drift = "" if e["drift"] is None else f"{e['drift']:10.2e}"
        print(f"{key:>34} {e['value']:20.13e} {e['value'] - ref:12.2e} {drift:>10} "
              f"{e['cells']:9d}")
    paper = data["paper_J_ref"]
    print(f"\nreference J = {ref:.13e} +- {uncertainty:.1e} (relative {uncertainty / ref:.1e}); "
          f"spread of the estimates {data['spread']:.1e}")
    print(f"paper's J_ref = {paper:.13e}: paper - ours = {paper - ref:.2e} "
          f"({(paper - ref) / ref:.1e} relative)")
    print(f"total time {data['runtime_seconds']:.0f} s")


def save(data: dict[str, Any], path: Path) -> None:
    """Write the JSON and one CSV table per run next to it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    for name, run_data in data["runs"].items():
        write_csv(path.parent / f"{path.stem}_{name}.csv", run_data["levels"])
    with open(path, "w") as fh:
        json.dump(data, fh, indent=1)
    print(f"wrote {path}")


def load_reference(path: Path = RESULTS / JSON_NAME) -> dict[str, Any] | None:
    """The saved reference (J_ref, uncertainty, ...), or None if there is none."""
    if not path.exists():
        return None
    return json.loads(path.read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--uniform-max-cells", type=int, default=2_200_000)
    parser.add_argument("--adaptive-max-cells", type=int, default=2_200_000)
    parser.add_argument("--higher-order-max-cells", type=int, default=1_100_000)
    parser.add_argument("--quick", action="store_true",
                        help="small runs (~70k cells) to check the script, not a reference")
    parser.add_argument("--output", type=Path, default=RESULTS / JSON_NAME)
    args = parser.parse_args()
    if args.quick:
        args.uniform_max_cells = args.adaptive_max_cells = args.higher_order_max_cells = 70_000
        if args.output == RESULTS / JSON_NAME:
            args.output = RESULTS / "bar_reference_quick.json"

    comm = MPI.COMM_WORLD
    data = compute_reference(comm, args.uniform_max_cells, args.adaptive_max_cells,
                             args.higher_order_max_cells, quick=args.quick)
    if comm.rank == 0:
        report(data)
        save(data, args.output)


if __name__ == "__main__":
    main()
