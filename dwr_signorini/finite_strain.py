"""Finite strain: a hyperelastic body on a rigid obstacle, contact in the deformed configuration.

With a hyperelastic law (:mod:`dwr_signorini.materials`) the problem is: find u in V_h (the
prescribed values t u_D on Gamma_D at the load factor t) and lambda in Lambda_H (P0 on the macro
facets of Gamma_C, a force per *reference* area) with

    R(u, lam)[v] = int_Omega P(F(u)) : grad v dx - t l(v) - sum_i lam_i G_i'(u)[v] = 0,
    C_i(u, lam) = M_i lam_i - max(0, M_i lam_i - c_i G_i(u)) = 0,

where F = I + grad u, P = dpsi/dF, G_i(u) = int_{E_i} d(x + u(x)) ds the gap of macro facet E_i:
the signed distance d of the deformed point x + u(x) to the obstacle (positive outside), M_i =
|E_i| and c_i = E / H_i (``ncp_scale="physical"``) or a number. G_i'(u)[v] = int grad d(x + u) . v
is the force along the obstacle's normal at the nearest point. This is the Lagrangian
Pi(u) - sum_i lam_i G_i(u) with lam >= 0, G >= 0, lam G = 0.

The semi-smooth Newton step at (u, lam) with the active set A = {i : M_i lam_i - c_i G_i > 0}
solves, with the Jacobian reassembled (UFL derivatives, the second derivative of d included),

    [ dR/du         -B^T  ] [du  ]   [ -R                ]
    [ -D_A B       D_I M  ] [dlam] = [ D_A G - D_I M lam ],   B_ij = G_i'(u)[phi_j],

i.e. the linearised gap closes on A and lam = 0 off it. The distances are exact for
:class:`~dwr_signorini.obstacles.Plane`, :class:`~dwr_signorini.obstacles.Sphere` (a disc
in 2D) and :class:`~dwr_signorini.obstacles.Cylinder`; other gaps are refused. The goal's
error estimate (the dual problem, eta_p, eta and the interval) is in
:mod:`~dwr_signorini.finite_strain_estimate`; :func:`~dwr_signorini.solve_adaptive` refines
with it, each level solved at the full load from the previous level's solution. Not covered
yet (refused with a ValueError): friction, contact pairs, force control, plane stress.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from dolfinx.mesh import CellType

from . import compat
from .collective import log_on_root
from .lifetime import Releasable, destroy_attributes
from .obstacles import Cylinder, Obstacle, Plane, Sphere
from .quadrature import with_quadrature_degrees
from .semismooth import ConvergenceError

__all__ = [
    "FiniteStrainSolution",
    "check_obstacle",
    "check_options",
    "refuse",
    "signed_distance",
    "solution_from",
    "solve",
]

logger = logging.getLogger("dwr_signorini.newton")



def check_obstacle(gap: Any) -> Obstacle:
    """The rigid obstacle of a finite-strain problem's ``gap`` (Plane, Sphere or Cylinder).

    Raises:
        ValueError: Any other gap (a number, a callable, a gap per tag, another obstacle).
    """
    if isinstance(gap, (Plane, Sphere, Cylinder)) and gap.force is None:
        return gap
    raise ValueError(
        "a finite-strain material needs gap=ds.obstacles.Plane(...), Sphere(...) or Cylinder(...) "
        "(the signed distance of the deformed boundary to a rigid obstacle), got "
        f"{gap!r}; numbers, callables, gaps per tag, Graph obstacles and obstacles under a given "
        "force are not "
        "covered at finite strain yet"
    )


def signed_distance(obstacle: Obstacle, y: Any) -> Any:
    """The signed distance of the point ``y`` to the obstacle, positive outside, as UFL.

    Plane ``{(y - p) . n >= 0}``: d = (p - y) . n. Sphere (disc) of center c, radius r:
    d = |y - c| - r. Cylinder of axis point p, unit axis a, radius r: d = |w - (w . a) a| - r,
    w = y - p.
    """
    if isinstance(obstacle, Plane):
        p = ufl.as_vector([float(c) for c in obstacle.point])
        return ufl.dot(p - y, ufl.as_vector([float(c) for c in obstacle.normal]))
    if isinstance(obstacle, Cylinder):
        a = ufl.as_vector([float(v) for v in obstacle.axis])
        w = y - ufl.as_vector([float(v) for v in obstacle.point])
        r = w - ufl.dot(w, a) * a
        return ufl.sqrt(ufl.dot(r, r)) - float(obstacle.radius)
    c = ufl.as_vector([float(v) for v in obstacle.center])
    return ufl.sqrt(ufl.dot(y - c, y - c)) - float(obstacle.radius)


def cell_degree(disc: Any) -> int:
    """The quadrature degree of the Newton system's cell integrals.

    P1 on simplices: P(F) is constant per cell for constant E, nu (degree 2 is exact); E or nu
    functions of x, or other cells, get the problem's data degree.
    """
    problem = disc.problem
    simplex = disc.mesh.topology.cell_type in (CellType.triangle, CellType.tetrahedron)
    varying = callable(problem.E) or callable(problem.nu)
    return problem.quadrature_degree if varying or not simplex else 2


def residual_forms(disc: Any, u: Any, lam: Any, t: Any, v: Any, dx: ufl.Measure,
                   dsc: ufl.Measure) -> tuple[ufl.Form, ufl.Form, ufl.Form, Any]:
    """The parts of R(u, lam)[v] (module docstring) and the distance d(x + u), as UFL.

    A pure function of its arguments, so that the Newton system, the dual problem and the
    estimator (:mod:`~dwr_signorini.finite_strain_estimate`) share one residual.

    Args:
        disc: The discretisation (material data, loads, measures).
        u: The displacement (a function on T_h).
        lam: The multiplier (a function on Lambda_H).
        t: The load factor (a Constant or a number).
        v: The displacement's test function or weight.
        dx: The cell measure (with its quadrature degree).
        dsc: The measure of Gamma_C (with its quadrature degree).

    Returns:
        ``(int P(F) : grad v dx, t l(v), -lam d'(x + u)[v] ds, d(x + u))``.
    """
    problem = disc.problem
    P = disc.fields.first_piola(u)  # the goals' m.P(u)
    d = signed_distance(check_obstacle(problem.gap), disc.m.x + u)
    internal = ufl.inner(P, ufl.grad(v)) * dx
    load = t * with_quadrature_degrees(disc.load_form(v), problem.quadrature_degree)
    contact = -ufl.derivative(lam * d * dsc, u, v)
    return internal, load, contact, d


class FiniteStrainSystem:
    """The forms of the finite-strain Newton step on a discretisation (module docstring)."""

    algebra = None  # the linear path's ContactAlgebra: none here

    def __init__(self, disc: Any, ncp_scale: str | float = "physical") -> None:
        self.disc = disc
        problem = disc.problem
        self.obstacle = check_obstacle(problem.gap)
        V, Q, m = disc.V, disc.Q, disc.m
        self.u = fem.Function(V, name="u")
        self.lam = fem.Function(Q, name="lambda")
        self.t = fem.Constant(disc.mesh, 1.0)
        v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
        mu_q = ufl.TestFunction(Q)
        E, _ = disc.fields.material(m.x)
        dx = m.dx(metadata={"quadrature_degree": cell_degree(disc)})
        dsc = m.ds_contact(metadata={"quadrature_degree": problem.quadrature_degree})
        gdim = disc.mesh.geometry.dim
        self._J_cells = fem.Function(fem.functionspace(disc.mesh, ("DG", 0)))
        self._J_expr = fem.Expression(
            ufl.det(ufl.Identity(gdim) + ufl.grad(self.u)),
            compat.interpolation_points(self._J_cells.function_space.element),
        )
        internal, load, contact, d = residual_forms(disc, self.u, self.lam, self.t, v, dx, dsc)
        residual = internal - load + contact
        gap = d * mu_q * dsc
        coupling = ufl.derivative(gap, self.u, du)
        self.forms = {
            name: disc.form(f) for name, f in {
                "internal": internal, "load": load, "contact": contact,
                "J": ufl.derivative(residual, self.u, du),
                "B": coupling, "BT": -ufl.adjoint(coupling), "G": gap,
                "M": mu_q * m.ds_contact, "E": E * mu_q * m.ds_contact,
            }.items()
        }
        self.n_u = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.n_q = Q.dofmap.index_map.size_local
        self.M = self._owned("M")
        E_M = self._owned("E")
        size = self.M if gdim == 2 else np.sqrt(self.M)
        if ncp_scale == "physical":
            self.c = np.divide(E_M, self.M * size, out=np.ones_like(self.M),
                               where=self.M > 0)
        else:
            self.c = np.full(self.n_q, float(ncp_scale))
        self.u_D = np.zeros_like(self.u.x.array)
        for bc in disc.prescribed_bcs:
            bc.set(self.u_D)
        #: The owned dofs on Gamma_D (a blocked condition's dof_indices() may count ghost
        #: dofs among its owned ones: filtered by index).
        self.owned_bc_dofs = np.unique(np.concatenate(
            [bc.dof_indices()[0] for bc in disc.bcs] + [np.zeros(0, np.int32)]))
        self.owned_bc_dofs = self.owned_bc_dofs[self.owned_bc_dofs < self.n_u]
        #: The prescribed values at t = 0 (zero, or those of a path's initial state).
        self.u_D0 = np.zeros_like(self.u_D)
        # MUMPS's default ordering (METIS), not the linear path's AMF in 2D: the analysis is
        # done once per system, and the numeric LU after METIS's ordering is the faster one
        # (docs/benchmarks/performance.md, "Finite strain: one Newton step").
        self.ksp = PETSc.KSP().create(disc.comm)
        self.ksp.setType("preonly")
        self.ksp.getPC().setType("lu")
        self.ksp.getPC().setFactorSolverType("mumps")
        #: The assembled matrices, kept with their patterns: (form name, with bcs) -> Mat.
        self._mats: dict[tuple[str, bool], PETSc.Mat] = {}
        self._D: PETSc.Mat | None = None
        self._nest: PETSc.Mat | None = None
        self._J: PETSc.Mat | None = None
        #: The active set of the last converged Newton solve (owned rows, :func:`newton`).
        self.active = np.zeros(self.n_q, dtype=bool)

    def destroy(self) -> None:
        """Release the PETSc objects (collective; idempotent)."""
        destroy_attributes(self, ("ksp", "_J", "_nest", "_D"))
        for mat in getattr(self, "_mats", {}).values():
            mat.destroy()
        self._mats = {}

    def _owned(self, name: str) -> np.ndarray:
        """The owned entries of the assembled vector of form ``name``."""
        vec = fem_petsc.assemble_vector(self.forms[name])
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out = vec.array_r[: len(vec.array_r)].copy()
        vec.destroy()
        return out

    def set_load(self, t: float) -> None:
        """The load factor t: loads t l, prescribed values u_D0 + t (u_D - u_D0).

        They are reached by the next step; u_D0 is zero unless the path starts from a state
        (:func:`~dwr_signorini.finite_strain_path.solve_path`).
        """
        self.t.value = t
        self.target = self.u_D0 + t * (self.u_D - self.u_D0)

    def increment(self) -> np.ndarray:
        """The owned displacement increment the prescribed values ask for (0 off Gamma_D)."""
        w = np.zeros(self.n_u)
        dofs = self.owned_bc_dofs
        w[dofs] = self.target[dofs] - self.u.x.array[dofs]
        return w

    def update(self, du: np.ndarray, dlam: np.ndarray) -> None:
        """(u, lam) += (du, dlam); the prescribed values exactly as set (no round-off)."""
        self.u.x.array[: self.n_u] += du
        self.lam.x.array[: self.n_q] += dlam
        for bc in self.disc.bcs:
            dofs = bc.dof_indices()[0]
            self.u.x.array[dofs] = self.target[dofs]
        self.u.x.scatter_forward()
        self.lam.x.scatter_forward()

    def min_det_F(self) -> float:
        """The smallest det F over the cells' midpoints, on all ranks (collective)."""
        self._J_cells.interpolate(self._J_expr)
        n = self._J_cells.function_space.dofmap.index_map.size_local
        local = float(np.min(self._J_cells.x.array[:n], initial=np.inf))
        return self.disc.comm.allreduce(local, op=MPI.MIN)

    def residuals(self) -> tuple[np.ndarray, np.ndarray, float]:
        """R (owned, zero on the Dirichlet rows), G (owned) and the size of R's terms."""
        parts = [self._owned(k) for k in ("internal", "load", "contact")]
        R = parts[0] - parts[1] + parts[2]
        R[self.owned_bc_dofs] = 0.0
        comm = self.disc.comm
        scale = max(np.sqrt(comm.allreduce(float(p @ p), op=MPI.SUM)) for p in parts)
        return R, self._owned("G"), max(scale, 1e-300)

    def ncp(self, G: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The set test, the NCP and its size per owned row at (u, lam), G = G(u) given.

        C_i = M_i lam_i - max(0, M_i lam_i - c_i G_i) (module docstring); row i is active where
        M_i lam_i - c_i G_i exceeds the round-off of its terms.

        Returns:
            ``(active, C, size)``: the mask, C and max(|M lam|, |c G|) + the round-off.
        """
        comm = self.disc.comm
        Mlam = self.M * self.lam.x.array[: self.n_q]
        cG = self.c * G
        u_max = comm.allreduce(float(np.max(np.abs(self.u.x.array), initial=0.0)), op=MPI.MAX)
        noise = 1e-10 * (comm.allreduce(float(np.max(np.abs(Mlam), initial=0.0)), op=MPI.MAX)
                         + self.c * self.M * u_max)
        C = Mlam - np.maximum(0.0, Mlam - cG)
        return Mlam - cG > noise, C, np.maximum(np.abs(Mlam), np.abs(cG)) + noise

    def step(self, active: np.ndarray, R: np.ndarray, G: np.ndarray, assemble: bool = True
             ) -> tuple[np.ndarray, ...]:
        """The Newton update (du, dlam) of the set ``active`` (owned rows), module docstring.

        The step also moves the prescribed dofs to their values (the increment w on Gamma_D,
        lifted: J w and B w enter the right-hand side), so that a load step does not distort
        the cells at Gamma_D before the first solve. ``assemble=False`` solves with the Newton
        matrix and factors in the KSP (those of ``active`` at the current state, assembled by
        :meth:`newton_matrix` before, e.g. for a dual solve).
        """
        comm = self.disc.comm
        w = self.increment()
        rhs_u, rhs_lam = -R, np.where(active, G, -self.M * self.lam.x.array[: self.n_q])
        if comm.allreduce(bool(np.any(w != 0.0)), op=MPI.LOR):
            lift_u, lift_lam = self._lifting(w)
            rhs_u = rhs_u - lift_u
            rhs_lam = np.where(active, rhs_lam + lift_lam, rhs_lam)
            on_bc = w != 0.0
            on_bc[self.owned_bc_dofs] = True
            rhs_u[on_bc] = w[on_bc]
        if assemble:
            self.newton_matrix(active)
        rhs = self._J.createVecLeft()
        rhs.array_w[:] = np.concatenate([rhs_u, rhs_lam])
        x = rhs.duplicate()
        self.ksp.solve(rhs, x)
        out = x.array_r.copy()
        for obj in (rhs, x):
            obj.destroy()
        return out[: self.n_u], out[self.n_u:]

    def newton_matrix(self, active: np.ndarray) -> PETSc.Mat:
        """Assemble the Newton matrix of the set ``active`` at (u, lam) into the system's KSP.

        The saddle matrix of the module docstring, kept (``_J``) with the KSP that factors it
        at its next solve; the dual problem solves with its transpose. Its blocks and the
        saddle matrix are created in the first call and refilled in later ones, the set's
        zeros kept as entries: the pattern stays, so MUMPS's analysis (ordering, symbolic
        factorisation) is done once and later steps factor numerically only.
        """
        J, B, BT = (self._assembled(k) for k in ("J", "B", "BT"))
        scale = B.createVecLeft()
        scale.array_w[:] = -active.astype(float)
        B.diagonalScale(L=scale)
        scale.array_w[:] = np.where(active, 0.0, self.M)
        D = self._diagonal(scale)
        scale.destroy()
        if self._nest is None:
            self._nest = PETSc.Mat().createNest([[J, BT], [B, D]], comm=self.disc.comm)
            self._J = PETSc.Mat()
            self._nest.convert("aij", out=self._J)
            self.ksp.setOperators(self._J)
        else:
            self._nest.assemble()
            self._nest.convert("aij", out=self._J)  # the values into the kept pattern
        return self._J

    def _diagonal(self, values: PETSc.Vec) -> PETSc.Mat:
        """The kept diagonal block, set to ``values`` (zeros stay entries)."""
        if self._D is None:
            n = self.n_q
            self._D = PETSc.Mat().createAIJ(((n, None), (n, None)), nnz=1, comm=self.disc.comm)
        self._D.setDiagonal(values)
        self._D.assemble()
        return self._D

    def _assembled(self, name: str, bcs: bool = True) -> PETSc.Mat:
        """The matrix of form ``name`` at (u, lam), assembled into its kept Mat."""
        key = (name, bcs)
        if key not in self._mats:
            self._mats[key] = fem_petsc.create_matrix(self.forms[name])
        A = self._mats[key]
        A.zeroEntries()
        fem_petsc.assemble_matrix(A, self.forms[name], bcs=self.disc.bcs if bcs else [])
        A.assemble()
        return A

    def _lifting(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """J w and B w (owned rows) of the increment ``w`` on Gamma_D."""
        J, B = self._assembled("J", bcs=False), self._assembled("B", bcs=False)
        wv = J.createVecRight()
        wv.array_w[:] = w
        Jw, Bw = J.createVecLeft(), B.createVecLeft()
        J.mult(wv, Jw)
        B.mult(wv, Bw)
        out = Jw.array_r.copy(), Bw.array_r.copy()
        for obj in (wv, Jw, Bw):
            obj.destroy()
        return out


@dataclass
class FiniteStrainSolution(Releasable):
    """A finite-strain solution (the fields of :class:`~dwr_signorini.Solution` it has).

    Attributes:
        u: Displacement on V_h.
        lam: Normal contact force per reference area on Lambda_H.
        active: The active set the Newton method converged with (owned multiplier rows).
        newton_iterations: Newton steps of the last solve.
        history: One record per iteration (residuals, active-set size and changes).
        disc: The discretisation.
        system: The :class:`FiniteStrainSystem` (release with :meth:`destroy`).
        load_factor: The load factor t of the state.
        owns_disc: Whether :meth:`destroy` releases the discretisation too (a level of
            :func:`~dwr_signorini.solve_adaptive`).
    """

    u: fem.Function
    lam: fem.Function
    active: np.ndarray
    newton_iterations: int
    history: list[dict[str, Any]]
    disc: Any
    system: FiniteStrainSystem = field(repr=False)
    load_factor: float = 1.0
    owns_disc: bool = False

    #: As :class:`~dwr_signorini.Solution`'s: frictionless, no obstacle under a given force,
    #: the saddle matrix factored whole in every step.
    method = "block"
    obstacle_displacement = num_stick = num_slip = None

    @property
    def multipliers(self) -> tuple[fem.Function]:
        """The contact law's multipliers: (lam,) (frictionless)."""
        return (self.lam,)

    @property
    def num_active(self) -> int:
        """Global number of active macro contact facets (collective)."""
        return self.disc.comm.allreduce(int(self.active.sum()), op=MPI.SUM)

    def destroy(self) -> None:
        """Release the Newton system and, if owned, the discretisation (collective)."""
        self.system.destroy()
        if self.owns_disc:
            self.disc.destroy()


def newton(system: FiniteStrainSystem, t: float, max_iterations: int, rtol: float
           ) -> list[dict[str, Any]]:
    """Semi-smooth Newton at load factor ``t`` from the system's current (u, lam).

    Converged when the active set repeats and both residuals (equilibrium relative to its
    terms, the NCP relative to M lam and c G per row) are below ``rtol``; the equilibrium one
    also where the last update was at the round-off of (u, lam) (:func:`_at_roundoff`): a
    stress-free state (a body moved rigidly, not touching) has terms of round-off size only.

    Raises:
        ConvergenceError: No convergence in ``max_iterations`` steps, NaN/Inf, or a set cycle.
    """
    comm = system.disc.comm
    system.set_load(t)
    history: list[dict[str, Any]] = []
    previous, seen, stagnant = None, set(), False
    for it in range(max_iterations + 1):
        R, G, scale = system.residuals()
        active, ncp, size = system.ncp(G)
        ncp = np.abs(ncp)
        record = {
            "iteration": it,
            "num_active": comm.allreduce(int(active.sum()), op=MPI.SUM),
            "num_changed": comm.allreduce(
                int(active.size if previous is None else (active != previous).sum()), op=MPI.SUM),
            "residual_equilibrium": np.sqrt(comm.allreduce(float(R @ R), op=MPI.SUM)) / scale,
            "residual_ncp": comm.allreduce(float(np.max(
                np.divide(ncp, size, out=np.zeros_like(ncp), where=size > 0), initial=0.0)),
                op=MPI.MAX),
        }
        history.append(record)
        log_on_root(comm, logger, logging.INFO,
                    "finite strain t=%g Newton %d: |A| = %d, changed %d, residuals %.2e / %.2e",
                    t, it, record["num_active"], record["num_changed"],
                    record["residual_equilibrium"], record["residual_ncp"])
        if not all(np.isfinite([record["residual_equilibrium"], record["residual_ncp"]])):
            raise ConvergenceError(f"NaN or Inf at Newton step {it} (J = det F <= 0?)", history)
        settled = not comm.allreduce(bool(np.any(system.increment() != 0.0)), op=MPI.LOR)
        equilibrium = record["residual_equilibrium"] <= rtol or stagnant
        ncp_met = record["residual_ncp"] <= rtol
        if settled and record["num_changed"] == 0 and equilibrium and ncp_met:
            if system.min_det_F() <= 0.0:  # an inverted cell: no physical state
                raise ConvergenceError(
                    f"finite strain: Newton converged to a state with det F <= 0 in a cell at "
                    f"load factor {t:g} (an inverted configuration; smaller load steps)", history)
            system.active = active
            return history
        if it == max_iterations:
            raise ConvergenceError(
                f"finite strain: no convergence in max_iterations={max_iterations} Newton steps "
                "(ds.solve_path with smaller load steps)", history)
        key = tuple(comm.allgather(bytes(np.packbits(active))))  # the global set
        if record["num_changed"] > 0 and key in seen:
            raise ConvergenceError(f"finite strain: active-set cycling at step {it}", history)
        seen.add(key)
        du, dlam = system.step(active, R, G)
        if not comm.allreduce(bool(np.all(np.isfinite(du)) and np.all(np.isfinite(dlam))),
                              op=MPI.LAND):
            raise ConvergenceError(f"NaN or Inf in the Newton update of step {it}", history)
        stagnant = _at_roundoff(system, du, dlam)
        system.update(du, dlam)
        previous = active
    raise AssertionError("unreachable")


def _at_roundoff(system: FiniteStrainSystem, du: np.ndarray, dlam: np.ndarray) -> bool:
    """Whether the update (du, dlam) is within 1000 eps of the state (u, lam), on all ranks."""
    tol = 1e3 * np.finfo(float).eps
    pairs = ((du, system.u.x.array), (dlam, system.lam.x.array))
    local = np.array([np.max(np.abs(a), initial=0.0) for pair in pairs for a in pair])
    out = np.empty_like(local)
    system.disc.comm.Allreduce(local, out, op=MPI.MAX)
    d_u, u, d_lam, lam = out
    return bool(d_u <= tol * u and d_lam <= tol * lam)


def check_options(options: Any) -> Any:
    """``options`` of :func:`~dwr_signorini.solve` that the finite-strain Newton method takes.

    It factors its Jacobian with MUMPS in every step: ``petsc_options``, ``method`` and the
    form compiler options are refused rather than ignored.

    Raises:
        ValueError: Any of these given.
    """
    given = [k for k in ("petsc_options", "method", "form_compiler_options", "jit_options")
             if getattr(options, k) is not None]
    if given:
        raise ValueError(
            f"{', '.join(given)}: not taken by the finite-strain Newton method yet (its "
            "Jacobian is factored with MUMPS in every step); leave them unset"
        )
    return options


def refuse(what: str, reason: str = "") -> None:
    """Raise the error of a function that does not take finite-strain problems yet.

    Args:
        what: The function (or combination) refused.
        reason: Why; default: a goal along a load path is missing.

    Raises:
        ValueError: Always, naming ``what``.
    """
    reason = reason or (
        "a goal along a load path is not implemented at finite strain; estimate a state of "
        "ds.solve_path(problem, None, load_factors=...) with ds.estimate(sol, goal), or refine "
        "for the full load with ds.solve_adaptive"
    )
    raise ValueError(
        f"{what} does not take a finite-strain problem (material=NeoHookean/"
        f"SaintVenantKirchhoff/Hyperelastic) yet: {reason}"
    )


def solve(disc: Any, options: Any, initial_guess: Any = None) -> FiniteStrainSolution:
    """:func:`dwr_signorini.solve` for a finite-strain problem (the full load in one step).

    Raises:
        ConvergenceError: As :func:`newton`; from an ``initial_guess`` (a level of
            :func:`~dwr_signorini.solve_adaptive` starts from the previous one's solution)
            the message says so: no other start is tried.
    """
    system = FiniteStrainSystem(disc, options.ncp_scale)
    try:
        if initial_guess is not None:
            system.u.x.array[:] = initial_guess[0].x.array
            system.lam.x.array[:] = initial_guess[1].x.array
        history = newton(system, 1.0, options.max_iterations, options.rtol)
    except ConvergenceError as error:
        system.destroy()
        if initial_guess is None:
            raise
        raise ConvergenceError(
            "from the initial guess (in solve_adaptive: the previous level's solution on this "
            f"level's mesh): {str(error).splitlines()[0]}", error.history) from error
    except BaseException:
        system.destroy()
        raise
    return solution_from(system, history, 1.0)


def solution_from(system: FiniteStrainSystem, history: list[dict[str, Any]], t: float
                  ) -> FiniteStrainSolution:
    """The system's converged state at load factor ``t`` as a :class:`FiniteStrainSolution`."""
    u = fem.Function(system.disc.V, name="u")
    lam = fem.Function(system.disc.Q, name="lambda")
    u.x.array[:] = system.u.x.array
    lam.x.array[:] = system.lam.x.array
    active = system.active.copy()  # not lam > 0: round-off of lam off the set decides nothing
    return FiniteStrainSolution(u, lam, active, len(history) - 1, history, system.disc,
                                system, t)
