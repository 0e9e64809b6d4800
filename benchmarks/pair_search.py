"""The contact search and the covered-part rule of a ContactPair, measured (issue: whole-boundary
tags, masters whose edges fall inside slave facets, hexahedra).

* Two annuli (``tests/pair_geometries.py``) whose contact tags are the facing arcs, then the whole
  outer circles of the same mesh: the force int lambda, max lambda, the force on the slave's far
  half (y > 2) and the smallest projected gap.
* A flat punch (master) on a block (slave), the punch's edges inside block facets: the overlap
  of the punch's corners with the block over the imposed approach, at macro facets of 1/4, 1/8,
  1/16.
* The patch test of two stacked hexahedral blocks whose interface faces are planar but not
  parallelograms: the range of lambda for a uniform 0.1, either side the slave.
* The CPU time of the master trace of the 3D Hertz pair (ball on block, 1564 slave facets).

Serial, about a minute::

    scripts/fenicsx python3 benchmarks/pair_search.py
"""

from __future__ import annotations

import time

from mpi4py import MPI

import numpy as np

import dwr_signorini as ds
from dwr_signorini.spaces import discretize
from tests import pair_geometries as G
from tests.helpers import global_max, integrate
from tests.test_pairs import annuli_problem, corner_penetration, punch_problem
from tests.test_pairs_3d import hertz_problem

COMM = MPI.COMM_WORLD


def report(text: str) -> None:
    if COMM.rank == 0:
        print(text, flush=True)


def annuli() -> None:
    for whole in (False, True):
        with ds.solve(annuli_problem(whole)) as sol:
            m, lam = sol.disc.m, sol.lam
            far = _far_force(sol)
            gap = COMM.allreduce(float(np.min(sol.disc.master_trace().gap.x.array,
                                              initial=np.inf)), op=MPI.MIN)
            report(f"annuli, tags {'whole circles' if whole else 'facing arcs '}: force "
                   f"{integrate(sol, lam * m.ds_contact):.10e}, max lambda "
                   f"{global_max(lam.x.array):.4g}, force on the far half {far:.3g}, "
                   f"min projected gap {gap:.3g}")


def _far_force(sol) -> float:
    import ufl

    m = sol.disc.m
    far = ufl.conditional(ufl.gt(m.x[1], 2.0), 1.0, 0.0)
    return integrate(sol, far * sol.lam * m.ds_contact)


def punch() -> None:
    for n in (4, 8, 16):
        with ds.solve(punch_problem(n)) as sol:
            report(f"punch, macro facets 1/{n}: corner overlap / approach "
                   f"{corner_penetration(sol, n):.4g}")


def hexahedra() -> None:
    p, E = 0.1, {1: 1.0, 2: 3.0}
    msh, cells, facets = G.hex_blocks(COMM)
    for slave, master in ((G.HEX_UPPER_BOTTOM, G.HEX_LOWER_TOP),
                          (G.HEX_LOWER_TOP, G.HEX_UPPER_BOTTOM)):
        problem = ds.SignoriniProblem(
            msh, facets, contact=ds.ContactPair(slave=slave, master=master), cell_tags=cells,
            E=E, nu={1: 0.3, 2: 0.2},
            dirichlet={G.HEX_BOTTOM: (None, None, 0.0), G.HEX_X0: (0.0, None, None),
                       G.HEX_Y0: (None, 0.0, None),
                       G.HEX_TOP: (None, None, -p * (1 / E[1] + 1 / E[2]))},
        )
        with ds.solve(problem) as sol:
            lam = sol.lam.x.array[: sol.system.n_lam]
            lo = COMM.allreduce(float(lam.min()), op=MPI.MIN)
            hi = COMM.allreduce(float(lam.max()), op=MPI.MAX)
            report(f"hexahedra, slave tag {slave}: lambda in [{lo:.6g}, {hi:.6g}] for 0.1 "
                   f"(max relative error {max(abs(lo - p), abs(hi - p)) / p:.2g})")


def trace_time() -> None:
    disc = discretize(hertz_problem(COMM))
    start = time.process_time()
    disc.master_trace()
    report(f"master trace, 3D Hertz ball on block: {time.process_time() - start:.2f} s CPU")


if __name__ == "__main__":
    annuli()
    punch()
    hexahedra()
    trace_time()
