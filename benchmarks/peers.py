"""Example 5.1 by two peer codes on our fine mesh T_h, beside our solve + estimate.

Each code uses its own discretisation on the same triangles, the fine mesh T_h that our solver
builds from the macro mesh T_H it is given (``analytic_2d_mesh(nx, ny, triangle)`` refined once):

* ours: ``SignoriniProblem`` on T_H, ``ds.solve`` and ``ds.estimate(sol, goal_a(-0.5))``, that is
  everything from the macro mesh on (refinement to T_h, spaces, assembly, semi-smooth Newton, dual
  problem, reconstructions, indicators; eta with patch weights): u_h in vector P1 on T_h,
  lambda_H in P0 on the macro contact facets (H = 2h); the body force integrated with the degree
  of GetFEM's load rule (3, ``--quadrature-degree``), and again with the package's default (8),
  timed beside it;
* GetFEM (``benchmarks/peer_getfem.py``, a child process, serial): u in vector P1 on T_h and a
  continuous P1 multiplier on the macro contact vertices, the integral contact brick
  (non-symmetric Alart-Curnier), ``Model.solve`` (Newton, sequential MUMPS), in its fastest
  configuration that reaches our accuracy (``peer_getfem.FASTEST``; the ``--gf-*`` options select
  the weaker ones, kept for reference);
* SNES VI (``benchmarks/peer_snesvi.py``, in this process, serial or in parallel): dolfinx with
  PETSc's ``vinewtonrsls`` on the displacement-only P1 problem, u_1 <= g(y) as bounds at the
  fine contact vertices, MUMPS (no multiplier, no estimate).

Errors of all three against the exact solution, computed here in the same way (numpy,
``exact_displacement_np`` & co., a 16-point rule on every triangle and an 8-point Gauss rule on
every fine contact facet; in parallel each rank sums over its cells): displacement L2 and H1
seminorm, contact pressure L2 on Gamma_C (the codes with a multiplier), and J_a1 =
J_{a,-0.5} relative to ``exact_J_a(-0.5)``.

Times, in the same run: ours is the wall-clock time of everything from T_H on, after one untimed
warm-up on a small mesh (so that the forms' JIT compilation, cached on disk, is not counted);
each peer's is its solve alone (``Model.solve``, ``SNES.solve``: the Newton iterations with
their assembly and factorisations), with its set-up (mesh import or refinement, spaces, data,
bricks, assembly of K and f for SNES VI) excluded and printed beside it. Where our level's time
went is printed as a third table: the package's timed phases (``dwr_signorini.timing``) of its
fastest run (rank 0's on more ranks), "discretize" being the refinement T_H -> T_h with the
spaces.

    make peer-env                                          # once: installs GetFEM (optional)
    scripts/fenicsx python3 benchmarks/peers.py            # 49k, 196k and 786k fine triangles
    scripts/fenicsx mpirun -n 2 python3 benchmarks/peers.py  # ours and SNES VI on 2 ranks
    scripts/fenicsx python3 benchmarks/peers.py --quick    # 49k only

Where GetFEM is not installed it is skipped with one line (and on more than one rank). Writes
``benchmarks/results/peers[_np2].csv`` and ``.json`` (``--output`` to move them).
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from peer_getfem import FASTEST  # noqa: E402

DEFAULT_OUTPUT = HERE / "results"
#: Fine triangles of the default sizes; a macro mesh of nx x ny = 3k x 2k squares, each split into
#: 2 triangles, refined once uniformly, has 48 k^2 of them (k even: the kinks y = +-1/2 are mesh
#: lines).
DEFAULT_SIZES = (49152, 196608, 786432)
#: Tags of analytic_2d_mesh (examples._mesh): clamped, traction-free, contact.
DIRICHLET, CONTACT = 1, 3
#: Our data's quadrature degree in the comparison: that of GetFEM's rule for its load data
#: (``IM_TRIANGLE(3)``, ``peer_getfem.FASTEST["load_rule"]``). The package's default
#: (``dwr_signorini.quadrature.DATA_QUADRATURE_DEGREE``) is timed beside it.
OURS_DEGREE = 3
SKIP_MESSAGE = (
    "SKIPPED: benchmarks/peers.py: GetFEM (Debian's python3-getfem) is not installed in this "
    "environment; `make peer-env` installs the optional peer packages (env/peer-packages.txt)"
)


# --------------------------------------------------------------------------------------------------
# Sizes
# --------------------------------------------------------------------------------------------------


def parse_size(text: str) -> int:
    """A number of fine triangles: ``786432``, or ``786k`` for the default size nearest to it."""
    text = text.strip().lower()
    if text.endswith("k"):
        approx = float(text[:-1]) * 1000.0
        k = max(2, 2 * round(math.sqrt(approx / 48.0) / 2.0))
        return 48 * k * k
    return int(text)


def macro_size(num_fine: int) -> tuple[int, int]:
    """Macro mesh nx x ny (triangles: 2 per square) whose uniform refinement has num_fine cells."""
    k = math.isqrt(num_fine // 48)
    if 48 * k * k != num_fine or k % 2:
        raise SystemExit(
            f"--sizes: {num_fine} fine triangles is not 48 k^2 with k even "
            "(e.g. 49152, 196608, 786432, or 49k, 196k, 786k)"
        )
    return 3 * k, 2 * k


# --------------------------------------------------------------------------------------------------
# Errors against the exact solution (numpy only, the same for all codes)
# --------------------------------------------------------------------------------------------------


def triangle_rule(n: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Collapsed n x n Gauss rule on the reference triangle (exact to degree 2n - 2 at least)."""
    t, w = np.polynomial.legendre.leggauss(n)
    s, ws = 0.5 * (t + 1.0), 0.5 * w
    xi = np.repeat(s, n)
    eta = np.tile(s, n) * (1.0 - xi)
    weights = np.repeat(ws, n) * np.tile(ws, n) * (1.0 - xi)
    return xi, eta, weights


def omega_np(x: np.ndarray, y: np.ndarray, m: float = -0.5, d: float = 0.5) -> np.ndarray:
    """The weight of J_{a,m} (examples.analytic_2d.omega) in numpy."""
    return 0.5 * (np.tanh(20.0 * (d - np.hypot(x - m, y))) + 1.0)


def domain_errors(
    comm: Any, points: np.ndarray, cells: np.ndarray, U: np.ndarray, chunk: int = 65536
) -> dict[str, float]:
    """||u - u_h||_L2, |u - u_h|_H1 and J_{a,-0.5}(u_h) of a P1 field given at the vertices.

    Each rank sums over the cells it is given; the sums are reduced over ``comm``.
    """
    from mpi4py import MPI

    from dwr_signorini import examples as ex

    xi, eta, wq = triangle_rule(4)
    l2 = h1 = J = 0.0
    for start in range(0, len(cells), chunk):
        c = cells[start : start + chunk]
        v0, v1, v2 = points[c[:, 0]], points[c[:, 1]], points[c[:, 2]]
        G = np.stack((v1 - v0, v2 - v0), axis=2)  # columns: the edges, G[k] = d x / d (xi, eta)
        det = G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] * G[:, 1, 0]
        Ginv = np.stack(
            (
                np.stack((G[:, 1, 1], -G[:, 0, 1]), axis=1),
                np.stack((-G[:, 1, 0], G[:, 0, 0]), axis=1),
            ),
            axis=1,
        ) / det[:, None, None]
        u0, u1, u2 = U[c[:, 0]], U[c[:, 1]], U[c[:, 2]]
        dU = np.stack((u1 - u0, u2 - u0), axis=2)  # d u_i / d (xi, eta)
        grad_h = np.einsum("kia,kaj->kij", dU, Ginv)  # d u_i / d x_j, constant per cell
        x = v0[:, 0, None] + G[:, 0, 0, None] * xi + G[:, 0, 1, None] * eta
        y = v0[:, 1, None] + G[:, 1, 0, None] * xi + G[:, 1, 1, None] * eta
        uh = (
            u0[:, :, None] * (1.0 - xi - eta)
            + u1[:, :, None] * xi
            + u2[:, :, None] * eta
        )  # (k, 2, q)
        dx = np.abs(det)[:, None] * wq  # (k, q)
        u = np.moveaxis(ex.exact_displacement_np(x, y), 0, 1)  # (k, 2, q)
        grad = np.moveaxis(ex.exact_displacement_gradient_np(x, y), 2, 0)  # (k, 2, 2, q)
        l2 += float(np.sum(dx * np.sum((uh - u) ** 2, axis=1)))
        h1 += float(np.sum(dx * np.sum((grad_h[..., None] - grad) ** 2, axis=(1, 2))))
        J += float(np.sum(dx * omega_np(x, y) * np.sum(uh**2, axis=1)))
    l2, h1, J = comm.allreduce(np.array([l2, h1, J]), op=MPI.SUM)
    return {"u_L2": math.sqrt(l2), "u_H1": math.sqrt(h1), "J": float(J)}


def pressure_error_sq(
    lo: np.ndarray, hi: np.ndarray, values: np.ndarray, kind: str, parts: int = 1, n: int = 8
) -> float:
    """Square of ||lambda - lambda_h||_L2 on the intervals [lo, hi] of Gamma_C (local sum).

    ``values`` are one value per interval (``kind="p0"``) or the P1 values at (lo, hi) (shape
    (k, 2), ``kind="p1"``); each interval is split into ``parts`` equal ones, each integrated
    with an n-point Gauss rule.
    """
    from dwr_signorini import examples as ex

    t, w = np.polynomial.legendre.leggauss(n)
    s = (np.arange(parts)[:, None] + 0.5 * (t + 1.0)).ravel() / parts  # (parts n,)
    w = np.tile(w, parts) / parts
    a, b = lo[:, None], hi[:, None]
    y = a + (b - a) * s
    if kind == "p1":
        lam_h = values[:, :1] * (1.0 - s) + values[:, 1:] * s
    else:
        lam_h = np.broadcast_to(values[:, None], y.shape)
    lam = ex.exact_contact_pressure_np(y, ex.ANALYTIC_MATERIAL.E, ex.ANALYTIC_MATERIAL.nu)
    return float(np.sum(0.5 * (b - a) * w * (lam_h - lam) ** 2))


# --------------------------------------------------------------------------------------------------
# Ours
# --------------------------------------------------------------------------------------------------


#: Our level's phases in the table of where its time went (dwr_signorini.timing.PHASES); the
#: rest of the level (other phases, and Python and form set-up outside every phase) is "other".
LEVEL_PHASES = ("discretize", "assemble", "factorize", "newton solve", "dual solve", "goal",
                "reconstruct", "indicators")


def level_phases(
    before: dict[str, float], after: dict[str, float], total: float
) -> dict[str, float]:
    """Seconds of each of :data:`LEVEL_PHASES` between two ``timing.snapshot()``s, and "other".

    "other" is ``total`` less the time of the phases in LEVEL_PHASES.
    """
    out = {name.replace(" ", "_"): after[name] - before[name] for name in LEVEL_PHASES}
    out["other"] = total - sum(out.values())
    return out


def run_ours(
    comm: Any, nx: int, ny: int, method: str | None, degree: int = OURS_DEGREE
) -> tuple[dict[str, Any], Any]:
    """Solve + estimate from the macro mesh on, timed; the errors and T_h afterwards.

    ``degree`` is the problem's ``quadrature_degree``: the rule of the body force, which is not a
    polynomial, in the Newton system and in the residuals of the estimate.
    """
    from mpi4py import MPI

    from dolfinx.mesh import CellType

    import dwr_signorini as ds
    from dwr_signorini import compat, timing
    from dwr_signorini import examples as ex

    mat = ex.ANALYTIC_MATERIAL
    msh, tags = ex.analytic_2d_mesh(comm, nx, ny, CellType.triangle)  # T_H, given
    goal = ex.goal_a(-0.5)
    comm.barrier()
    before = timing.snapshot()
    tic = time.perf_counter()
    problem = ds.SignoriniProblem(
        msh, tags, contact=CONTACT, dirichlet=(DIRICHLET,), E=mat.E, nu=mat.nu, model=mat.model,
        body_force=ex.analytic_body_force, gap=ex.analytic_gap, quadrature_degree=degree,
    )
    sol = ds.solve(problem, method=method)
    comm.barrier()
    t_solve = time.perf_counter() - tic
    est = ds.estimate(sol, goal)
    comm.barrier()
    t_total = time.perf_counter() - tic
    phases = level_phases(before, timing.snapshot(), t_total)

    disc = sol.disc
    fine = disc.mesh
    points = np.ascontiguousarray(fine.geometry.x[:, :2])
    gdm = compat.geometry_dofmap(fine)
    U = np.zeros_like(points)
    U[gdm] = sol.u.x.array.reshape(-1, 2)[disc.V.dofmap.list]  # P1 on a P1 mesh
    # lambda_H: one value per owned macro contact facet, on its interval [lo, hi] of y.
    sub = disc.contact_mesh
    sub_y = sub.geometry.x[compat.geometry_dofmap(sub)][:, :, 1]
    qdofs = disc.Q.dofmap.list[:, 0]
    owned = qdofs < disc.Q.dofmap.index_map.size_local
    lam_sq = pressure_error_sq(
        sub_y.min(axis=1)[owned], sub_y.max(axis=1)[owned], sol.lam.x.array[qdofs[owned]],
        "p0", parts=2,
    )
    errors = domain_errors(comm, points, gdm, U)
    info = {
        "ours_time": t_total,
        "ours_solve_time": t_solve,
        "ours_newton": int(sol.newton_iterations),
        "ours_method": sol.method,
        "ours_dofs": int(
            disc.V.dofmap.index_map.size_global * 2 + disc.Q.dofmap.index_map.size_global
        ),
        "ours_J_h": float(est.J_h),
        "ours_eta": float(est.eta) if est.eta is not None else float("nan"),
        "ours_eta_p": float(est.eta_p),
        "num_fine_cells": int(fine.topology.index_map(2).size_global),
        "ours_u_L2": errors["u_L2"],
        "ours_u_H1": errors["u_H1"],
        "ours_J_quadrature": errors["J"],
        "ours_lam_L2": math.sqrt(comm.allreduce(lam_sq, op=MPI.SUM)),
        **{f"ours_t_{name}": seconds for name, seconds in phases.items()},
    }
    est.destroy()
    sol.destroy()
    return info, fine


# --------------------------------------------------------------------------------------------------
# SNES VI (this process)
# --------------------------------------------------------------------------------------------------


def run_snesvi(comm: Any, nx: int, ny: int, args: argparse.Namespace) -> dict[str, Any]:
    """SNES VI on T_h (T_H refined as ours refines it), its errors; set-up timed separately."""
    from dolfinx.mesh import CellType
    from peer_snesvi import SnesOptions, solve_snesvi

    from dwr_signorini import compat
    from dwr_signorini import examples as ex

    msh, _ = ex.analytic_2d_mesh(comm, nx, ny, CellType.triangle)
    comm.barrier()
    tic = time.perf_counter()
    fine, _, _ = compat.refine(msh)
    t_refine = time.perf_counter() - tic
    opts = SnesOptions(
        pc=args.snes_pc, dirichlet=args.snes_dirichlet, linesearch=args.snes_linesearch,
        rtol=args.snes_rtol, ordering=args.snes_ordering,
    )
    times, out = [], None
    for _ in range(args.repeat):
        out = solve_snesvi(fine, opts)
        times.append(out["t_solve"])
    points = np.ascontiguousarray(fine.geometry.x[:, :2])
    errors = domain_errors(comm, points, compat.geometry_dofmap(fine), out["U"])
    return {
        "snes_time": min(times),
        "snes_times": times,
        "snes_setup_time": t_refine + out["t_setup"],
        "snes_newton": out["newton"],
        "snes_ordering": opts.ordering,
        "snes_reason": out["reason"],
        "snes_dofs": out["dofs"],
        "snes_u_L2": errors["u_L2"],
        "snes_u_H1": errors["u_H1"],
        "snes_J_quadrature": errors["J"],
    }


# --------------------------------------------------------------------------------------------------
# GetFEM (child process)
# --------------------------------------------------------------------------------------------------


def getfem_version() -> str | None:
    """GetFEM's release, or None if the Python interface is not importable."""
    if importlib.util.find_spec("getfem") is None:
        return None
    out = subprocess.run(
        [sys.executable, "-c", "import getfem; print(getfem.getfem_env('release'))"],
        capture_output=True, text=True, check=False,
    )
    return out.stdout.strip() if out.returncode == 0 else None


def _child(args: list[str]) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.run(
        [sys.executable, str(HERE / "peer_getfem.py"), *args], env=env, check=False,
        capture_output=args[0] == "--rule", text=args[0] == "--rule",
    )


def getfem_config(args: argparse.Namespace) -> dict[str, Any]:
    """The GetFEM configuration of the ``--gf-*`` options (default: ``FASTEST``)."""
    return {key: getattr(args, "gf_" + key) for key in FASTEST}


def run_getfem(fine: Any, args: argparse.Namespace) -> dict[str, Any]:
    """Run the GetFEM worker in a child process on T_h (serial); its errors."""
    from mpi4py import MPI

    import ufl
    from dolfinx import fem

    from dwr_signorini import compat
    from dwr_signorini import examples as ex

    cfg = getfem_config(args)
    mat = ex.ANALYTIC_MATERIAL
    points = np.ascontiguousarray(fine.geometry.x[:, :2])
    cells = np.ascontiguousarray(compat.geometry_dofmap(fine), dtype=np.int64)
    on_c = np.abs(points[:, 0]) < 1e-12
    breaks = np.sort(points[on_c, 1])
    f_ufl = ex.analytic_body_force(ufl.SpatialCoordinate(fine), mat.E, mat.nu)
    data: dict[str, Any] = {}
    if cfg["load"] == "imdata":
        # f at the points of GetFEM's rule, from our UFL expression (the cells are the same, and
        # both map reference vertex k to the cell's vertex k).
        proc = _child(["--rule", cfg["load_rule"]])
        if proc.returncode != 0:
            raise RuntimeError(f"GetFEM's rule {cfg['load_rule']}: {proc.stderr}")
        ref = np.asarray(json.loads(proc.stdout)).T  # (q, 2)
        all_cells = np.arange(len(cells), dtype=np.int32)
        values = fem.Expression(f_ufl, ref).eval(fine, all_cells).reshape(len(cells), -1, 2)
        xq = fem.Expression(ufl.SpatialCoordinate(fine), ref).eval(fine, all_cells)
        data["f_values_q"] = values.reshape(-1, 2)
        data["f_points"] = xq.reshape(-1, 2)
    else:
        V2 = fem.functionspace(fine, ("Lagrange", 2, (2,)))
        f = fem.Function(V2)
        f.interpolate(fem.Expression(f_ufl, compat.interpolation_points(V2.element)))
        data["f_nodes"] = V2.tabulate_dof_coordinates()[:, :2].copy()
        data["f_values"] = f.x.array.reshape(-1, 2).copy()
    with tempfile.TemporaryDirectory(prefix="dwr-peers-") as tmp:
        inp, out = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(
            inp, points=points, cells=cells, E=mat.E, nu=mat.nu,
            h=float(np.max(np.diff(breaks))), config=json.dumps(cfg), repeat=args.repeat, **data,
        )
        proc = _child([str(inp), str(out)])
        if proc.returncode != 0:
            raise RuntimeError(f"the GetFEM worker failed with status {proc.returncode}")
        res = {k: (v.item() if np.ndim(v) == 0 else v) for k, v in dict(np.load(out)).items()}
    errors = domain_errors(MPI.COMM_SELF, points, cells, res["U"])
    lam_breaks = breaks[0::2] if cfg["multiplier"] == "coarse" else breaks
    if not np.allclose(res["lam_y"], lam_breaks, atol=1e-12):
        raise RuntimeError("GetFEM's multiplier dofs are not where they should be")
    # GetFEM's lambda_n is the normal stress sigma_nn (<= 0); the pressure is -lambda_n.
    lam = -res["lam"]
    lam_sq = pressure_error_sq(
        lam_breaks[:-1], lam_breaks[1:], np.stack((lam[:-1], lam[1:]), axis=1), "p1",
        parts=2 if cfg["multiplier"] == "coarse" else 1,
    )
    return {
        "getfem_time": res["t_solve"],
        "getfem_times": [float(t) for t in np.atleast_1d(res["t_solves"])],
        "getfem_setup_time": res["t_setup"],
        "getfem_newton": res["newton"],
        "getfem_converged": bool(res["converged"]),
        "getfem_dofs": res["dofs"],
        "getfem_peak_rss_gib": res["peak_rss_gib"],
        "getfem_u_L2": errors["u_L2"],
        "getfem_u_H1": errors["u_H1"],
        "getfem_J_quadrature": errors["J"],
        "getfem_lam_L2": math.sqrt(lam_sq),
    }


# --------------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------------


def time_columns(peers: list[str]) -> list[tuple[str, str, str]]:
    """Columns of the time table: (title, key, format)."""
    cols = [
        ("fine cells", "num_fine_cells", "{:d}"),
        ("ours [s]", "ours_time", "{:.2f}"),
        ("(solve)", "ours_solve_time", "{:.2f}"),
        ("Newton", "ours_newton", "{:d}"),
        ("ours, default degree [s]", "ours_default_time", "{:.2f}"),
    ]
    names = {"getfem": "GetFEM", "snes": "SNES VI"}
    for p in peers:
        cols += [
            (f"{names[p]} solve [s]", f"{p}_time", "{:.2f}"),
            ("(set-up)", f"{p}_setup_time", "{:.2f}"),
            ("Newton", f"{p}_newton", "{:d}"),
            (f"ours/{names[p]}", f"ratio_{p}", "{:.2f}"),
        ]
    return cols


def phase_columns() -> list[tuple[str, str, str]]:
    """Columns of the table of our level's phases (:func:`level_phases`)."""
    names = [name.replace(" ", "_") for name in LEVEL_PHASES] + ["other"]
    return [("fine cells", "num_fine_cells", "{:d}"), ("ours [s]", "ours_time", "{:.2f}")] + [
        (name.replace("_", " "), f"ours_t_{name}", "{:.3f}") for name in names
    ]


def error_columns(peers: list[str]) -> list[tuple[str, str, str]]:
    """Columns of the error table."""
    cols = [("fine cells", "num_fine_cells", "{:d}")]
    for what, title in (("u_L2", "|u-u_h|_L2"), ("u_H1", "|u-u_h|_H1"),
                        ("lam_L2", "|lam-lam_h|"), ("J_rel", "E_rel(J_a1)")):
        for code in ("ours", *peers):
            if what == "lam_L2" and code == "snes":
                continue
            cols.append((f"{title} {code}", f"{code}_{what}", "{:.3e}"))
    cols.append(("Ieff ours", "ours_ieff", "{:.3f}"))
    return cols


def print_table(cols: list[tuple[str, str, str]], rows: list[dict[str, Any]]) -> None:
    """Print a header and the rows."""
    widths = [max(len(title), 9) for title, _, _ in cols]
    print("  ".join(t.rjust(w) for (t, _, _), w in zip(cols, widths, strict=True)))
    for row in rows:
        print("  ".join(fmt.format(row[key]).rjust(w)
                        for (_, key, fmt), w in zip(cols, widths, strict=True)), flush=True)


def write_results(rows: list[dict[str, Any]], meta: dict[str, Any], output: Path, tag: str) -> None:
    """CSV (one row per size) and JSON (rows and run metadata) under ``output``."""
    output.mkdir(parents=True, exist_ok=True)
    keys = list(rows[0])
    with open(output / f"peers{tag}.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    with open(output / f"peers{tag}.json", "w") as fh:
        json.dump({"meta": meta, "rows": rows}, fh, indent=2)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default=",".join(map(str, DEFAULT_SIZES)),
                        help="fine triangles, comma-separated (49152 or 49k, ...)")
    parser.add_argument("--quick", action="store_true", help="the smallest size only")
    parser.add_argument("--peers", default="getfem,snes",
                        help="comma-separated: getfem, snes (default both; GetFEM serial only)")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument("--repeat", type=int, default=1,
                        help="time each code this many times per size, report the fastest")
    parser.add_argument("--quadrature-degree", type=int, default=OURS_DEGREE,
                        help="our data's quadrature degree (the problem's quadrature_degree; "
                             f"default {OURS_DEGREE}, GetFEM's load rule); the package's default "
                             "is timed beside it")
    parser.add_argument("--method", default=None, choices=("block", "schur"),
                        help="our linear solver (default: the package's choice)")
    parser.add_argument("--check", action="store_true",
                        help="only report whether GetFEM is installed (status 1 if not)")
    g = parser.add_argument_group("GetFEM (defaults: the fastest configuration, FASTEST)")
    g.add_argument("--gf-r", default=FASTEST["r"], choices=("E", "E/h"),
                   help="augmentation parameter r = r0 E or r0 E / h")
    g.add_argument("--gf-r0", type=float, default=FASTEST["r0"])
    g.add_argument("--gf-load", default=FASTEST["load"], choices=("imdata", "p2"),
                   help="body force at the quadrature points or as a P2 field")
    g.add_argument("--gf-load-rule", default=FASTEST["load_rule"],
                   help="GetFEM's integration method of the load with --gf-load imdata")
    g.add_argument("--gf-obstacle", default=FASTEST["obstacle"], choices=("levelset", "shift"))
    g.add_argument("--gf-slope", type=float, default=FASTEST["slope"],
                   help="K of the level-set obstacle d = g(y) - K x")
    g.add_argument("--gf-dirichlet", default=FASTEST["dirichlet"],
                   choices=("simplification", "multipliers"))
    g.add_argument("--gf-max-res", type=float, default=FASTEST["max_res"])
    g.add_argument("--gf-lsolver", default=FASTEST["lsolver"])
    g.add_argument("--gf-lsearch", default=FASTEST["lsearch"],
                   choices=("default", "simplest", "systematic", "quadratic", "basic"))
    g.add_argument("--gf-option", type=int, default=FASTEST["option"], choices=(1, 2, 3))
    g.add_argument("--gf-multiplier", default=FASTEST["multiplier"], choices=("coarse", "fine"))
    s = parser.add_argument_group("SNES VI")
    s.add_argument("--snes-pc", default="cholesky", choices=("cholesky", "lu"))
    s.add_argument("--snes-dirichlet", default="bc", choices=("bc", "bounds"))
    s.add_argument("--snes-linesearch", default="basic", choices=("basic", "bt", "l2", "cp"))
    s.add_argument("--snes-rtol", type=float, default=1e-10)
    s.add_argument("--snes-ordering", type=int, default=2, choices=(0, 2, 4, 5, 6, 7),
                   help="MUMPS's ICNTL(7) (2: AMF, the default; 7: MUMPS's choice)")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run the comparison; print and write the tables."""
    args = parse_args(argv)
    peers = [p.strip() for p in args.peers.split(",") if p.strip()]
    if not set(peers) <= {"getfem", "snes"}:
        raise SystemExit(f"--peers: unknown peer in {args.peers!r} (getfem, snes)")
    version = getfem_version() if "getfem" in peers else None
    if args.check:
        if version is None:
            print(SKIP_MESSAGE)
            return 1
        print(f"benchmarks/peers.py: GetFEM {version} is installed")
        return 0

    from mpi4py import MPI

    from dwr_signorini import examples as ex
    from dwr_signorini.quadrature import DATA_QUADRATURE_DEGREE

    comm = MPI.COMM_WORLD
    rank0 = comm.rank == 0
    if "getfem" in peers and (version is None or comm.size > 1):
        if rank0:
            print(SKIP_MESSAGE if version is None else
                  "benchmarks/peers.py: GetFEM is serial; skipped on more than one rank")
        peers.remove("getfem")
    sizes = sorted({parse_size(s) for s in args.sizes.split(",") if s.strip()})
    if args.quick:
        sizes = sizes[:1]
    J_exact = ex.exact_J_a(-0.5)
    if rank0:
        print(f"Example 5.1 on triangles, {comm.size} rank(s): ours (set-up + solve + estimate "
              f"from T_H) against the peers' solve alone; J_a1 = {J_exact:.12e}", flush=True)
        if "getfem" in peers:
            print(f"GetFEM {version}: {getfem_config(args)}", flush=True)
    # Warm-up: JIT compilation (cached on disk) not timed.
    for degree in dict.fromkeys((args.quadrature_degree, DATA_QUADRATURE_DEGREE)):
        run_ours(comm, 12, 8, args.method, degree)
    if "snes" in peers:
        run_snesvi(comm, 12, 8, argparse.Namespace(**{**vars(args), "repeat": 1}))

    rows: list[dict[str, Any]] = []
    tag = "" if comm.size == 1 else f"_np{comm.size}"
    for num_fine in sizes:
        nx, ny = macro_size(num_fine)
        times, default_times, phase_runs = [], [], []
        for _ in range(args.repeat):
            info, fine = run_ours(comm, nx, ny, args.method, args.quadrature_degree)
            times.append((info["ours_time"], info["ours_solve_time"]))
            phase_runs.append(dict(info))
            default_times.append(
                info if args.quadrature_degree == DATA_QUADRATURE_DEGREE
                else run_ours(comm, nx, ny, args.method, DATA_QUADRATURE_DEGREE)[0]
            )
        fastest = min(range(len(times)), key=lambda k: times[k][0])
        info["ours_time"], info["ours_solve_time"] = times[fastest]
        info.update({k: v for k, v in phase_runs[fastest].items() if k.startswith("ours_t_")})
        info["ours_times"] = [t for t, _ in times]
        info["ours_degree"] = args.quadrature_degree
        info["ours_default_time"] = min(d["ours_time"] for d in default_times)
        info["ours_default_J_h"] = default_times[-1]["ours_J_h"]
        info["ours_default_eta"] = default_times[-1]["ours_eta"]
        row = {**info, "macro": f"{nx}x{ny}"}
        if "getfem" in peers:
            row.update(run_getfem(fine, args))
        del fine
        if "snes" in peers:
            row.update(run_snesvi(comm, nx, ny, args))
        for code in ("ours", *peers):
            row[f"{code}_J_rel"] = abs(row[f"{code}_J_quadrature"] - J_exact) / abs(J_exact)
        row["ours_ieff"] = row["ours_eta"] / (J_exact - row["ours_J_h"])
        for p in peers:
            row[f"ratio_{p}"] = row["ours_time"] / row[f"{p}_time"]
        rows.append(row)
        if rank0:
            meta = {
                "command": " ".join(["benchmarks/peers.py", *(argv or sys.argv[1:])]),
                "ranks": comm.size,
                "getfem": version,
                "getfem_config": getfem_config(args) if "getfem" in peers else None,
                "J_exact": J_exact,
                "load_average": os.getloadavg(),
            }
            write_results(rows, meta, args.output, tag)
            print(f"[{num_fine} fine cells done, load average {os.getloadavg()[0]:.2f}]",
                  flush=True)
    if rank0:
        print("\nTimes [s] (ours: everything from T_H on; peers: solve alone, set-up beside):")
        print_table(time_columns(peers), rows)
        print("\nWhere our level's time went (its fastest run) [s], by dwr_signorini.timing phase:")
        print_table(phase_columns(), rows)
        print("\nErrors:")
        print_table(error_columns(peers), rows)
        print(f"wrote {args.output / f'peers{tag}.csv'} and {args.output / f'peers{tag}.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
