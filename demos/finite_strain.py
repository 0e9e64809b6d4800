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
# $P = \int_{\Gamma_C} \lambda_H\,dS$ (per unit thickness), the contact width (the deformed
# length of the facets in contact), the Newton steps (of all solves of the step), the cut steps
# and the time.
#
# **Not shown here: the error estimate.** The dual weighted residual estimate with its interval
# is not available at finite strain yet (`ds.estimate` and `ds.solve_adaptive` refuse a
# finite-strain problem), so this demo reports $J_h$ without an error bar.
#
# ```
# python3 demos/finite_strain.py               # or: mpirun -n 2 python3 demos/finite_strain.py
# python3 demos/finite_strain.py --h-contact 0.025 --press-steps 10
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
# The defaults (macro facets of 0.05 at the contact, 5 press and 4 slide steps) take a few
# seconds, serial or on two processes.

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
parser.add_argument("--output", type=Path, default=Path("results/finite_strain"))
parser.add_argument("--no-plots", action="store_true")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
if args.press_steps < 1 or args.slide_steps < 1:
    parser.error("--press-steps and --slide-steps must be at least 1")
out = args.output
print0(f"Neo-Hookean cylinder on a rigid flat, {comm.size} process(es): approach "
       f"{args.approach}, slide {args.slide}, nu = {args.nu}; output in {out}/")
# -

# ## The problem and the steps
#
# One mesh for both phases (`cases.rubber_cylinder_mesh`, gmsh on rank 0), two problems that
# differ only in the plate's displacement (`cases.rubber_cylinder_problems`). The callback
# measures each step while its solution is alive (`cases.measure_contact`: the force, the
# deformed contact width, each facet's Cauchy pressure) and keeps the deformed mesh of a few
# steps for the pictures, coloured by the mean Cauchy pressure $-\operatorname{tr}\sigma / 2$
# (`m.cauchy(u)`, the Cauchy stress of the goals).

# +
mesh = cases.rubber_cylinder_mesh(comm, h_contact=args.h_contact)
press, slide = cases.rubber_cylinder_problems(mesh, args.approach, args.slide, nu=args.nu)
writer = OutputDirectory(out, comm, "path")
rows: list[dict] = []
profiles: dict[int, cases.ContactMeasure] = {}
shapes: dict[int, tuple] = {}
HEADER = (f"{'phase':>6} {'step':>4} {'t':>5} {'approach':>8} {'slide':>6} {'force':>12} "
          f"{'width':>8} {'newton':>6} {'cuts':>4} {'time':>6}")


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
        row = {"step": k, "phase": phase, "t": t, "approach": approach, "slide": shift,
               "force": c.force, "width": c.width, "num_active": sol.num_active,
               "num_cells": sol.disc.num_cells, "newton_iterations": record.newton_iterations,
               "cuts": len(record.cuts), "time": record.seconds}
        rows.append(row)
        writer.append(row, {"num_processes": comm.size, "args": {
            key: str(value) for key, value in vars(args).items()}})
        writer.write_fields(k, [sol.u], [sol.lam], series=True)
        profiles[k] = c
        if not args.no_plots and (k in (0, steps - 1) or (phase == "slide" and t == 1.0)):
            shapes[k] = deformed_cells(sol)
        print0(f"{phase:>6} {k:4d} {t:5.2f} {approach:8.4f} {shift:6.3f} {c.force:12.8f} "
               f"{c.width:8.4f} {record.newton_iterations:6d} {len(record.cuts):4d} "
               f"{record.seconds:6.2f}")

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
# The force and the width of the last slide step against those of the pressed state: the
# translated state to the Newton tolerance.

# +
last_press = rows[args.press_steps - 1]
change = abs(rows[-1]["force"] - last_press["force"]) / last_press["force"]
print0(f"\nslid by {args.slide}: the contact force changed by {change:.1e} (relative), "
       f"the width by {abs(rows[-1]['width'] - last_press['width']):.1e}; {wall:.1f} s")
if comm.rank == 0:
    write_json(out / "summary.json", {
        "args": {key: str(value) for key, value in vars(args).items()},
        "num_processes": comm.size, "wall_time": wall, "slide_force_change": change,
        "runs": {"path": rows},
    })
# -

# ## Pictures
#
# The deformed meshes (the first and last press steps and the slid state, coloured by the mean
# Cauchy pressure), the Cauchy contact pressure along $\Gamma_C$ per press step against the
# deformed position (relative to the plate), and the force against the approach.

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

    fig = new_figure((6.4, 4.2))
    ax = fig.add_subplot()
    pr = [r for r in rows if r["phase"] == "press"]
    ax.plot([0.0] + [r["approach"] for r in pr], [0.0] + [r["force"] for r in pr], "o-",
            label="press")
    ax.set_xlabel("approach of the plate")
    ax.set_ylabel("contact force P (per unit thickness)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    save_figure(fig, out / "force_displacement.png")
if comm.rank == 0:
    written = sorted(q.name for q in out.iterdir() if q.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -
