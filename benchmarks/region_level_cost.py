"""Where one level's seconds go: frictionless, per region and Coulomb on the same mesh.

The long block (0, 16) x (0, 0.5) of ``benchmarks/model_adaptivity.py`` (its top displaced by
(0.01, -0.005) on a rigid plane, goal int_{x < 0.5} u_x on the base), on a macro mesh of
32n x 2n rectangles of two triangles (``--n``), or with ``--dim 3`` the box
(0, 8) x (0, 1) x (0, 0.5) (4n x n x n/2 boxes of six tetrahedra, top displaced by
(0.01, 0, -0.005)); mu = 0.5. On the one mesh: frictionless, Coulomb(mu chi_R) with R the
contact facets under x < 2 (as a per-region run's second level) and Coulomb, each solved from
zero and estimated (``weights="auto"``), the first two with the model error against Coulomb (as
a level of ``solve_adaptive(..., model_regions=True)`` does). Per law: the Newton steps, the
seconds of the solve and, inside it, of the assembly, the factorisations and the triangular
solves (``dwr_signorini.timing`` phases), the seconds of the estimate of the discretisation
error (its weights: "patch", or P2 ones where ``"auto"`` judges the contact set unresolved) and
of the model error estimate, the FGMRES iterations of the hierarchical P2 solves (dual +
primal); the second of two runs (the first compiles the forms)::

    scripts/fenicsx python3 benchmarks/region_level_cost.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/region_level_cost.py
    scripts/fenicsx python3 benchmarks/region_level_cost.py --dim 3 --n 4

``--weights higher_order hierarchical`` estimates each solution once per kind of weights (a
row each, the solve shared), e.g. the factored against the hierarchical P2 weights::

    scripts/fenicsx python3 benchmarks/region_level_cost.py --weights higher_order hierarchical
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from mpi4py import MPI

from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import timing
from dwr_signorini.model_regions import RegionMu, flag_function

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.p2_weights_cost import ITERATIONS, count_iterations
from tests.problems import block
from tests.test_model_regions import near_end, owned_midpoints

COMM = MPI.COMM_WORLD
MU = 0.5
#: The timing phases of a solve that the table shows.
SOLVE_PHASES = ("assemble", "factorize", "newton solve")


def scene(n: int, dim: int):
    """A function law -> problem on the long block (2D) or box (3D)."""
    if dim == 2:
        msh, tags = block(COMM, 32 * n, 2 * n, lx=16.0, ly=0.5)
        shift = (0.01, -0.005)
    else:
        msh = mesh.create_box(COMM, [(0.0, 0.0, 0.0), (8.0, 1.0, 0.5)], [4 * n, n, max(n // 2, 1)],
                              mesh.CellType.tetrahedron, ghost_mode=mesh.GhostMode.none)
        tags, shift = ex.tag_block_facets(msh, 0.5), (0.01, 0.0, -0.005)

    def problem(law):
        return ds.SignoriniProblem(msh, tags, contact=ex.CONTACT,
                                   dirichlet={ex.DIRICHLET: shift}, E=1.0, nu=0.3, friction=law)

    return problem


def measure(disc, rich, weights: tuple[str, ...]) -> list[dict]:
    """Solve ``disc`` from zero and estimate it once per ``weights`` (the model error against
    ``rich``, if any): a row per estimate."""
    COMM.Barrier()
    before, tic = timing.snapshot(), time.perf_counter()
    rows = []
    with ds.solve(disc) as sol:
        t_solve = time.perf_counter() - tic
        inside = timing.snapshot()
        for kind in weights:
            COMM.Barrier()
            ITERATIONS.clear()
            tic = time.perf_counter()
            with ds.estimate(sol, near_end, model_error=rich, weights=kind) as est:
                t_estimate = COMM.allreduce(time.perf_counter() - tic, op=MPI.MAX)
                row = {"steps": sol.newton_iterations, "solve": t_solve, "weights": est.weights,
                       "model_error": est.timings.get("model_error", 0.0),
                       "fgmres": "+".join(str(n) for _, n in ITERATIONS) or "-",
                       "dofs": disc.V.dofmap.index_map.size_global * disc.V.dofmap.index_map_bs}
            row["estimate"] = t_estimate - row["model_error"]
            row.update({phase: inside[phase] - before[phase] for phase in SOLVE_PHASES})
            rows.append(row)
    return rows


def level_costs(n: int, dim: int, weights: tuple[str, ...] = ("auto",)) -> dict[str, list]:
    """The three laws on one mesh (module docstring), a row per kind of ``weights``."""
    problem = scene(n, dim)
    rich = problem(ds.Coulomb(MU))
    disc = ds.discretize(problem(None))
    chi = flag_function(disc, (owned_midpoints(disc) < 2.0).astype(float))
    laws = {"frictionless": (disc, rich),
            "per region": (disc.for_problem(problem(ds.Coulomb(RegionMu(MU, chi)))), rich),
            "coulomb": (disc.for_problem(rich), None)}
    return {name: measure(d, r, weights) for name, (d, r) in laws.items()}


def main() -> None:
    """Print the table (rank 0)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=4)
    parser.add_argument("--dim", type=int, choices=(2, 3), default=2)
    parser.add_argument("--weights", nargs="+", default=["auto"],
                        help="the kinds of weights to estimate each solution with")
    args = parser.parse_args()
    weights = tuple(args.weights)
    count_iterations()
    level_costs(args.n, args.dim, weights)
    rows = level_costs(args.n, args.dim, weights)
    if COMM.rank == 0:
        dofs = rows["coulomb"][0]["dofs"]
        print(f"dim {args.dim}, n {args.n}, {dofs} displacement dofs, {COMM.size} rank(s)")
        print(f"{'law':14s} {'newton':>6s} {'solve':>6s} {'assemble':>8s} {'factorize':>9s} "
              f"{'triang':>6s} {'estimate':>8s} {'weights':>12s} {'model err':>9s} {'total':>6s} "
              f"{'fgmres':>7s}")
        for name, r in ((name, r) for name, law in rows.items() for r in law):
            total = r["solve"] + r["estimate"] + r["model_error"]
            print(f"{name:14s} {r['steps']:6d} {r['solve']:6.3f} {r['assemble']:8.3f} "
                  f"{r['factorize']:9.3f} {r['newton solve']:6.3f} {r['estimate']:8.3f} "
                  f"{r['weights']:>12s} {r['model_error']:9.3f} {total:6.3f} {r['fgmres']:>7s}")


if __name__ == "__main__":
    main()
