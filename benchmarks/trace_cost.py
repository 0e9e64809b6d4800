"""The cost of the master trace against the number of slave facets (3D, two stacked boxes).

Two boxes [0, 1]^2 x [0, 1] (lower, n x n x 2 cells of 6 tetrahedra) and [0, 1]^2 x [1, 1.5]
(upper, (n + 1) x (n + 1) x 2), one mesh whose bodies share no vertex, so that the contact
facets at z = 1 do not match: the upper box's bottom is the slave side (8 (n+1)^2 fine slave
facets on T_h), the lower box's top the master side. For each n, on the discretisation of the
pair (one uniform refinement):

* ``search``: the trace geometry (:class:`~dwr_signorini.pairs.TraceGeometry`: the facets, the
  mortar rule of P1 and the share), with the candidate search
  (:func:`~dwr_signorini.search.candidate_parts`, a KD-tree of the master facets' centres and
  the batched clipping of :mod:`~dwr_signorini.clipping`), and ``full``: the same with every
  slave facet against the master facets in its shadow, one facet at a time
  (:func:`~dwr_signorini.mortar.mortar_rule`, the per-facet rule);
* ``P1``, ``P2``: the projections of the P1 and P2 spaces on the geometry (the P2 rule, placed
  on the geometry's pieces, included);
* P2 only up to ``--p2-up-to`` slave facets (its memory, below);
* the peak resident memory of the process after each size (``ru_maxrss``, it only grows).

The rules of the two searches are compared (covered measure per slave facet, to 1e-12).
The least of ``--repeat`` runs is shown. Tables go to ``benchmarks/results/trace_cost.csv``::

    scripts/fenicsx python3 benchmarks/trace_cost.py                 # n = 11, 23, 47 (~4 min)
    scripts/fenicsx python3 benchmarks/trace_cost.py --sizes 11 23   # smaller
    scripts/fenicsx mpirun -n 2 python3 benchmarks/trace_cost.py --sizes 11 23
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

from mpi4py import MPI

import numpy as np

import dwr_signorini as ds
from dwr_signorini import pair_facets, pairs
from dwr_signorini.io import write_csv
from dwr_signorini.search import candidate_parts
from dwr_signorini.spaces import discretize
from tests import pair_geometries as G

RESULTS = Path(__file__).resolve().parent / "results"
comm = MPI.COMM_WORLD


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


def show(row: dict[str, object]) -> dict[str, object]:
    """Print one row of the table on rank 0 (as it is measured); return it."""
    print0("  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                     for k, v in row.items()))
    return row


def write_rows(rows: list[dict[str, object]], stem: str) -> None:
    """Write the table to ``benchmarks/results/<stem>_np<ranks>.csv`` (rank 0)."""
    if comm.rank == 0:
        RESULTS.mkdir(exist_ok=True)
        keys = list(dict.fromkeys(k for r in rows for k in r))
        write_csv(RESULTS / f"{stem}_np{comm.size}.csv",
                  [{k: r.get(k, "") for k in keys} for r in rows])


def two_boxes(n: int, layers: int = 2) -> ds.SignoriniProblem:
    """The pair of the module docstring (``layers`` cells across each box's height)."""
    msh, tags = G.tet_boxes(comm, n, layers=layers)
    return ds.SignoriniProblem(msh, tags, contact=ds.ContactPair(slave=G.TET_SLAVE,
                                                                 master=G.TET_MASTER),
                               E=1.0, nu=0.3, model="3d",
                               dirichlet={G.TET_BOTTOM: 0.0, G.TET_TOP: (0.0, 0.0, -0.01)})


def _timed(build, repeat: int) -> tuple[float, object]:
    """The least wall time of ``repeat`` calls of ``build`` (collective) and the last result."""
    best, out = np.inf, None
    for _ in range(repeat):
        if out is not None and hasattr(out, "destroy"):
            out.destroy()
        comm.barrier()
        tic = time.perf_counter()
        out = build()
        best = min(best, comm.allreduce(time.perf_counter() - tic, op=MPI.MAX))
    return best, out


def _no_candidates(slave: np.ndarray, *args: object, **kwargs: object) -> tuple:
    """No facet kept from candidates: every one searched against the master facets in its
    shadow (:func:`~dwr_signorini.mortar.mortar_rule`, the per-facet rule)."""
    return [], np.arange(len(slave), dtype=np.int64)


def measure(n: int, repeat: int, full: bool, p2: bool) -> dict[str, float]:
    """One row of the table."""
    disc = discretize(two_boxes(n))
    slaves = comm.allreduce(len(pair_facets.slave_facets(disc)[0].vertices), op=MPI.SUM)
    t_search, geometry = _timed(lambda: pairs.TraceGeometry(disc), repeat)
    t_p1, p1 = _timed(lambda: pairs.MasterTrace(disc, disc.V, geometry), repeat)

    def p2_trace() -> pairs.MasterTrace:
        geometry._rules.pop(2, None)  # its rule placed on the geometry's pieces included
        return pairs.MasterTrace(disc, disc.vector_space(2), geometry)

    t_p2, trace2 = _timed(p2_trace, repeat) if p2 else (float("nan"), None)
    row = {"n": n, "slave_facets": slaves,
           "master_facets": comm.allreduce(len(geometry.exchanges[0].own.cell), op=MPI.SUM),
           "search": t_search, "P1": t_p1, "P2": t_p2}
    if full:
        pairs.candidate_parts = _no_candidates
        try:
            t_full, reference = _timed(lambda: pairs.TraceGeometry(disc), 1)
        finally:
            pairs.candidate_parts = candidate_parts
        row["full"] = t_full
        row["full / search"] = t_full / t_search
        a, b = np.zeros(len(geometry.vertices)), np.zeros(len(geometry.vertices))
        np.add.at(a, geometry.rule(1).facet, geometry.rule(1).weights)
        np.add.at(b, reference.rule(1).facet, reference.rule(1).weights)
        gap = comm.allreduce(float(np.max(np.abs(a - b), initial=0.0)), op=MPI.MAX)
        row["rule difference"] = gap
        reference.destroy()
    row["peak memory [MB]"] = comm.allreduce(
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, op=MPI.MAX)
    for obj in (p1, trace2, geometry):
        if obj is not None:
            obj.destroy()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[11, 23, 47])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--full-up-to", type=int, default=10**9,
                        help="time the full search only up to this many slave facets")
    parser.add_argument("--p2-up-to", type=int, default=10**4,
                        help="build the P2 trace only up to this many slave facets (its COO "
                             "expansion needs about 0.8 MB per slave facet)")
    args = parser.parse_args()
    rows = []
    for n in args.sizes:
        slaves = 8 * (n + 1) ** 2
        rows.append(show(measure(n, args.repeat, slaves <= args.full_up_to,
                                 slaves <= args.p2_up_to)))
    write_rows(rows, "trace_cost")


if __name__ == "__main__":
    main()
