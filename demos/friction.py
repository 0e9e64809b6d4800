# # Friction: a block pressed onto a cylinder (or sphere) and sheared (Tresca's law)
#
# Contact with friction adds a tangential traction $\lambda_t$ on $\Gamma_C$ and one more
# nonlinear complementarity condition. This demo solves it with the same semi-smooth Newton
# method, estimates the error in the **total friction force** with the dual weighted residual
# method, and refines the mesh where that number needs it.
#
# ## The problem
#
# The block $\Omega = (0, 1) \times (0, 1/2)$ (plane strain, $E = 10$, $\nu = 0.3$) lies with
# its bottom $\Gamma_C$ on a rigid cylinder of radius $R = 1$ touching it at $x = 1/2$; its top
# is displaced by $(\delta_t, -\delta_n)$. The cylinder indents the bottom over a contact zone
# about the middle; the shear makes the centre of that zone stick and its ends, where the
# pressure falls, slip. In mixed form we seek $u$, $\lambda_n$ and $\lambda_t$ with
#
# $$
# a(u, v) + (\lambda_n, v_n)_{\Gamma_C} + (\lambda_t, v_t)_{\Gamma_C} = 0, \quad
# \lambda_n - \max\{0, \lambda_n + c\,(u_n - g)\} = 0, \quad
# \lambda_t - \max\{-s, \min\{s, \lambda_t + c\,u_t\}\} = 0,
# $$
#
# the last being Tresca's law: $|\lambda_t| \le s$, no slip ($u_t = 0$) where $|\lambda_t| < s$,
# and $\lambda_t = s\, u_t / |u_t|$ where the block slips ($t = (-n_2, n_1)$, here $t = (1, 0)$).
# Tresca's threshold $s$ is given: it acts on all of $\Gamma_C$, also where the block has left
# the cylinder (Coulomb's law, $s = \mu \lambda_n$, is the one that follows contact).
#
# With `--dim 3` the block $(0, 1)^2 \times (0, 1/2)$ lies on a sphere of radius $R = 4$ and its
# top is displaced by $(\delta_t, 0, -\delta_n)$. Now $\lambda_t$ is a vector in the tangent
# plane and $P$ is the projection onto the disc $|\lambda_t| \le s$, whose derivative on a
# slipping facet, $(s / |x|)(I - q q^T)$ with $q = x / |x|$, couples the two tangential
# directions: the Newton matrix is no longer symmetric and is factored by LU, and the dual
# problem is its transpose. The goal is the friction force along $x$,
# $\int_{\Gamma_C} \lambda_t \cdot e_x \, ds$.
#
# ## Quantity of interest and its error bar
#
# $J(u, \lambda_n, \lambda_t) = \int_{\Gamma_C} \lambda_t \, ds$, the total friction force, a
# goal with four arguments `goal(u, lam, m, lam_t)`. The dual problem is the transposed last
# Newton system (the stick rows hold $u_t$, the slip rows $\lambda_t = \pm s$), and the estimate
# $\eta$ carries the tangential residual and contact term besides the normal ones. Every level
# prints the interval $[J_{low}, J_{high}]$ for $J$ of {mod}`dwr_signorini.interval`.
#
# Run it with
#
# ```
# python3 demos/friction.py                   # or: mpirun -n 2 python3 demos/friction.py
# python3 demos/friction.py --levels 12 --s 0.1
# mpirun -n 2 python3 demos/friction.py --dim 3
# ```
#
# and find the tables (CSV, JSON), pictures (PNG) and fields (XDMF) in `results/friction/`.

# +
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import viz
from dwr_signorini.io import write_csv, write_json

comm = MPI.COMM_WORLD


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## Options
#
# The defaults finish in about 15 s, serial or on two processes (2D), and in a few minutes
# in 3D.

# +
defaults = ex.FRICTION_DEFAULTS
parser = argparse.ArgumentParser(
    description="A block pressed onto a cylinder and sheared, with Tresca friction: adaptive "
    "refinement for the friction force.",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--dim", type=int, choices=(2, 3), default=2,
                    help="2: a cylinder under the block (plane strain); 3: a sphere")
parser.add_argument("--levels", type=int, default=None,
                    help="levels (solves) per run (default 9 in 2D, 5 in 3D)")
parser.add_argument("--refinement", choices=("adaptive", "uniform", "both"), default="both")
parser.add_argument("--s", type=float, default=None,
                    help="Tresca's slip threshold (default 0.2 in 2D, 0.1 in 3D)")
parser.add_argument("--shear", type=float, default=defaults["shear"],
                    help="tangential displacement of the top")
parser.add_argument("--press", type=float, default=defaults["press"],
                    help="normal displacement of the top (into the cylinder)")
parser.add_argument("--fraction", type=float, default=None,
                    help="marking fraction (default: solve_adaptive's, 0.2 in 2D, Doerfler's "
                         "0.3 in 3D)")
parser.add_argument("--growth", type=float, default=None,
                    help="cell count growth per adaptive level instead of a fraction "
                         "(default: none; solve_adaptive's 3D default caps it at 2)")
parser.add_argument("--weights", choices=ds.WEIGHTS, default="auto",
                    help="weights of the estimator")
parser.add_argument("--max-cells", type=int, default=400_000,
                    help="stop a run before a level with more fine cells")
parser.add_argument("--reference", type=float, default=None,
                    help="reference value of J (default: the finest adaptive level's J_h)")
parser.add_argument("--radius", type=float, default=None,
                    help="radius of the cylinder/sphere (default 1 in 2D, 4 in 3D)")
parser.add_argument("--mesh-level", type=int, default=None,
                    help="adaptive level whose mesh is drawn (default 6 in 2D, the last in 3D)")
parser.add_argument("--output", type=Path, default=Path("results/friction"))
parser.add_argument("--no-plots", action="store_true", help="write tables and fields only")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
args.levels = args.levels if args.levels is not None else (9 if args.dim == 2 else 5)
args.s = args.s if args.s is not None else (
    defaults["s"] if args.dim == 2 else ex.FRICTION_DEFAULTS_3D["s"])
args.radius = args.radius if args.radius is not None else (
    defaults["radius"] if args.dim == 2 else ex.FRICTION_DEFAULTS_3D["radius"])
args.mesh_level = args.mesh_level if args.mesh_level is not None else (
    6 if args.dim == 2 else args.levels - 1)
if args.levels < 2:
    parser.error(f"--levels must be at least 2, got {args.levels}")
refinements = ("adaptive", "uniform") if args.refinement == "both" else (args.refinement,)
out = args.output
print0(f"Tresca friction (s = {args.s:g}) in {args.dim}D on {comm.size} process(es); "
       f"output in {out}/")


def problem() -> ds.SignoriniProblem:
    size = {} if args.dim == 2 else {k: ex.FRICTION_DEFAULTS_3D[k] for k in ("nx", "ny")}
    return ex.friction_problem(comm, s=args.s, shear=args.shear, press=args.press,
                               radius=args.radius, dim=args.dim, **size)


goal = ex.goal_friction_force()
# -

# ## Adaptive and uniform runs
#
# `solve_adaptive` prints one line per level (cells, DoFs, $J_h$, the interval, the estimate,
# the numbers of sticking and slipping contact elements, Newton steps, time). A callback keeps
# the adaptive mesh of one level for a picture.

# +
ds.solve_adaptive(problem(), goal, refinement="uniform", max_levels=1, verbose=False)  # JIT
results: dict[str, ds.AdaptiveResult] = {}
wall: dict[str, float] = {}
snapshots: dict[int, viz.MeshSnapshot | None] = {}
for refinement in refinements:
    print0(f"\n--- {refinement} refinement ---")

    def keep_mesh(record: ds.LevelRecord, sol: ds.Solution, est: ds.Estimate,
                  refinement: str = refinement) -> None:
        if refinement == "adaptive" and record.level == args.mesh_level and not args.no_plots:
            snapshots[record.level] = viz.snapshot_mesh(sol.disc.mesh)

    tic = time.perf_counter()
    results[refinement] = ds.solve_adaptive(
        problem(), goal, refinement=refinement, fraction=args.fraction, growth=args.growth,
        max_levels=args.levels, max_cells=args.max_cells, weights=args.weights,
        output_dir=out / refinement, callback=keep_mesh,
    )
    wall[refinement] = time.perf_counter() - tic
# -

# ## The table
#
# Without an exact value the reference is the finest adaptive level's $J_h$ (from $J_h$ alone,
# not from an estimate), with the change from the level before as its uncertainty; a level is
# judged (its $I_{eff}$ printed) when its error is at least ten times that uncertainty.

# +
finest = results.get("adaptive", next(iter(results.values()))).levels
reference = args.reference if args.reference is not None else finest[-1].J_h
uncertainty = 0.0 if args.reference is not None else abs(finest[-1].J_h - finest[-2].J_h)
rows_out = []
for refinement, res in results.items():
    cumulative = viz.cumulative_time(res.rows())
    print0(f"\n{refinement}: {len(res.levels)} levels in {wall[refinement]:.1f} s; "
           f"reference J = {reference:.8e} +- {uncertainty:.1e}")
    print0(f"{'cells':>8} {'L':>2} {'M_C':>5} {'stick':>5} {'slip':>5} {'J_h':>13} "
           f"{'J in [J_low, J_high]':>29} {'eta':>10} {'Ieff':>7} {'time [s]':>8}")
    for r, t in zip(res.levels, cumulative, strict=True):
        error = reference - r.J_h
        judged = abs(error) >= 10 * uncertainty and r is not finest[-1]
        ieff = error / r.eta if judged and r.eta else None
        print0(f"{r.num_cells:8d} {r.level:2d} {r.num_contact_elements:5d} {r.num_stick:5d} "
               f"{r.num_slip:5d} {r.J_h:13.6e} [{r.J_low:.6e}, {r.J_high:.6e}] "
               f"{r.eta:10.3e} {'-' if ieff is None else format(ieff, '7.3f'):>7} {t:8.2f}")
        rows_out.append({
            "refinement": refinement, "level": r.level, "num_cells": r.num_cells,
            "num_dofs": r.num_dofs, "M_C": r.num_contact_elements, "num_stick": r.num_stick,
            "num_slip": r.num_slip, "J_h": r.J_h, "J_low": r.J_low, "J_high": r.J_high,
            "eta": r.eta, "eta_p": r.eta_p, "estimate": r.estimate, "ieff": ieff,
            "rel_error": abs(error) / abs(reference), "time_cumulative": float(t),
            "weights": r.weights, "time": r.time,
        })
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", rows_out)
    write_json(out / "summary.json", {
        "args": {k: str(v) for k, v in vars(args).items()}, "num_processes": comm.size,
        "reference": reference, "reference_uncertainty": uncertainty,
        "runs": {k: res.rows() for k, res in results.items()},
    })
# -

# ## Pictures
#
# The tractions along $\Gamma_C$ with the stick (green) and slip (orange) zones, the interval
# for $J$ on every level, the error against cells and run time, the effectivity indices, the
# adaptive mesh and the deformed block.

# +
if not args.no_plots:
    runs = {k: [row for row in rows_out if row["refinement"] == k] for k in results}
    best = results.get("adaptive", next(iter(results.values())))
    viz.plot_friction(best.solution, out / "tractions.png", threshold=args.s,
                      title="tractions on the finest adaptive mesh")
    viz.plot_interval(runs, out / "interval.png", reference=reference,
                      title="the friction force J and its interval", comm=comm)
    for x, name in (("num_cells", "convergence_cells.png"), ("time", "convergence_time.png")):
        viz.plot_convergence(runs, out / name, x=x, reference=reference, dim=args.dim,
                             title="error in the friction force", comm=comm)
    viz.plot_effectivity(runs, out / "effectivity.png",
                         title="effectivity of eta (judged levels)", comm=comm)
    if args.dim == 2:
        viz.plot_solution_2d(best.solution, out / "solution.png", scale=5.0,
                             color="von_mises", title="deformed block (x5), von Mises stress")
    else:
        viz.plot_solution_3d(best.solution, out / "solution.png", scale=5.0,
                             title="deformed block (x5)")
    for level, snap in snapshots.items():
        viz.plot_mesh(snap, out / f"mesh_level{level:02d}.png",
                      title=f"adaptive mesh, level {level}: "
                            f"{0 if snap is None else snap.num_cells} cells")
if comm.rank == 0:
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -

# The last levels' solvers are released here (collective).

# +
for res in results.values():
    res.destroy()
# -
