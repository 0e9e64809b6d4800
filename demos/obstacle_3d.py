# # A 3D body pushed by a curved obstacle (Example 5.3)
#
# This demo follows Section 5.3 of the paper (Figure 8): goal-oriented adaptive refinement in
# three dimensions, compared with uniform refinement, with the estimate against cells and run
# time and the contact-violation term $C(w_h)(\xi_h)$ over the levels.
#
# ## The problem
#
# $\Omega = (0, 0.25) \times (0, 1) \times (0, 1)$, clamped on $\Gamma_D = \{x_1 = 0\}$, with
# the possible contact zone $\Gamma_C = \{x_1 = 0.25,\ 0 \le x_2, x_3 \le 0.5\}$ and traction
# free elsewhere; $E = 10^5$, $\nu = 0.3$, no volume or surface loads. The body is deformed
# only by the obstacle
#
# $$
# \psi(x) = \begin{cases} 0.25 + 0.05\,(65536\, z^8 - 1), & z \le 0.25, \\
#                         0.25, & \text{else,} \end{cases} \qquad
# z = \sqrt{(x_2 - 0.25)^2 + (x_3 - 0.25)^2},
# $$
#
# which reaches $\psi = 0.2$ at the centre of $\Gamma_C$: the gap $g = \psi - 0.25 \le 0$
# pushes the contact face inwards by up to 0.05.
#
# ## Quantity of interest
#
# $$
# J(u, \lambda_n) = 10^{-3} \int_B \sigma(u) : \sigma(u)\, dx + \int_{\Gamma_C} \lambda_n\, ds,
# \qquad B = \{0.625 \le x_2, x_3 \le 0.875\},
# $$
#
# a stress functional away from the contact zone plus the total contact force. The exact value
# is not known (pass `--reference` if you have one), so the tables show $J(w_h)$, the two
# estimators $\eta_p$ and $\eta$, and the contact term $C(w_h)(\xi_h)$ that both contain with a
# minus sign; the paper observes that this term is comparatively large on the first meshes and
# then decreases fast.
#
# 3D adaptive refinement of tetrahedra (Plaza) with a 20% fixed fraction multiplies the cells
# by about 4 per level here, so the default is a coarse start ($1 \times 8 \times 8$ boxes of 6
# tetrahedra, 3072 fine cells) and a cap on the number of cells; `--n 2 8 8 --max-cells 400000`
# goes further.
#
# ```
# python3 demos/obstacle_3d.py             # or: mpirun -n 2 python3 demos/obstacle_3d.py
# ```

# +
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import viz
from dwr_signorini.io import write_csv, write_json
from dwr_signorini.linalg import iterative_petsc_options

comm = MPI.COMM_WORLD


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


# -

# ## Options

# +
parser = argparse.ArgumentParser(
    description="Example 5.3 of the paper: adaptive refinement in 3D.",
    formatter_class=argparse.ArgumentDefaultsHelpFormatter,
)
parser.add_argument("--levels", type=int, default=4, help="levels (solves) per run at most")
parser.add_argument("--refinement", choices=("adaptive", "uniform", "both"), default="both")
parser.add_argument("--estimator", choices=("eta", "eta_p"), default="eta",
                    help="estimator that drives marking")
parser.add_argument("--weights", choices=ds.WEIGHTS, default="patch")
parser.add_argument("--fraction", type=float, default=0.2, help="marking fraction")
parser.add_argument("--strategy", choices=("fixed_fraction", "doerfler"),
                    default="fixed_fraction")
parser.add_argument("--max-cells", type=int, default=60_000,
                    help="stop a run before a level with more fine cells")
parser.add_argument("--n", type=int, nargs=3, default=(1, 8, 8), metavar=("N1", "N2", "N3"),
                    help="boxes of the initial macro mesh (N2, N3 multiples of 8)")
parser.add_argument("--reference", type=float, default=None,
                    help="reference value of J, for E_rel and effectivity indices")
parser.add_argument("--plot-backend", choices=("auto", "pyvista", "matplotlib"),
                    default="auto", help="3D pictures: pyvista off screen or matplotlib")
parser.add_argument("--solver", choices=("direct", "schur", "iterative"), default="direct",
                    help="Newton steps: block matrix by MUMPS; Schur complement with K factored; "
                         "Schur complement by CG with GAMG on K (large meshes)")
parser.add_argument("--output", type=Path, default=Path("results/obstacle_3d"))
parser.add_argument("--no-plots", action="store_true", help="write tables and fields only")
args = parser.parse_args([] if "ipykernel" in sys.modules else None)
if args.levels < 1:
    parser.error(f"--levels must be at least 1, got {args.levels}")
refinements = ("adaptive", "uniform") if args.refinement == "both" else (args.refinement,)
solver = {
    "direct": {"method": "block"},
    "schur": {"method": "schur"},
    "iterative": {"method": "schur", "petsc_options": iterative_petsc_options()},
}[args.solver]
out = args.output
print0(f"Example 5.3 (3D obstacle) on {comm.size} process(es); output in {out}/")
# -

# ## Problem


# +
def obstacle_problem() -> ds.SignoriniProblem:
    return ex.obstacle_problem(comm, tuple(args.n))


# The first solve of a session loads the compiled forms (JIT); do it before the timed runs.
ds.solve_adaptive(obstacle_problem(), ex.goal_obstacle(), refinement="uniform", max_levels=1,
                  weights=args.weights, verbose=False, **solver)
# -

# ## Adaptive and uniform runs
#
# One progress line per level; tables and fields (XDMF) go to `out/<refinement>/`.

# +
results: dict[str, ds.AdaptiveResult] = {}
for refinement in refinements:
    print0(f"\n--- {refinement} refinement ---")
    results[refinement] = ds.solve_adaptive(
        obstacle_problem(), ex.goal_obstacle(), refinement=refinement, fraction=args.fraction,
        strategy=args.strategy, max_levels=args.levels, max_cells=args.max_cells,
        estimator=args.estimator, weights=args.weights, exact=args.reference,
        output_dir=out / refinement, **solver,
    )
    if len(results[refinement].levels) < args.levels:
        print0(f"(stopped by --max-cells {args.max_cells})")
# -

# ## Summary: estimates and the contact term over the levels

# +
table = []
for refinement, res in results.items():
    cumulative = viz.cumulative_time(res.rows())
    print0(f"\n{refinement}")
    print0(f"{'M_Omega':>8} {'L':>2} {'M_C':>5} {'|A|':>5} {'J_h':>14} {'eta_p':>11} "
           f"{'eta':>11} {'C(w_h)(xi)':>11} {'|C|/|eta|':>9} {'time [s]':>8}")
    for r, t in zip(res.levels, cumulative, strict=True):
        ratio = abs(r.contact_term) / abs(r.estimate) if r.estimate else float("nan")
        eta = float("nan") if r.eta is None else r.eta
        print0(f"{r.num_cells:8d} {r.level:2d} {r.num_contact_elements:5d} {r.num_active:5d} "
               f"{r.J_h:14.8e} {r.eta_p:11.4e} {eta:11.4e} {r.contact_term:11.4e} "
               f"{ratio:9.2e} {t:8.2f}")
        table.append({
            "refinement": refinement, "M_Omega": r.num_cells, "L": r.level,
            "M_C": r.num_contact_elements, "num_active": r.num_active, "J_h": r.J_h,
            "eta_p": r.eta_p, "eta": r.eta, "contact_term": r.contact_term,
            "E_rel": r.rel_error, "ieff": r.ieff, "ieff_p": r.ieff_p,
            "time_cumulative": float(t),
        })
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", table)
    write_json(out / "summary.json", {
        "example": "5.3", "args": {k: str(v) for k, v in vars(args).items()},
        "num_processes": comm.size, "J_ref": args.reference,
        "runs": {k: res.rows() for k, res in results.items()},
    })
# -

# ## Pictures
#
# Estimate (and error, with `--reference`) against cells and cumulative run time; the parts of
# the estimate over the levels; the adaptive mesh (Figure 8b) and the deformed body with the
# obstacle (Figure 8a), rendered off screen; and the contact force on $\Gamma_C$.

# +
if not args.no_plots:
    runs = {k: res.rows() for k, res in results.items()}
    quantities = ("rel_error", "estimate") if args.reference else ("estimate",)
    for x, name in (("num_cells", "convergence_cells.png"), ("time", "convergence_time.png")):
        viz.plot_convergence(runs, out / name, x=x, quantities=quantities,
                             reference=args.reference, dim=3, comm=comm,
                             title="Example 5.3: estimated error in J")
    viz.plot_convergence(runs, out / "contact_term.png", x="num_cells",
                         quantities=("eta_p", "eta", "contact_term"), dim=3,
                         slopes=(-2.0 / 3.0,), comm=comm,
                         title=r"Example 5.3: estimators and the contact term $C(w_h)(\xi_h)$")
    if args.reference:
        viz.plot_effectivity(runs, out / "effectivity.png", comm=comm)
    best = results.get("adaptive", next(iter(results.values())))
    sol = best.solution
    viz.plot_mesh(sol.disc.mesh, out / "mesh.png", backend=args.plot_backend,
                  title=f"{next(k for k, v in results.items() if v is best)} mesh, "
                        f"{sol.disc.num_cells} cells")
    viz.plot_solution_3d(sol, out / "solution.png", backend=args.plot_backend)
    viz.plot_contact_force(sol, out / "contact_force.png")
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
