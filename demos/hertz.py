# # Hertz contact of a cylinder and of a ball on a rigid flat, from gmsh meshes
#
# This demo shows the route for your own part: a gmsh script of `meshes/` builds the body with
# named physical groups, `ds.read_mesh` turns the in-memory gmsh model into a dolfinx mesh with
# cell and facet tags, and `boundary_projection` moves the new vertices of every refined macro
# mesh onto the true (curved) contact face, so that refinement converges to the body and not to
# the polygon of the first mesh.
#
# ## The problem
#
# `--dim 2`: the quarter disc of `meshes/hertz_2d.py` (radius $R = 1$, centre $(0, R)$, cut at
# $y = R$), plane strain, the symmetry plane $x = 0$ ($u_x = 0$) and the top pressed down by
# $u_y = -\delta$, onto the rigid half-plane $y \le 0$ (`ds.obstacles.Plane`). `--dim 3`: the
# quarter hemisphere of `meshes/hertz_3d.py` with the
# symmetry conditions $u_x = 0$ on $x = 0$ and $u_y = 0$ on $y = 0$
# (`dirichlet={SYMMETRY_X: (0.0, None, None), SYMMETRY_Y: (None, 0.0, None)}`), the top pressed
# down by $u_z = -\delta$. $E = 1$, $\nu = 0.3$.
#
# Hertz's theory (a half-space, $a \ll R$) gives, with $E^* = E / (1 - \nu^2)$ and the force $P$
# (per unit length in 2D; of the whole body, i.e. 2 and 4 times the symmetric part's):
#
# $$
# \text{2D: } a = \sqrt{\frac{4 P R}{\pi E^*}},\quad p_0 = \frac{2P}{\pi a}; \qquad
# \text{3D: } a = \Big(\frac{3 P R}{4 E^*}\Big)^{1/3},\quad p_0 = \frac{3P}{2\pi a^2}; \qquad
# p(r) = p_0 \sqrt{1 - (r/a)^2}.
# $$
#
# `ds.contact_summary(sol)` reads the numbers off the solution: the force, the computed
# half-width (radius) as the length (area) of the active set, $\lambda_H > 0$, the half-width
# (radius) from the pressure's second moment (column `err a_M`, Hertz's profile with the same
# force and moment; it converges with the pressure's means, not with the active set's edge),
# and the peak pressure $\max \lambda_H$; all are compared with Hertz's values for the
# computed force. $\delta$ is chosen so that $a/R \approx 0.08$ (2D) and $0.1$ (3D).
#
# ## Goals
#
# Two adaptive runs, driven by the estimator $\eta$ of
# $J_1(u, \lambda) = \int_{\Gamma_C} \lambda\,ds$ (the contact force of the model) and of
# $J_2 = |B|^{-1}\int_{B} \lambda\,ds$, the mean pressure on the central patch
# $B = \Gamma_C \cap \{r < a_0 / 4\}$. The error of $J$ is shown as the estimate
# $|\eta| / |J_h|$ (there is no closed form of $P(\delta)$ for a finite body), against DoFs and
# against run time, beside the errors of $a$ and $p_0$ against Hertz.
#
# What to expect: in 2D the half-width settles within 1.5 % of Hertz's and the peak within
# 1.6 % (the half-width moves by up to one macro facet from level to level: a facet only partly
# in contact is inactive). In 3D the radius improves from -7.6 % to -2 % after one adaptive
# level and the mean pressure on the central patch (column `err p_B`, the mean of
# $\lambda_H$ on $B$ against Hertz's mean there) stays within about 1 %, but the peak
# $\max \lambda_H$ overshoots Hertz's $p_0$ by 30-60 % on the locally refined meshes: the
# macro-facet multiplier oscillates from facet to facet on locally refined curved faces while
# its means converge (uniform gmsh meshes give +2-6 %, see `tests/test_hertz.py`). Read the 3D
# pressure through its means (the force, the patch goal), not through its maximum.
# `--refinement-rule longest_edge` bisects only the longest edge of each marked cell.
#
# ```
# python3 demos/hertz.py --dim 2            # or: mpirun -n 2 python3 demos/hertz.py --dim 3
# ```

# +
from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import obstacles as ob
from dwr_signorini import viz
from dwr_signorini.io import write_csv, write_json
from dwr_signorini.viz.canvas import new_figure, save_figure
from dwr_signorini.viz.gather import gather_contact_force

comm = MPI.COMM_WORLD
ROOT = Path(__file__).resolve().parent.parent


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## Options

# +
parser = argparse.ArgumentParser(
    description="Hertz contact (2D cylinder, 3D ball) from the gmsh meshes of meshes/",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--dim", type=int, choices=(2, 3), default=2)
parser.add_argument("--levels", type=int, default=None,
                    help="adaptive levels per goal (default 7 in 2D, 2 in 3D)")
parser.add_argument("--fraction", type=float, default=0.2, help="marking fraction")
parser.add_argument("--refinement-rule", choices=ds.refine.RULES, default="edges",
                    help="which edges of the marked cells are bisected")
parser.add_argument("--h-contact", type=float, default=None,
                    help="mesh size at the contact (default 0.01 in 2D, 0.02 in 3D)")
parser.add_argument("--output", type=Path, default=None, help="default results/hertz_<dim>d")
parser.add_argument("--no-plots", action="store_true")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
dim = args.dim
levels = args.levels if args.levels is not None else (7 if dim == 2 else 2)
if levels < 1:
    parser.error(f"--levels must be at least 1, got {levels}")
h_contact = args.h_contact or (0.01 if dim == 2 else 0.02)
out = args.output or Path(f"results/hertz_{dim}d")
E, NU, R = 1.0, 0.3, 1.0
E_STAR = E / (1 - NU**2)
DELTA = 0.01
SYMMETRY = 2 if dim == 2 else 4  # the model is 1/2 (2D) or 1/4 (3D) of the body
print0(f"Hertz {dim}D on {comm.size} process(es); output in {out}/")
# -

# ## The mesh from `meshes/` and the problem

# +
spec = importlib.util.spec_from_file_location("hertz_mesh", ROOT / "meshes" / f"hertz_{dim}d.py")
script = importlib.util.module_from_spec(spec)
spec.loader.exec_module(script)


def read() -> tuple:
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.add(f"hertz_{dim}d")
            script.build(gmsh.model, radius=R, h=0.2 if dim == 2 else 0.3,
                         h_contact=h_contact, refine_radius=0.1 if dim == 2 else 0.11)
        return ds.read_mesh(gmsh.model, comm)
    finally:
        gmsh.finalize()


msh, cell_tags, facet_tags = read()


def hertz_problem() -> ds.SignoriniProblem:
    if dim == 2:
        dirichlet = {script.TOP: (None, -DELTA), script.SYMMETRY: (0.0, None)}
        flat = ob.Plane((0.0, 0.0), (0.0, -1.0))
    else:
        dirichlet = {script.TOP: (None, None, -DELTA), script.SYMMETRY_X: (0.0, None, None),
                     script.SYMMETRY_Y: (None, 0.0, None)}
        flat = ob.Plane((0.0, 0.0, 0.0), (0.0, 0.0, -1.0))
    return ds.SignoriniProblem(msh, facet_tags, contact=script.CONTACT, dirichlet=dirichlet,
                               E=E, nu=NU, gap=flat, cell_tags=cell_tags,
                               boundary_projection=script.projections(R))


def hertz_patch_mean(a: float, p0: float) -> float:
    """Hertz's mean pressure on the central patch B (r < C_PATCH, defined below)."""
    s = min(C_PATCH / a, 1.0)
    if dim == 2:  # (1/c) int_0^c p0 sqrt(1 - x^2/a^2) dx
        return p0 * (math.asin(s) + s * math.sqrt(1 - s**2)) / (2 * s)
    return p0 * 2 / (3 * s**2) * (1 - (1 - s**2) ** 1.5)  # (1/(pi c^2)) int_B p dA


def hertz(P: float) -> tuple[float, float]:
    """Hertz's (a, p0) for the force P of the whole body."""
    if dim == 2:
        a = math.sqrt(4 * P * R / (math.pi * E_STAR))
        return a, 2 * P / (math.pi * a)
    a = (3 * P * R / (4 * E_STAR)) ** (1 / 3)
    return a, 3 * P / (2 * math.pi * a**2)


# -

# ## Goals
#
# The patch $B$ is $r < c$ with $c = a_0 / 4$ and $a_0 = 0.076$ (2D), $0.10$ (3D), Hertz's
# values at this $\delta$; its exact size on the arc (sphere) is $R \arcsin(c/R)$ (the quarter
# of the cap, $\pi R (R - \sqrt{R^2 - c^2}) / 2$).

# +
C_PATCH = 0.25 * (0.076 if dim == 2 else 0.10)
PATCH = (R * math.asin(C_PATCH / R) if dim == 2
         else 0.5 * math.pi * R * (R - math.sqrt(R**2 - C_PATCH**2)))


def radius_of(x):
    return abs(x[0]) if dim == 2 else ufl.sqrt(x[0] ** 2 + x[1] ** 2)


def goal_force(u, lam, m):
    return lam * m.ds_contact


def goal_patch(u, lam, m):
    inside = ufl.conditional(ufl.lt(m.x[0] ** 2 + (m.x[1] ** 2 if dim == 3 else 0.0),
                                    C_PATCH**2), 1.0, 0.0)
    return inside * lam / PATCH * m.ds_contact


GOALS = {"force": goal_force, "patch": goal_patch}
# -

# ## Measuring the contact as a user would

# +


def measure(sol: ds.Solution) -> dict[str, float]:
    m = sol.disc.m

    def integrate(form):
        return comm.allreduce(fem.assemble_scalar(sol.disc.form(form)), op=MPI.SUM)

    # the force, the contact set, the peak and the radius from the moments, about the axis
    summary = ds.contact_summary(sol, centre=np.zeros(dim))
    P = SYMMETRY * summary.normal_force
    a_h = summary.area if dim == 2 else math.sqrt(SYMMETRY * summary.area / math.pi)
    p_h = summary.peak_pressure
    a, p0 = hertz(P)
    inside = ufl.conditional(ufl.lt(radius_of(m.x), C_PATCH), 1.0, 0.0)
    mean_h = integrate(inside * sol.lam * m.ds_contact) / integrate(inside * m.ds_contact)
    mean = hertz_patch_mean(a, p0)
    profile = p0 * ufl.sqrt(ufl.max_value(1.0 - radius_of(m.x) ** 2 / a**2, 0.0))
    e_l2 = math.sqrt(integrate((sol.lam - profile) ** 2 * m.ds_contact)
                     / integrate(profile**2 * m.ds_contact))
    return {"P": P, "a_h": a_h, "a_hertz": a, "err_a": a_h / a - 1,
            "a_moments": summary.radius, "err_a_moments": summary.radius / a - 1, "p_h": p_h,
            "p0_hertz": p0, "err_p0": p_h / p0 - 1, "patch_mean": mean_h,
            "patch_mean_hertz": mean, "err_patch_mean": mean_h / mean - 1, "err_profile": e_l2}


# -

# ## Adaptive runs, one per goal

# +
# A throwaway solve loads the compiled forms (JIT cache), so that run times compare.
with ds.solve(hertz_problem()):
    pass
results: dict[str, ds.AdaptiveResult] = {}
table: list[dict] = []
for name, goal in GOALS.items():
    print0(f"\n--- goal {name} ---")
    print0(f"{'L':>2} {'cells':>8} {'DoFs':>8} {'J_h':>12} {'|eta|/J':>9} {'a_h':>8} "
           f"{'a Hertz':>8} {'err a':>7} {'err a_M':>7} {'p_h':>9} {'p0 Hertz':>9} {'err p0':>7} "
           f"{'err p_B':>7} {'L2 prof':>7} {'time':>6}")
    tic = time.perf_counter()

    def on_level(record, sol, est, name=name, tic=tic):
        row = {"goal": name, "level": record.level, "num_cells": record.num_cells,
               "num_dofs": record.num_dofs, "J_h": record.J_h, "estimate": record.estimate,
               "time_total": record.time.get("total"), **measure(sol),
               "time_cumulative": time.perf_counter() - tic}
        table.append(row)
        print0(f"{record.level:2d} {record.num_cells:8d} {record.num_dofs:8d} "
               f"{record.J_h:12.5e} {abs(record.estimate / record.J_h):9.2e} "
               f"{row['a_h']:8.5f} {row['a_hertz']:8.5f} {row['err_a']:+7.2%} "
               f"{row['err_a_moments']:+7.2%} "
               f"{row['p_h']:9.3e} {row['p0_hertz']:9.3e} {row['err_p0']:+7.2%} "
               f"{row['err_patch_mean']:+7.2%} {row['err_profile']:7.4f} "
               f"{row['time_cumulative']:6.1f}")

    results[name] = ds.solve_adaptive(
        hertz_problem(), goal, refinement="adaptive", fraction=args.fraction,
        refinement_rule=args.refinement_rule, max_levels=levels,
        output_dir=out / f"{name}_adaptive", callback=on_level, verbose=False,
    )
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "hertz.csv", table)
    write_json(out / "summary.json", {
        "dim": dim, "args": {k: str(v) for k, v in vars(args).items()},
        "num_processes": comm.size, "E": E, "nu": NU, "R": R, "delta": DELTA,
        "patch_radius": C_PATCH, "levels": table,
        "runs": {name: res.rows() for name, res in results.items()},
    })
# -

# ## Pictures
#
# The estimate of each goal and the errors of $a$ and $p_0$ against DoFs and against the
# cumulative run time; the pressure along the contact of the finest level of $J_1$ against
# Hertz's profile.

# +
if not args.no_plots:
    runs = {name: res.rows() for name, res in results.items()}
    viz.plot_convergence(runs, out / "estimate_time.png", x="time", quantities=("estimate",),
                         dim=dim, title=f"Hertz {dim}D: estimate of J", comm=comm)
    if comm.rank == 0:
        for x, label, fname in (("num_dofs", "DoFs", "errors_dofs.png"),
                                ("time_cumulative", "cumulative wall-clock time [s]",
                                 "errors_time.png")):
            fig = new_figure((6.4, 4.8))
            ax = fig.add_subplot()
            for i, name in enumerate(GOALS):
                rows = [r for r in table if r["goal"] == name]
                xs = [r[x] for r in rows]
                ax.loglog(xs, [abs(r["estimate"] / r["J_h"]) for r in rows], "o--",
                          color=f"C{i}", label=rf"{name}: $|\eta|/|J_h|$")
                ax.loglog(xs, [max(abs(r["err_a"]), 1e-5) for r in rows], "s-", color=f"C{i}",
                          label=f"{name}: |a_h/a - 1|")
                ax.loglog(xs, [max(abs(r["err_p0"]), 1e-5) for r in rows], "^:",
                          color=f"C{i}", label=f"{name}: |p_h/p0 - 1|")
                ax.loglog(xs, [max(abs(r["err_patch_mean"]), 1e-5) for r in rows], "d-",
                          color=f"C{i}", label=f"{name}: |p_B/p_B,Hertz - 1| (patch mean)")
                ax.loglog(xs, [r["err_profile"] for r in rows], "v-.", color=f"C{i}",
                          label=f"{name}: L2 distance to Hertz profile")
            ax.set_xlabel(label)
            ax.set_ylabel("relative error / estimate")
            ax.grid(True, which="both", alpha=0.3)
            ax.set_title(f"Hertz {dim}D against Hertz's formulas")
            ax.legend(fontsize="x-small")
            save_figure(fig, out / fname)
    final = results["force"].solution
    gathered = gather_contact_force(final)
    last = [r for r in table if r["goal"] == "force"][-1]
    if comm.rank == 0:
        x, lam, _ = gathered
        mid = x.mean(axis=1)
        r = np.abs(mid[:, 0]) if dim == 2 else np.hypot(mid[:, 0], mid[:, 1])
        a, p0 = last["a_hertz"], last["p0_hertz"]
        fig = new_figure((6.4, 4.0))
        ax = fig.add_subplot()
        order = np.argsort(r)
        ax.plot(r[order] / a, lam[order] / p0, ".", markersize=3,
                label=r"computed $\lambda_H$ (macro facets)")
        s = np.linspace(0.0, 1.0, 200)
        ax.plot(s, np.sqrt(1 - s**2), "k-", label=r"Hertz $p_0\sqrt{1 - (r/a)^2}$")
        ax.set_xlim(0.0, 1.5)
        ax.set_xlabel("r / a" if dim == 3 else "x / a")
        ax.set_ylabel(r"$p / p_0$")
        ax.set_title(f"Hertz {dim}D, level {last['level']}: pressure along the contact")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        save_figure(fig, out / "pressure_profile.png")
if comm.rank == 0:
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -

# The last levels' solvers are released with `destroy()`, collectively.

# +
for res in results.values():
    res.destroy()
# -
