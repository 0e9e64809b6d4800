"""Where adaptivity pays for two bodies: error against cumulative time, adaptive and uniform.

Two cylinders of different materials pressed together (``meshes/hertz_cylinders_2d.py``, the
polygonal arcs of the initial mesh: the estimate is of the discretisation error of the domain
meshed) from a quasi-uniform initial mesh (h = h_contact), and the pin pressed into the hole of a
plate (``meshes/pin_plate_2d.py``). For each, the goal's value is measured against a reference from
J_h alone: the finest level of a longer adaptive run, its uncertainty U the change from the level
before. The script prints per run a table (level, cells of each body, J_h, the interval, J_ref -
J_h, cumulative time) and the payoff: the error of the uniform run's finest level, the first
adaptive level below it (by more than U) and the ratio of their cumulative times (the issue's
target: <= 1/3). It writes ``benchmarks/results/two_bodies_payoff.json``::

    scripts/fenicsx python3 benchmarks/two_bodies_payoff.py
    scripts/fenicsx python3 benchmarks/two_bodies_payoff.py --cases hertz-stress

A level-0 solve runs first, untimed, so that the times do not include the JIT compilation.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl

import dwr_signorini as ds

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def script(name: str) -> Any:
    """The gmsh script ``meshes/<name>.py``."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "meshes" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def from_model(build: Any, **kwargs: Any) -> tuple:
    """``(mesh, cell_tags, facet_tags)`` of the gmsh model that ``build`` makes (rank 0)."""
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if MPI.COMM_WORLD.rank == 0:
            gmsh.model.add("benchmark")
            build(gmsh.model, **kwargs)
        return ds.read_mesh(gmsh.model, MPI.COMM_WORLD)
    finally:
        gmsh.finalize()


CYL, PIN = script("hertz_cylinders_2d"), script("pin_plate_2d")


def hertz(h: float) -> ds.SignoriniProblem:
    """The cylinders (R 1 and 1.5, E 1 and 2.5), the upper flat pressed down by 0.004."""
    msh, cells, facets = from_model(CYL.build, h=h, h_contact=h)
    return ds.SignoriniProblem(
        msh, facets, contact=ds.ContactPair(slave=CYL.UPPER_ARC, master=CYL.LOWER_ARC),
        cell_tags=cells, E={CYL.LOWER: 1.0, CYL.UPPER: 2.5}, nu={CYL.LOWER: 0.3, CYL.UPPER: 0.25},
        dirichlet={CYL.LOWER_FLAT: (None, 0.0), CYL.UPPER_FLAT: (None, -0.004),
                   CYL.LOWER_SYMMETRY: (0.0, None), CYL.UPPER_SYMMETRY: (0.0, None)},
    )


def pin(h: float) -> ds.SignoriniProblem:
    """The pin (E 3) pushed 0.1 into the hole (clearance 0.05) of the plate (E 1)."""
    msh, cells, facets = from_model(PIN.build, h=h, h_contact=h / 3)
    return ds.SignoriniProblem(
        msh, facets, contact=ds.ContactPair(slave=PIN.PIN_SURFACE, master=PIN.HOLE),
        cell_tags=cells, E={PIN.PIN: 3.0, PIN.PLATE: 1.0}, nu=0.3,
        dirichlet={PIN.PLATE_EDGE: (0.0, 0.0), PIN.PIN_BORE: (0.1, 0.0),
                   PIN.PIN_SYMMETRY: (None, 0.0), PIN.PLATE_SYMMETRY: (None, 0.0)},
    )


def force(u: Any, lam: Any, m: Any) -> Any:
    """The contact force (on the slave side)."""
    return lam * m.ds_contact


def lower_stress(u: Any, lam: Any, m: Any) -> Any:
    """sigma_yy in a window of the lower cylinder (the master) below the contact."""
    window = ufl.conditional(ufl.And(ufl.lt(m.x[0], 0.05), ufl.gt(m.x[1], -0.05)), 1.0, 0.0)
    return window * m.sigma(u)[1, 1] * m.dx(CYL.LOWER)


CASES = {
    # name: (problem, goal, cell tags of the bodies, uniform levels, adaptive levels, reference)
    "hertz-force": (lambda: hertz(0.1), force, (CYL.LOWER, CYL.UPPER), 6, 9, 10),
    "hertz-stress": (lambda: hertz(0.1), lower_stress, (CYL.LOWER, CYL.UPPER), 6, 9, 10),
    "pin-force": (lambda: pin(0.3), force, (PIN.PIN, PIN.PLATE), 3, 6, 7),
}


def run(make: Any, goal: Any, bodies: tuple, **options: Any) -> list[dict[str, Any]]:
    """One run's levels: cells per body, J_h, the interval, cumulative time."""
    rows: list[dict[str, Any]] = []
    clock = [0.0]

    def record(rec: Any, sol: Any, est: Any) -> None:
        tags = sol.disc.cell_tags
        num = sol.disc.mesh.topology.index_map(sol.disc.mesh.topology.dim).size_local
        keep = tags.indices < num
        cells = [MPI.COMM_WORLD.allreduce(int(np.sum(tags.values[keep] == t)), op=MPI.SUM)
                 for t in bodies]
        clock[0] += rec.time["total"]
        rows.append({"level": rec.level, "cells": cells, "J_h": rec.J_h, "J_low": rec.J_low,
                     "J_high": rec.J_high, "weights": rec.weights, "time": clock[0]})
        if MPI.COMM_WORLD.rank == 0:  # progress
            print(f"  {options.get('refinement', 'adaptive')} level {rec.level}: "
                  f"{rec.num_cells} cells, J_h {rec.J_h:.9g}, {clock[0]:.1f} s", flush=True)

    with ds.solve_adaptive(make(), goal, callback=record, verbose=False, **options):
        pass
    return rows


def payoff(name: str) -> dict[str, Any]:
    """The uniform and adaptive runs of one case, against the reference."""
    make, goal, bodies, n_uniform, n_adaptive, n_reference = CASES[name]
    with ds.solve(make()):  # compile, untimed
        pass
    reference_run = run(make, goal, bodies, max_levels=n_reference)
    ref = reference_run[-1]["J_h"]
    doubt = abs(ref - reference_run[-2]["J_h"])
    uniform = run(make, goal, bodies, refinement="uniform", max_levels=n_uniform)
    adaptive = reference_run[:n_adaptive]
    target = abs(ref - uniform[-1]["J_h"])
    reached = next((r for r in adaptive if abs(ref - r["J_h"]) + doubt < target - doubt), None)
    return {"case": name, "reference": ref, "uncertainty": doubt, "uniform": uniform,
            "adaptive": adaptive, "target": target,
            "ratio": None if reached is None else reached["time"] / uniform[-1]["time"],
            "reached_level": None if reached is None else reached["level"]}


def table(result: dict[str, Any]) -> str:
    """The levels of both runs and the payoff line."""
    ref = result["reference"]
    lines = [f"== {result['case']}: J_ref = {ref:.10g} +- {result['uncertainty']:.2g}"]
    head = (f"{'run':>8} {'lvl':>3} {'cells/body':>17} {'J_h':>15} {'J_low':>15} "
            f"{'J_high':>15} {'J_ref - J_h':>12} {'in':>3} {'time':>8}")
    lines.append(head)
    for kind in ("uniform", "adaptive"):
        for r in result[kind]:
            inside = r["J_low"] - result["uncertainty"] <= ref <= r["J_high"] + \
                result["uncertainty"]
            cells = "/".join(str(c) for c in r["cells"])
            lines.append(f"{kind:>8} {r['level']:3d} {cells:>17} {r['J_h']:15.9g} "
                         f"{r['J_low']:15.9g} {r['J_high']:15.9g} {ref - r['J_h']:12.3e} "
                         f"{'yes' if inside else 'NO':>3} {r['time']:8.2f}")
    ratio = result["ratio"]
    lines.append(
        f"uniform finest error {result['target']:.3e}; adaptive reaches it at level "
        f"{result['reached_level']}: time ratio adaptive / uniform = "
        f"{'not reached' if ratio is None else f'{ratio:.2f}'}"
    )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["hertz-force", "hertz-stress"],
                        choices=list(CASES))
    args = parser.parse_args()
    results = []
    for name in args.cases:
        result = payoff(name)
        results.append(result)
        if MPI.COMM_WORLD.rank == 0:
            print(table(result), flush=True)
    if MPI.COMM_WORLD.rank == 0:
        RESULTS.mkdir(parents=True, exist_ok=True)
        path = RESULTS / "two_bodies_payoff.json"
        path.write_text(json.dumps(results, indent=1))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
