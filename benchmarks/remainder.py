"""Effectivity with the active-set remainder added: eta + R_A and eta_p + R_A against eta, eta_p.

The error identity (13) of Proposition 4 is J(w) - J(w_h) = rho(w_h)(z - z_h) - C(w_h)(xi_h)
+ R_J + R_A: eta_p estimates the first two terms, and ``Estimate.active_set_remainder``
evaluates R_A with the reconstructions in place of w and xi. This script measures whether
adding that evaluation to the estimate brings the effectivity Ieff = (J_ref - J_h) / estimate
closer to 1, with patch weights, on:

* the 2D block indented by a disc of ``tests/problems.py`` (``indented_block(4, 3, 0.002)``,
  goal the contact force, 12 adaptive levels computed here; reference the finest J_h, its
  uncertainty the last change, as in ``tests/test_unresolved.py``), whose first levels miss the
  contact;
* example 5.2 (the bar), 9 adaptive levels computed here (eta, fraction 0.2, as
  ``adaptive_examples.py``), against the reference of ``benchmarks/results/bar_reference.json``;
* the 3D indentation and example 5.3, read from ``benchmarks/results/weights_3d.json``
  (written by ``weights_3d.py``).

A level is judged when its error is at least 10 times the reference's uncertainty. Serial, about
40 seconds::

    scripts/fenicsx python3 benchmarks/remainder.py
"""

from __future__ import annotations

import json
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import examples as ex
from tests.problems import indented_block

RESULTS = Path("benchmarks/results")
ESTIMATES = ("eta", "eta_p", "eta+R_A", "eta_p+R_A")


def _row(level: int, error: float, judged: bool, eta: float, eta_p: float, r_a: float) -> str:
    values = (eta, eta_p, eta + r_a, eta_p + r_a)
    ieff = " ".join(f"{error / v:10.3f}" if v != 0 else f"{'inf':>10}" for v in values)
    return f"{level:3d} {error:+11.3e} {'yes' if judged else 'no':>6} {r_a / error:+8.3f} {ieff}"


def _header(title: str) -> str:
    names = " ".join(f"{e:>10}" for e in ESTIMATES)
    return f"\n{title}\n{'L':>3} {'J_ref-J_h':>11} {'judged':>6} {'R_A/e':>8} {names}"


def indented_block_rows(comm: MPI.Comm) -> list[str]:
    def force(u, lam, m):
        return lam * m.ds_contact

    with ds.solve_adaptive(indented_block(comm, 4, 3, 0.002), force, fraction=0.2,
                           max_levels=12, verbose=False) as res:
        levels = res.levels
    reference, uncertainty = levels[-1].J_h, abs(levels[-1].J_h - levels[-2].J_h)
    rows = []
    for r in levels[:-2]:
        error = reference - r.J_h
        rows.append(_row(r.level, error, abs(error) >= 10 * uncertainty, r.eta, r.eta_p,
                         r.active_set_remainder))
    return rows


def bar_rows(comm: MPI.Comm, levels: int = 9) -> list[str]:
    reference = json.loads((RESULTS / "bar_reference.json").read_text())
    J_ref, uncertainty = reference["J_ref"], reference["uncertainty"]
    with ds.solve_adaptive(ex.bar_problem(comm), ex.goal_bar(), fraction=0.2,
                           max_levels=levels, verbose=False) as res:
        return [_row(r.level, J_ref - r.J_h, abs(J_ref - r.J_h) >= 10 * uncertainty, r.eta,
                     r.eta_p, r.active_set_remainder) for r in res.levels]


def rows_3d() -> dict[str, list[str]]:
    path = RESULTS / "weights_3d.json"
    if not path.exists():
        return {f"3D runs: {path} is missing (run weights_3d.py first)": []}
    data = json.loads(path.read_text())
    out = {}
    for name, run in data["runs"].items():
        rows = []
        for r in run["levels"]:
            p = r["patch"]
            rows.append(_row(r["level"], r["error"],
                             abs(r["error"]) >= 10 * run["uncertainty"], p["eta"], p["eta_p"],
                             p["R_A"]))
        out[f"{name} ({path.name})"] = rows
    return out


def main() -> None:
    comm = MPI.COMM_WORLD
    tables = {"2D block indented by a disc (tests/problems.py)": indented_block_rows(comm),
              "example 5.2 (bar_reference.json)": bar_rows(comm), **rows_3d()}
    if comm.rank == 0:
        for title, rows in tables.items():
            print(_header(title))
            print("\n".join(rows))


if __name__ == "__main__":
    main()
