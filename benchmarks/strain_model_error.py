"""The error small strain makes in J against solving the Neo-Hookean problem, and what it costs.

The quarter disc of radius 1 (``tests/test_finite_strain_estimate.py``, E 10, nu 0.3) pressed
onto a rigid flat by a share of its radius, goals the contact force and a weighted average of
P_yy near the contact. Per press, mesh and goal: the true model difference J(w_r) - J(w_s), both
models solved on the same mesh (the Neo-Hookean one along four load steps), the estimate eta_M
of ``ds.estimate(sol, goal, model_error=neo_hookean)`` (theory, eq. (M6)), its effectivity,
whether its interval holds the truth, and the seconds of the small-strain solve with its
estimate and model error against the Neo-Hookean path with its estimate (one run: compare the
ratio)::

    scripts/fenicsx python3 benchmarks/strain_model_error.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/strain_model_error.py

Writes ``benchmarks/results/strain_model_error_np<N>.csv``. With ``--adaptive`` it runs
``solve_adaptive(small, force, tol=tol, models=[small, neo_hookean])`` against the Neo-Hookean
run alone to the same tolerance (relative to the force, ``--tol``) and writes
``strain_model_choice_np<N>.csv``::

    scripts/fenicsx python3 benchmarks/strain_model_error.py --adaptive --h 0.25 --press 0.02 0.1
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini.goal import GoalForms

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.trace_cost import show, write_rows
from tests.problems import from_model
from tests.test_finite_strain_estimate import (
    contact_force,
    cylinder_problem,
    quarter_disc,
    stress_average,
)

COMM = MPI.COMM_WORLD
GOALS = {"force": contact_force, "stress": stress_average}
STEPS = [0.25, 0.5, 0.75, 1.0]


def small_strain(simple, rich, goal) -> tuple[float, object, float]:
    """J_h of the small-strain solve, its model error and the seconds of solve + estimate."""
    tic = time.perf_counter()
    with ds.solve(simple) as sol, ds.estimate(sol, goal, model_error=rich) as est:
        return est.J_h, est.model, time.perf_counter() - tic


def finite_strain(problem, goal) -> tuple[float, float]:
    """J_h of the Neo-Hookean path's last state and the seconds of the path + its estimate."""
    tic = time.perf_counter()
    path = ds.solve_path(problem, None, load_factors=STEPS)
    try:
        last = path.solutions[-1]
        J = GoalForms(goal, last.u, last.lam, last.disc).value()
        ds.estimate(last, goal).destroy()
    finally:
        for s in path.solutions:
            s.destroy()
    return J, time.perf_counter() - tic


def row(h: float, press: float, goal_name: str, meshes: dict) -> dict:
    """One row of the table."""
    msh, facets = meshes[h]
    rich = cylinder_problem(msh, facets, press)
    simple = cylinder_problem(msh, facets, press, material=ds.LinearElastic())
    goal = GOALS[goal_name]
    try:
        J_s, me, t_small = small_strain(simple, rich, goal)
    except RuntimeError as error:  # a goal of P(F) is NaN where small strain inverts a cell
        return {"h": h, "press": press, "goal": goal_name, "estimate": f"({error})"}
    J_r, t_rich = finite_strain(rich, goal)
    true = J_r - J_s
    low, high = me.interval
    return {
        "h": h, "press": press, "goal": goal_name, "J_small": J_s, "true": true,
        "estimate": me.value, "ieff": me.value / true, "low": low, "high": high,
        "holds": bool(low <= true <= high), "sets changed": me.num_changed,
        "t small+model error": t_small, "t neo-hookean": t_rich, "ratio": t_rich / t_small,
    }


def adaptive_row(press: float, tol_rel: float, h: float, max_levels: int) -> dict:
    """``models=[small, Neo-Hookean]`` against the Neo-Hookean run alone, goal the force.

    The tolerance is relative to the small-strain force on the first mesh; both runs stop by
    their intervals (the model run: half its width plus the model error's bound).
    """
    msh, _, facets = from_model(quarter_disc, h=h)
    small = cylinder_problem(msh, facets, press, material=ds.LinearElastic())
    neo = cylinder_problem(msh, facets, press)
    with ds.solve(small) as sol:
        tol = tol_rel * GoalForms(contact_force, sol.u, sol.lam, sol.disc).value()
    out = {"press": press, "tol": tol}
    for name, problem, models in (("models", small, [small, neo]), ("neo alone", neo, None)):
        tic = time.perf_counter()
        with ds.solve_adaptive(problem, contact_force, tol=tol, max_levels=max_levels,
                               models=models, verbose=False) as res:
            rows = res.levels
            out[f"t {name}"] = time.perf_counter() - tic
            out[f"{name}: levels"] = ",".join(r.model[:3] for r in rows)
            out[f"{name}: J_best"] = rows[-1].J_best
            out[f"{name}: converged"] = res.converged
    out["|J_best models - J_best neo|"] = abs(out["models: J_best"] - out["neo alone: J_best"])
    out["t ratio"] = out["t models"] / out["t neo alone"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--h", type=float, nargs="+", default=[0.25, 0.125])
    parser.add_argument("--press", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.3])
    parser.add_argument("--adaptive", action="store_true",
                        help="the model choice's runs against the Neo-Hookean runs instead")
    parser.add_argument("--tol", type=float, nargs="+", default=[1e-2, 1e-3])
    args = parser.parse_args()
    if args.adaptive:
        adaptive_row(args.press[0], args.tol[0], args.h[0], 2)  # compile the forms
        rows = [show(adaptive_row(p, t, args.h[0], 6)) for p in args.press for t in args.tol]
        write_rows(rows, "strain_model_choice")
        return
    meshes = {}
    for h in args.h:
        msh, _, facets = from_model(quarter_disc, h=h)
        meshes[h] = (msh, facets)
    for goal in GOALS:  # compile the forms once before the timed rows
        row(args.h[0], args.press[0], goal, meshes)
    rows = [show(row(h, p, g, meshes)) for h in args.h for p in args.press for g in GOALS]
    write_rows(rows, "strain_model_error")


if __name__ == "__main__":
    main()
