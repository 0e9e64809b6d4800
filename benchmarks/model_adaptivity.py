"""Mesh and model adaptivity against the rich model on the same meshes.

``solve_adaptive(simple, goal, tol=tol, models=[simple, rich])`` (frictionless, then Coulomb)
on three scenes; then the rich model alone (cold start, solve and estimate) on each mesh the
adaptive run made; the least seconds of ``--repeat`` runs of each. Per scene: the law each
level ran, J_best of the run, J_h of the rich model on the run's last mesh, whether the run
converged, and the seconds of the run's levels (solve, estimates, the model error estimate,
re-solves after a switch; without refinement) against the rich model's solves and estimates on
the same meshes::

    scripts/fenicsx python3 benchmarks/model_adaptivity.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/model_adaptivity.py

The scenes: the block (0, 2) x (0, 1) of ``tests/test_model_error.py`` with its top displaced
by (0.02, -0.01) on a rigid plane, mu = 0.5 (friction changes int u_x on the base by -0.038 of
0.040) and mu = 0.0001 (by about 7e-6); and the 2D Hertz press of ``meshes/hertz_2d.py`` with
mu = 0.3, whose contact force friction changes by about 1 %.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini.goal import GoalForms
from dwr_signorini.io import write_json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.problems import block, from_model, mesh_script
from tests.test_model_error import sheared, slide

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


def rich_on(levels: list, rich_law, goal) -> tuple[list[float], float]:
    """J_h of the rich law on each mesh of ``levels`` and the seconds of its solves+estimates."""
    out, seconds = [], 0.0
    for problem in levels:
        rich = problem.with_mesh(problem.mesh, problem.facet_tags, problem.cell_tags,
                                 law=rich_law)
        COMM.Barrier()
        tic = time.perf_counter()
        with ds.solve(rich) as r, ds.estimate(r, goal) as est:
            out.append(est.J_h)
        seconds += time.perf_counter() - tic
    return out, seconds


def run(scene: dict, max_levels: int, repeat: int) -> dict:
    """The adaptive-model run of ``scene`` and the rich model on its meshes, ``repeat`` times
    (the least seconds of each: the first run also compiles the forms)."""
    rows = [run_once(scene, max_levels) for _ in range(repeat)]
    best = rows[-1]
    best["time"] = min(r["time"] for r in rows)
    best["time_rich"] = min(r["time_rich"] for r in rows)
    return best


def run_once(scene: dict, max_levels: int) -> dict:
    """One adaptive-model run of ``scene`` and the rich model on its meshes."""
    meshes = []

    def keep(record, sol, est):
        meshes.append(sol.disc.problem)

    simple, rich = scene["models"][0], scene["models"][-1]
    with ds.solve_adaptive(simple, scene["goal"], tol=scene["tol"], max_levels=max_levels,
                           models=scene["models"], callback=keep, verbose=False) as res:
        levels, converged = res.levels, res.converged
    seconds = sum(r.time["total"] - r.time["refine"] for r in levels)
    rich_J, rich_seconds = rich_on(meshes, rich.law, scene["goal"])
    return {
        "problem": scene["name"], "tol": scene["tol"],
        "models": [r.model for r in levels], "cells": [r.num_cells for r in levels],
        "J_best": levels[-1].J_best, "J_h": levels[-1].J_h, "J_rich": rich_J[-1],
        "model_error": levels[-1].model_error, "converged": converged,
        "time": seconds, "time_rich": rich_seconds,
    }


def main() -> None:
    """Run the scenes and print the table (rank 0)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-levels", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    scenes = [block_scene(0.5, 2e-4), block_scene(0.0001, 2e-5), hertz_scene(0.05)]
    rows = [run(scene, args.max_levels, args.repeat) for scene in scenes]
    if COMM.rank == 0:
        print(f"{'problem':28s} {'tol':>9s} {'models per level':34s} {'J_best':>12s} "
              f"{'J_h':>12s} {'J rich, same mesh':>17s} {'conv':>5s} {'time':>7s} "
              f"{'rich':>7s}")
        for r in rows:
            models = ",".join(m[:4] for m in r["models"])
            print(f"{r['problem']:28s} {r['tol']:9.2e} {models:34s} {r['J_best']:12.6e} "
                  f"{r['J_h']:12.6e} {r['J_rich']:17.6e} {r['converged']!s:>5s} "
                  f"{r['time']:7.2f} {r['time_rich']:7.2f}")
        RESULTS.mkdir(exist_ok=True)
        write_json(RESULTS / f"model_adaptivity_np{COMM.size}.json", {"rows": rows})


if __name__ == "__main__":
    main()
