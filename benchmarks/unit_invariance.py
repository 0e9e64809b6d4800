"""The estimate in two unit systems, with the physical and the paper's scale c of the NCP.

Runs the problems of ``tests/test_units.py`` (a block indented by a disc; resolved contact on a
32 x 12 macro mesh, unresolved on 4 x 3, where no multiplier is active) with lengths scaled by
1e-3 and Young's modulus by 1e6, and prints J_h, eta_p, eta and the contact term of both unit
systems, the second divided by the scale of J (1e3)::

    scripts/fenicsx python3 benchmarks/unit_invariance.py
"""

import sys
from pathlib import Path

from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.test_units import CASES, S_E, S_L, _run


def main() -> None:
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        print(f"{'case':>10} {'ncp_scale':>9} {'active':>6} {'quantity':>12} "
              f"{'units 1':>14} {'units 2 / 1e3':>14}")
    for case in CASES:
        for c in ("physical", 1.0):
            a, _, active = _run(comm, *CASES[case], c)
            b, _, _ = _run(comm, *CASES[case], c, S_L, S_E)
            if comm.rank == 0:
                for key in a:
                    print(f"{case:>10} {c!s:>9} {active:6d} {key:>12} {a[key]:14.6e} "
                          f"{b[key] / (S_E * S_L):14.6e}")


if __name__ == "__main__":
    main()
