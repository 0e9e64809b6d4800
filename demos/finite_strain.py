# # Finite strain: a rubber cylinder pressed onto a rigid flat, then slid along it
#
# A soft, rubber-like body at large deformation: the half of a cylinder of radius $R = 1$ below
# its axis (plane strain), its flat top bonded to a rigid plate, is pressed onto a rigid,
# frictionless flat by 20 % of its radius and then slid along it by one radius. The material is
# the compressible Neo-Hookean law (`ds.NeoHookean()`, $E = 1$, $\nu = 0.4$),
#
# $$
# \psi(F) = \frac{\mu}{2}\,(\operatorname{tr}(F^T F) - 2 - 2 \ln J) + \frac{\lambda}{2} (\ln J)^2,
# \qquad F = I + \nabla u, \quad J = \det F,
# $$
#
# and the contact is measured in the deformed configuration: the gap of a point $x$ of
# $\Gamma_C$ is the signed distance of $x + u(x)$ to the flat, the contact force acts along the
# flat's normal, and the multiplier $\lambda_H$ is a force per *reference* length, constant on
# the macro facets of $\Gamma_C$. The [finite-strain guide](../guide/finite_strain.md) states
# the discrete problem and the semi-smooth Newton method that solves it.
#
# ## The load path
#
# `ds.solve_path(problem, None, load_factors=[...])` applies the plate's displacement in steps,
# each from the last state; a step whose Newton method fails is halved and retried (column
# `cuts`). The press moves the plate by $t\,(0, -\delta)$, $t = 1/n, \dots, 1$. The slide starts
# from the pressed state (`initial_guess=` the press's last solution) and moves the plate from
# $(0, -\delta)$ to $(s, -\delta)$. On a frictionless flat nothing resists the slide: the slid
# state is the pressed state translated by $(s, 0)$, so the contact force and width must stay
# those of the press, to round-off, over any sliding distance (the last line of the table).
#
# Each step prints the plate's approach and slide, the contact force
# $P = \int_{\Gamma_C} \lambda_H\,dS$ (per unit thickness) and a stress near the contact, each
# with its error bar, the contact width (the deformed length of the facets in contact), the
# Newton steps (of all solves of the step), the cut steps and the times of the solve and of the
# two estimates.
#
# ## The goals and their error bars
#
# Two quantities of interest, written in UFL on the reference configuration: the contact force
#
# $$
# J_P(u, \lambda) = \int_{\Gamma_C} \lambda\,dS,
# $$
#
# and a weighted average of the nominal (first Piola-Kirchhoff) pressure $-P_{yy}$ near the
# first contact point, the origin,
#
# $$
# J_S(u, \lambda) = \frac{\int_\Omega \omega\,(-P_{yy}(F(u)))\,dx}{\int_\Omega \omega\,dx},
# \qquad \omega(X) = e^{-|X|^2 / r^2},\quad r = 0.25,
# $$
#
# with `m.P(u)`, the first Piola-Kirchhoff stress of the problem's law. After each load step the
# callback estimates both at the step's state, `ds.estimate(sol, goal)` (a state of
# `ds.solve_path` is estimated at its own load factor): the dual problem is the transposed
# Newton matrix at $w_h = (u_h, \lambda_H)$, the estimate $\eta$ the paper's primal-dual one with
# the patch weights, and the interval
#
# $$
# J \in [J_{low}, J_{high}] \ni J_h + \eta
# $$
#
# is the linear path's (a saturation assumption on the weights, $|\eta - \eta_p|$ and the
# active-set remainder $R_A$) widened on both sides by the estimated nonlinear remainder
# $|R^{(3)}|$ of the error identity
# ([the finite-strain guide](../guide/finite_strain.md#the-goals-error)). The interval is an
# estimate, not a bound. On a frictionless flat the slid state is the pressed state translated,
# and so are its dual solution and weights: the slide's intervals must be the pressed state's.
#
# **Is the interval right?** With `--reference L` the press is solved again, step for step, on
# the macro mesh refined uniformly $L - 2$, $L - 1$ and $L$ times, and $J$ extrapolated from
# $J_h$ alone on these three meshes (Richardson with the observed ratio); each step's
# interval is judged against it (`reference.csv`). This costs far more than the demo itself:
# the meshes of $L = 3$ have 64 times its cells.
#
# ```
# python3 demos/finite_strain.py               # or: mpirun -n 2 python3 demos/finite_strain.py
# python3 demos/finite_strain.py --h-contact 0.025 --press-steps 10
# python3 demos/finite_strain.py --reference 3  # judge the intervals (about a minute)
# ```
#
# Tables (CSV, JSON), pictures (PNG) and the fields of every step (XDMF, and VTX where dolfinx has
# ADIOS2) go to `results/finite_strain/`.

# +
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import cases, compat
from dwr_signorini.io import OutputDirectory, write_json
from dwr_signorini.viz.canvas import new_figure, save_figure

comm = MPI.COMM_WORLD


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## Options
#
# The defaults (macro facets of 0.05 at the contact, 5 press and 4 slide steps, both goals
# estimated after each step) take a few seconds, serial or on two processes.

# +
D = cases.RC_DEFAULTS
parser = argparse.ArgumentParser(
    description="Finite strain: a Neo-Hookean cylinder pressed onto a rigid flat and slid",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--h-contact", type=float, default=D["h_contact"],
                    help="macro facet size near the contact")
parser.add_argument("--approach", type=float, default=D["approach"],
                    help="the plate's downward displacement (R = 1)")
parser.add_argument("--slide", type=float, default=D["slide"],
                    help="the plate's horizontal displacement after the press")
parser.add_argument("--press-steps", type=int, default=5, help="load steps of the press")
parser.add_argument("--slide-steps", type=int, default=4, help="load steps of the slide")
parser.add_argument("--nu", type=float, default=D["nu"], help="Poisson's ratio")
parser.add_argument("--reference", type=int, default=0, metavar="L",
                    help="judge the press's intervals against J from J_h alone on the meshes "
                         "refined L-2, L-1 and L times (L >= 3; 0: no reference)")
parser.add_argument("--output", type=Path, default=Path("results/finite_strain"))
parser.add_argument("--no-plots", action="store_true")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
if args.press_steps < 1 or args.slide_steps < 1:
    parser.error("--press-steps and --slide-steps must be at least 1")
if args.reference not in (0,) and args.reference < 3:
    parser.error("--reference takes 0 (none) or at least 3 (three meshes finer than the demo's)")
out = args.output
print0(f"Neo-Hookean cylinder on a rigid flat, {comm.size} process(es): approach "
       f"{args.approach}, slide {args.slide}, nu = {args.nu}; output in {out}/")
# -

# ## The problem, the goals and the steps
#
# One mesh for both phases (`cases.rubber_cylinder_mesh`, gmsh on rank 0), two problems that
# differ only in the plate's displacement (`cases.rubber_cylinder_problems`). The goals are
# functions `goal(u, lam, m)` returning a UFL form; the stress goal's denominator
# $\int_\Omega \omega\,dx$ is a number, assembled once.

# +
mesh = cases.rubber_cylinder_mesh(comm, h_contact=args.h_contact)
press, slide = cases.rubber_cylinder_problems(mesh, args.approach, args.slide, nu=args.nu)
RADIUS = 0.25  # r of the stress goal's weight


def weight(x):
    return ufl.exp(-(x[0] ** 2 + x[1] ** 2) / RADIUS**2)


WEIGHT = comm.allreduce(fem.assemble_scalar(fem.form(weight(ufl.SpatialCoordinate(mesh[0]))
                                                     * ufl.dx(domain=mesh[0]))), op=MPI.SUM)


def contact_force(u, lam, m):
    """J_P: the contact force per unit thickness."""
    return lam * m.ds_contact


def contact_stress(u, lam, m):
    """J_S: the weighted average of -P_yy near the first contact point."""
    return -weight(m.x) / WEIGHT * m.P(u)[1, 1] * m.dx


GOALS = {"force": contact_force, "stress": contact_stress}
# -

# The callback measures each step while its solution is alive (`cases.measure_contact`: the
# deformed contact width, each facet's Cauchy pressure), estimates both goals (`interval`), and
# keeps the deformed mesh of a few steps for the pictures, coloured by the mean Cauchy pressure
# $-\operatorname{tr}\sigma / 2$ (`m.cauchy(u)`, the Cauchy stress of the goals).

# +
writer = OutputDirectory(out, comm, "path")
rows: list[dict] = []
profiles: dict[int, cases.ContactMeasure] = {}
shapes: dict[int, tuple] = {}
HEADER = (f"{'phase':>6} {'step':>4} {'approach':>8} {'slide':>6} "
          f"{'force J_P in [J_low, J_high]':>36} {'stress J_S in [J_low, J_high]':>36} "
          f"{'width':>7} {'newton':>6} {'cuts':>4} {'solve':>6} {'est.':>5}")


def estimate_goals(sol) -> dict:
    """J_h, eta, eta_p, R3 and the interval of each goal at the state ``sol`` (collective)."""
    row = {}
    for name, goal in GOALS.items():
        with ds.estimate(sol, goal) as est:
            low, high = est.interval
            row.update({name: est.J_h, f"{name}_eta": est.eta, f"{name}_eta_p": est.eta_p,
                        f"{name}_R3": est.nonlinear_remainder, f"{name}_low": low,
                        f"{name}_high": high})
    return row


def interval_text(row: dict, name: str) -> str:
    return f"{row[name]:.7f} in [{row[name + '_low']:.7f}, {row[name + '_high']:.7f}]"


def deformed_cells(sol) -> tuple | None:
    """The fine cells' deformed vertices and mean Cauchy pressure, gathered on rank 0."""
    V = sol.u.function_space
    n = V.mesh.topology.index_map(2).size_local
    dofs = V.dofmap.list[:n]
    x = V.tabulate_dof_coordinates()[dofs][:, :, :2] + sol.u.x.array.reshape(-1, 2)[dofs]
    W = fem.functionspace(V.mesh, ("DG", 0))
    p = fem.Function(W)
    p.interpolate(fem.Expression(-ufl.tr(sol.disc.m.cauchy(sol.u)) / 2,
                                 compat.interpolation_points(W.element)))
    pieces = comm.gather((x, p.x.array[W.dofmap.list[:n, 0]]), root=0)
    return None if pieces is None else tuple(np.concatenate(v) for v in zip(*pieces, strict=True))


def on_step(phase: str, steps: int):
    def callback(record, sol, estimate) -> None:
        c = cases.measure_contact(sol)
        k = len(rows)
        t = record.factor
        approach = args.approach if phase == "slide" else t * args.approach
        shift = t * args.slide if phase == "slide" else 0.0
        tic = time.perf_counter()
        goals = estimate_goals(sol)
        row = {"step": k, "phase": phase, "t": t, "approach": approach, "slide": shift,
               **goals, "width": c.width, "num_active": sol.num_active,
               "num_cells": sol.disc.num_cells, "newton_iterations": record.newton_iterations,
               "cuts": len(record.cuts), "time": record.seconds,
               "time_estimate": time.perf_counter() - tic}
        rows.append(row)
        writer.append(row, {"num_processes": comm.size, "args": {
            key: str(value) for key, value in vars(args).items()}})
        writer.write_fields(k, [sol.u], [sol.lam], series=True)
        profiles[k] = c
        if not args.no_plots and (k in (0, steps - 1) or (phase == "slide" and t == 1.0)):
            shapes[k] = deformed_cells(sol)
        print0(f"{phase:>6} {k:4d} {approach:8.4f} {shift:6.3f} {interval_text(row, 'force'):>36} "
               f"{interval_text(row, 'stress'):>36} {c.width:7.4f} "
               f"{record.newton_iterations:6d} {len(record.cuts):4d} {record.seconds:6.2f} "
               f"{row['time_estimate']:5.2f}")

    return callback


print0(HEADER)
tic = time.perf_counter()
factors = [(k + 1) / args.press_steps for k in range(args.press_steps)]
with ds.solve_path(press, None, load_factors=factors,
                   callback=on_step("press", args.press_steps)) as pressed:
    factors = [(k + 1) / args.slide_steps for k in range(args.slide_steps)]
    with ds.solve_path(slide, None, load_factors=factors, initial_guess=pressed.solutions[-1],
                       callback=on_step("slide", args.press_steps)):
        pass
wall = time.perf_counter() - tic
writer.close()
# -

# ## The slide keeps the state
#
# The force, the width and the intervals of the last slide step against those of the pressed
# state: the translated state to the Newton tolerance.

# +
last_press = rows[args.press_steps - 1]
change = abs(rows[-1]["force"] - last_press["force"]) / last_press["force"]
interval_change = max(abs(rows[-1][f"{g}_{end}"] - last_press[f"{g}_{end}"]) / abs(last_press[g])
                      for g in GOALS for end in ("low", "high"))
estimating = sum(r["time_estimate"] for r in rows)
print0(f"\nslid by {args.slide}: the contact force changed by {change:.1e} (relative), "
       f"the width by {abs(rows[-1]['width'] - last_press['width']):.1e}, the intervals' ends "
       f"by {interval_change:.1e} (relative to J_h); {wall:.1f} s, of which "
       f"{estimating:.1f} s estimating")
# -

# ## The intervals against a reference (`--reference L`)
#
# The press again on the macro mesh refined uniformly $L - 2$, $L - 1$ and $L$ times
# (`refine_with_tags`: the polygon of the demo's mesh, whose discretisation error the estimate
# measures), $J_h$ of both goals at every press step, and per step Richardson's extrapolation
# $J_{ref} = J_3 + (J_3 - J_2) / (q - 1)$ with the observed ratio
# $q = (J_2 - J_1) / (J_3 - J_2)$. The slid states are the pressed state translated, so the
# last press step's reference is theirs as well.

# +
def reference_values(levels: int) -> dict[str, np.ndarray]:
    """J_h of each goal per press step on the demo's macro mesh refined 1..``levels`` times."""
    from dwr_signorini.goal import GoalForms
    from dwr_signorini.refine import refine_with_tags

    factors = [(k + 1) / args.press_steps for k in range(args.press_steps)]
    values = {name: [] for name in GOALS}
    problem = press
    for level in range(1, levels + 1):
        fine, _, _, facets = refine_with_tags(problem, None)
        problem, _ = cases.rubber_cylinder_problems((fine, None, facets), args.approach,
                                                    args.slide, nu=args.nu)
        if level < levels - 2:
            continue
        tic = time.perf_counter()
        with ds.solve_path(problem, None, load_factors=factors) as path:
            for name, goal in GOALS.items():
                values[name].append([GoalForms(goal, sol.u, sol.lam, sol.disc).value()
                                     for sol in path.solutions])
            cells = path.solutions[-1].disc.num_cells
        print0(f"reference level {level}: {cells} cells, {time.perf_counter() - tic:.1f} s")
    return {name: np.array(v) for name, v in values.items()}


reference_rows: list[dict] = []
if args.reference:
    J = reference_values(args.reference)
    print0(f"\n{'step':>4} {'goal':>6} {'J_h':>11} {'J_ref':>11} {'q':>5} "
           f"{'J_ref - J_h':>12} {'eta':>10} {'Ieff':>6} {'J_low':>11} {'J_high':>11} inside")
    for k, row in enumerate(rows):
        j = min(k, args.press_steps - 1)  # a slide step: the last press step's reference
        for name in GOALS:
            j1, j2, j3 = J[name][:, j]
            q = (j2 - j1) / (j3 - j2)
            ref = j3 + (j3 - j2) / (q - 1.0)
            inside = bool(row[f"{name}_low"] <= ref <= row[f"{name}_high"])
            judged = {"step": k, "phase": row["phase"], "goal": name, "J_h": row[name],
                      "J_ref": ref, "ratio": q, "eta": row[f"{name}_eta"],
                      "ieff": (ref - row[name]) / row[f"{name}_eta"],
                      "J_low": row[f"{name}_low"], "J_high": row[f"{name}_high"],
                      "inside": inside}
            reference_rows.append(judged)
            print0(f"{k:4d} {name:>6} {row[name]:11.8f} {ref:11.8f} {q:5.2f} "
                   f"{ref - row[name]:12.4e} {judged['eta']:10.3e} {judged['ieff']:6.2f} "
                   f"{judged['J_low']:11.8f} {judged['J_high']:11.8f} {inside}")
    inside = sum(r["inside"] for r in reference_rows)
    print0(f"the interval contains the reference in {inside} of {len(reference_rows)} cases")
    table = OutputDirectory(out, comm, "reference")
    for judged in reference_rows:
        table.append(judged)
    table.close()
if comm.rank == 0:
    write_json(out / "summary.json", {
        "args": {key: str(value) for key, value in vars(args).items()},
        "num_processes": comm.size, "wall_time": wall, "estimate_time": estimating,
        "slide_force_change": change, "slide_interval_change": interval_change,
        "runs": {"path": rows}, "reference": reference_rows,
    })
# -

# Measured with the defaults (4048 cells) and `--reference 3` (reference meshes of 16k, 65k and
# 259k cells; one process and two give the same numbers to 1e-12): the interval contains the
# reference at every press step for both goals, and so at the slid states (18 of 18). The error
# of $J_h$ is 0.06-0.56 % of $J$ for the force and 0.10-0.17 % for the stress; the intervals are
# 0.23-0.72 % and 0.10-0.17 % of $J_h$ wide, 1.1-4.1 and 0.7-1.2 times the error, with
# $I_{eff} = (J_{ref} - J_h) / \eta$ of 1.14-1.57 and 1.24-1.46 ($\eta$ finds 64-88 % of the
# error, the widening covers the rest). $|R^{(3)}|$ is at most 0.9 % of $\eta$. The
# extrapolation's observed ratio $q$ is 2.1-4.0 for the stress and 2.7-13 for the force, so
# the force's reference at steps 0 and 2 ($q$ = 8.8 and 13) rests mostly on the finest mesh.
# The slid states' intervals are the pressed state's to 8e-11. The run takes 3 minutes on one
# process, 5 on two (on a shared 2-core machine), most of it the finest reference mesh.

# ## Pictures
#
# The deformed meshes (the first and last press steps and the slid state, coloured by the mean
# Cauchy pressure), the Cauchy contact pressure along $\Gamma_C$ per press step against the
# deformed position (relative to the plate), the force against the approach with its interval
# as a band, and both goals' intervals relative to $J_h$ per load step (with the reference, if
# computed).

# +
if not args.no_plots and comm.rank == 0:
    from matplotlib.collections import PolyCollection

    fig = new_figure((4.0 * len(shapes), 3.6))
    vmax = max(float(np.percentile(p, 99)) for _, p in shapes.values())
    for i, (k, (x, p)) in enumerate(sorted(shapes.items())):
        ax = fig.add_subplot(1, len(shapes), i + 1)
        cells = PolyCollection(x, array=p, cmap="viridis", edgecolor="k", linewidth=0.1)
        cells.set_clim(0.0, vmax)
        ax.add_collection(cells)
        ax.axhline(0.0, color="k", lw=1.5)
        ax.set_xlim(x[..., 0].min() - 0.1, x[..., 0].max() + 0.1)
        ax.set_ylim(-0.1, 1.0)
        ax.set_aspect("equal")
        ax.set_title(f"step {k} ({rows[k]['phase']}): P = {rows[k]['force']:.3f}",
                     fontsize="small")
    fig.colorbar(cells, ax=fig.axes, shrink=0.8, label=r"$-\operatorname{tr}\sigma / 2$")
    save_figure(fig, out / "deformed_meshes.png")

    fig = new_figure((6.4, 4.2))
    ax = fig.add_subplot()
    for k in range(args.press_steps):
        c = profiles[k]
        ax.step(c.x, c.pressure, where="mid", color=f"C{k % 10}",
                label=f"approach {rows[k]['approach']:.3f}")
    c = profiles[len(rows) - 1]
    ax.step(c.x - args.slide, c.pressure, "k:", where="mid",
            label=f"slid by {args.slide} (shifted back)")
    ax.set_xlim(-1.0, 1.0)
    ax.set_xlabel("deformed position x + u_x (relative to the plate)")
    ax.set_ylabel("Cauchy contact pressure")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    save_figure(fig, out / "contact_pressure.png")

    fig = new_figure((11.0, 4.2))
    ax = fig.add_subplot(1, 2, 1)
    pr = [r for r in rows if r["phase"] == "press"]
    approach = [0.0] + [r["approach"] for r in pr]
    ax.fill_between(approach, [0.0] + [r["force_low"] for r in pr],
                    [0.0] + [r["force_high"] for r in pr], color="C0", alpha=0.3, lw=0,
                    label="interval [J_low, J_high]")
    ax.plot(approach, [0.0] + [r["force"] for r in pr], "o-", ms=3, label="J_h (press)")
    refs = {r["step"]: r["J_ref"] for r in reference_rows if r["goal"] == "force"}
    if refs:
        ax.plot([pr[k]["approach"] for k in range(len(pr))], [refs[k] for k in range(len(pr))],
                "kx", label=f"reference ({args.reference}x refined)")
    ax.set_xlabel("approach of the plate")
    ax.set_ylabel("contact force P (per unit thickness)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    ax = fig.add_subplot(1, 2, 2)
    for i, name in enumerate(GOALS):
        steps = np.arange(len(rows)) + (i - 0.5) * 0.2
        J_h = np.array([r[name] for r in rows])
        low = np.array([r[f"{name}_low"] for r in rows]) / J_h - 1.0
        high = np.array([r[f"{name}_high"] for r in rows]) / J_h - 1.0
        centre = (low + high) / 2
        ax.errorbar(steps, 100 * centre, yerr=100 * np.array([centre - low, high - centre]),
                    fmt="o", ms=3, capsize=3, color=f"C{i}",
                    label=f"{name}: [J_low, J_high], centre J_best")
        refs = {r["step"]: r["J_ref"] for r in reference_rows if r["goal"] == name}
        if refs:
            ax.plot(steps, [100 * (refs[k] / J_h[k] - 1.0) for k in range(len(rows))], "x",
                    color=f"C{i}", label=f"{name}: reference")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.axvline(args.press_steps - 0.5, color="k", lw=0.8, ls=":")
    ax.set_xlabel(f"load step (press 0-{args.press_steps - 1}, then slide)")
    ax.set_ylabel("J / J_h - 1 [%]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    save_figure(fig, out / "force_displacement.png")
if comm.rank == 0:
    written = sorted(q.name for q in out.iterdir() if q.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -
