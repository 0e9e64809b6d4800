"""The price of the P2 weights: solve against estimate, phase by phase, on one 2D level.

A block (0, 1) x (0, 0.5), clamped on top, pressed onto a disc of radius 1 lowered by 0.01
(a Hertz contact), nearly incompressible (nu = 0.49, plane strain), so ``weights="auto"`` takes
the hierarchical P2 weights on every level; goal the total contact force. On one uniform mesh of
``--n`` x ``--n / 2`` squares (each cut in two triangles) the script solves, then estimates with
``weights="auto"`` (and with ``--compare``, also with ``"patch"`` and ``"higher_order"``), and
prints the seconds of the solve and of every timed phase of the estimate
(:mod:`dwr_signorini.timing`), the FGMRES iterations of each P2 solve, the ratio of the
estimate's time to the solve's, and, with ``--profile``, the functions of the estimate that take
most time (cProfile). ``--baseline FILE`` also estimates with the two-level solver of another
version of ``dwr_signorini/hierarchical.py`` (in the same run, on the same solution)::

    git show 2b0e0a5:dwr_signorini/hierarchical.py > results/baseline_hierarchical.py
    scripts/fenicsx python3 benchmarks/p2_weights_cost.py --n 190 --compare \
        --baseline results/baseline_hierarchical.py
    scripts/fenicsx mpirun -n 2 python3 benchmarks/p2_weights_cost.py --n 190 \
        --baseline results/baseline_hierarchical.py

``--law coulomb`` puts Coulomb friction (``--mu``) on the contact, whose Newton matrix has
coupled rows on the slipping facets; ``--weights`` names the weights of the last estimate
(default ``"auto"``), e.g. the factored against the hierarchical P2 weights in one run::

    scripts/fenicsx python3 benchmarks/p2_weights_cost.py --n 190 --nu 0.3 --law coulomb \
        --compare --weights hierarchical --repeat 2
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import time
import types
from pathlib import Path
from typing import Any

from mpi4py import MPI

import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import estimator, hierarchical
from dwr_signorini import examples as ex
from dwr_signorini.timing import snapshot


def hertz_problem(comm: MPI.Comm, n: int, nu: float, law: Any = None) -> ds.SignoriniProblem:
    """The indented block on n x n/2 squares (the slightly off-square ratio avoids ties)."""
    msh = mesh.create_rectangle(comm, [(0.0, 0.0), (1.0, 0.5)], [n, n // 2 + 1],
                                mesh.CellType.triangle, ghost_mode=mesh.GhostMode.none)


    return ds.SignoriniProblem(
        msh, ex.tag_block_facets(msh, 0.5), contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,), E=10.0, nu=nu, model="plane_strain",
        gap=lambda x: (x[0] - 0.5) ** 2 / 2.0 - 0.01, friction=law,
    )


def total_force(u: Any, lam: Any, m: Any) -> ufl.Form:
    """J = the total contact force."""
    return lam * m.ds_contact


#: (transpose, FGMRES iterations) of every P2 solve of the hierarchical weights.
ITERATIONS: list[tuple[bool, int]] = []


def baseline_module(path: str) -> types.ModuleType:
    """Another version of ``dwr_signorini/hierarchical.py``, loaded inside the package."""
    source = Path(path).read_text()
    module = types.ModuleType("dwr_signorini._baseline_hierarchical")
    module.__package__ = "dwr_signorini"
    sys.modules[module.__name__] = module
    exec(compile(source, path, "exec"), module.__dict__)
    return module


def count_iterations(module: types.ModuleType = hierarchical) -> None:
    """Record the FGMRES iterations of every P2 solve of ``module`` in :data:`ITERATIONS`."""
    record = ITERATIONS
    solve = module._P2System.solve

    def counted(self: Any, transpose: bool, *args: Any, **kwargs: Any) -> Any:
        try:
            return solve(self, transpose, *args, **kwargs)
        finally:
            record.append((transpose, self.ksp.getIterationNumber()))

    module._P2System.solve = counted


def phases(before: dict[str, float], after: dict[str, float]) -> dict[str, float]:
    """The seconds of every phase between two snapshots (those above 1 ms)."""
    return {k: after[k] - before[k] for k in after if after[k] - before[k] > 1e-3}


def estimate(comm: MPI.Comm, sol: Any, weights: str, profile: bool, t_solve: float) -> None:
    """One estimate, its phases, FGMRES iterations and profile printed on rank 0."""
    ITERATIONS.clear()
    record = ITERATIONS
    prof = cProfile.Profile() if profile else None
    comm.Barrier()
    before, tic = snapshot(), time.perf_counter()
    if prof:
        prof.enable()
    with ds.estimate(sol, total_force, weights=weights) as est:
        pass
    if prof:
        prof.disable()
    seconds = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
    spent = phases(before, snapshot())
    if comm.rank == 0:
        print(f"estimate weights={weights!r} -> {est.weights}: {seconds:.2f} s "
              f"({seconds / t_solve:.2f} x the solve), eta {est.eta:.8e}, "
              f"eta_p {est.eta_p:.8e}")
        print("  phases: " + ", ".join(f"{k} {v:.2f}" for k, v in spent.items()))
        if record:
            print("  FGMRES iterations (transpose, count): " + str(record))
        if prof:
            out = io.StringIO()
            pstats.Stats(prof, stream=out).sort_stats("tottime").print_stats(25)
            print(out.getvalue())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=190,
                        help="squares along x (of T_H; T_h is once finer)")
    parser.add_argument("--nu", type=float, default=0.49)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--compare", action="store_true",
                        help="also estimate with patch and higher_order weights")
    parser.add_argument("--baseline", help="a file with another hierarchical.py to compare")
    parser.add_argument("--law", choices=("frictionless", "coulomb"), default="frictionless")
    parser.add_argument("--mu", type=float, default=0.3, help="Coulomb's friction coefficient")
    parser.add_argument("--weights", default="auto", help="the weights of the last estimate")
    parser.add_argument("--repeat", type=int, default=1,
                        help="rounds of the estimates (patch, higher_order, --weights); the "
                             "last one's timings count")
    args = parser.parse_args()
    law = ds.Coulomb(args.mu) if args.law == "coulomb" else None
    comm = MPI.COMM_WORLD
    count_iterations()
    baseline = None
    if args.baseline:
        baseline = baseline_module(args.baseline)
        count_iterations(baseline)
    disc = ds.discretize(hertz_problem(comm, args.n, args.nu, law))
    comm.Barrier()
    before, tic = snapshot(), time.perf_counter()
    with ds.solve(disc) as sol:
        t_solve = comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)
        spent = phases(before, snapshot())
        if comm.rank == 0:
            print(f"{comm.size} rank(s), {disc.mesh.topology.index_map(2).size_global} cells, "
                  f"{disc.num_dofs} DoFs, nu = {args.nu}, {args.law}")
        if sol.stick is not None:
            counts = (sol.num_stick, sol.num_slip)  # collective
            if comm.rank == 0:
                print(f"stick {counts[0]}, slip {counts[1]}")
            print(f"solve: {t_solve:.2f} s, {sol.newton_iterations} Newton steps; phases: "
                  + ", ".join(f"{k} {v:.2f}" for k, v in spent.items()))
        for _ in range(args.repeat - 1):  # a first round compiles (or loads) the forms
            for weights in ("patch", "higher_order", args.weights):
                estimate(comm, sol, weights, False, t_solve)
        if args.compare:  # first, so that the P2 forms are compiled before the timings below
            for weights in ("patch", "higher_order"):
                estimate(comm, sol, weights, False, t_solve)
        if baseline is not None:
            if comm.rank == 0:
                print(f"baseline: the hierarchical solver of {args.baseline}")
            estimator.hierarchical_solutions = baseline.hierarchical_solutions
            estimate(comm, sol, "auto", False, t_solve)
            estimator.hierarchical_solutions = hierarchical.hierarchical_solutions
            if comm.rank == 0:
                print("this version:")
        estimate(comm, sol, args.weights, args.profile, t_solve)


if __name__ == "__main__":
    main()
