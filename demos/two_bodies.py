# # Two elastic cylinders in contact: a contact pair in one mesh
#
# Two bodies of different materials touch; neither is rigid. Both live in one dolfinx mesh as
# two separate gmsh surfaces (no shared node), and `ds.ContactPair(slave=..., master=...)`
# names the facets of one body (the *slave* side, where the contact force $\lambda_H$ lives)
# that may touch the facets of the other (the *master* side). The contact condition holds for
# the relative displacement: a slave point $x$ with outward normal $n$ meets the master surface
# at $\Pi(x) = x + g(x)\,n$, and
#
# $$
# [u]_n(x) = \big(u(x) - u(\Pi(x))\big) \cdot n \le g(x), \qquad \lambda \ge 0, \qquad
# \lambda\,([u]_n - g) = 0
# $$
#
# (small sliding, in the reference configuration; `dwr_signorini/pairs.py` assembles the master
# trace $u \circ \Pi$ once per mesh with the mortar rule, so the discrete problem, its dual and
# the estimator's residuals use the same coupling in both bodies).
#
# ## The problem
#
# The mesh of `meshes/hertz_cylinders_2d.py`: the quarter disc of radius $R_1 = 1$ below the
# origin (cells 1, $E_1 = 1$, $\nu_1 = 0.3$) and the quarter disc of radius $R_2 = 1.5$ above
# it (cells 2, $E_2 = 2.5$, $\nu_2 = 0.25$), touching at the origin, plane strain, symmetric
# about $x = 0$ ($u_x = 0$ there). The lower flat $y = -R_1$ is held ($u_y = 0$), the upper flat
# $y = R_2$ pressed down by $u_y = -\delta$, $\delta = 0.004$. The upper arc is the slave side
# (`--slave lower` swaps the roles).
#
# Hertz's theory of two cylinders (half-spaces, $a \ll R$) with the force $F$ per unit length
# (twice the half model's):
#
# $$
# \frac{1}{E^*} = \frac{1 - \nu_1^2}{E_1} + \frac{1 - \nu_2^2}{E_2},\quad
# \frac{1}{R} = \frac{1}{R_1} + \frac{1}{R_2},\quad
# a = 2\sqrt{\frac{R F}{\pi E^*}},\quad p_0 = \frac{2F}{\pi a},\quad
# p(x) = p_0\sqrt{1 - x^2/a^2}.
# $$
#
# Every level compares the half-width $a_h$ (from the second moment of the pressure,
# $a_h^2 = 4 \int x^2 \lambda_H / \int \lambda_H$, exact for Hertz's profile) and the peak
# $\max \lambda_H$ with $a$ and $p_0$ of the computed force.
#
# ## Goal
#
# The contact force near the centre of the slave side, weighted by a smooth bump,
# $J(u, \lambda) = \int_{\Gamma_C} e^{-x^2/c^2} \lambda \, ds$, $c = a_0 / 2$ with
# $a_0 = 0.033$ (Hertz's half-width at this $\delta$); `--goal force` takes the whole contact
# force instead. (A sharp window $|x| < c$ makes a poor goal here: a macro facet cut by its
# edge is integrated inexactly, and that error, which the estimator does not see, moves $J_h$
# from level to level by more than the interval's width.) Goals may also integrate over the
# cells of either body: `m.dx(1)` and `m.dx(2)` are the cells of the lower and of the upper
# body (the cell tags). Every level
# prints $J_h$ and the interval $[J_{low}, J_{high}]$ of the estimator for $J(u, \lambda)$.
# The estimator's weights are `--weights patch` here.
#
# What to expect: $a_h$ within 0.2 % and the peak within 0.3 % of Hertz's from level 2 on, the
# interval of $J$ narrowing from 2.7 % of $J_h$ (level 0) to 0.01 % (level 5). The arcs are
# projected onto the circles as the mesh is refined; the interval is for the domain meshed on
# each level (the geometry error of the arcs is not in it).
#
# ```
# python3 demos/two_bodies.py            # or: mpirun -n 2 python3 demos/two_bodies.py
# ```

# +
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import viz
from dwr_signorini.io import write_csv, write_json
from dwr_signorini.meshes import hertz_cylinders_2d as script
from dwr_signorini.viz.canvas import new_figure, save_figure
from dwr_signorini.viz.gather import gather_contact_force

comm = MPI.COMM_WORLD


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## Options

# +
parser = argparse.ArgumentParser(
    description="Hertz contact of two elastic cylinders (a ContactPair in one mesh)",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--levels", type=int, default=6, help="adaptive levels")
parser.add_argument("--fraction", type=float, default=0.2, help="marking fraction")
parser.add_argument("--goal", choices=("centre", "force"), default="centre",
                    help="the contact force weighted by exp(-x^2/c^2), c = a0/2, or all of it")
parser.add_argument("--weights", choices=("patch", "auto", "higher_order", "hierarchical"),
                    default="patch", help="the estimator's weights")
parser.add_argument("--slave", choices=("upper", "lower"), default="upper",
                    help="the body whose arc carries the multiplier")
parser.add_argument("--h-contact", type=float, default=0.01, help="mesh size at the contact")
parser.add_argument("--output", type=Path, default=Path("results/two_bodies"))
parser.add_argument("--no-plots", action="store_true")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
if args.levels < 1:
    parser.error(f"--levels must be at least 1, got {args.levels}")
out = args.output
R1, R2, E1, E2, NU1, NU2 = 1.0, 1.5, 1.0, 2.5, 0.3, 0.25
E_STAR = 1.0 / ((1 - NU1**2) / E1 + (1 - NU2**2) / E2)
R = 1.0 / (1.0 / R1 + 1.0 / R2)
DELTA = 0.004
A0 = 0.033
C_WINDOW = A0 / 2
print0(f"two cylinders on {comm.size} process(es); output in {out}/")
# -

# ## The mesh and the problem
#
# `build` makes the two quarter discs as two OCC surfaces, so that gmsh gives them no common
# node; the physical groups are the cell tags 1, 2 and the facet tags of `script`. The arcs are
# curved: `boundary_projection` moves the vertices that refinement adds onto the true circles.

# +


def read() -> tuple:
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.add("hertz_cylinders_2d")
            script.build(gmsh.model, r_lower=R1, r_upper=R2, h_contact=args.h_contact)
        return ds.read_mesh(gmsh.model, comm)
    finally:
        gmsh.finalize()


msh, cell_tags, facet_tags = read()
if args.slave == "upper":
    PAIR = ds.ContactPair(slave=script.UPPER_ARC, master=script.LOWER_ARC)
else:
    PAIR = ds.ContactPair(slave=script.LOWER_ARC, master=script.UPPER_ARC)


def pair_problem() -> ds.SignoriniProblem:
    return ds.SignoriniProblem(
        msh, facet_tags, contact=PAIR,
        dirichlet={script.LOWER_FLAT: (None, 0.0), script.UPPER_FLAT: (None, -DELTA),
                   script.LOWER_SYMMETRY: (0.0, None), script.UPPER_SYMMETRY: (0.0, None)},
        E={script.LOWER: E1, script.UPPER: E2}, nu={script.LOWER: NU1, script.UPPER: NU2},
        cell_tags=cell_tags, boundary_projection=script.projections(R1, R2),
    )


def goal_centre(u, lam, m):
    return ufl.exp(-(m.x[0] ** 2) / C_WINDOW**2) * lam * m.ds_contact


def goal_force(u, lam, m):
    return lam * m.ds_contact


GOAL = {"centre": goal_centre, "force": goal_force}[args.goal]
# -

# ## Measuring the contact
#
# The force $F$ of the whole pair, Hertz's $a$ and $p_0$ for it, the half-width $a_h$ from the
# second moment of $\lambda_H$, the peak, and the cells of each body on the fine mesh $T_h$
# (the cell tags follow refinement: `sol.disc.cell_tags`).

# +


def integrate(sol: ds.Solution, form) -> float:
    return comm.allreduce(fem.assemble_scalar(sol.disc.form(form)), op=MPI.SUM)


def cells_per_body(sol: ds.Solution) -> tuple[int, int]:
    tags = sol.disc.cell_tags
    owned = sol.disc.mesh.topology.index_map(sol.disc.mesh.topology.dim).size_local
    keep = tags.indices < owned
    counts = [int(np.count_nonzero(tags.values[keep] == t)) for t in (script.LOWER, script.UPPER)]
    return tuple(comm.allreduce(c, op=MPI.SUM) for c in counts)


def measure(sol: ds.Solution) -> dict[str, float]:
    m = sol.disc.m
    m0 = integrate(sol, sol.lam * m.ds_contact)
    m2 = integrate(sol, sol.lam * m.x[0] ** 2 * m.ds_contact)
    F = 2 * m0
    a = 2 * math.sqrt(R * F / (math.pi * E_STAR))
    p0 = 2 * F / (math.pi * a)
    a_h = 2 * math.sqrt(m2 / m0) if m0 > 0 else 0.0
    lam = sol.lam.x.array[: sol.system.n_lam]
    peak = comm.allreduce(float(np.max(lam, initial=0.0)), op=MPI.MAX)
    lower, upper = cells_per_body(sol)
    return {"cells_lower": lower, "cells_upper": upper, "F": F, "a_hertz": a, "p0_hertz": p0,
            "a_h": a_h, "err_a": a_h / a - 1, "peak": peak, "err_p0": peak / p0 - 1}


# -

# ## The adaptive run
#
# `ds.solve_adaptive` with the goal; the callback records a row per level and keeps a drawing
# of the first and of the last macro mesh (`viz.snapshot_mesh` is collective; it gathers on
# rank 0).

# +
with ds.solve(pair_problem()):  # loads the compiled forms (JIT cache): times compare
    pass
table: list[dict] = []
meshes: dict[int, viz.MeshSnapshot | None] = {}
print0(f"{'L':>2} {'cells lower':>11} {'cells upper':>11} {'J_h':>12} {'[J_low, J_high]':>27} "
       f"{'F':>10} {'a_h':>8} {'a Hertz':>8} {'err a':>7} {'peak':>9} {'p0':>9} {'err p0':>7} "
       f"{'time':>6}")
tic = time.perf_counter()


def on_level(record, sol, est):
    row = {"level": record.level, "num_cells": record.num_cells, "num_dofs": record.num_dofs,
           "J_h": record.J_h, "J_low": record.J_low, "J_high": record.J_high,
           "J_best": record.J_best, "estimate": record.estimate, "num_active": record.num_active,
           **measure(sol), "time_cumulative": time.perf_counter() - tic}
    table.append(row)
    snap = viz.snapshot_mesh(sol.disc.macro_mesh)
    meshes.setdefault(0, snap)
    meshes[1] = snap
    print0(f"{record.level:2d} {row['cells_lower']:11d} {row['cells_upper']:11d} "
           f"{record.J_h:12.5e} [{record.J_low:12.5e}, {record.J_high:12.5e}] {row['F']:10.4e} "
           f"{row['a_h']:8.5f} {row['a_hertz']:8.5f} {row['err_a']:+7.2%} {row['peak']:9.3e} "
           f"{row['p0_hertz']:9.3e} {row['err_p0']:+7.2%} {row['time_cumulative']:6.1f}")


result = ds.solve_adaptive(pair_problem(), GOAL, refinement="adaptive", fraction=args.fraction,
                           max_levels=args.levels, output_dir=out / "adaptive",
                           callback=on_level, verbose=False,
                           weights=args.weights)
if comm.rank == 0:
    write_csv(out / "two_bodies.csv", table)
    write_json(out / "summary.json", {
        "args": {k: str(v) for k, v in vars(args).items()}, "num_processes": comm.size,
        "E": [E1, E2], "nu": [NU1, NU2], "R": [R1, R2], "E_star": E_STAR, "R_eff": R,
        "delta": DELTA, "goal_width": C_WINDOW, "slave": args.slave, "levels": table,
        "runs": {"adaptive": result.rows()},
    })
# -

# ## Pictures
#
# The first and the last macro mesh $T_H$, both bodies (lower body blue, upper body orange),
# in full and near the contact; the pressure along the interface of the last level against Hertz's
# profile; $J_h$ and its interval per level.

# +
gathered = gather_contact_force(result.solution)
if not args.no_plots and comm.rank == 0:
    from matplotlib.collections import PolyCollection

    fig = new_figure((10.0, 8.0))
    for row, (key, label) in enumerate(((0, "level 0"), (1, f"level {table[-1]['level']}"))):
        polys = meshes[key].cells[:, :, :2]
        lower = polys[:, :, 1].mean(axis=1) < 0.0
        for col, (half, zoom) in enumerate(((1.6, False), (4 * A0, True))):
            ax = fig.add_subplot(2, 2, 2 * row + col + 1)
            faces = np.where(lower[:, None], [[0.75, 0.85, 1.0, 1.0]], [[1.0, 0.85, 0.7, 1.0]])
            seen = np.count_nonzero(np.all(polys[:, :, 0] < half, axis=1)
                                    & np.all(np.abs(polys[:, :, 1]) < half, axis=1))
            width = float(np.clip(25.0 / math.sqrt(max(seen, 1)), 0.02, 0.6))
            ax.add_collection(PolyCollection(polys, facecolors=faces, edgecolors="k",
                                             linewidths=width))
            ax.set_xlim(0.0, half)
            ax.set_ylim(-half / 2 if zoom else -R1, half / 2 if zoom else R2)
            ax.set_aspect("equal")
            where = ", near the contact" if zoom else ""
            ax.set_title(f"{label}: {len(polys)} macro cells{where}", fontsize="medium")
    save_figure(fig, out / "meshes.png", dpi=150)

    x, lam, _ = gathered
    mid = np.abs(x.mean(axis=1)[:, 0])
    last = table[-1]
    a, p0 = last["a_hertz"], last["p0_hertz"]
    fig = new_figure((6.4, 4.0))
    ax = fig.add_subplot()
    order = np.argsort(mid)
    ax.plot(mid[order] / a, lam[order] / p0, ".", markersize=4,
            label=r"computed $\lambda_H$ (macro facets)")
    s = np.linspace(0.0, 1.0, 200)
    ax.plot(s, np.sqrt(1 - s**2), "k-", label=r"Hertz $p_0\sqrt{1 - x^2/a^2}$")
    ax.axvline(C_WINDOW / a, color="grey", ls=":", label="goal width c")
    ax.set_xlim(0.0, 1.5)
    ax.set_xlabel("x / a")
    ax.set_ylabel(r"$p / p_0$")
    ax.set_title(f"two cylinders, level {last['level']}: pressure along the interface")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    save_figure(fig, out / "pressure_profile.png")
if not args.no_plots:
    viz.plot_interval({f"J ({args.goal})": table}, out / "interval.png",
                      title="two cylinders: J_h and its interval per level", comm=comm)
if comm.rank == 0:
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -

# The last level's solvers are released with `destroy()`, collectively.

# +
result.destroy()
# -
