"""Two elastic cylinders in contact (a ContactPair): J_h and its interval on adaptive levels
against a reference from uniform refinement, and the cost of the master trace.

The Hertz pair of ``demos/two_bodies.py`` (``meshes/hertz_cylinders_2d.py``: R1 = 1, E1 = 1,
nu1 = 0.3 below; R2 = 1.5, E2 = 2.5, nu2 = 0.25 above, the upper arc the slave side, the top
pressed down by 0.004), two contact-force goals: ``centre``, the force weighted by
exp(-x^2/c^2), c = 0.0165 (the demo's goal), and ``force``, the whole contact force of the half
model.

1. Adaptive levels (``ds.solve_adaptive``, its default weights, fraction 0.2) for each goal:
   level, cells of T_h per body, J_h, the interval [J_low, J_high], the time of the level.
   The arcs stay the polygons of the initial mesh (no ``boundary_projection``) here and in 2:
   the estimate is of the discretisation error of the domain meshed, which is what the
   reference converges to (the demo projects onto the circles, for Hertz's formulas).
2. The reference J: ``ds.solve`` on the initial mesh refined uniformly ``--uniform`` times (no
   estimate, J_h alone); Richardson extrapolation of the last three levels with the fitted rate
   where they converge monotonically, else the finest level's J_h; its last change is printed
   as a measure of its uncertainty.
3. The master trace against a rigid obstacle of the same size: on every adaptive macro mesh of
   the ``centre`` run, one ``ds.solve`` of the pair and one of the same mesh with the upper arc on
   the rigid disc that the lower arc bounds (``gap=ds.obstacles.Sphere((0, -1), 1)``, the lower
   body then unloaded: the same unknowns and the same Newton system sizes), ``--repeat`` times
   each, the least times shown. The timing phases
   (``dwr_signorini.timing``) of each solve: ``master trace`` (the mortar rule and P, once per
   mesh), ``assemble`` (the Newton system's matrices), and the total of the solve.

Tables go to ``benchmarks/results/two_bodies*.csv`` and ``two_bodies.json``::

    scripts/fenicsx python3 benchmarks/two_bodies.py --uniform 4    # ~5 min
    scripts/fenicsx python3 benchmarks/two_bodies.py                 # ~1.5 min
    scripts/fenicsx python3 benchmarks/two_bodies.py --quick         # seconds
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini.io import write_csv, write_json
from dwr_signorini.meshes import hertz_cylinders_2d as cyl
from dwr_signorini.refine import refine_marked
from dwr_signorini.timing import snapshot

RESULTS = Path(__file__).resolve().parent / "results"
comm = MPI.COMM_WORLD
C = 0.033 / 2


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


def read(h_contact: float) -> tuple:
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.add("hertz_cylinders_2d")
            cyl.build(gmsh.model, r_lower=1.0, r_upper=1.5, h_contact=h_contact)
        return ds.read_mesh(gmsh.model, comm)
    finally:
        gmsh.finalize()


DIRICHLET = {cyl.LOWER_FLAT: (None, 0.0), cyl.UPPER_FLAT: (None, -0.004),
             cyl.LOWER_SYMMETRY: (0.0, None), cyl.UPPER_SYMMETRY: (0.0, None)}
MATERIAL = {"E": {cyl.LOWER: 1.0, cyl.UPPER: 2.5}, "nu": {cyl.LOWER: 0.3, cyl.UPPER: 0.25}}


def pair_problem(msh, facet_tags, cell_tags, project: bool = True) -> ds.SignoriniProblem:
    return ds.SignoriniProblem(
        msh, facet_tags, contact=ds.ContactPair(slave=cyl.UPPER_ARC, master=cyl.LOWER_ARC),
        dirichlet=DIRICHLET, cell_tags=cell_tags, **MATERIAL,
        boundary_projection=cyl.projections(1.0, 1.5) if project else None)


def rigid_problem(msh, facet_tags, cell_tags) -> ds.SignoriniProblem:
    return ds.SignoriniProblem(
        msh, facet_tags, contact=cyl.UPPER_ARC, gap=ds.obstacles.Sphere((0.0, -1.0), 1.0),
        dirichlet=DIRICHLET, cell_tags=cell_tags, **MATERIAL)


def goal_centre(u, lam, m):
    return ufl.exp(-(m.x[0] ** 2) / C**2) * lam * m.ds_contact


def goal_force(u, lam, m):
    return lam * m.ds_contact


GOALS = {"centre": goal_centre, "force": goal_force}


def cells_per_body(disc) -> tuple[int, int]:
    tags = disc.cell_tags
    owned = disc.mesh.topology.index_map(disc.mesh.topology.dim).size_local
    keep = tags.indices < owned
    return tuple(comm.allreduce(int(np.count_nonzero(tags.values[keep] == t)), op=MPI.SUM)
                 for t in (cyl.LOWER, cyl.UPPER))


def richardson(levels: list[tuple[int, float]]) -> tuple[float, float]:
    """J extrapolated from the last three (cells, J_h) of uniform refinement, and the rate p in
    cells (J_h - J ~ N^-p)."""
    (n0, j0), (n1, j1), (n2, j2) = levels[-3:]
    ratio = (j1 - j0) / (j2 - j1)
    p = math.log(abs(ratio)) / math.log(n1 / n0) if ratio > 0 else float("nan")
    if not math.isfinite(p) or p <= 0:
        return j2, float("nan")
    r = (n2 / n1) ** p
    return j2 + (j2 - j1) / (r - 1), p


def solve_phases(make, repeat: int) -> dict[str, float]:
    """``repeat`` times ds.solve(make()): the least time of each phase (max over ranks) and of
    the total."""
    best: dict[str, float] = {}
    for _ in range(repeat):
        problem = make()
        comm.Barrier()
        before, tic = snapshot(), time.perf_counter()
        with ds.solve(problem):
            pass
        total = time.perf_counter() - tic
        after = snapshot()
        phases = {k: comm.allreduce(after[k] - before[k], op=MPI.MAX) for k in after}
        phases["total"] = comm.allreduce(total, op=MPI.MAX)
        best = {k: min(v, best.get(k, math.inf)) for k, v in phases.items()}
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, default=6, help="adaptive levels per goal")
    parser.add_argument("--uniform", type=int, default=3, help="uniform refinements (reference)")
    parser.add_argument("--h-contact", type=float, default=0.01)
    parser.add_argument("--repeat", type=int, default=3,
                        help="solves per mesh in the cost table (the least times are shown)")
    parser.add_argument("--quick", action="store_true", help="3 adaptive levels, 2 uniform")
    args = parser.parse_args()
    if args.quick:
        args.levels, args.uniform = 3, 2
    msh, cell_tags, facet_tags = read(args.h_contact)
    with ds.solve(pair_problem(msh, facet_tags, cell_tags)):  # JIT cache
        pass
    with ds.solve(rigid_problem(msh, facet_tags, cell_tags)):
        pass

    # 2. the reference: J_h on uniform refinements
    print0(f"uniform refinement, J_h of both goals ({comm.size} process(es))")
    print0(f"{'L':>2} {'cells':>8} {'J_h centre':>14} {'J_h force':>14} {'time':>6}")
    problem = pair_problem(msh, facet_tags, cell_tags, project=False)
    uniform = []
    for level in range(args.uniform + 1):
        tic = time.perf_counter()
        with ds.solve(problem) as sol:
            row = {"level": level, "num_cells": sol.disc.num_cells}
            for name, goal in GOALS.items():
                form = sol.disc.form(goal(sol.u, sol.lam, sol.disc.m))
                row[f"J_{name}"] = comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)
        row["time"] = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
        uniform.append(row)
        print0(f"{level:2d} {row['num_cells']:8d} {row['J_centre']:14.8e} "
               f"{row['J_force']:14.8e} {row['time']:6.1f}")
        if level < args.uniform:
            problem, _ = refine_marked(problem, None)
    reference = {}
    for name in GOALS:
        series = [(r["num_cells"], r[f"J_{name}"]) for r in uniform]
        value, rate = richardson(series) if len(series) >= 3 else (series[-1][1], float("nan"))
        drift = abs(series[-1][1] - series[-2][1]) if len(series) >= 2 else float("nan")
        reference[name] = {"value": value, "rate": rate, "finest": series[-1][1],
                           "finest_cells": series[-1][0], "drift": drift,
                           "method": "richardson" if math.isfinite(rate) else "finest uniform"}
        print0(f"reference {name}: {value:.8e} ({reference[name]['method']}, rate {rate:.2f} "
               f"in cells), finest uniform {series[-1][1]:.8e} ({series[-1][0]} cells), last "
               f"change {drift:.2e} ({drift / abs(value):.1e} relative)")

    # 1. adaptive levels
    adaptive, macro = [], []
    for name, goal in GOALS.items():
        ref = reference[name]["value"]
        print0(f"\nadaptive, goal {name}")
        print0(f"{'L':>2} {'cells lower':>11} {'cells upper':>11} {'J_h':>14} "
               f"{'J_low':>14} {'J_high':>14} {'J_ref':>14} {'J_h/J_ref-1':>11} "
               f"{'ref in':>6} {'time':>6}")
        last = [time.perf_counter()]

        def on_level(record, sol, est, name=name, ref=ref, last=last):
            lower, upper = cells_per_body(sol.disc)
            now = time.perf_counter()
            row = {"goal": name, "level": record.level, "num_cells": record.num_cells,
                   "cells_lower": lower, "cells_upper": upper, "J_h": record.J_h,
                   "J_low": record.J_low, "J_high": record.J_high, "J_ref": ref,
                   "rel_error": record.J_h / ref - 1,
                   "ref_inside": bool(record.J_low <= ref <= record.J_high),
                   "time": comm.allreduce(now - last[0], op=MPI.MAX)}
            last[0] = now
            adaptive.append(row)
            if name == "centre":
                p = sol.disc.problem
                macro.append((p.mesh, p.facet_tags, p.cell_tags))
            print0(f"{record.level:2d} {lower:11d} {upper:11d} {record.J_h:14.8e} "
                   f"{record.J_low:14.8e} {record.J_high:14.8e} {ref:14.8e} "
                   f"{row['rel_error']:+11.2e} {'yes' if row['ref_inside'] else 'no':>6} "
                   f"{row['time']:6.1f}")

        ds.solve_adaptive(pair_problem(msh, facet_tags, cell_tags, project=False), goal,
                          fraction=0.2, max_levels=args.levels, callback=on_level,
                          verbose=False).destroy()

    # 3. the master trace against a rigid obstacle, on the adaptive meshes
    print0("\none ds.solve per adaptive mesh (goal centre): the pair against the rigid disc")
    print0(f"{'L':>2} {'cells':>8} {'slave':>6} | {'master trace':>12} {'assemble':>9} "
           f"{'total':>7} | {'rigid: assemble':>15} {'total':>7} | {'trace/rigid asm':>15} "
           f"{'pair/rigid':>10}")
    cost = []
    for level, (m, ft, ct) in enumerate(macro):
        data = (m, ft, ct)
        pair = solve_phases(lambda d=data: pair_problem(*d, project=False), args.repeat)
        rigid = solve_phases(lambda d=data: rigid_problem(*d), args.repeat)
        slave = comm.allreduce(int(np.count_nonzero(ft.values == cyl.UPPER_ARC)), op=MPI.SUM)
        row = {"level": level, "num_cells": adaptive[level]["num_cells"],
               "slave_macro_facets": slave,
               "pair_master_trace": pair["master trace"], "pair_assemble": pair["assemble"],
               "pair_total": pair["total"], "rigid_assemble": rigid["assemble"],
               "rigid_total": rigid["total"],
               "trace_over_rigid_assemble": pair["master trace"] / rigid["assemble"],
               "pair_over_rigid_total": pair["total"] / rigid["total"]}
        cost.append(row)
        print0(f"{level:2d} {row['num_cells']:8d} {slave:6d} | {pair['master trace']:12.3f} "
               f"{pair['assemble']:9.3f} {pair['total']:7.2f} | "
               f"{rigid['assemble']:15.3f} {rigid['total']:7.2f} | "
               f"{row['trace_over_rigid_assemble']:15.2f} {row['pair_over_rigid_total']:10.2f}")

    if comm.rank == 0:
        RESULTS.mkdir(parents=True, exist_ok=True)
        suffix = "" if comm.size == 1 else f"_np{comm.size}"
        write_csv(RESULTS / f"two_bodies_adaptive{suffix}.csv", adaptive)
        write_csv(RESULTS / f"two_bodies_uniform{suffix}.csv", uniform)
        write_csv(RESULTS / f"two_bodies_cost{suffix}.csv", cost)
        write_json(RESULTS / f"two_bodies{suffix}.json", {
            "args": vars(args), "num_processes": comm.size, "reference": reference,
            "adaptive": adaptive, "uniform": uniform, "cost": cost})


if __name__ == "__main__":
    main()
