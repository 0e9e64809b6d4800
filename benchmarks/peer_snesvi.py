"""Example 5.1 as a FEniCSx user would write it with PETSc's SNES VI: the peer of ``peers.py``.

Displacement only, vector P1 on the fine mesh T_h (the same mesh as ours: T_H refined once by
``dolfinx.mesh.refine``), plane strain, clamped on x = -3 (``dirichletbc``, applied
symmetrically), the body force of example 5.1 from its UFL expression, and the contact condition
u_1 <= g(y) as an upper bound on the x-component at every fine contact vertex (node-wise, the
classical obstacle-type discretisation; no multiplier, no estimate). The problem is linear with
bounds, so the residual is ``F(u) = K u - f`` with K and f assembled once (set-up), and the
Jacobian is K; PETSc's reduced-space active-set Newton method (``vinewtonrsls``) solves it,
each step factoring the reduced matrix on the inactive set by MUMPS (``cholesky``, LDL^T of the
symmetric K; ``--snes-pc lu`` for LU), ordered by approximate minimum fill (ICNTL(7)=2, the
fastest ordering on these 2D matrices, ``benchmarks/mumps_ordering.py``; ``--snes-ordering 7``
for MUMPS's default).

Run through ``benchmarks/peers.py`` (``--peers snesvi``), serial or under ``mpirun -n 2``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc

__all__ = ["SnesOptions", "solve_snesvi"]


@dataclass
class SnesOptions:
    """The configuration of the SNES VI peer.

    Attributes:
        pc: ``"cholesky"`` (MUMPS LDL^T) or ``"lu"`` (MUMPS LU) of the reduced matrix.
        dirichlet: ``"bc"`` (rows and columns of K eliminated, ``dirichletbc``) or ``"bounds"``
            (the clamped dofs as equal lower and upper bounds, removed by the VI solver).
        rtol: ``snes_rtol`` (the Newton residual relative to the initial one).
        atol: ``snes_atol``.
        linesearch: ``snes_linesearch_type`` (``"basic"``: full steps; ``"bt"``: PETSc's
            default backtracking, which evaluates the residual more often).
        ordering: MUMPS's ICNTL(7) (2: AMF; 0: AMD; 5: METIS; 7: MUMPS's choice).
    """

    pc: str = "cholesky"
    dirichlet: str = "bc"
    rtol: float = 1e-10
    atol: float = 1e-12
    linesearch: str = "basic"
    ordering: int = 2


def _plane_strain_stress(u: Any, E: float, nu: float) -> Any:
    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    eps = ufl.sym(ufl.grad(u))
    return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)


def solve_snesvi(fine: mesh.Mesh, opts: SnesOptions) -> dict[str, Any]:
    """Set up and solve example 5.1 by SNES VI on ``fine``; time both parts separately.

    Args:
        fine: The fine mesh T_h (triangles of (-3, 0) x (-1, 1)).
        opts: The configuration.

    Returns:
        ``t_setup`` (spaces, assembly of K and f, bounds, SNES), ``t_solve`` (``SNES.solve``),
        ``newton`` (SNES iterations), ``ksp_its`` (linear solves), ``reason`` (converged
        reason), ``dofs`` (global), and the displacement at the local vertices, ``U``
        (indexed by the geometry's nodes, as ``fine.geometry.x``).
    """
    from dwr_signorini import examples as ex

    comm = fine.comm
    mat = ex.ANALYTIC_MATERIAL
    comm.barrier()
    tic = time.perf_counter()
    V = fem.functionspace(fine, ("Lagrange", 1, (2,)))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    x = ufl.SpatialCoordinate(fine)
    f = ex.analytic_body_force(x, mat.E, mat.nu)
    a = fem.form(ufl.inner(_plane_strain_stress(u, mat.E, mat.nu), ufl.sym(ufl.grad(v))) * ufl.dx)
    L = fem.form(ufl.inner(f, v) * ufl.dx)
    fdim = fine.topology.dim - 1
    fine.topology.create_connectivity(fdim, fdim + 1)
    clamped = mesh.locate_entities_boundary(fine, fdim, lambda p: np.isclose(p[0], -3.0))
    contact = mesh.locate_entities_boundary(fine, fdim, lambda p: np.isclose(p[0], 0.0))
    clamped_dofs = fem.locate_dofs_topological(V, fdim, clamped)
    bcs = [fem.dirichletbc(np.zeros(2), clamped_dofs, V)] if opts.dirichlet == "bc" else []
    K = fem_petsc.assemble_matrix(a, bcs=bcs)
    K.assemble()
    K.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    b = fem_petsc.assemble_vector(L)
    fem_petsc.apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem_petsc.set_bc(b, bcs)

    # Bounds: u_1 <= g(y) at the contact vertices (the dofs of V.sub(0) there), else free.
    V0, _ = V.sub(0).collapse()
    contact_x = fem.locate_dofs_topological((V.sub(0), V0), fdim, contact)[0]
    y = V.tabulate_dof_coordinates()[:, 1]
    bs = V.dofmap.index_map_bs
    n_owned = V.dofmap.index_map.size_local * bs
    g = np.where(np.abs(y) < 0.5, -9.0 * (y**2 - 0.25) ** 4, 0.0)
    upper = fem.Function(V)
    lower = fem.Function(V)
    upper.x.array[:] = PETSc.INFINITY
    lower.x.array[:] = PETSc.NINFINITY
    upper.x.array[contact_x] = g[contact_x // bs]
    if opts.dirichlet == "bounds":
        dofs = np.concatenate([bs * clamped_dofs + k for k in range(bs)])  # unrolled
        upper.x.array[dofs] = 0.0
        lower.x.array[dofs] = 0.0

    sol = fem.Function(V)
    residual = b.duplicate()

    def F(_snes: PETSc.SNES, xvec: PETSc.Vec, rvec: PETSc.Vec) -> None:
        K.mult(xvec, rvec)
        rvec.axpy(-1.0, b)

    def J(_snes: PETSc.SNES, _x: PETSc.Vec, _A: PETSc.Mat, _P: PETSc.Mat) -> None:
        return None  # K is constant: assembled once

    snes = PETSc.SNES().create(comm)
    snes.setType("vinewtonrsls")
    snes.setFunction(F, residual)
    snes.setJacobian(J, K, K)
    snes.setVariableBounds(lower.x.petsc_vec, upper.x.petsc_vec)
    snes.setTolerances(rtol=opts.rtol, atol=opts.atol, max_it=50)
    snes.setOptionsPrefix("peer_snesvi_")
    options = PETSc.Options()
    options["peer_snesvi_snes_linesearch_type"] = opts.linesearch
    # Read when MUMPS factors (in SNES.solve): kept in the database until the solve is done.
    options["peer_snesvi_mat_mumps_icntl_7"] = opts.ordering
    ksp = snes.getKSP()
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType(opts.pc)
    pc.setFactorSolverType("mumps")
    snes.setFromOptions()
    del options["peer_snesvi_snes_linesearch_type"]
    comm.barrier()
    t_setup = time.perf_counter() - tic

    tic = time.perf_counter()
    snes.solve(None, sol.x.petsc_vec)
    comm.barrier()
    t_solve = time.perf_counter() - tic
    del options["peer_snesvi_mat_mumps_icntl_7"]
    sol.x.scatter_forward()

    # Displacement at the geometry nodes (P1 on a P1 mesh: the dofs sit at the vertices).
    from dwr_signorini import compat

    gdm = compat.geometry_dofmap(fine)
    U = np.zeros((fine.geometry.x.shape[0], 2))
    U[gdm] = sol.x.array.reshape(-1, 2)[V.dofmap.list]
    out = {
        "t_setup": t_setup,
        "t_solve": t_solve,
        "newton": int(snes.getIterationNumber()),
        "ksp_its": int(snes.getLinearSolveIterations()),
        "reason": int(snes.getConvergedReason()),
        "dofs": int(V.dofmap.index_map.size_global * bs),
        "U": U,
        "num_owned": n_owned,
    }
    for obj in (snes, K, b, residual):
        obj.destroy()
    return out
