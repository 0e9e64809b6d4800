"""Why adaptivity does (not) pay for the Neo-Hookean disc pressed onto a rigid flat.

The disc of ``tests/test_finite_strain_adapt.py``'s slow test (mesh size 0.2, pressed by 25 %
of its radius), its two goals and a third one, the P_yy average concentrated at the contact
edge. The reference J from J_h alone on uniform levels 3-5 (Richardson), computed once and kept
in ``benchmarks/results/finite_strain_payoff_ref.json``. Per run and level: cells, the share of
cells within 0.1 of the contact zone (reference configuration), the error, the error times the
cells, the effectivity (J_ref - J_h) / estimate (of the estimator that drove the run), the
level's seconds in solve / dual / estimate / refine, and the cumulative time; then per run the
first cumulative time at which the error is
at most the finest uniform level's::

    scripts/fenicsx python3 benchmarks/finite_strain_payoff.py
    scripts/fenicsx python3 benchmarks/finite_strain_payoff.py --goals edge --runs growth4
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import dwr_signorini as ds

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.problems import from_model  # noqa: E402
from tests.test_finite_strain_adapt import (  # noqa: E402
    EDGE_GOALS,
    SLOW_H,
    SLOW_PRESS,
    _richardson,
    quarter_disc,
    uniform_values,
)
from tests.test_finite_strain_estimate import cylinder_problem  # noqa: E402

REFERENCE = ROOT / "benchmarks" / "results" / "finite_strain_payoff_ref.json"

#: The runs: solve_adaptive's keyword arguments (besides the problem and the goal).
RUNS = {
    "uniform": {"refinement": "uniform", "max_levels": 4},
    "default": {"max_levels": 20, "max_cells": 40000},
    "growth3": {"max_levels": 20, "max_cells": 40000, "growth": 3.0},
    "growth4": {"max_levels": 20, "max_cells": 40000, "growth": 4.0},
    "doerfler5": {"max_levels": 20, "max_cells": 40000, "strategy": "doerfler", "fraction": 0.5},
    "eta_p": {"max_levels": 20, "max_cells": 40000, "estimator": "eta_p"},
    "growth4_eta_p": {"max_levels": 20, "max_cells": 40000, "growth": 4.0, "estimator": "eta_p"},
}


def references(msh, facets) -> dict[str, float]:
    """J of every goal from J_h on uniform levels 3-5 (stored after the first computation)."""
    stored = json.loads(REFERENCE.read_text()) if REFERENCE.exists() else {}
    missing = {k: g for k, g in EDGE_GOALS.items() if k not in stored}
    if missing:
        values = uniform_values(msh, facets, SLOW_PRESS, (3, 4, 5), goals=missing)
        for name in missing:
            J = [values[k][name] for k in (3, 4, 5)]
            stored[name] = {"J": _richardson(*J), "J_3,4,5": J}
        REFERENCE.write_text(json.dumps(stored, indent=1))
    for name, ref in stored.items():
        J3, J4, J5 = ref["J_3,4,5"]
        print(f"{name}: J_3,4,5 {J3:.9e} {J4:.9e} {J5:.9e}, Richardson {ref['J']:.9e} "
              f"(|J_5 - J| = {abs(J5 - ref['J']):.1e}, ratio {(J4 - J3) / (J5 - J4):.2f})")
    return {name: ref["J"] for name, ref in stored.items()}


def near_contact_share(sol, distance: float = 0.1) -> float:
    """The share of fine cells whose midpoint lies within ``distance`` of the contact zone.

    The contact zone: the reference-configuration points whose deformed height is below 1e-6
    (the flat is y = 0). Also returns the zone's largest x, its edge.
    """
    msh = sol.disc.mesh
    x = msh.geometry.x[:, :2]
    V = sol.u.function_space
    coords = V.tabulate_dof_coordinates()[:, :2]
    uy = sol.u.x.array.reshape(-1, 2)[: len(coords), 1]
    touching = coords[coords[:, 1] + uy < 1e-6]  # only points of the arc reach the flat
    msh.topology.create_connectivity(2, 0)
    cells = msh.topology.connectivity(2, 0).array.reshape(-1, 3)
    mid = x[cells].mean(axis=1)
    d = np.min(np.linalg.norm(mid[:, None, :] - touching[None, :, :], axis=2), axis=1)
    return float(np.mean(d < distance)), float(touching[:, 0].max())


def run(msh, facets, goal, kwargs):
    """The levels with the near-contact share and the contact edge's x per level."""
    shares = []

    def record(r, sol, est):
        shares.append(near_contact_share(sol))

    with ds.solve_adaptive(cylinder_problem(msh, facets, SLOW_PRESS), goal, verbose=False,
                           callback=record, **kwargs) as result:
        return list(zip(result.levels, shares, strict=True))


def table(name, J_ref, levels, target=None):
    """Print the run's levels; return the first cumulative time with error <= target."""
    print(f"\n### {name}\n| level | cells | near | edge x | error | error*cells | Ieff | solve "
          "| dual | estimate | refine | level s | cum s |\n" + "|---" * 13 + "|")
    cum, reached = 0.0, None
    for r, (near, edge) in levels:
        cum += r.time["total"]
        err = abs(J_ref - r.J_h)
        t = r.time
        print(f"| {r.level} | {r.num_cells} | {near:.2f} | {edge:.3f} | {err:.1e} | "
              f"{err * r.num_cells:.2f} | {(J_ref - r.J_h) / r.estimate:.2f} | "
              f"{t.get('solve', 0):.2f} | {t.get('dual', 0):.2f} | {t.get('estimate', 0):.2f} | "
              f"{t.get('refine', 0):.2f} | {t['total']:.2f} | {cum:.2f} |")
        if target is not None and reached is None and err <= target:
            reached = cum
    return cum, abs(J_ref - levels[-1][0].J_h), reached


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--goals", nargs="*", default=sorted(EDGE_GOALS))
    parser.add_argument("--runs", nargs="*", default=sorted(RUNS))
    args = parser.parse_args()
    msh, _, facets = from_model(quarter_disc, h=SLOW_H)
    J = references(msh, facets)
    for goal in args.goals:
        run(msh, facets, EDGE_GOALS[goal], {"max_levels": 2})  # forms compiled, untimed
        print(f"\n## {goal}: reference {J[goal]:.9e}")
        uniform_time, target, _ = table("uniform", J[goal],
                                        run(msh, facets, EDGE_GOALS[goal], RUNS["uniform"]))
        for name in args.runs:
            if name != "uniform":
                _, _, reached = table(name, J[goal], run(msh, facets, EDGE_GOALS[goal],
                                                         RUNS[name]), target)
                print(f"{goal} {name}: uniform error {target:.2e} in {uniform_time:.2f} s, "
                      f"reached after {reached} s "
                      f"(ratio {reached / uniform_time if reached else float('inf'):.2f})")


if __name__ == "__main__":
    main()
