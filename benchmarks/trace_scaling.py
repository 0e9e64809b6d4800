"""The master trace against the pair's solve: time and memory per rank, from 1e3 slave facets up.

The pair of ``benchmarks/trace_cost.py`` (two stacked boxes of tetrahedra, non-matching contact
faces, ``tests/pair_geometries.tet_boxes``; 8 (n + 1)^2 fine slave facets). For each n, on
the discretisation of the pair (one uniform refinement), per size in one run:

* ``trace``: the trace the solve needs, built before it (:class:`~dwr_signorini.pairs.
  TraceGeometry`: the master facets each rank needs, the P1 mortar rule, frame and share; and the
  P1 projection), the largest wall time over the ranks;
* ``P2``: the P2 projection of the estimator's weights (its rule's search included);
* ``solve``: :func:`dwr_signorini.solve` of the discretisation, its trace already built (the
  Newton steps: assembly, factorisation, solves), and ``trace / solve``,
  ``(trace + P2) / solve``;
* ``held``: the most master facets a rank holds, of ``master facets`` in all;
* on more than one rank, ``trace unbalanced``: the same trace with each rank searching its own
  slave facets (``TraceGeometry(disc, balance=False)``, :mod:`dwr_signorini.trace_balance`),
  the least of as many builds, in the same run: the baseline of the shared search;
* wall and CPU times (the largest over the ranks; on a shared machine the wall time also
  counts the waits for a core), the ratios of both; each trace's times the least of
  ``--repeat`` builds (the first, the discretisation's, and builds anew, each destroyed);
* ``traces MB``: the resident memory the traces hold (largest over the ranks), ``peak MB``: the
  peak resident memory of a rank after the traces and after the solve (``ru_maxrss``; it only
  grows over the sizes, so each size's peak shows where it exceeds the smaller sizes');
* ``trace peak MB``, ``P2 peak MB``: the peak resident memory of a rank while the trace (P2)
  is built above its resident memory before (the peak reset before each build,
  ``/proc/self/clear_refs``), the largest over the ranks: a lower bound, as the build reuses
  memory the process already holds;
* ``trace numpy MB``, ``P2 numpy MB``: the peak of the memory that Python and numpy allocate
  while the same trace is built once more (``tracemalloc``; PETSc's matrix not included), the
  largest over the ranks; and per slave facet, the CPU time ``trace CPU / facet [us]`` and
  ``trace numpy / facet [kB]``.

Beyond ``--solve-up-to`` slave facets only the traces are built (``solve`` empty), beyond
``--p2-up-to`` only the trace the solve needs (``P2`` empty). With
``--layers 1`` the boxes are thin slabs (one cell across each box's height, before the
refinement): many contact facets in a small volume, to measure the traces alone toward 1e6
slave facets. The table goes to ``benchmarks/results/trace_scaling_np<ranks>.csv`` (thin slabs:
``trace_scaling_thin_np<ranks>.csv``)::

    scripts/fenicsx python3 benchmarks/trace_scaling.py --sizes 10 23 47
    scripts/fenicsx mpirun -n 2 python3 benchmarks/trace_scaling.py --sizes 10 23 47
    scripts/fenicsx python3 benchmarks/trace_scaling.py --layers 1 --solve-up-to 0 \
        --p2-up-to 100000 --sizes 47 95 191 287 353
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import tracemalloc

from mpi4py import MPI

import numpy as np
from trace_cost import comm, show, two_boxes, write_rows  # the same pair

import dwr_signorini as ds
from dwr_signorini import pairs
from dwr_signorini.spaces import discretize


def resident_mb() -> float:
    """This process's resident memory now [MB]."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def timed(build) -> tuple[float, float, object]:
    """The largest wall and CPU times over the ranks of the collective ``build()``, its result.

    (The CPU time of the process, its threads included: on a machine shared with other jobs
    the wall time also counts the waits for a core.)
    """
    comm.barrier()
    tic, cpu = time.perf_counter(), time.process_time()
    out = build()
    cpu = time.process_time() - cpu
    return (comm.allreduce(time.perf_counter() - tic, op=MPI.MAX),
            comm.allreduce(cpu, op=MPI.MAX), out)


def peak_mb() -> float:
    """The peak resident memory of a rank so far [MB], the largest over the ranks."""
    return comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                          op=MPI.MAX)


def high_water_mb() -> float:
    """This process's peak resident memory since the last :func:`reset_peak` [MB]."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmHWM")) / 1024.0


def reset_peak() -> float:
    """Reset this process's peak resident memory to the current one; return that [MB]."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    return resident_mb()


def peak_of(build) -> tuple[float, float, float, object]:
    """:func:`timed` ``build()`` and the largest rise of a rank's peak memory over its resident
    memory before [MB]."""
    before = reset_peak()
    t, c, out = timed(build)
    return t, c, comm.allreduce(high_water_mb() - before, op=MPI.MAX), out


def anew(disc, degree: int, balance: bool = True) -> list:
    """A trace of ``degree`` built anew beside the discretisation's (collective): degree 1
    with its geometry (its search shared between the ranks or not: ``balance``), degree 2 on
    the discretisation's geometry (its rule placed anew), as the first ``disc.master_trace`` of
    each builds them. Destroy them in reverse order."""
    if degree == 1:
        geometry = pairs.TraceGeometry(disc, balance=balance)
        return [geometry, pairs.MasterTrace(disc, disc.V, geometry)]
    geometry = disc.master_trace().geometry
    geometry._rules.pop(2, None)
    return [pairs.MasterTrace(disc, disc.vector_space(2), geometry)]


def destroy(built: list) -> None:
    """Destroy what :func:`anew` built."""
    for obj in reversed(built):
        obj.destroy()


def least(disc, degree: int, repeat: int, balance: bool = True) -> tuple[float, float]:
    """The least wall and CPU times of ``repeat`` builds :func:`anew` (inf if none)."""
    best = (np.inf, np.inf)
    for _ in range(repeat):
        t, c, built = timed(lambda: anew(disc, degree, balance))
        destroy(built)
        best = (min(best[0], t), min(best[1], c))
    return best


def numpy_peak(disc, degree: int) -> float:
    """The peak of Python's and numpy's memory while a trace of ``degree`` is built anew [MB].

    (``tracemalloc``, the largest over the ranks; degree 1: its geometry included.)
    """
    tracemalloc.start()
    built = anew(disc, degree)
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    destroy(built)
    return comm.allreduce(peak, op=MPI.MAX)


def measure(n: int, solve: bool, layers: int, p2: bool = True, repeat: int = 1,
            ) -> dict[str, object]:
    """One row of the table (times: the least of ``repeat`` builds)."""
    disc = discretize(two_boxes(n, layers))
    before = resident_mb()
    t_trace, c_trace, m_trace, trace = peak_of(disc.master_trace)
    if p2:
        t_p2, c_p2, m_p2, _ = peak_of(lambda: disc.master_trace(disc.vector_space(2)))
    if repeat > 1:
        t, c = least(disc, 1, repeat - 1)
        t_trace, c_trace = min(t_trace, t), min(c_trace, c)
        if p2:
            t, c = least(disc, 2, repeat - 1)
            t_p2, c_p2 = min(t_p2, t), min(c_p2, c)
    # the baseline in the same run: each rank searches its own slave facets
    t_own, c_own = least(disc, 1, max(repeat, 1), balance=False) if comm.size > 1 else (
        t_trace, c_trace)
    geometry = trace.geometry
    slaves = comm.allreduce(len(geometry.vertices), op=MPI.SUM)
    row = {
        "n": n,
        "slave facets": slaves,
        "master facets": comm.allreduce(len(geometry.exchanges[0].own.cell), op=MPI.SUM),
        "held": comm.allreduce(len(geometry.master.cell), op=MPI.MAX),
        "slave facets held": comm.allreduce(len(geometry.vertices), op=MPI.MAX),
        "trace [s]": t_trace, "trace CPU [s]": c_trace,
        "trace unbalanced [s]": t_own, "trace CPU unbalanced [s]": c_own,
        "P2 [s]": t_p2 if p2 else "", "P2 CPU [s]": c_p2 if p2 else "",
        "traces MB": comm.allreduce(resident_mb() - before, op=MPI.MAX),
        "peak MB, traces": peak_mb(),
        "trace peak MB": m_trace, "P2 peak MB": m_p2 if p2 else "",
    }
    numpy_trace = numpy_peak(disc, 1)
    row.update({
        "trace numpy MB": numpy_trace, "P2 numpy MB": numpy_peak(disc, 2) if p2 else "",
        "trace CPU / facet [us]": 1e6 * c_trace / slaves,
        "trace numpy / facet [kB]": 1024.0 * numpy_trace / slaves,
    })
    if solve:
        t_solve, c_solve, sol = timed(lambda: ds.solve(disc))
        with sol:
            row["Newton steps"] = sol.newton_iterations
        row["solve [s]"], row["solve CPU [s]"] = t_solve, c_solve
        row["trace / solve"] = t_trace / t_solve
        row["trace / solve, CPU"] = c_trace / c_solve
        row["trace / solve, CPU, unbalanced"] = c_own / c_solve
        row["(trace + P2) / solve, CPU"] = (c_trace + c_p2) / c_solve if p2 else ""
        row["peak MB, solve"] = peak_mb()
    disc.destroy()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 23, 47])
    parser.add_argument("--solve-up-to", type=int, default=20_000,
                        help="solve the pair only up to this many slave facets")
    parser.add_argument("--layers", type=int, default=2,
                        help="cells across each box's height (1: thin slabs)")
    parser.add_argument("--p2-up-to", type=int, default=10**9,
                        help="build the P2 trace only up to this many slave facets")
    parser.add_argument("--repeat", type=int, default=3,
                        help="time the least of this many builds of each trace")
    args = parser.parse_args()
    rows = [show(measure(n, 8 * (n + 1) ** 2 <= args.solve_up_to, args.layers,
                         8 * (n + 1) ** 2 <= args.p2_up_to, args.repeat)) for n in args.sizes]
    write_rows(rows, "trace_scaling" if args.layers == 2 else "trace_scaling_thin")


if __name__ == "__main__":
    main()
