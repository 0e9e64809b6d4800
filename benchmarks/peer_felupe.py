"""Finite strain beside felupe: a Neo-Hookean cylinder pressed onto a rigid flat, same mesh.

The press of :mod:`dwr_signorini.cases.rubber_cylinder` (the half-disc of radius 1, plane strain,
E = 1, nu = 0.4, its top bonded to a plate moved by (0, -t approach)) is solved by ours
(``ds.solve_path``: the contact gap in the deformed configuration, a P0 multiplier on the macro
facets, semi-smooth Newton) and by felupe (``ContactRigidPlane``: node-to-plane contact of the
fine boundary vertices, a penalty with the mean-stiffness multiplier of its ``items``, Newton
per load step) on the same fine mesh T_h (our points and triangles exported to a
``felupe.Mesh``; cells turned counter-clockwise where dolfinx stores them clockwise) with the
same law: felupe's ``NeoHookeCompressible(mu, lmbda)`` on a ``FieldPlaneStrain`` is
psi = mu/2 (tr C - 3 - 2 ln J) + lmbda/2 (ln J)^2 with C_33 = 1, ours
psi = mu/2 (I_1 - 2 - 2 ln J) + lambda/2 (ln J)^2: the same energy.

The quantity compared per load step is the contact force P (per unit thickness): ours
int_{Gamma_C} lambda dS, felupe's the plate's reaction (equal to the contact force: no body
force). The discretisation error is measured by both codes on the mesh with half the contact
facet size (``h/2`` columns); felupe's penalty lets the vertices penetrate the flat (column
``pen``, the deepest vertex), which lowers its force by about dP/d(approach) times that depth
(column ``P_fe + dP pen``, the slope from our curve).

felupe is a benchmark dependency only (never the package's): ``make peer-felupe`` installs it
from PyPI into ``benchmarks/.peers`` (not committed), which this script puts on ``sys.path``.

    scripts/fenicsx python3 benchmarks/peer_felupe.py --check    # is felupe there?
    scripts/fenicsx python3 benchmarks/peer_felupe.py            # the table, serial

Writes ``benchmarks/results/peer_felupe.json``, ``.csv`` and ``.png`` (``peer_felupe_m100.*``
with ``--multiplier 100``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import time
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

import dwr_signorini as ds
from dwr_signorini import cases, compat
from dwr_signorini.io import write_csv, write_json
from dwr_signorini.spaces import discretize

HERE = Path(__file__).resolve().parent
#: Where ``make peer-felupe`` installs felupe (``pip install --target``).
PEERS = HERE / ".peers"
RESULTS = HERE / "results"


def import_felupe() -> Any:
    """felupe from :data:`PEERS` (or the environment), or None if it is not installed."""
    if PEERS.is_dir() and str(PEERS) not in sys.path:
        sys.path.insert(0, str(PEERS))
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import felupe
    except ImportError:
        return None
    return felupe


def ours(h_contact: float, factors: list[float], approach: float) -> list[dict]:
    """Our press path: force, Newton steps and time per load step."""
    mesh = cases.rubber_cylinder_mesh(MPI.COMM_SELF, h_contact=h_contact)
    press, _ = cases.rubber_cylinder_problems(mesh, approach=approach)
    rows: list[dict] = []

    def record(step: Any, sol: Any, _: Any) -> None:
        rows.append({"approach": step.factor * approach,
                     "force": cases.measure_contact(sol).force,
                     "newton": step.newton_iterations, "cuts": len(step.cuts),
                     "seconds": step.seconds, "num_cells": sol.disc.num_cells})

    ds.solve_path(press, None, load_factors=factors, callback=record).destroy()
    return rows


def fine_mesh(h_contact: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Our T_h (points, counter-clockwise triangles) and its contact and top vertices."""
    mesh = cases.rubber_cylinder_mesh(MPI.COMM_SELF, h_contact=h_contact)
    disc = discretize(cases.rubber_cylinder_problems(mesh)[0])
    msh = disc.mesh
    points = msh.geometry.x[:, :2].copy()
    cells = np.asarray(compat.geometry_dofmap(msh)).copy()
    a, b, c = (points[cells[:, k]] for k in range(3))
    clockwise = np.cross(b - a, c - a) < 0.0
    cells[clockwise] = cells[clockwise][:, [0, 2, 1]]

    def vertices(tag: int) -> np.ndarray:
        return np.unique(dmesh.entities_to_geometry(msh, 1, disc.facet_tags.find(tag)))

    return points, cells, vertices(cases.CM_CONTACT), vertices(cases.CM_TOP)


def peer(fe: Any, h_contact: float, factors: list[float], approach: float,
         multiplier: float) -> list[dict]:
    """felupe's press path on our T_h: reaction force, penetration, Newton steps, time."""
    points, cells, contact, top = fine_mesh(h_contact)
    D = cases.RC_DEFAULTS
    mu = D["E"] / (2 * (1 + D["nu"]))
    lmbda = D["E"] * D["nu"] / ((1 + D["nu"]) * (1 - 2 * D["nu"]))
    mesh = fe.Mesh(points, cells, "triangle")
    mesh.add_points(np.array([[5.0, 0.0]]))  # the flat's centre point: the plane y = 0
    u = fe.FieldPlaneStrain(fe.RegionTriangle(mesh), dim=2)
    field = fe.FieldContainer([u])
    solid = fe.SolidBody(fe.NeoHookeCompressible(mu=mu, lmbda=lmbda), field)
    flat = fe.ContactRigidPlane(field, points=contact, centerpoint=-1, normal=[0.0, 1.0],
                                multiplier=multiplier, items=[solid])
    on_top = np.isin(np.arange(mesh.npoints), top)
    centre = np.arange(mesh.npoints) == mesh.npoints - 1
    boundaries = {"flat": fe.Boundary(u, mask=centre),
                  "top_x": fe.Boundary(u, mask=on_top, skip=(0, 1)),
                  "top_y": fe.Boundary(u, mask=on_top, skip=(1, 0))}
    ramp = {boundaries["top_y"]: -approach * np.asarray(factors)}
    step = fe.Step([solid, flat], ramp=ramp, boundaries=boundaries)
    rows: list[dict] = []
    clock = [time.perf_counter()]

    def record(_: int, k: int, substep: Any) -> None:
        now = time.perf_counter()
        y = points[contact, 1] + u.values[contact, 1]
        force = fe.tools.force(field, substep.fun, boundaries["top_y"])
        rows.append({"approach": factors[k] * approach, "force": -float(force[1]),
                     "penetration": float(max(0.0, -y.min())),
                     "newton": int(substep.iterations), "seconds": now - clock[0]})
        clock[0] = now

    with contextlib.redirect_stdout(io.StringIO()):
        fe.Job([step], callback=record).evaluate()
    return rows


def table(runs: dict[str, list[dict]]) -> list[dict]:
    """One row per load step: both codes on both meshes, the penetration-corrected force."""
    o, f, o2, f2 = (runs[k] for k in ("ours_h", "felupe_h", "ours_h2", "felupe_h2"))
    approach = np.array([0.0] + [r["approach"] for r in o])
    force = np.array([0.0] + [r["force"] for r in o])
    slope = np.gradient(force, approach)[1:]
    rows = []
    for k in range(len(o)):
        corrected = f[k]["force"] + slope[k] * f[k]["penetration"]
        rows.append({
            "approach": o[k]["approach"], "P_ours": o[k]["force"], "P_felupe": f[k]["force"],
            "rel_diff": f[k]["force"] / o[k]["force"] - 1,
            "P_felupe_corrected": corrected, "rel_diff_corrected": corrected / o[k]["force"] - 1,
            "penetration": f[k]["penetration"],
            "P_ours_h2": o2[k]["force"], "P_felupe_h2": f2[k]["force"],
            "rel_diff_h2": f2[k]["force"] / o2[k]["force"] - 1,
            "ours_h_vs_h2": o[k]["force"] / o2[k]["force"] - 1,
            "felupe_h_vs_h2": f[k]["force"] / f2[k]["force"] - 1,
            "newton_ours": o[k]["newton"], "newton_felupe": f[k]["newton"],
            "seconds_ours": o[k]["seconds"], "seconds_felupe": f[k]["seconds"],
            "seconds_ours_h2": o2[k]["seconds"], "seconds_felupe_h2": f2[k]["seconds"],
        })
    return rows


def print_table(rows: list[dict], cells: tuple[int, int]) -> None:
    print(f"T_h: {cells[0]} cells (h), {cells[1]} cells (h/2)")
    print(f"{'approach':>8} {'P_ours':>9} {'P_felupe':>9} {'diff':>7} {'pen':>8} "
          f"{'P_fe+dP pen':>11} {'diff':>7} {'diff h/2':>8} {'ours h/h2':>9} {'fe h/h2':>8} "
          f"{'it':>5} {'t_ours':>6} {'t_fe':>6} {'t_ours/2':>8} {'t_fe/2':>6}")
    for r in rows:
        print(f"{r['approach']:8.3f} {r['P_ours']:9.5f} {r['P_felupe']:9.5f} "
              f"{r['rel_diff']:+7.2%} {r['penetration']:8.5f} {r['P_felupe_corrected']:11.5f} "
              f"{r['rel_diff_corrected']:+7.2%} {r['rel_diff_h2']:+8.2%} {r['ours_h_vs_h2']:+9.2%} "
              f"{r['felupe_h_vs_h2']:+8.2%} {r['newton_ours']:2d}/{r['newton_felupe']:<2d} "
              f"{r['seconds_ours']:6.2f} {r['seconds_felupe']:6.2f} "
              f"{r['seconds_ours_h2']:8.2f} {r['seconds_felupe_h2']:6.2f}")


def plot(runs: dict[str, list[dict]], path: Path) -> None:
    from dwr_signorini.viz.canvas import new_figure, save_figure

    fig = new_figure((6.4, 4.4))
    ax = fig.add_subplot()
    styles = {"ours_h": "C0o-", "ours_h2": "C0s--", "felupe_h": "C1^-", "felupe_h2": "C1v--"}
    for name, rows in runs.items():
        ax.plot([0.0] + [r["approach"] for r in rows], [0.0] + [r["force"] for r in rows],
                styles[name], markersize=4, label=name.replace("_", ", ").replace("h2", "h/2"))
    ax.set_xlabel("approach of the plate")
    ax.set_ylabel("contact force P (per unit thickness)")
    ax.set_title("Neo-Hookean cylinder on a rigid flat: ours and felupe, same meshes")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    save_figure(fig, path)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="report felupe's version, exit")
    parser.add_argument("--h-contact", type=float, default=0.1)
    parser.add_argument("--steps", type=int, default=4)
    parser.add_argument("--approach", type=float, default=cases.RC_DEFAULTS["approach"])
    parser.add_argument("--multiplier", type=float, default=1.0,
                        help="felupe's penalty scale (times the mean stiffness of the body)")
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args()
    fe = import_felupe()
    if fe is None:
        print("peer_felupe: felupe is not installed (make peer-felupe installs it into "
              f"{PEERS})")
        return 1 if args.check else 0
    print(f"felupe {fe.__version__}")
    if args.check:
        return 0
    if MPI.COMM_WORLD.size > 1:
        raise SystemExit("peer_felupe.py runs serially (felupe is a serial code)")
    factors = [(k + 1) / args.steps for k in range(args.steps)]
    runs = {}
    for name, h in (("h", args.h_contact), ("h2", args.h_contact / 2)):
        runs[f"ours_{name}"] = ours(h, factors, args.approach)
        runs[f"felupe_{name}"] = peer(fe, h, factors, args.approach, args.multiplier)
    rows = table(runs)
    print_table(rows, (runs["ours_h"][0]["num_cells"], runs["ours_h2"][0]["num_cells"]))
    out = args.output
    out.mkdir(parents=True, exist_ok=True)
    stem = "peer_felupe" + ("" if args.multiplier == 1.0 else f"_m{args.multiplier:g}")
    write_csv(out / f"{stem}.csv", rows)
    write_json(out / f"{stem}.json", {"felupe": fe.__version__, "args": {
        k: str(v) for k, v in vars(args).items()}, "rows": rows, "runs": runs})
    plot(runs, out / f"{stem}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
