# # Goal-oriented adaptivity for a bar pressed against an obstacle (Example 5.2)
#
# This demo reproduces Section 5.2 of the paper (Table 3, Figures 5, 6 and 7): adaptive
# refinement driven by the dual weighted residual estimator $\eta$ for Signorini's problem,
# compared with uniform refinement, in error against cells *and* against run time.
#
# ## The problem
#
# A bar $\Omega = (0, 0.05) \times (0, 0.2)$ is clamped at its bottom
# $\Gamma_D = [0, 0.05] \times \{0\}$ and pushed to the right by the volume force
# $f = (0.5, 0)^\top$. Part of its right side, $\Gamma_C = \{0.05\} \times [0.15, 0.2]$, may
# touch a rigid obstacle at the constant distance (gap) $g = 0.005$; the rest of the boundary is
# traction free. Hooke's law under the plane stress assumption, $E = 10$, $\nu = 0.33$.
#
# In mixed form we seek $u \in V$ and the contact force $\lambda_n \ge 0$ on $\Gamma_C$ with
#
# $$
# a(u, v) + (\lambda_n, v_n)_{\Gamma_C} = (f, v) \quad \forall v \in V, \qquad
# \lambda_n - \max\{0, \lambda_n + c\,(u_n - g)\} = 0 \ \text{ on } \Gamma_C,
# $$
#
# the second equation being the NCP form of Signorini's conditions $u_n \le g$,
# $\lambda_n \ge 0$, $\lambda_n (u_n - g) = 0$. The discretisation uses $P_1$ displacements on
# $T_h$ and piecewise constant $\lambda_{n,H}$ on the macro mesh $T_H$ with $H = 2h$; the
# semi-smooth Newton method solves the discrete NCP.
#
# ## Quantity of interest and error estimator
#
# $J(u) = \int_B \nabla u : \nabla u \,dx$ with $B = [0, 0.05]^2$, the clamped end of the bar.
# The error $J(u, \lambda_n) - J(u_h, \lambda_{n,H})$ is estimated by
#
# $$
# \eta = \tfrac12 \rho(w_h)(i_{2h}^{(2)} z_h - z_h)
#      + \tfrac12 \rho^*(w_h, z_h)(i_{2h}^{(2)} w_h - w_h) - C(w_h)(\xi_h),
# $$
#
# with the dual solution $z_h = (y_h, \xi_h)$ of the transposed last Newton system, patch-wise
# quadratic reconstructions $i_{2h}^{(2)}$, and the contact-violation term $C$. Its cell-wise
# contributions are summed over the patches (macro cells), the largest 20% are marked (fixed
# fraction), and the macro mesh is refined.
#
# The paper obtained a reference value $J_{ref} = 5.934693870188204 \cdot 10^{-6}$ by
# extrapolating uniformly refined solutions; $E_{rel} = |J_{ref} - J(w_h)| / |J_{ref}|$ and
# $I_{eff} = (J_{ref} - J(w_h)) / \eta$ are measured against it (pass `--reference` to use
# another value). The effectivity index on fine meshes is therefore only as good as $J_{ref}$.
#
# Run it with
#
# ```
# python3 demos/bar_2d.py                 # or: mpirun -n 2 python3 demos/bar_2d.py
# python3 -m dwr_signorini run bar_2d --levels 6 --refinement adaptive
# ```
#
# and find the tables (CSV, JSON), pictures (PNG) and fields (XDMF, for ParaView) in
# `results/bar_2d/`.

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
# The defaults finish in well under a minute, serial or on two processes.

# +
parser = argparse.ArgumentParser(
    description="Example 5.2 of the paper: adaptive vs uniform refinement for a bar in contact.",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--levels", type=int, default=9, help="levels (solves) per run")
parser.add_argument("--refinement", choices=("adaptive", "uniform", "both"), default="both")
parser.add_argument("--estimator", choices=("eta", "eta_p"), default="eta",
                    help="estimator that drives marking")
parser.add_argument("--weights", choices=ds.WEIGHTS, default="patch",
                    help="weights of the estimator: patch-wise reconstruction or P2 solves")
parser.add_argument("--fraction", type=float, default=0.2, help="marking fraction")
parser.add_argument("--strategy", choices=("fixed_fraction", "doerfler"),
                    default="fixed_fraction")
parser.add_argument("--max-cells", type=int, default=150_000,
                    help="stop a run before a level with more fine cells")
parser.add_argument("--reference", type=float, default=ex.BAR_J_REF,
                    help="reference value of J (default: the paper's extrapolated value)")
parser.add_argument("--nx", type=int, default=4, help="macro cells in x of the initial mesh")
parser.add_argument("--ny", type=int, default=16, help="macro cells in y (multiple of 4)")
parser.add_argument("--mesh-level", type=int, default=5,
                    help="adaptive level whose mesh is drawn (the paper's Figure 7: 5)")
parser.add_argument("--output", type=Path, default=Path("results/bar_2d"))
parser.add_argument("--no-plots", action="store_true", help="write tables and fields only")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
if args.levels < 1:
    parser.error(f"--levels must be at least 1, got {args.levels}")
refinements = ("adaptive", "uniform") if args.refinement == "both" else (args.refinement,)
out = args.output
print0(f"Example 5.2 (bar) on {comm.size} process(es); output in {out}/")
# -

# ## The problem on the initial mesh
#
# `ex.bar_problem` builds the problem on the mesh of `ex.bar_2d_mesh`, which tags $\Gamma_D$ (1),
# $\Gamma_N$ (2) and $\Gamma_C$ (3); this mesh is the macro mesh $T_H$, its uniform refinement is
# $T_h$.


def bar_problem() -> ds.SignoriniProblem:
    return ex.bar_problem(comm, args.nx, args.ny)


# ## Adaptive and uniform runs
#
# `solve_adaptive` prints one line per level as it goes and writes `<refinement>.csv/.json`
# and the fields `level_XX.xdmf` (u, indicators, dual y) and `level_XX_contact.xdmf`
# (lambda, xi) into `out/<refinement>/`. A callback gathers the adaptive mesh of the paper's
# Figure 7 when its level is reached (`snapshot_mesh`, collective); it is drawn after the runs.

# +
# The first solve of a session loads the compiled forms (JIT, cached on disk); a throwaway
# level 0 does it now, so that the run times of both runs compare fairly.
ds.solve_adaptive(bar_problem(), ex.goal_bar(), refinement="uniform", max_levels=1,
                  weights=args.weights, verbose=False)
results: dict[str, ds.AdaptiveResult] = {}
wall: dict[str, float] = {}
snapshots: dict[int, viz.MeshSnapshot | None] = {}
for refinement in refinements:
    print0(f"\n--- {refinement} refinement ---")

    def draw_mesh(record: ds.LevelRecord, sol: ds.Solution, est: ds.Estimate,
                  refinement: str = refinement) -> None:
        if refinement == "adaptive" and record.level == args.mesh_level and not args.no_plots:
            snapshots[record.level] = viz.snapshot_mesh(sol.disc.mesh)

    tic = time.perf_counter()
    results[refinement] = ds.solve_adaptive(
        bar_problem(), ex.goal_bar(), refinement=refinement, fraction=args.fraction,
        strategy=args.strategy, max_levels=args.levels, max_cells=args.max_cells,
        estimator=args.estimator, weights=args.weights, exact=args.reference,
        output_dir=out / refinement, callback=draw_mesh,
    )
    wall[refinement] = time.perf_counter() - tic
# -

# ## Table 3 of the paper, and ours
#
# The paper's adaptive run (Table 3; its meshes start from 256 cells, ours from 512, so the
# rows compare by level, not by cell count). Copied from the paper's text (Section 5.2,
# Table 3) as independent data. The last two effectivity indices read 0.09065 and 0.13039 in
# the text, although the paper speaks of "very good effectivity indices up to the last
# iterates": probably 1.09065 and 1.13039 with the leading digit lost; they are kept as printed.

# +
PAPER_TABLE_3 = [  # (M_Omega, L, E_rel, Ieff) of the paper's adaptive run, Table 3
    (256, 0, 1.98594e-2, 1.26467),
    (436, 1, 7.41959e-3, 1.96084),
    (880, 2, 3.88619e-3, 1.39197),
    (1660, 3, 1.68179e-3, 1.14467),
    (3244, 4, 9.29281e-4, 1.28651),
    (6028, 5, 4.28825e-4, 1.07428),
    (11536, 6, 2.38628e-4, 1.01518),
    (21388, 7, 1.12832e-4, 1.08988),
    (39448, 8, 5.77479e-5, 0.09065),
    (72604, 9, 2.60956e-5, 0.13039),
]


def fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


rows_out = []
for refinement, res in results.items():
    cumulative = viz.cumulative_time(res.rows())
    print0(f"\n{refinement}: {len(res.levels)} levels in {wall[refinement]:.1f} s")
    head = (f"{'M_Omega':>8} {'L':>2} {'M_C':>4} {'J_h':>13} {'J in [J_low, J_high]':>29} "
            f"{'E_rel':>11} {'Ieff(eta)':>9} "
            f"{'Ieff(eta_p)':>11} {'time [s]':>8}")
    if refinement == "adaptive":
        head += f" | paper: {'M_Omega':>7} {'E_rel':>11} {'Ieff':>7}"
    print0(head)
    for r, t in zip(res.levels, cumulative, strict=True):
        line = (f"{r.num_cells:8d} {r.level:2d} {r.num_contact_elements:4d} {r.J_h:13.6e} "
                f"[{r.J_low:.6e}, {r.J_high:.6e}] {fmt(r.rel_error, '11.5e')} "
                f"{fmt(r.ieff, '9.5f')} {fmt(r.ieff_p, '11.5f')} "
                f"{t:8.2f}")
        if refinement == "adaptive" and r.level < len(PAPER_TABLE_3):
            m, _, e, i = PAPER_TABLE_3[r.level]
            line += f" | paper: {m:7d} {e:11.5e} {i:7.5f}"
        print0(line)
        rows_out.append({
            "refinement": refinement, "M_Omega": r.num_cells, "L": r.level,
            "M_C": r.num_contact_elements, "J_h": r.J_h, "J_low": r.J_low, "J_high": r.J_high,
            "E_rel": r.rel_error,
            "ieff": r.ieff, "ieff_p": r.ieff_p, "estimate": r.estimate,
            "time_cumulative": float(t),
        })
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table3.csv", rows_out)
    write_json(out / "summary.json", {
        "example": "5.2", "args": {k: str(v) for k, v in vars(args).items()},
        "num_processes": comm.size, "J_ref": args.reference,
        "runs": {k: res.rows() for k, res in results.items()},
        "paper_table_3": [dict(zip(("M_Omega", "L", "E_rel", "Ieff"), row, strict=True))
                          for row in PAPER_TABLE_3],
    })
# -

# ## Pictures
#
# Error and estimate against the number of cells (Figure 6) and against the cumulative
# wall-clock time; effectivity indices; the deformed bar coloured by the von Mises stress with
# the obstacle (Figure 5a) and the contact force $\lambda_{n,H}$ (Figure 5b) on the finest
# adaptive mesh. The gap is $g = 0.005$, 10% of the bar's width, so the displacement is drawn
# at true scale.

# +
if not args.no_plots:
    runs = {k: res.rows() for k, res in results.items()}
    for x, name in (("num_cells", "convergence_cells.png"), ("time", "convergence_time.png")):
        viz.plot_convergence(runs, out / name, x=x, reference=args.reference, dim=2,
                             title="Example 5.2: error in J", comm=comm)
    viz.plot_effectivity(runs, out / "effectivity.png",
                         references={"paper, Table 3": ([r[1] for r in PAPER_TABLE_3],
                                                        [r[3] for r in PAPER_TABLE_3])},
                         title="Example 5.2: effectivity indices", comm=comm)
    best = results.get("adaptive", next(iter(results.values())))
    viz.plot_solution_2d(best.solution, out / "solution.png", scale=1.0, color="von_mises",
                         title="Example 5.2: deformed bar (true scale), von Mises stress")
    viz.plot_contact_force(best.solution, out / "contact_force.png")
    for level, snap in snapshots.items():
        viz.plot_mesh(snap, out / f"mesh_level{level:02d}.png",
                      title=f"adaptive mesh, level {level}: "
                            f"{0 if snap is None else snap.num_cells} cells")
    if not snapshots:
        viz.plot_mesh(best.solution.disc.mesh, out / "mesh_final.png")
if comm.rank == 0:
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    print(f"\nwritten to {out}/: {', '.join(written)}")
# -

# The last levels' solvers (MUMPS factorisations) are released here with `destroy()`, which is
# collective: every process calls it at the same point.

# +
for res in results.values():
    res.destroy()
# -
