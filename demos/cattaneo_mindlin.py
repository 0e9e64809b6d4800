# # Cattaneo-Mindlin: a cylinder or a sphere on a rigid flat, sheared (Coulomb friction)
#
# The classical test of frictional contact: a cylinder (or a sphere, `--dim 3`) is pressed onto
# a flat by a normal force $P$, then pulled sideways by a tangential force $Q < \mu P$. The
# contact does not slide as a whole: its centre sticks, and slip zones spread in from the ends
# (an annulus from the rim) as $Q$ grows. Cattaneo (1938) and Mindlin (1949) found the zones and
# tractions in closed form. This demo follows the load path with `ds.solve_path` (each step
# starts from the last and measures its slip from it), and compares what it computes with their
# theory.
#
# ## The problem
#
# The half-disc of `meshes/cattaneo_2d.py` (radius $R = 1$, centre $(0, R)$, cut at $y = R$;
# plane strain, $E = 1$, $\nu = 0.49$) lies with its lower arc $\Gamma_C$ on the rigid
# half-plane $y \le 0$ (`ds.obstacles.Plane`), with Coulomb friction $\mu$ (`ds.Coulomb(mu)`).
# The top is displaced by $(0, -\delta)$ in step 0 (the press) and by
# $(k\,s/n, -\delta)$ in the shear steps $k = 1, \dots, n$; $\delta = 0.012$ gives
# $a / R = 0.094$ and the final shear $s = 0.0055$ gives $Q / (\mu P) = 0.69$
# (`dwr_signorini.cases.cattaneo_mindlin_path`). The macro mesh has facets of $h_C$ on the
# arc near the first contact point; `--levels` solves the path on meshes with
# $h_C = 0.02, 0.01, 0.005, \dots$, and `--adaptive` also solves it adaptively
# (`solve_path(..., adaptive=True)`: the mesh refined after each step for the friction force).
#
# In 3D (`--dim 3`) the body is the half $y \ge 0$ of the hemisphere of `meshes/hertz_3d.py`
# (the ball of radius $R = 1$ centred at $(0, 0, R)$, cut at $z = R$), with the symmetry
# condition $u_y = 0$ on $y = 0$: a shear along $x$ keeps the whole sphere's problem symmetric
# about that plane. The top is displaced by $(0, 0, -\delta)$, then by $(k\,s/n, 0, -\delta)$;
# $\delta = 0.01$ gives $a / R = 0.105$ and $s = 0.004$ a final $Q / (\mu P)$ of 0.81
# (`cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`). The meshes have macro facets of
# $h_C = 0.03, 0.02, \dots$ (a factor 1.5 per level) near the first contact point.
#
# ## The theory
#
# For a half-plane ($a \ll R$) and a rigid flat, $E^* = E / (1 - \nu^2)$ (Johnson, *Contact
# Mechanics*, eqs. 4.43-4.45 and 7.7-7.11), with $x$ measured from the first contact point:
#
# $$
# a = \sqrt{\frac{4 P R}{\pi E^*}}, \quad p_0 = \frac{2P}{\pi a}, \quad
# p(x) = p_0 \sqrt{1 - x^2/a^2}, \qquad c = a \sqrt{1 - \frac{Q}{\mu P}},
# $$
#
# $$
# q(x) = \frac{\mu p_0}{a}\Big(\sqrt{a^2 - x^2} - \sqrt{c^2 - x^2}\Big) \;(|x| \le c), \qquad
# q(x) = \mu p(x) \;(c \le |x| \le a).
# $$
#
# For a sphere (Johnson, eqs. 4.22-4.23 and 7.38-7.43; $r$ the distance from the first contact
# point, $P$ and $Q$ the whole sphere's forces, $q$ along $Q$ in Mindlin's approximation):
#
# $$
# a = \Big(\frac{3 P R}{4 E^*}\Big)^{1/3}, \quad p_0 = \frac{3P}{2\pi a^2}, \quad
# p(r) = p_0 \sqrt{1 - r^2/a^2}, \qquad c = a \Big(1 - \frac{Q}{\mu P}\Big)^{1/3},
# $$
#
# $$
# q(r) = \mu p_0 \Big(\sqrt{1 - r^2/a^2} - \frac{c}{a}\sqrt{1 - r^2/c^2}\Big) \;(r \le c),
# \qquad q(r) = \mu p(r) \;(c \le r \le a).
# $$
#
# $P = \int_{\Gamma_C} \lambda_n$ and $Q = \int_{\Gamma_C} \lambda_t$ are taken from the computed
# solution (in 3D $Q$ from $\lambda_t \cdot e_x$, both doubled for the half body). The theory
# needs the normal and tangential problems to decouple, which they do for
# $\nu = 1/2$: Dundurs' $\beta = (1 - 2\nu)/(2(1 - \nu))$ is $0.0196$ at $\nu = 0.49$. Step 0
# measures what is left of the coupling: the press alone should give no friction force and an
# odd, small $\lambda_t$ (column `coupling`: the mean friction on the half $x > 0$ in units of its
# Coulomb limit; in 3D the mean radial friction $\int \lambda_t \cdot e_r / (\mu P)$).
#
# ## Quantity of interest
#
# $J = \int_{\Gamma_C} \lambda_t\, ds = Q$, the friction force
# (`ex.goal_friction_force()`; in 3D $\int_{\Gamma_C} \lambda_t \cdot e_x\, ds$ on the half
# body, $Q / 2$); every step prints $J_h$ and the interval $[J_{low}, J_{high}]$ of the dual
# weighted residual estimate. In 3D the estimate uses the patch weights and leaves out the
# error the earlier steps carry (`history=False`), about five times cheaper;
# `--full-estimate` computes it as in 2D.
#
# ```
# python3 demos/cattaneo_mindlin.py                    # or: mpirun -n 2 python3 demos/...
# python3 demos/cattaneo_mindlin.py --levels 4 --steps 8 --adaptive
# mpirun -n 2 python3 demos/cattaneo_mindlin.py --dim 3
# ```
#
# Tables (CSV, JSON), pictures (PNG) and each path's fields (XDMF) go to
# `results/cattaneo_mindlin/`.

# +
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.cases import cattaneo_mindlin_3d as cm
from dwr_signorini.io import write_csv, write_json
from dwr_signorini.viz.canvas import new_figure, save_figure
from dwr_signorini.viz.gather import snapshot_mesh

comm = MPI.COMM_WORLD


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## Options
#
# The defaults (three meshes, four shear steps) take about 15 s on two processes in 2D; in 3D
# (two meshes of 19,264 and 36,024 cells) about 1.5 min.

# +
parser = argparse.ArgumentParser(
    description="Cattaneo-Mindlin: a cylinder (a sphere in 3D) pressed onto a rigid flat and "
    "sheared, Coulomb friction, against the theory",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--dim", type=int, choices=(2, 3), default=2,
                    help="2: the cylinder (plane strain), 3: the sphere (its half y >= 0)")
parser.add_argument("--levels", type=int, default=None,
                    help="meshes: h_contact, h_contact / 2 (/ 1.5 in 3D), ... (default 3, in "
                    "3D 2)")
parser.add_argument("--h-contact", type=float, default=None,
                    help="macro facet size at the contact on the coarsest mesh (default 0.02, "
                    "in 3D 0.03)")
parser.add_argument("--steps", type=int, default=int(cases.CM_DEFAULTS["steps"]),
                    help="shear steps")
parser.add_argument("--mu", type=float, default=cases.CM_DEFAULTS["mu"],
                    help="Coulomb's friction coefficient")
parser.add_argument("--nu", type=float, default=cases.CM_DEFAULTS["nu"], help="Poisson's ratio")
parser.add_argument("--press", type=float, default=None,
                    help="downward displacement of the top (default 0.012, in 3D 0.01)")
parser.add_argument("--shear", type=float, default=None,
                    help="final sideways displacement of the top (default: 0.0055 mu / 0.3, in "
                    "3D 0.004 mu / 0.3)")
parser.add_argument("--adaptive", action="store_true",
                    help="also solve the path adaptively from the coarsest mesh")
parser.add_argument("--full-estimate", action="store_true",
                    help="3D: the estimate as in 2D (weights 'auto' and the history's error)")
parser.add_argument("--output", type=Path, default=None,
                    help="default results/cattaneo_mindlin (results/cattaneo_mindlin_3d)")
parser.add_argument("--no-plots", action="store_true")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
dim = args.dim
D = cases.CM_DEFAULTS if dim == 2 else cm.CM_DEFAULTS_3D
levels = args.levels if args.levels is not None else (3 if dim == 2 else 2)
h_coarse = args.h_contact if args.h_contact is not None else (0.02 if dim == 2 else 0.03)
if levels < 1 or args.steps < 1:
    parser.error("--levels and --steps must be at least 1")
press = args.press if args.press is not None else D["press"]
shear = args.shear if args.shear is not None else D["shear"] * args.mu / D["mu"]
out = args.output or Path("results/cattaneo_mindlin" + ("_3d" if dim == 3 else ""))
builder = cases.cattaneo_mindlin_path if dim == 2 else cm.cattaneo_mindlin_path_3d
estimate_options = ({} if dim == 2 or args.full_estimate
                    else {"weights": "patch", "history": False})
data = {"mu": args.mu, "nu": args.nu, "E": D["E"], "radius": D["radius"]}
print0(f"Cattaneo-Mindlin in {dim}D on {comm.size} process(es): mu = {args.mu}, nu = {args.nu} "
       f"(Dundurs' beta = {cases.dundurs_beta(args.nu):.4f}), {args.steps} shear steps; "
       f"output in {out}/")
# -

# ## The load paths
#
# One path per mesh (and one adaptive path). The callback measures every step against the
# theory while its solution is alive and keeps the facets' tractions (numpy arrays, gathered on
# rank 0) and, for the adaptive path in 2D, a snapshot of the macro mesh. In 3D the radii
# $a_h$, $c_h$ are those of the discs of the areas in contact and sticking (the half body's
# areas doubled), and `dc/h` counts in mean edges of the contact facets. `cS/a` is the stick
# zone's half-width (radius) from the measure of the sticking facets that
# `ds.contact_summary(sol)` returns (its `stick_area`; the 2D zone's extent 2c, the 3D half
# disc's area pi c^2 / 2), beside `c_h/a` from the outermost sticking facets.

# +
HEADER = (f"{'step':>4} {'cells':>7} {'Q/muP':>6} {'a_h/a':>6} {'c/a':>6} {'c_h/a':>6} "
          f"{'cS/a':>6} {'dc/h':>6} {'L2 q':>6} {'best':>6} {'L2 p':>6} {'coupl':>7} {'stick':>5} "
          f"{'slip':>5} {'J_h':>11} {'[J_low, J_high]':>25} {'it':>3} {'time':>6}")
rows: list[dict] = []
profiles: dict[str, list] = {}
snapshots: list = []


def run(name: str, h_contact: float, adaptive: bool) -> None:
    problems = builder(comm, h_contact=h_contact, mu=args.mu, nu=args.nu, steps=args.steps,
                       press=press, shear=shear)
    profiles[name] = []
    tic = time.perf_counter()
    print0(f"\n--- {name}: h_contact = {h_contact:g}{', adaptive' if adaptive else ''} ---")
    print0(HEADER)

    def on_step(record: ds.StepRecord, sol: ds.Solution, est: ds.Estimate) -> None:
        m = cases.measure_cattaneo_mindlin(sol, **data)
        summary = ds.contact_summary(sol)  # the stick zone's extent from its facets' measure
        c_summary = (summary.stick_area / 2 if dim == 2
                     else math.sqrt(2 * summary.stick_area / math.pi))  # the half body's
        profiles[name].append(cases.gather_contact_profile(sol) if dim == 2
                              else cm.gather_contact_patch(sol))
        if adaptive and dim == 2 and not args.no_plots:
            snapshots.append(snapshot_mesh(sol.disc.macro_mesh))
        row = {"run": name, "h_contact": h_contact, "adaptive": adaptive,
               "step": record.step, "level": record.level, "num_cells": record.num_cells,
               "num_dofs": record.num_dofs, "M_C": record.num_contact_elements,
               "J_h": record.J_h, "J_low": record.J_low, "J_high": record.J_high,
               "eta": record.eta, "newton_iterations": record.newton_iterations,
               **m.as_dict(), "P_summary": summary.normal_force,
               "Q_summary": summary.friction_force[0], "c_summary": c_summary,
               "time_cumulative": time.perf_counter() - tic}
        rows.append(row)
        print0(f"{record.step:4d} {record.num_cells:7d} {m.ratio:6.3f} {m.a_h / m.a:6.3f} "
               f"{m.c / m.a:6.3f} {m.c_h / m.a:6.3f} {c_summary / m.a:6.3f} "
               f"{m.c_error_facets:+6.2f} "
               f"{m.l2_lam_t:6.3f} {m.l2_best:6.3f} {m.l2_lam:6.3f} {m.coupling:+7.4f} "
               f"{m.num_stick:5d} {m.num_slip:5d} {record.J_h:11.4e} "
               f"[{record.J_low:.4e}, {record.J_high:.4e}] {record.newton_iterations:3d} "
               f"{row['time_cumulative']:6.1f}")

    ds.solve_path(problems, ex.goal_friction_force(), adaptive=adaptive,
                  output_dir=out / name, callback=on_step, verbose=False,
                  **estimate_options).destroy()


factor = 2.0 if dim == 2 else 1.5
runs = {f"h{k}": (h_coarse / factor**k, False) for k in range(levels)}
if args.adaptive:
    runs["adaptive"] = (h_coarse, True)
tic = time.perf_counter()
for name, (h_contact, adaptive) in runs.items():
    run(name, h_contact, adaptive)
wall = time.perf_counter() - tic
# -

# ## Convergence on the meshes
#
# `L2 q` is $\|\lambda_t - q\| / \|q\|$ on $\Gamma_C$, `best` the same for the best
# facet-wise constant approximation of $q$ (what the multiplier space allows), `dc/h` the
# error of the stick half-width in macro facets. The slip is measured in the flat's frame
# (the horizontal displacement of the contact points, see the theory page's contact frame):
# `L2 q` falls from 0.46 to 0.34 and 0.27 at the last step on facets of 0.02, 0.01 and 0.005,
# and a part of it does not fall with $h_C$: the half-disc is not a half-plane, on a
# frictionless flat its contact points move outwards (the half-plane's $\beta = 0.02$ would
# move them inwards), so sticking needs an odd traction on the press step (0.17-0.21
# $\mu P$ on each half) and the stick zone sits about $0.13\,a$ off centre under shear. The stick
# zone comes out a little small, by 0.2 to 1.2 facets: the discrete traction undershoots $q$'s
# square-root rise at the stick boundary. On top of it $\lambda_t$ oscillates from facet to
# facet by about $\pm 0.08\,\mu p_0$ in the stick zone: the response of P1 displacements to
# $\nu = 0.49$ ($\lambda / \mu = 49$), seen in $\lambda_n$ as well (`L2 p`), and the reason
# why the press step's $\lambda_t$ is not the small odd profile of the theory.
#
# In 3D ($h_C = 0.03, 0.02$) the contact radius comes out within half a facet of Hertz's
# ($-0.36$, $-0.43$ facets) and the stick radius small by about one facet ($-0.74$ and
# $-1.23$ facets at the last step, measured with the slip along each slave facet's tangent; in
# the flat's frame the finite sphere shows as the half-disc does, $-1.54$ facets at the second
# shear step on $h_C = 0.03$): $\lambda_n$ oscillates from facet to facet by about
# $\pm 0.3\,p_0$ (rms; half that at $\nu = 0.3$), a sticking facet with a low $\lambda_n$
# reaches its Coulomb limit and slips, and $\lambda_t = \mu \lambda_n$ on the slipping facets
# carries the oscillation: `L2 q` is about 0.67 on both meshes, against 0.18 and 0.15 for the
# best facet-wise constants. The mean tractions are right: $Q$ is the theory's integral of
# $q$ by construction, and the picture of the facet values against $r$ scatters about $q(r)$.

# +
last = {name: [r for r in rows if r["run"] == name][-1] for name in runs}
print0(f"\nlast step ({args.steps}): {'run':>9} {'Q/muP':>6} {'c_h - c':>8} {'facets':>6} "
       f"{'L2 q':>6} {'best':>6}")
for name, r in last.items():
    print0(f"{'':>18}{name:>9} {r['ratio']:6.3f} {r['c_h'] - r['c']:+8.4f} "
           f"{r['c_error_facets']:+6.2f} {r['l2_lam_t']:6.3f} {r['l2_best']:6.3f}")
press = [r for r in rows if r["step"] == 0]
print0(f"press step (coupling, beta = {cases.dundurs_beta(args.nu):.4f}): "
       + ", ".join(f"{r['run']}: mean {r['coupling']:+.4f}, rms {r['rms_lam_t']:.3f} of mu p, "
                   f"max {r['max_lam_t']:.3f} mu p0" for r in press))
print0(f"{len(runs)} paths in {wall:.1f} s")
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", rows)
    write_json(out / "summary.json", {
        "args": {k: str(v) for k, v in vars(args).items()}, "num_processes": comm.size,
        "shear": shear, "dundurs_beta": cases.dundurs_beta(args.nu), "wall_time": wall,
        "runs": {name: [r for r in rows if r["run"] == name] for name in runs},
    })
# -

# ## Pictures
#
# The friction force with its interval per step; the stick half-width against the theory's
# $c/a = \sqrt{1 - Q/(\mu P)}$; the tractions along the contact at the last step against
# $q(x)$ and $\mu p(x)$; with `--adaptive`, the adaptive path's meshes near the contact.

# +
if not args.no_plots and comm.rank == 0:
    finest = f"h{levels - 1}"
    ref_run = "adaptive" if "adaptive" in runs else finest
    ref = {r["step"]: r["J_h"] for r in rows if r["run"] == ref_run}
    fig = new_figure((6.4, 6.4))
    top, bottom = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    for i, name in enumerate(runs):
        rs = [r for r in rows if r["run"] == name]
        steps = np.array([r["step"] for r in rs]) + 0.08 * (i - len(runs) / 2)
        J = np.array([r["J_h"] for r in rs])
        low = np.array([r["J_low"] for r in rs])
        high = np.array([r["J_high"] for r in rs])
        top.plot(steps, J, "o-", color=f"C{i}", markersize=4, label=f"{name}: J_h")
        shear_steps = steps[1:]
        scale = np.array([ref[r["step"]] for r in rs[1:]])
        bottom.errorbar(shear_steps, 0.5 * (low + high)[1:] / scale - 1,
                        yerr=0.5 * (high - low)[1:] / scale, fmt="none", capsize=3,
                        color=f"C{i}", label=f"{name}: [J_low, J_high]")
        bottom.plot(shear_steps, J[1:] / scale - 1, "o", color=f"C{i}", markersize=4)
    top.set_ylabel(r"friction force $J = \int_{\Gamma_C} \lambda_t\,ds$" if dim == 2 else
                   r"$J = \int_{\Gamma_C} \lambda_t \cdot e_x\,ds$ (half body)")
    top.set_title("the friction force per step and its interval")
    top.legend(fontsize="x-small")
    bottom.set_xlabel("load step (0: press)")
    bottom.set_ylabel(f"relative to {ref_run}'s $J_h$")
    bottom.legend(fontsize="x-small", title="dots: J_h", title_fontsize="x-small")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    save_figure(fig, out / "friction_force.png")

    fig = new_figure((6.4, 4.4))
    ax = fig.add_subplot()
    r_theory = np.linspace(0.0, 1.0, 200)
    if dim == 2:
        ax.plot(r_theory, np.sqrt(1 - r_theory), "k-", label=r"theory $\sqrt{1 - Q/(\mu P)}$")
    else:
        ax.plot(r_theory, np.cbrt(1 - r_theory), "k-", label=r"theory $(1 - Q/(\mu P))^{1/3}$")
    for i, name in enumerate(runs):
        rs = [r for r in rows if r["run"] == name and r["step"] > 0]
        ax.errorbar([r["ratio"] for r in rs], [r["c_h"] / r["a"] for r in rs],
                    yerr=[r["h_facet"] / r["a"] for r in rs], fmt="o", capsize=3,
                    color=f"C{i}", markersize=4, label=f"{name}: $c_h/a$ (bars: one facet)")
    ax.set_xlabel(r"$Q / (\mu P)$")
    ax.set_ylabel(r"stick half-width $c / a$" if dim == 2 else r"stick radius $c / a$")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.05)
    ax.set_title("Cattaneo-Mindlin: the stick zone")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    save_figure(fig, out / "stick_zone.png")

    r = last[finest]
    p = profiles[finest][-1]
    a, c, p0, mu = r["a"], r["c"], r["p0"], args.mu
    sign = 1.0 if r["Q"] >= 0 else -1.0
    fig = new_figure((7.0, 4.4))
    if dim == 3:  # facet values against the distance r of their centroids from the axis
        ax = fig.add_subplot()
        rr = np.linspace(0.0, 1.2 * a, 801)
        ax.plot(rr / a, cm.cm_traction_3d(rr, a, c, p0, mu) / (mu * p0), "k-",
                label="theory $q(r)$")
        ax.plot(rr / a, cases.hertz_pressure(rr, a, p0) / p0, "k--", lw=0.8,
                label=r"theory $\mu p(r)$ (slip limit)")
        inside = p.r < 1.2 * a
        ax.plot(p.r[inside] / a, p.lam[inside] / p0, ".", color="C7", markersize=4,
                label=r"computed $\mu \lambda_n$ (facets)")
        for mask, color, label in ((p.stick, "C2", "stick"), (p.slip, "C1", "slip")):
            ax.plot(p.r[mask] / a, sign * p.lam_t[mask, 0] / (mu * p0), "o", color=color,
                    markersize=4, label=rf"computed $\lambda_t \cdot e_x$, {label} facets")
        ax.axvline(c / a, color="C2", lw=0.8, ls=":")
        ax.axvline(r["c_h"] / a, color="C2", lw=0.8, ls="--", label="$c_h$ (stick area)")
        ax.set_xlim(0.0, 1.2)
        ax.set_xlabel("r / a")
        ax.set_ylabel(r"traction / $(\mu p_0)$")
        ax.set_title(f"{finest}, step {args.steps}: Q/(mu P) = {r['ratio']:.2f}, "
                     f"L2 error {r['l2_lam_t']:.3f} (best P0 {r['l2_best']:.3f})")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small", loc="upper left")
        save_figure(fig, out / "traction_profile.png")
        p = None
    if p is not None:
        ax = fig.add_subplot()
        x = np.linspace(-1.2 * a, 1.2 * a, 801)
        ax.plot(x / a, cases.cm_traction(x, a, c, p0, mu) / (mu * p0), "k-", label="theory $q(x)$")
        ax.plot(x / a, cases.hertz_pressure(x, a, p0) / p0, "k--", lw=0.8,
                label=r"theory $\mu p(x)$ (slip limit)")
        edges = np.stack([p.x0, p.x1], axis=1).ravel() / a
        ax.plot(edges, np.repeat(sign * p.lam_t / (mu * p0), 2), "-", color="C0",
                label=r"computed $\lambda_t$ (macro facets)")
        ax.plot(edges, np.repeat(p.lam / p0, 2), "-", color="C7", lw=0.8,
                label=r"computed $\mu \lambda_n$")
        for mask, color, label in ((p.stick, "C2", "stick"), (p.slip, "C1", "slip")):
            ax.plot(p.mid[mask] / a, np.full(mask.sum(), -0.05), "|", color=color, markersize=8,
                    label=f"computed {label} facets")
        for s in (-c / a, c / a):
            ax.axvline(s, color="C2", lw=0.8, ls=":")
        ax.set_xlim(-1.2, 1.2)
        ax.set_xlabel("x / a")
        ax.set_ylabel(r"traction / $(\mu p_0)$")
        ax.set_title(f"{finest}, step {args.steps}: Q/(mu P) = {r['ratio']:.2f}, "
                     f"L2 error {r['l2_lam_t']:.3f}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small", loc="upper right")
        save_figure(fig, out / "traction_profile.png")

    if snapshots:
        from matplotlib.collections import PolyCollection

        n = len(snapshots)
        cols = min(n, 3)
        fig = new_figure((4.0 * cols, 2.0 * math.ceil(n / cols)))
        a = last["adaptive"]["a"]
        for k, snap in enumerate(snapshots):
            ax = fig.add_subplot(math.ceil(n / cols), cols, k + 1)
            ax.add_collection(PolyCollection(snap.cells[:, :, :2], facecolor="none",
                                             edgecolor="k", linewidth=0.2))
            prof = profiles["adaptive"][k]
            for mask, color in ((prof.stick, "C2"), (prof.slip, "C1")):
                ax.plot(np.stack([prof.x0[mask], prof.x1[mask]]),
                        np.zeros((2, mask.sum())), "-", color=color, lw=3)
            ax.set_xlim(-2 * a, 2 * a)
            ax.set_ylim(-0.1 * a, 1.5 * a)
            ax.set_aspect("equal")
            ax.set_title(f"step {k}: {snap.num_cells} macro cells", fontsize="small")
            ax.set_xticks([])
            ax.set_yticks([])
        fig.suptitle("adaptive path: macro meshes near the contact (green: stick, orange: slip)")
        save_figure(fig, out / "adaptive_meshes.png")
if comm.rank == 0:
    written = sorted(q.name for q in out.iterdir() if q.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -
