"""Example 5.1 by GetFEM on our fine mesh T_h: the GetFEM peer of ``peers.py`` (child process).

``peers.py`` runs this module as a child process that imports getfem and not dolfinx (both link
a MUMPS, GetFEM the sequential one): it loads the mesh, the load and the configuration from an
``.npz`` file and writes its solution and times to another.

The model (``gf.Model``): u in vector P1 on T_h (``add_isotropic_linearized_elasticity_pstrain_
brick``), plane strain, clamped on x = -3, the body force of example 5.1, frictionless contact
with a rigid obstacle through the integral contact brick
(``add_integral_contact_with_rigid_obstacle_brick``, option 1: non-symmetric Alart-Curnier)
with a multiplier in continuous P1 on the macro contact vertices (every second fine one, H = 2h),
solved by ``Model.solve`` (Newton, sequential MUMPS). The configuration (:data:`FASTEST` is the
default; the others are kept for reference):

* ``r``: the augmentation parameter, ``"E"`` (r = r0 E) or ``"E/h"`` (r = r0 E / h, with which
  the Alart-Curnier Newton matrix is badly scaled);
* ``load``: ``"imdata"``, the body force given once as data at the quadrature points of the
  load's integration method (``MeshImData``, values from our UFL expression), or ``"p2"``, the
  body force interpolated in P2 and a source term brick (assembled by the generic assembly in
  every Newton step);
* ``obstacle``: ``"levelset"``, the steep level set d(x, y) = g(y) - K x (K = ``slope``) on a
  P2 field (normal (1, 0) up to 1/K, gap g(y) on x = 0), or ``"shift"``, the obstacle d = -x for
  w = u - u_g with u_g = (g(y), 0) at the contact vertices (an extra volume source term);
* ``dirichlet``: ``"simplification"`` (``add_Dirichlet_condition_with_simplification``) or
  ``"multipliers"`` (``add_Dirichlet_condition_with_multipliers``, a P1 multiplier);
* ``max_res``, ``lsolver`` (``"mumps"``; Debian's build has no SuperLU interface),
  ``lsearch`` (``"default"``, ``"simplest"``), ``option`` (1-3), ``multiplier``
  (``"coarse"``: H = 2h, or ``"fine"``: all fine contact vertices, which violates the inf-sup
  condition).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

#: The fastest configuration found that reaches the accuracy of ours (benchmarks/README.md).
FASTEST = {
    "r": "E",
    "r0": 1.0,
    "load": "imdata",
    "load_rule": "IM_TRIANGLE(3)",
    "obstacle": "levelset",
    "slope": 1.0e8,
    "dirichlet": "simplification",
    "max_res": 1e-7,
    "lsolver": "mumps",
    "lsearch": "default",
    "option": 1,
    "multiplier": "coarse",
}


def peak_rss_gib() -> float:
    """Peak resident memory of this process (VmHWM) in GiB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 2**20
    return float("nan")


def rule_points(name: str) -> np.ndarray:
    """Reference points (2, q) of a GetFEM integration method on the triangle (volume only)."""
    import getfem as gf

    integ = gf.Integ(name)
    q = int(np.atleast_1d(integ.nbpts())[0])
    return np.asarray(integ.pts())[:, :q]


def _gap(y: np.ndarray) -> np.ndarray:
    return np.where(np.abs(y) < 0.5, -9.0 * (y**2 - 0.25) ** 4, 0.0)


def worker(inp: Path, out: Path) -> None:
    """Build and solve example 5.1 with GetFEM on the given triangles; write the solution."""
    import getfem as gf
    from scipy.spatial import cKDTree

    gf.util_trace_level(0)
    d = np.load(inp)
    cfg = json.loads(str(d["config"]))
    points, cells = d["points"], d["cells"]
    E, nu, h = float(d["E"]), float(d["nu"]), float(d["h"])
    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))  # plane strain
    r = cfg["r0"] * (E if cfg["r"] == "E" else E / h)
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
    mfl = gf.MeshFem(m, 1)
    mfl.set_classical_fem(1)
    ldof = mfl.basic_dof_on_region(GC)
    fine_dofs = ldof[np.argsort(mfl.basic_dof_nodes(ldof)[1])]  # sorted by y
    if cfg["multiplier"] == "coarse":
        # Continuous P1 on every second fine contact vertex (the macro vertices, H = 2h), by
        # reduction/extension matrices: a value in between is the mean of its neighbours'.
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
    mim_e = gf.MeshIm(m, gf.Integ("IM_TRIANGLE(1)"))  # exact for constant gradients
    # The composite rule of GetFEM's contact demo on Gamma_C (the integrand has kinks).
    mim_c = gf.MeshIm(m, gf.Integ("IM_STRUCTURED_COMPOSITE(IM_TRIANGLE(4),4)"))

    tree = cKDTree(points)
    dist, vert_u = tree.query(mfu.basic_dof_nodes().T)
    if dist.max() > 1e-12:
        raise RuntimeError("a P1 dof of GetFEM is not at a vertex")
    comp_u = np.zeros(len(vert_u), dtype=np.int64)
    comp_u[1::2] = 1
    if not np.array_equal(vert_u[0::2], vert_u[1::2]):
        raise RuntimeError("unexpected order of GetFEM's vector dofs")
    on_c = np.abs(points[:, 0]) < 1e-12
    UG = np.where(on_c[vert_u] & (comp_u == 0), _gap(points[vert_u, 1]), 0.0)

    if cfg["load"] == "imdata":
        mim_f = gf.MeshIm(m, gf.Integ(cfg["load_rule"]))
        nodes = mim_f.im_nodes()[:2]  # physical points, cell by cell
        if not np.allclose(nodes.T, d["f_points"].reshape(-1, 2), rtol=0.0, atol=1e-12):
            raise RuntimeError("GetFEM's quadrature points are not those of the given load")
        mimd = gf.MeshImData(mim_f, -1, [2])
        if mimd.nbpts() != nodes.shape[1]:
            raise RuntimeError("unexpected number of points of the load's data")
    else:
        mim_f = gf.MeshIm(m, gf.Integ("IM_TRIANGLE(3)"))  # exact for f_h . v (P2 x P1)
        dist, idx = cKDTree(d["f_nodes"]).query(mfd.basic_dof_nodes().T)
        if dist.max() > 1e-12:
            raise RuntimeError("a P2 node of GetFEM is not a P2 node of dolfinx")
        F = d["f_values"][idx]

    def build_model() -> Any:
        md = gf.Model("real")
        md.add_fem_variable("u", mfu)
        md.add_initialized_data("E", [E])
        md.add_initialized_data("nu", [nu])
        md.add_isotropic_linearized_elasticity_pstrain_brick(mim_e, "u", "E", "nu")
        if cfg["load"] == "imdata":
            md.add_im_data("f", mimd)
            md.set_variable("f", d["f_values_q"].ravel())
            md.add_source_term_brick(mim_f, "u", "f")
        else:
            md.add_initialized_fem_data("f1", mfd, F[:, 0].copy())
            md.add_initialized_fem_data("f2", mfd, F[:, 1].copy())
            md.add_source_term_brick(mim_f, "u", "[f1, f2]")
        if cfg["obstacle"] == "shift":
            md.add_initialized_data("clambda", [lmbda])
            md.add_initialized_data("cmu", [mu])
            md.add_initialized_fem_data("ug", mfu, UG)
            md.add_source_term(
                mim_e, "-(clambda*Div_ug*Div_Test_u + 2*cmu*Sym(Grad_ug):Grad_Test_u)"
            )
            md.add_initialized_fem_data("obstacle", mfl, -mfl.basic_dof_nodes()[0])  # d = -x
        else:
            xy = mfd.basic_dof_nodes()
            md.add_initialized_fem_data(
                "obstacle", mfd, _gap(xy[1]) - float(cfg["slope"]) * xy[0]
            )
        if cfg["dirichlet"] == "simplification":
            md.add_Dirichlet_condition_with_simplification("u", GD)
        else:
            md.add_Dirichlet_condition_with_multipliers(mim_e, "u", mfu, GD)
        md.add_fem_variable("lambda_n", mfl_c)
        md.add_initialized_data("r", [r])
        md.add_integral_contact_with_rigid_obstacle_brick(
            mim_c, "u", "lambda_n", "obstacle", "r", GC, int(cfg["option"])
        )
        return md

    # Each repeat solves a new model (nothing assembled before its solve); the set-up reported
    # is that of the first (mesh, spaces, integration methods, data, bricks).
    t_solves, t_builds = [], []
    t_setup = time.perf_counter() - tic
    for _ in range(int(d["repeat"])):
        tic = time.perf_counter()
        md = build_model()
        t_builds.append(time.perf_counter() - tic)
        tic = time.perf_counter()
        nit, converged = md.solve(
            "max_res", float(cfg["max_res"]), "max_iter", 100, "lsolver", cfg["lsolver"],
            "lsearch", cfg["lsearch"],
        )
        t_solves.append(time.perf_counter() - tic)

    U = np.zeros_like(points)
    U[vert_u, comp_u] = md.variable("u") + (UG if cfg["obstacle"] == "shift" else 0.0)
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
        t_setup=t_setup + t_builds[0],
        t_solve=min(t_solves),
        t_solves=np.array(t_solves),
        dofs=int(md.nbdof()),
        peak_rss_gib=peak_rss_gib(),
    )


if __name__ == "__main__":
    if sys.argv[1] == "--rule":
        print(json.dumps(rule_points(sys.argv[2]).tolist()))
    else:
        worker(Path(sys.argv[1]), Path(sys.argv[2]))
