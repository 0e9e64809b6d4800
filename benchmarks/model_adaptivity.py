"""Mesh and model adaptivity against the rich model on the same meshes: global and per region.

``solve_adaptive(simple, goal, tol=tol, models=[simple, rich])`` (frictionless, then Coulomb),
with the global switch and, on the thin block, per region (``model_regions=True``); then the
simple and the rich model alone (cold start, solve and estimate) on each mesh the run made, and
the rich model's own adaptive run; the least seconds of ``--repeat`` runs of each. Per scene and
run: the law each level ran (per region: the share of Gamma_C on Coulomb), the true model
difference J(rich) - J(simple) on the first mesh with its estimate and effectivity, J_best of the
run, J_h of the rich model on the run's last mesh, whether the run converged, and the seconds of
the run's levels (solve, estimates, the model error estimate, re-solves after a switch; without
refinement) against the simple and the rich model's solves and estimates on the same meshes, with
the Newton steps of the run and of the rich model there::

    scripts/fenicsx python3 benchmarks/model_adaptivity.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/model_adaptivity.py

The scenes: the block (0, 2) x (0, 1) of ``tests/test_model_error.py`` with its top displaced
by (0.02, -0.01) on a rigid plane, mu = 0.5 (friction changes int u_x on the base by -0.038 of
0.040) and mu = 0.0001 (by about 7e-6); the 2D Hertz press of ``meshes/hertz_2d.py`` with
mu = 0.3, whose contact force friction changes by about 1 %; and the thin block (0, 4) x (0, 0.5)
of ``tests/test_model_regions.py``, mu = 0.2, goal the slide of the base under x < 0.5: friction
changes J by -1.6e-3 of 3.8e-3, and its model indicators fall to 0.3 % towards the far end; the
long block (0, 16) x (0, 0.5) with the same load and goal, mu = 0.5 (friction changes J by
-3.7e-3), per region: most of its Gamma_C is far from the goal, where the per-region run leaves
friction out and Coulomb alone solves and estimates it; and the same with mu = 0.2 under x < 4
and 1.5 beyond, where Coulomb's base sticks far from the goal (on the first mesh the 16
facets under x < 4 slip, the 48 beyond stick).
"""

from __future__ import annotations

import argparse
import sys
import time
from functools import partial
from pathlib import Path

from mpi4py import MPI

import ufl

import dwr_signorini as ds
from dwr_signorini.goal import GoalForms
from dwr_signorini.io import write_json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.problems import block, from_model, mesh_script
from tests.test_model_error import sheared, slide, value
from tests.test_model_regions import MU, near_end, thin, thin_block

COMM = MPI.COMM_WORLD
RESULTS = Path(__file__).resolve().parent / "results"


def force(u, lam, m):
    """The normal contact force, int lambda_n."""
    return lam * m.ds_contact


def block_scene(mu: float, tol: float) -> dict:
    """The sheared block with models [frictionless, Coulomb(mu)]."""
    msh, tags = block(COMM, 8, 4, lx=2.0, ly=1.0)
    return {"name": f"sheared block, mu = {mu:g}", "goal": slide, "tol": tol,
            "models": [sheared(msh, tags, None), sheared(msh, tags, ds.Coulomb(mu))]}


def hertz_scene(tol_rel: float) -> dict:
    """The 2D Hertz press with models [frictionless, Coulomb(0.3)], tol relative to J."""
    module = mesh_script("hertz_2d")
    msh, cells, facets = from_model(module.build, h=0.2, h_contact=0.04, refine_radius=0.1)

    def press(law):
        return ds.SignoriniProblem(
            msh, facets, contact=module.CONTACT,
            dirichlet={module.TOP: (None, -0.01), module.SYMMETRY: (0.0, None)},
            E=1.0, nu=0.3, gap=ds.obstacles.Plane((0.0, 0.0), (0.0, -1.0)), cell_tags=cells,
            friction=law,
        )

    models = [press(None), press(ds.Coulomb(0.3))]
    with ds.solve(models[0]) as s:
        J = GoalForms(force, s.u, s.lam, s.disc).value()
    return {"name": "Hertz press, mu = 0.3", "goal": force, "tol": tol_rel * abs(J),
            "models": models}


def thin_scene(tol: float, regions: bool) -> dict:
    """The thin block with models [frictionless, Coulomb(0.2)], globally or per region."""
    msh, tags = thin_block()
    how = "per region" if regions else "global"
    return {"name": f"thin block, mu = {MU:g}, {how}", "goal": near_end, "tol": tol,
            "models": [thin(msh, tags, None), thin(msh, tags, ds.Coulomb(MU))],
            "regions": regions}


def long_scene(tol: float, mu: float = 0.5, far: float | None = None) -> dict:
    """The long block (0, 16) x (0, 0.5) (64 x 4) with models [frictionless, Coulomb(mu)] per
    region: the goal's end is 1/32 of Gamma_C, the rest is Coulomb's work the goal hardly feels.
    With ``far``, the coefficient is mu under x < 4 and ``far`` beyond (a rough far zone)."""
    msh, tags = block(COMM, 64, 4, lx=16.0, ly=0.5)
    law = ds.Coulomb(mu if far is None else partial(zoned, mu, far))
    name = f"mu = {mu:g}" if far is None else "two zones"
    return {"name": f"long block, {name}, per region", "goal": near_end, "tol": tol,
            "models": [thin(msh, tags, None), thin(msh, tags, law)], "regions": True}


def zoned(near: float, far: float, x):
    """mu of the long block's two zones: ``near`` under x < 4, ``far`` beyond."""
    return ufl.conditional(ufl.lt(x[0], 4.0), near, far)


def alone_on(levels: list, law, goal) -> dict:
    """``law`` alone on each mesh of ``levels`` (cold starts): its J_h and weights per mesh,
    the seconds of its solves+estimates, of its solves alone and its Newton steps."""
    out = {"J": [], "weights": [], "seconds": 0.0, "solving": 0.0, "steps": 0}
    for problem in levels:
        one = on_law(problem, law)
        COMM.Barrier()
        tic = time.perf_counter()
        with ds.solve(one) as r:
            out["solving"] += time.perf_counter() - tic
            with ds.estimate(r, goal) as est:
                out["J"].append(est.J_h)
                out["weights"].append(est.weights)
                out["steps"] += r.newton_iterations
        out["seconds"] += time.perf_counter() - tic
    return out


def run(scene: dict, max_levels: int, repeat: int) -> dict:
    """The adaptive-model run of ``scene`` and the models alone on its meshes, ``repeat`` times
    (the least seconds of each: the first run also compiles the forms)."""
    rows = [run_once(scene, max_levels) for _ in range(repeat)]
    best = rows[-1]
    for key in ("time", "time_simple", "time_rich", "time_rich_run", "time_cold_own",
                "time_cold_rich", *PHASES):
        best[key] = min(r[key] for r in rows)
    return best


def first_level(scene: dict) -> tuple[float, float]:
    """The true model difference J(rich) - J(simple) on the first mesh and its estimate."""
    simple, rich = scene["models"][0], scene["models"][-1]
    with ds.solve(simple) as s, ds.solve(rich) as r:
        with ds.estimate(s, scene["goal"], model_error=rich) as est:
            return value(r, scene["goal"]) - value(s, scene["goal"]), est.model_error


def on_law(problem, law):
    """``problem`` with ``law`` on its own mesh."""
    return problem.with_mesh(problem.mesh, problem.facet_tags, problem.cell_tags, law=law)


def cold_solve(disc) -> tuple[int, float]:
    """Newton steps and seconds of a cold solve on ``disc`` (the level's own spaces, so that a
    per-region law's chi_R fits them)."""
    COMM.Barrier()
    tic = time.perf_counter()
    with ds.solve(disc) as sol:
        return sol.newton_iterations, time.perf_counter() - tic


def adaptive_seconds(levels: list) -> float:
    """The seconds of a run's levels without refinement."""
    return sum(r.time["total"] - r.time["refine"] for r in levels)


#: The weights of each level's estimate, as the table prints them.
SHORT = {"patch": "p", "higher_order": "ho", "hierarchical": "hi", "local": "lo"}

#: Where a run's seconds go (:func:`phases`), and the rich model's on the same meshes.
PHASES = ("t_solve", "t_estimate", "t_model", "t_rich_solve", "t_rich_estimate")


def phases(levels: list, model_seconds: float, rich_seconds: float, rich_solving: float
           ) -> dict[str, float]:
    """The run's seconds of its solves, its estimates of the discretisation error (with the dual
    solve) and its model error estimates; the rich model's solves and estimates on its meshes."""
    return {
        "t_solve": sum(r.time["solve"] for r in levels),
        "t_estimate": sum(r.time["dual"] + r.time["estimate"] for r in levels),
        "t_model": model_seconds, "t_rich_solve": rich_solving,
        "t_rich_estimate": rich_seconds - rich_solving,
    }


def run_once(scene: dict, max_levels: int) -> dict:
    """One adaptive-model run of ``scene``, the models alone on its meshes, the rich run."""
    meshes, cold = [], {"own": [0, 0.0], "rich": [0, 0.0], "model": [0, 0.0]}

    def keep(record, sol, est):
        meshes.append(sol.disc.problem)
        cold["model"][1] += est.timings.get("model_error", 0.0)
        own = sol.disc.problem
        for key, problem in (("own", own), ("rich", on_law(own, rich.law))):
            steps, seconds = cold_solve(sol.disc.for_problem(problem))
            cold[key][0] += steps
            cold[key][1] += seconds

    simple, rich = scene["models"][0], scene["models"][-1]
    options = {"tol": scene["tol"], "max_levels": max_levels, "verbose": False}
    with ds.solve_adaptive(simple, scene["goal"], models=scene["models"], callback=keep,
                           model_regions=scene.get("regions", False), **options) as res:
        levels, converged = res.levels, res.converged
    with ds.solve_adaptive(rich, scene["goal"], **options) as res:
        rich_run = res.levels
    alone = alone_on(meshes, rich.law, scene["goal"])
    simple_seconds = alone_on(meshes, simple.law, scene["goal"])["seconds"]
    true, est = first_level(scene)
    return {
        "problem": scene["name"], "tol": scene["tol"], "true": true, "estimate": est,
        "models": [r.model for r in levels], "rich_share": [r.rich_share for r in levels],
        "cells": [r.num_cells for r in levels],
        "J_best": levels[-1].J_best, "J_h": levels[-1].J_h, "J_rich": alone["J"][-1],
        "J_rich_run": rich_run[-1].J_best, "model_error": levels[-1].model_error,
        "converged": converged, "newton": sum(r.newton_iterations for r in levels),
        "newton_rich": alone["steps"], "time": adaptive_seconds(levels),
        "time_simple": simple_seconds, "time_rich": alone["seconds"],
        "weights": [r.weights for r in levels], "weights_rich": alone["weights"],
        "time_rich_run": adaptive_seconds(rich_run), "levels_rich_run": len(rich_run),
        "newton_cold_own": cold["own"][0], "newton_cold_rich": cold["rich"][0],
        "time_cold_own": cold["own"][1], "time_cold_rich": cold["rich"][1],
        **phases(levels, cold["model"][1], alone["seconds"], alone["solving"]),
    }


def print_table(rows: list[dict]) -> None:
    """The table (rank 0)."""
    print(f"{'problem':34s} {'tol':>8s} {'true':>10s} {'estimate':>10s} {'ieff':>5s} "
          f"{'coulomb share per level':28s} {'J_best':>11s} {'J rich,same':>11s} "
          f"{'conv':>5s} {'t run':>6s} {'simple':>6s} {'rich':>6s} {'rich run':>8s} "
          f"{'newton':>6s} {'rich':>4s} {'cold: own':>9s} {'rich':>4s} {'t own':>6s} "
          f"{'t rich':>6s}")
    for r in rows:
        shares = ",".join(f"{s:.2f}" for s in r["rich_share"])
        print(f"{r['problem']:34s} {r['tol']:8.1e} {r['true']:10.3e} {r['estimate']:10.3e} "
              f"{r['true'] / r['estimate']:5.3f} {shares:28s} {r['J_best']:11.5e} "
              f"{r['J_rich']:11.5e} {r['converged']!s:>5s} {r['time']:6.2f} "
              f"{r['time_simple']:6.2f} {r['time_rich']:6.2f} {r['time_rich_run']:8.2f} "
              f"{r['newton']:6d} {r['newton_rich']:4d} {r['newton_cold_own']:9d} "
              f"{r['newton_cold_rich']:4d} {r['time_cold_own']:6.2f} {r['time_cold_rich']:6.2f}")
    print(f"\n{'seconds: run (solve, estimate, model error), rich (solve, estimate)':75s} "
          "weights: run, rich")
    for r in rows:
        weights = [",".join(SHORT[w] for w in r[key]) for key in ("weights", "weights_rich")]
        print(f"{r['problem']:34s} " + " ".join(f"{r[key]:6.2f}" for key in PHASES)
              + f"  {weights[0]:>7s} {weights[1]:>7s}")


def main() -> None:
    """Run the scenes and print the table (rank 0)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-levels", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--only", default="", help="the scenes whose name contains this")
    args = parser.parse_args()
    scenes = [block_scene(0.5, 2e-4), block_scene(0.0001, 2e-5), hertz_scene(0.05),
              thin_scene(2e-5, False), thin_scene(2e-5, True), long_scene(2e-5),
              long_scene(2e-5, 0.2, 1.5)]
    rows = [run(scene, args.max_levels, args.repeat) for scene in scenes
            if args.only in scene["name"]]
    if COMM.rank == 0:
        print_table(rows)
        RESULTS.mkdir(exist_ok=True)
        write_json(RESULTS / f"model_adaptivity_np{COMM.size}.json", {"rows": rows})


if __name__ == "__main__":
    main()
