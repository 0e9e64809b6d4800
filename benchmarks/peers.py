"""Example 5.1 solved by a peer code, GetFEM, on our fine mesh T_h, beside our solve + estimate.

Each code uses its own discretisation on the same triangles (the fine mesh T_h that our solver
builds from the macro mesh T_H it is given; GetFEM gets T_h's vertices and cells):

* ours: ``ds.solve(problem)`` then ``ds.estimate(sol, goal_a(-0.5))`` from the macro mesh on
  (uniform refinement to T_h, spaces, assembly, semi-smooth Newton, dual problem, estimate): u_h
  in vector P1 on T_h, lambda_H in P0 on the macro contact facets (H = 2h), NCP with c = E / H;
* GetFEM (its Python interface, ``gf.Model``; a separate process, see below): u in vector P1 on
  T_h (``add_isotropic_linearized_elasticity_pstrain_brick``), clamped on Gamma_D
  (``add_Dirichlet_condition_with_simplification``), the body force of example 5.1 as a P2 field
  (``add_source_term_brick``), and frictionless contact with a rigid obstacle through the integral
  contact brick (``add_integral_contact_with_rigid_obstacle_brick``, option 1: the non-symmetric
  Alart-Curnier augmented Lagrangian, r = E / h) with a multiplier in continuous P1 on the macro
  contact vertices (every second fine one, H = 2h: GetFEM asks for an inf-sup condition, which the
  equal-order multiplier on all fine contact vertices, ``--multiplier fine``, violates), solved
  by GetFEM's Newton method (``Model.solve``, sequential MUMPS).

The obstacle. GetFEM's rigid-obstacle bricks take the obstacle as a signed distance d: the gap is
d and the normal -grad d / |grad d|, so a curved gap g(y) would tilt the normal, while example 5.1
prescribes u . n <= g(y) with the body's normal n = (1, 0) (and no friction in that frame).
The driver therefore solves for w = u - u_g, where u_g is the P1 function with first component
g(y_i) at the nodes of Gamma_C and zero elsewhere: the obstacle of w is the plane x = 0 (d = -x,
normal (1, 0), zero gap), the load gets -a(u_g, v) (``add_source_term``), and u = w + u_g. This is
GetFEM's integral contact with normal (1, 0) and the gap interpolated in P1 (as the brick
interpolates any obstacle on a finite element space).

Errors of both against the exact solution, computed here in the same way for both (numpy,
``exact_displacement_np`` & co., a 16-point rule on every triangle and an 8-point Gauss rule on
every fine contact facet): displacement L2 and H1 seminorm, contact pressure L2 on Gamma_C, and
J_a1 = J_{a,-0.5} relative to ``exact_J_a(-0.5)``.

Times, in the same run: ours is the wall-clock time of problem set-up on the given macro mesh +
``ds.solve`` + ``ds.estimate`` (everything from T_H on, after one untimed warm-up on a small mesh
so that the forms' JIT compilation, cached on disk, is not counted); the peer's is
``Model.solve`` alone (the Newton iterations with their assembly and factorisations; GetFEM's mesh
import, finite element spaces, data and bricks, its model set-up, are excluded and reported
separately). GetFEM runs in a child process of this script (``--worker``) that imports getfem
and not dolfinx, since both link a MUMPS (GetFEM the sequential one): the child loads our mesh
and the load from a temporary ``.npz`` file and returns its solution the same way.

    make peer-env                                         # once: installs GetFEM (optional)
    scripts/fenicsx python3 benchmarks/peers.py           # 49k, 196k and 786k fine triangles
    scripts/fenicsx python3 benchmarks/peers.py --quick   # 49k only
    scripts/fenicsx python3 benchmarks/peers.py --sizes 49k,196k

Serial. Where GetFEM is not installed it prints one SKIPPED line and exits 0. Writes
``benchmarks/results/peers.csv`` and ``peers.json`` (``--output`` to move them).
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
DEFAULT_OUTPUT = HERE / "results"
#: Fine triangles of the default sizes; a macro mesh of nx x ny = 3k x 2k squares, each split into
#: 2 triangles, refined once uniformly, has 48 k^2 of them (k even: the kinks y = +-1/2 are mesh
#: lines).
DEFAULT_SIZES = (49152, 196608, 786432)
#: Tags of analytic_2d_mesh (examples._mesh): clamped, traction-free, contact.
DIRICHLET, CONTACT = 1, 3
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
# Errors against the exact solution (numpy only, the same for both codes)
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
    points: np.ndarray, cells: np.ndarray, U: np.ndarray, chunk: int = 65536
) -> dict[str, float]:
    """||u - u_h||_L2, |u - u_h|_H1 and J_{a,-0.5}(u_h) of a P1 field given at the vertices."""
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
    return {"u_L2": math.sqrt(l2), "u_H1": math.sqrt(h1), "J": J}


def pressure_error(breaks: np.ndarray, values: np.ndarray, kind: str, n: int = 8) -> float:
    """||lambda - lambda_h||_L2(Gamma_C) of a piecewise P0 or P1 function of y.

    ``breaks`` are the sorted y of the fine contact vertices; ``values`` the P1 nodal values at
    them (``kind="p1"``) or one value per fine interval (``kind="p0"``).
    """
    from dwr_signorini import examples as ex

    t, w = np.polynomial.legendre.leggauss(n)
    a, b = breaks[:-1, None], breaks[1:, None]
    s = 0.5 * (t + 1.0)
    y = a + (b - a) * s
    if kind == "p1":
        lam_h = values[:-1, None] * (1.0 - s) + values[1:, None] * s
    else:
        lam_h = np.broadcast_to(values[:, None], y.shape)
    lam = ex.exact_contact_pressure_np(y, ex.ANALYTIC_MATERIAL.E, ex.ANALYTIC_MATERIAL.nu)
    return math.sqrt(float(np.sum(0.5 * (b - a) * w * (lam_h - lam) ** 2)))


# --------------------------------------------------------------------------------------------------
# Ours
# --------------------------------------------------------------------------------------------------


def run_ours(nx: int, ny: int) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Solve + estimate from the macro mesh on, timed; then T_h, u_h and lambda_H as arrays."""
    from mpi4py import MPI

    import ufl
    from dolfinx import fem
    from dolfinx.mesh import CellType

    import dwr_signorini as ds
    from dwr_signorini import compat
    from dwr_signorini import examples as ex

    mat = ex.ANALYTIC_MATERIAL
    msh, tags = ex.analytic_2d_mesh(MPI.COMM_WORLD, nx, ny, CellType.triangle)  # T_H, given
    goal = ex.goal_a(-0.5)
    tic = time.perf_counter()
    problem = ds.SignoriniProblem(
        msh, tags, contact=CONTACT, dirichlet=(DIRICHLET,), E=mat.E, nu=mat.nu, model=mat.model,
        body_force=ex.analytic_body_force, gap=ex.analytic_gap,
    )
    sol = ds.solve(problem)
    t_solve = time.perf_counter() - tic
    est = ds.estimate(sol, goal)
    t_total = time.perf_counter() - tic

    disc = sol.disc
    fine = disc.mesh
    points = np.ascontiguousarray(fine.geometry.x[:, :2])
    gdm = compat.geometry_dofmap(fine)
    dofs = disc.V.dofmap.list
    U = np.zeros_like(points)
    U[gdm] = sol.u.x.array.reshape(-1, 2)[dofs]  # P1 on a P1 mesh: dofs follow the vertices
    # lambda_H: one value per macro contact facet (interval of Sigma_H), on the fine breaks.
    sub = disc.contact_mesh
    sub_x = sub.geometry.x[compat.geometry_dofmap(sub)][:, :, 1]  # (facets, 2) y of the ends
    qdofs = disc.Q.dofmap.list[:, 0]
    lam_values = sol.lam.x.array[qdofs]
    on_contact = np.abs(points[:, 0]) < 1e-12
    breaks = np.sort(points[on_contact, 1])
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    lo, hi = sub_x.min(axis=1), sub_x.max(axis=1)
    order = np.argsort(lo)
    which = np.searchsorted(lo[order], mids, side="right") - 1
    if np.any(mids > hi[order][which]):
        raise RuntimeError("a fine contact facet outside every macro contact facet")
    lam_fine = lam_values[order][which]
    # Example 5.1's body force f at the P2 nodes of T_h, from its UFL, for GetFEM's source term.
    V2 = fem.functionspace(fine, ("Lagrange", 2, (2,)))
    f = fem.Function(V2)
    f.interpolate(fem.Expression(
        ex.analytic_body_force(ufl.SpatialCoordinate(fine), mat.E, mat.nu),
        compat.interpolation_points(V2.element),
    ))
    f_nodes = V2.tabulate_dof_coordinates()[:, :2].copy()
    f_values = f.x.array.reshape(-1, 2).copy()

    info = {
        "ours_time": t_total,
        "ours_solve_time": t_solve,
        "ours_estimate_time": t_total - t_solve,
        "ours_newton": int(sol.newton_iterations),
        "ours_dofs": int(
            disc.V.dofmap.index_map.size_global * 2 + disc.Q.dofmap.index_map.size_global
        ),
        "ours_J_h": float(est.J_h),
        "ours_eta": float(est.eta) if est.eta is not None else float("nan"),
        "ours_eta_p": float(est.eta_p),
        "num_fine_cells": len(gdm),
        "num_macro_cells": int(msh.topology.index_map(2).size_global),
    }
    est.destroy()
    sol.destroy()
    arrays = {
        "points": points, "cells": np.ascontiguousarray(gdm, dtype=np.int64), "U": U,
        "breaks": breaks, "lam_fine": lam_fine, "f_nodes": f_nodes, "f_values": f_values,
    }
    return info, arrays


# --------------------------------------------------------------------------------------------------
# GetFEM (child process)
# --------------------------------------------------------------------------------------------------


def peak_rss_gib() -> float:
    """Peak resident memory of this process (VmHWM) in GiB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20
    return float("nan")


def reset_peak_rss() -> None:
    """Reset VmHWM to the current resident memory (Linux; ignored where not allowed)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass


def getfem_version() -> str | None:
    """GetFEM's release, or None if the Python interface is not importable."""
    if importlib.util.find_spec("getfem") is None:
        return None
    out = subprocess.run(
        [sys.executable, "-c", "import getfem; print(getfem.getfem_env('release'))"],
        capture_output=True, text=True, check=False,
    )
    return out.stdout.strip() if out.returncode == 0 else None


def getfem_worker(inp: Path, out: Path) -> None:
    """Build and solve example 5.1 with GetFEM on the given triangles; write the solution."""
    import getfem as gf
    from scipy.spatial import cKDTree

    gf.util_trace_level(0)

    d = np.load(inp)
    points, cells = d["points"], d["cells"]
    E, nu, r, option = float(d["E"]), float(d["nu"]), float(d["r"]), int(d["option"])
    lsolver, multiplier = str(d["lsolver"]), str(d["multiplier"])
    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))  # plane strain
    GC, GD = 1, 2

    tic = time.perf_counter()
    m = gf.Mesh("ptND", points.T.copy(), cells.T.copy())
    if m.nbcvs() != len(cells) or not np.array_equal(m.pts().T, points):
        raise RuntimeError("GetFEM renumbered the mesh's points or cells")
    faces = m.outer_faces()
    normals = m.normal_of_faces(faces)
    m.set_region(GC, faces[:, normals[0] > 0.5])  # x = 0, outer normal (1, 0)
    m.set_region(GD, faces[:, normals[0] < -0.5])  # x = -3
    mfu = gf.MeshFem(m, 2)
    mfu.set_classical_fem(1)
    mfd = gf.MeshFem(m, 1)
    mfd.set_classical_fem(2)
    # The multiplier: continuous P1 on Gamma_C. "coarse": on every second fine contact vertex
    # (the macro vertices, H = 2h), through GetFEM's reduction/extension matrices (the values at
    # the fine vertices in between are the means of their neighbours'); "fine": on all fine
    # contact vertices (the trace space of u, which violates the inf-sup condition).
    mfl = gf.MeshFem(m, 1)
    mfl.set_classical_fem(1)
    ldof = mfl.basic_dof_on_region(GC)
    fine_dofs = ldof[np.argsort(mfl.basic_dof_nodes(ldof)[1])]  # sorted by y
    if multiplier == "coarse":
        if len(fine_dofs) % 2 == 0:
            raise RuntimeError("an odd number of fine contact facets")
        lam_dofs = fine_dofs[0::2]
        nb, nc = mfl.nb_basic_dof(), len(lam_dofs)
        R, Ext = gf.Spmat("empty", nc, nb), gf.Spmat("empty", nb, nc)
        for j, dof in enumerate(lam_dofs):
            R[j, dof] = 1.0
            Ext[dof, j] = 1.0
        for k in range(1, len(fine_dofs), 2):
            Ext[fine_dofs[k], k // 2] = 0.5
            Ext[fine_dofs[k], k // 2 + 1] = 0.5
        mfl_c = gf.MeshFem("clone", mfl)
        mfl_c.reduction_matrices(R, Ext)
    else:
        lam_dofs = np.sort(fine_dofs)
        mfl_c = gf.MeshFem("partial", mfl, lam_dofs)
    if mfl_c.nbdof() != len(lam_dofs):
        raise RuntimeError("unexpected multiplier space on Gamma_C")
    # Integration: exact for the stiffness (constant gradients) and for f_h . v (P2 x P1); the
    # composite rule of GetFEM's contact demo on Gamma_C (the brick's integrand has kinks).
    mim_e = gf.MeshIm(m, gf.Integ("IM_TRIANGLE(1)"))
    mim_f = gf.MeshIm(m, gf.Integ("IM_TRIANGLE(3)"))
    mim_c = gf.MeshIm(m, gf.Integ("IM_STRUCTURED_COMPOSITE(IM_TRIANGLE(4),4)"))

    # Vertex of each dof (P1 and P1 multiplier), and the component of each displacement dof.
    tree = cKDTree(points)
    nodes_u = mfu.basic_dof_nodes()
    dist, vert_u = tree.query(nodes_u.T)
    if dist.max() > 1e-12:
        raise RuntimeError("a P1 dof of GetFEM is not at a vertex")
    comp_u = np.zeros(len(vert_u), dtype=np.int64)
    comp_u[1::2] = 1
    if not np.array_equal(vert_u[0::2], vert_u[1::2]):
        raise RuntimeError("unexpected order of GetFEM's vector dofs")

    # f at the P2 nodes (computed by the parent from the UFL expression).
    dist, idx = cKDTree(d["f_nodes"]).query(mfd.basic_dof_nodes().T)
    if dist.max() > 1e-12:
        raise RuntimeError("a P2 node of GetFEM is not a P2 node of dolfinx")
    F = d["f_values"][idx]
    # The lifting u_g: first component g(y) at the vertices of Gamma_C.
    on_c = np.abs(points[:, 0]) < 1e-12
    yv = points[:, 1]
    g = np.where(np.abs(yv) < 0.5, -9.0 * (yv**2 - 0.25) ** 4, 0.0)
    UG = np.where(on_c[vert_u] & (comp_u == 0), g[vert_u], 0.0)

    def build_model() -> Any:
        md = gf.Model("real")
        md.add_fem_variable("w", mfu)
        md.add_initialized_data("E", [E])
        md.add_initialized_data("nu", [nu])
        md.add_initialized_data("clambda", [lmbda])
        md.add_initialized_data("cmu", [mu])
        md.add_isotropic_linearized_elasticity_pstrain_brick(mim_e, "w", "E", "nu")
        md.add_initialized_fem_data("f1", mfd, F[:, 0].copy())
        md.add_initialized_fem_data("f2", mfd, F[:, 1].copy())
        md.add_source_term_brick(mim_f, "w", "[f1, f2]")
        md.add_initialized_fem_data("ug", mfu, UG)
        md.add_source_term(mim_e, "-(clambda*Div_ug*Div_Test_w + 2*cmu*Sym(Grad_ug):Grad_Test_w)")
        md.add_Dirichlet_condition_with_simplification("w", GD)
        md.add_fem_variable("lambda_n", mfl_c)
        md.add_initialized_data("r", [r])
        md.add_initialized_fem_data("obstacle", mfl, -mfl.basic_dof_nodes()[0])  # d = -x
        md.add_integral_contact_with_rigid_obstacle_brick(
            mim_c, "w", "lambda_n", "obstacle", "r", GC, option
        )
        return md

    # Each repeat solves a new model (nothing assembled before its solve).
    t_solves = []
    for _ in range(int(d["repeat"])):
        md = build_model()
        if not t_solves:
            t_setup = time.perf_counter() - tic
        tic = time.perf_counter()
        nit, converged = md.solve("max_res", float(d["max_res"]), "max_iter", 100,
                                  "lsolver", lsolver)
        t_solves.append(time.perf_counter() - tic)

    W = md.variable("w")
    U = np.zeros_like(points)
    U[vert_u, comp_u] = W + UG
    lam = md.variable("lambda_n")
    lam_nodes = mfl.basic_dof_nodes(lam_dofs)  # the dofs of mfl_c, in this order
    order = np.argsort(lam_nodes[1])
    np.savez(
        out,
        U=U,
        lam_y=lam_nodes[1][order],
        lam=lam[order],
        newton=int(nit),
        converged=bool(converged),
        t_setup=t_setup,
        t_solve=min(t_solves),
        t_solves=np.array(t_solves),
        dofs=int(md.nbdof()),
        peak_rss_gib=peak_rss_gib(),
    )


def run_getfem(arrays: dict[str, np.ndarray], args: argparse.Namespace) -> dict[str, Any]:
    """Run :func:`getfem_worker` in a child process on our T_h; return its results."""
    from dwr_signorini import examples as ex

    points = arrays["points"]
    h = float(np.max(np.diff(arrays["breaks"])))  # fine contact facets
    mat = ex.ANALYTIC_MATERIAL
    with tempfile.TemporaryDirectory(prefix="dwr-peers-") as tmp:
        inp, out = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(
            inp, points=points, cells=arrays["cells"], f_nodes=arrays["f_nodes"],
            f_values=arrays["f_values"],
            E=mat.E, nu=mat.nu, r=args.r0 * mat.E / h, option=args.option,
            lsolver=args.lsolver, max_res=args.max_res, multiplier=args.multiplier,
            repeat=args.repeat,
        )
        env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
        proc = subprocess.run(
            [sys.executable, str(Path(__file__).resolve()), "--worker", str(inp), str(out)],
            env=env, check=False,
        )
        if proc.returncode != 0:
            raise RuntimeError(f"the GetFEM worker failed with status {proc.returncode}")
        res = dict(np.load(out))
    return {k: (v.item() if np.ndim(v) == 0 else v) for k, v in res.items()}


# --------------------------------------------------------------------------------------------------
# Driver
# --------------------------------------------------------------------------------------------------

COLUMNS = (
    ("fine cells", "num_fine_cells", "{:d}"),
    ("ours [s]", "ours_time", "{:.2f}"),
    ("ours solve [s]", "ours_solve_time", "{:.2f}"),
    ("GetFEM solve [s]", "peer_time", "{:.2f}"),
    ("ratio", "time_ratio", "{:.2f}"),
    ("Newton ours/GetFEM", "newton", "{}"),
    ("|u-u_h|_L2 ours", "ours_u_L2", "{:.3e}"),
    ("GetFEM", "peer_u_L2", "{:.3e}"),
    ("|u-u_h|_H1 ours", "ours_u_H1", "{:.3e}"),
    ("GetFEM", "peer_u_H1", "{:.3e}"),
    ("|lam-lam_h|_L2 ours", "ours_lam_L2", "{:.3e}"),
    ("GetFEM", "peer_lam_L2", "{:.3e}"),
    ("E_rel(J_a1) ours", "ours_J_rel", "{:.3e}"),
    ("GetFEM", "peer_J_rel", "{:.3e}"),
    ("eta/(J-J_h) ours", "ours_ieff", "{:.3f}"),
)


def print_row(row: dict[str, Any] | None) -> None:
    """Print the table's header (row None) or one row."""
    widths = [max(len(title), 10) for title, _, _ in COLUMNS]
    if row is None:
        print("  ".join(title.rjust(w) for (title, _, _), w in zip(COLUMNS, widths, strict=True)))
        return
    cells = [fmt.format(row[key]) for (_, key, fmt), _w in zip(COLUMNS, widths, strict=True)]
    print("  ".join(c.rjust(w) for c, w in zip(cells, widths, strict=True)), flush=True)


def write_results(rows: list[dict[str, Any]], meta: dict[str, Any], output: Path) -> None:
    """CSV (one row per size) and JSON (rows and run metadata) under ``output``."""
    output.mkdir(parents=True, exist_ok=True)
    keys = list(rows[0])
    with open(output / "peers.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)
    with open(output / "peers.json", "w") as fh:
        json.dump({"meta": meta, "rows": rows}, fh, indent=2)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default=",".join(map(str, DEFAULT_SIZES)),
                        help="fine triangles, comma-separated (49152 or 49k, ...)")
    parser.add_argument("--quick", action="store_true", help="the smallest size only")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    parser.add_argument("--r0", type=float, default=1.0,
                        help="GetFEM's augmentation parameter r = r0 E / h (default 1)")
    parser.add_argument("--option", type=int, default=1, choices=(1, 2, 3, 4),
                        help="version of GetFEM's integral contact brick (default 1)")
    parser.add_argument("--lsolver", default="mumps", help="GetFEM's linear solver")
    parser.add_argument("--multiplier", default="coarse", choices=("coarse", "fine"),
                        help="GetFEM's multiplier: continuous P1 on the macro contact vertices "
                        "(coarse, H = 2h, the default) or on all fine contact vertices (fine)")
    parser.add_argument("--max-res", type=float, default=1e-10,
                        help="GetFEM's Newton tolerance on the residual (default 1e-10)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="time each code this many times per size, report the fastest")
    parser.add_argument("--check", action="store_true",
                        help="only report whether GetFEM is installed (status 1 if not)")
    parser.add_argument("--worker", nargs=2, type=Path, metavar=("IN", "OUT"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if args.worker:
        getfem_worker(*args.worker)
        return 0
    version = getfem_version()
    if args.check:
        if version is None:
            print(SKIP_MESSAGE)
            return 1
        print(f"benchmarks/peers.py: GetFEM {version} is installed")
        return 0
    if version is None:
        print(SKIP_MESSAGE)
        return 0

    from mpi4py import MPI

    if MPI.COMM_WORLD.size > 1:
        raise SystemExit("benchmarks/peers.py runs in serial (GetFEM's Python interface is serial)")
    from dwr_signorini import examples as ex

    sizes = sorted({parse_size(s) for s in args.sizes.split(",") if s.strip()})
    if args.quick:
        sizes = sizes[:1]
    J_exact = ex.exact_J_a(-0.5)
    print(f"Example 5.1 on triangles, ours (solve + estimate from T_H) and GetFEM {version} "
          f"(Model.solve; set-up excluded) on the same T_h; J_a1 = {J_exact:.12e}", flush=True)
    run_ours(12, 8)  # warm-up: JIT compilation of the forms (cached on disk) is not timed

    rows: list[dict[str, Any]] = []
    print_row(None)
    for num_fine in sizes:
        nx, ny = macro_size(num_fine)
        reset_peak_rss()
        times = []
        for _ in range(args.repeat):
            info, arrays = run_ours(nx, ny)
            times.append((info["ours_time"], info["ours_solve_time"]))
        rss_ours = peak_rss_gib()
        best = min(times)
        info["ours_time"], info["ours_solve_time"] = best
        info["ours_estimate_time"] = best[0] - best[1]
        info["ours_times"] = [t for t, _ in times]
        peer = run_getfem(arrays, args)

        ours_err = domain_errors(arrays["points"], arrays["cells"], arrays["U"])
        peer_err = domain_errors(arrays["points"], arrays["cells"], peer["U"])
        breaks = arrays["breaks"]
        lam_breaks = breaks[0::2] if args.multiplier == "coarse" else breaks
        if not np.allclose(peer["lam_y"], lam_breaks, atol=1e-12):
            raise RuntimeError("GetFEM's multiplier dofs are not where they should be")
        # GetFEM's lambda_n is the normal stress sigma_nn (<= 0); ours is -sigma_nn (>= 0).
        ours_lam = pressure_error(breaks, arrays["lam_fine"], "p0")
        peer_lam = pressure_error(lam_breaks, -peer["lam"], "p1")
        ours_Jrel = abs(ours_err["J"] - J_exact) / abs(J_exact)
        row = {
            **info,
            "macro": f"{nx}x{ny}",
            "ours_J_quadrature": ours_err["J"],
            "ours_u_L2": ours_err["u_L2"],
            "ours_u_H1": ours_err["u_H1"],
            "ours_lam_L2": ours_lam,
            "ours_J_rel": ours_Jrel,
            "ours_ieff": info["ours_eta"] / (J_exact - info["ours_J_h"]),
            "ours_peak_rss_gib": rss_ours,
            "peer_time": peer["t_solve"],
            "peer_setup_time": peer["t_setup"],
            "peer_times": [float(t) for t in np.atleast_1d(peer["t_solves"])],
            "peer_newton": peer["newton"],
            "peer_converged": bool(peer["converged"]),
            "peer_dofs": peer["dofs"],
            "peer_J": peer_err["J"],
            "peer_u_L2": peer_err["u_L2"],
            "peer_u_H1": peer_err["u_H1"],
            "peer_lam_L2": peer_lam,
            "peer_J_rel": abs(peer_err["J"] - J_exact) / abs(J_exact),
            "peer_peak_rss_gib": peer["peak_rss_gib"],
        }
        row["time_ratio"] = row["ours_time"] / row["peer_time"]
        row["newton"] = f"{row['ours_newton']}/{row['peer_newton']}"
        rows.append(row)
        print_row(row)
        meta = {
            "command": " ".join(["benchmarks/peers.py", *(argv or sys.argv[1:])]),
            "getfem": version,
            "J_exact": J_exact,
            "getfem_options": {"r0": args.r0, "option": args.option, "lsolver": args.lsolver,
                               "max_res": args.max_res, "multiplier": args.multiplier},
        }
        write_results(rows, meta, args.output)
    print(f"wrote {args.output / 'peers.csv'} and {args.output / 'peers.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
