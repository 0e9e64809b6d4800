"""The same runs on two dolfinx versions: J_h to 1e-10, eta_p and eta to 1e-8 relative.

Example 5.1 (Tables 1-2: uniform levels 0-2 of the quadrilateral mesh, goals J_a1 and J_a2, the
paper's c = 1 of the NCP) and example 5.2 (4 adaptive levels, the default c). Each suite writes
its values with ``run``; ``compare`` reads two files and prints the largest differences::

    DWR_SIGNORINI_SUITE=trixie scripts/fenicsx python3 benchmarks/compare_versions.py run a.json
    DWR_SIGNORINI_SUITE=sid scripts/fenicsx python3 benchmarks/compare_versions.py run b.json
    python3 benchmarks/compare_versions.py compare a.json b.json

(``make compare-versions`` does all three.) Nothing is stored from an earlier run.
"""

import argparse
import json
import sys

#: Relative tolerances: J_h, and the estimates.
TOL_J, TOL_ETA = 1e-10, 1e-8


def run(path: str) -> None:
    from mpi4py import MPI

    import dolfinx

    import dwr_signorini as ds
    from dwr_signorini import examples as ex

    comm = MPI.COMM_WORLD
    out: dict = {"dolfinx": dolfinx.__version__, "runs": {}}
    for key, goal in (("5.1 J_a1", ex.goal_a(-0.5)), ("5.1 J_a2", ex.goal_a2())):
        res = ds.solve_adaptive(ex.analytic_problem(comm), goal, refinement="uniform",
                                max_levels=3, ncp_scale=1.0, verbose=False)
        out["runs"][key] = [(r.J_h, r.eta_p, r.eta) for r in res.levels]
        res.destroy()
    res = ds.solve_adaptive(ex.bar_problem(comm), ex.goal_bar(), refinement="adaptive",
                            max_levels=4, verbose=False)
    out["runs"]["5.2 adaptive"] = [(r.J_h, r.eta_p, r.eta) for r in res.levels]
    res.destroy()
    if comm.rank == 0:
        with open(path, "w") as fh:
            json.dump(out, fh, indent=1)
        print(f"dolfinx {out['dolfinx']}: wrote {path}")


def compare(path_a: str, path_b: str) -> int:
    with open(path_a) as fh:
        a = json.load(fh)
    with open(path_b) as fh:
        b = json.load(fh)
    print(f"dolfinx {a['dolfinx']} against dolfinx {b['dolfinx']}")
    print(f"{'run':>14} {'levels':>6} {'max rel. J_h':>13} {'max rel. eta_p':>15} "
          f"{'max rel. eta':>13}")
    ok = a["runs"].keys() == b["runs"].keys()
    for key, rows_a in a["runs"].items():
        rows_b = b["runs"].get(key, [])
        if len(rows_a) != len(rows_b):
            print(f"{key:>14}: {len(rows_a)} levels against {len(rows_b)}")
            ok = False
            continue
        worst = [max(abs(x[i] - y[i]) / abs(x[i]) for x, y in zip(rows_a, rows_b, strict=True))
                 for i in range(3)]
        print(f"{key:>14} {len(rows_a):6d} {worst[0]:13.2e} {worst[1]:15.2e} {worst[2]:13.2e}")
        ok &= worst[0] <= TOL_J and max(worst[1:]) <= TOL_ETA
    print("agree" if ok else f"DIFFER (tolerances: J_h {TOL_J:g}, eta_p and eta {TOL_ETA:g})")
    return 0 if ok else 1


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("run").add_argument("output")
    cmp_ = sub.add_parser("compare")
    cmp_.add_argument("a")
    cmp_.add_argument("b")
    args = parser.parse_args()
    if args.command == "run":
        run(args.output)
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
