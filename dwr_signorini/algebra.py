"""The algebra of one mesh (Section 4): K, N, N^T, M, f, g and c_n, assembled once.

K is the stiffness matrix of V_h, f the load vector, N_ij = int_GC psi_i (phi_j . n) the coupling
of the multipliers psi_i of Lambda_H to the normal displacement, M = diag(|E_i|) (the lumped
mass of the macro contact facets) and g_i = int_GC g psi_i. The discrete contact conditions (19)
are written with the NCP function (20),

    C_N(u, lam)_i = (M lam)_i - max(0, (M lam)_i + c_n,i (N u - g)_i) = 0,

whose active set (21) is A = {i : (M lam + c_n (N u - g))_i > 0}.

Choice of c_n (``ncp_scale``, one c for the Newton method, the dual problem and the estimator,
see :mod:`dwr_signorini.residuals`): ``"physical"`` (the default) is c_n,i = E / H_i with H_i
the size of macro contact facet i (length in 2D, square root of the area in 3D). (M lam)_i
scales like E u H^(d-2) and c_n (N u)_i like E u H^(d-2) too, so the active-set test, and the
estimator's contact terms, are invariant under scaling E, the loads and the lengths. A number c
gives c_n,i = c (the paper's c = 1, whose terms add a force per area to a length).

:class:`ContactAlgebra` assembles these pieces once per mesh (and per displacement space: the
higher-order solves assemble them in P2) and owns them; every linear solver of the Newton steps
(:mod:`dwr_signorini.linalg`) and the dual problem share them.
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .laws import Coupling
from .lifetime import destroy_attributes
from .quadrature import with_quadrature_degrees
from .spaces import Discretization
from .timing import timed

__all__ = [
    "NCP_SCALES",
    "ContactAlgebra",
    "check_ncp_scale",
    "distributed_norm",
]

#: The named choices of ``ncp_scale`` (besides a positive number).
NCP_SCALES = ("physical",)


def check_ncp_scale(ncp_scale: Any) -> str | float:
    """``ncp_scale`` validated: ``"physical"`` or a finite number > 0 (as a float).

    Raises:
        ValueError: Anything else, naming the argument.
    """
    if isinstance(ncp_scale, str) and ncp_scale in NCP_SCALES:
        return ncp_scale
    if (
        isinstance(ncp_scale, (int, float))
        and not isinstance(ncp_scale, bool)
        and 0 < ncp_scale < np.inf
    ):
        return float(ncp_scale)
    raise ValueError(
        f"ncp_scale must be 'physical' (c = E / H on each macro contact facet) or a finite "
        f"number c > 0 (e.g. 1.0, the paper's choice), got {ncp_scale!r}"
    )


def distributed_norm(comm: MPI.Comm, local: np.ndarray) -> float:
    """Euclidean norm of a distributed array given by its owned entries (collective)."""
    return float(np.sqrt(comm.allreduce(float(local @ local), op=MPI.SUM)))


class ContactAlgebra:
    """K, N, N^T, f, M, g and c_n of one discretisation, with the block layout [u; lam].

    Owns its PETSc objects; release them with :meth:`destroy` (collective).

    Args:
        disc: The discretisation.
        V: The displacement space (default ``disc.V``; the P2 space of the higher-order
            solves).
        ncp_scale: ``"physical"`` (c_n,i = E / H_i) or a number c (c_n,i = c).
        compile_options: ``form_compiler_options`` and ``jit_options`` of ``dolfinx.fem.form``
            (None values are left out).
        band: ``(band, data)``: K on a band of cells only, the displacement fixed to ``data``
            off its free nodes (:class:`~dwr_signorini.local_p2.ContactBand`, P2 weights near
            Gamma_C); None: the whole mesh.

    Attributes:
        disc, V: The discretisation and the displacement space.
        band: The :class:`~dwr_signorini.local_p2.ContactBand`, or None.
        stiffness_form: The compiled form of K (over the band where there is one).
        bcs: Homogeneous Dirichlet conditions on V (the rows and columns of K, N, N^T; the dual
            problem's right-hand side is zero on them).
        prescribed_bcs: The same conditions with their prescribed values u_D: f holds the
            lifting -K u_D on the free rows and u_D on the Dirichlet rows, g is g - N u_D.
        K, N, NT, f, M, g: The assembled pieces (PETSc Mat/Vec; M and g on the multiplier rows).
        c_n: c_n,i on the owned multiplier rows.
        gap_rate: With a force-controlled obstacle, m_i = int dg/ddelta psi_i on the owned normal
            rows at its current displacement (:meth:`set_obstacle_displacement`); else None.
        slip_rate: With a force-controlled obstacle, int (d . e_l) psi_i on the owned
            tangential rows (stacked as the multipliers' after the normal ones): the rate of
            the tangential offsets in delta; else None.
        resultant: With a force-controlled obstacle, w_i = int (-e_k . d) psi_i on all owned
            multiplier rows (e_0 = n_c): w . lam is the contact force on the obstacle against
            its direction d of approach; else None.
        ncp_scale: The validated ``ncp_scale``.
        n_u, n_lam: Owned displacement dofs and multiplier rows of this rank.
    """

    _petsc_objects = ("K", "N", "NT", "f", "M", "g")

    def __init__(
        self,
        disc: Discretization,
        V: fem.FunctionSpace | None = None,
        ncp_scale: str | float = "physical",
        compile_options: dict[str, Any] | None = None,
        band: tuple[Any, fem.Function] | None = None,
    ) -> None:
        self.disc = disc
        self.band = None if band is None else band[0]
        problem = disc.problem
        V = disc.V if V is None else V
        Q, m = disc.Q, disc.m
        self.V = V
        self.components = problem.law.components(disc.mesh.topology.dim)
        self.conditions = problem.law.conditions(disc.mesh.topology.dim)
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        mu = ufl.TestFunction(Q)
        options = {k: v for k, v in (compile_options or {}).items() if v is not None}

        def form(expr: ufl.Form) -> fem.Form:
            return disc.form(expr, **options)

        # Non-polynomial loads and gaps at the problem's quadrature degree, as in the residuals
        # (and the stiffness, if E or nu is a function of x).
        degree = problem.quadrature_degree
        fields = disc.fields
        a = fields.elastic_form(u, v, m.dx if band is None else band[0].dx)
        if callable(problem.E) or callable(problem.nu):
            a = with_quadrature_degrees(a, degree)
        directions = disc.directions(self.components)  # in the contact frame
        couplings = [ufl.inner(mu, ufl.dot(u, e)) * m.ds_contact for e in directions]
        forms = {
            "a": form(a),
            "L": form(with_quadrature_degrees(disc.load_form(v), degree)),
            "N": [form(c) for c in couplings],
            "NT": [form(ufl.adjoint(c)) for c in couplings],
            "M": form(mu * m.ds_contact),
            "g": form(
                with_quadrature_degrees(
                    disc.normal_gap(self.components, fields.gap(m.x, m.n)) * mu * m.ds_contact,
                    degree)
            ),
        }
        self.trace = disc.master_trace(V)
        if self.trace is not None:  # the master side: B_W of (mu, w . e_k), w in W
            w = ufl.TrialFunction(self.trace.W)
            forms["B"] = [
                form(ufl.inner(mu, ufl.dot(w, e)) * m.ds_contact) for e in directions
            ]
        origin = disc.slip_origin()
        if origin is not None:  # a step's slip increment: g_k = B_k (u_old + t + motion)
            forms["u_old"] = [
                form(ufl.dot(origin, e) * mu * m.ds_contact) for e in directions[1:]
            ]
        if problem.force_obstacle is not None:  # m_i = int dg_c/ddelta psi_i (force control)
            normal = self.components[0]
            rate = fields.gap_rate(m.x, m.n, lambda g, frame: normal.offset_in(g, m.n, frame))
            forms["g_rate"] = form(with_quadrature_degrees(rate * mu * m.ds_contact, degree))
            forms["resultant"] = [  # w_k = int (-e_k . d) psi, one form per component
                form(w) for w in disc.force_balance([mu] * len(directions), per_component=True)]
        bound = problem.law.bound_expr(fields, m.x)
        if bound is not None:
            forms["bound"] = form(with_quadrature_degrees(bound * mu * m.ds_contact, degree))
        if V is disc.V:
            self.bcs, self.prescribed_bcs = disc.bcs, disc.prescribed_bcs
        else:
            self.bcs = disc.dirichlet_bcs(V)
            self.prescribed_bcs = disc.dirichlet_bcs(V, homogeneous=False)
        if band is not None:
            self.bcs, self.prescribed_bcs = band[0].conditions(
                self.bcs, self.prescribed_bcs, band[1])
        self.n_u = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.n_q = Q.dofmap.index_map.size_local
        self.n_lam = self.n_q * len(self.components)
        try:  # on a failure (e.g. data that raise), what was assembled is destroyed
            self._assemble(forms, problem.homogeneous_dirichlet and band is None, ncp_scale,
                           form, mu)
        except BaseException:
            self.destroy()
            raise

    def _assemble(
        self, forms: dict[str, Any], homogeneous: bool, ncp_scale: Any, form: Any, mu: Any
    ) -> None:
        """K, N, N^T, f, M, g and c_n from the compiled ``forms`` (see the class).

        With several components (a frictional law) N, N^T, M, g and c_n stack the rows of the
        components, per rank: the owned rows of the normal multiplier, then those of the next
        component (:meth:`components_of`).
        """
        disc = self.disc
        lift = not homogeneous
        with timed("assemble"):
            self.stiffness_form = forms["a"]
            self.K = (self._matrix(forms["a"]) if self.band is None
                      else self.band.stiffness(forms["a"], self.bcs))
            N = [self._matrix(f) for f in forms["N"]]
            NT = [self._matrix(f) for f in forms["NT"]]
            self.N, self.NT = self._stacked(N, rows=True), self._stacked(NT, rows=False)
            # f: the lifting -K u_D on the free rows, u_D on the Dirichlet rows; g: g - N u_D,
            # so that N u - g (N without the Dirichlet columns) is the gap residual of u.
            self.f = self._vector(forms["L"], forms["a"] if lift else None, self.prescribed_bcs)
            for bc in self.prescribed_bcs:
                bc.set(self.f.array_w)
            M = self._vector(forms["M"])
            g = [self._vector(forms["g"], forms["N"][0] if lift else None, self.prescribed_bcs)]
            M_owned = M.array.copy()
            self._gap_forms = (forms["g"], forms["N"][0] if lift else None, forms.get("g_rate"))
            constant = disc.fields.obstacle_displacement
            self._framed = None if constant is None else (forms["N"], float(constant.value))
            self._offset_forms = [(forms["M"], forms["N"][k] if lift else None,
                                   forms["u_old"][k - 1] if "u_old" in forms else None)
                                  for k in range(1, len(self.components))]
            self.gap_rate = self._gap_rate()
            self.resultant = self.slip_rate = None
            if "resultant" in forms:
                self.resultant = self._owned_rows(forms["resultant"])
                self.slip_rate = -self.resultant[self.n_q :]  # int (d . e_l) psi = -w_l
            g += [self._offset(*parts) for parts in self._offset_forms]
            self.M = self._stacked_vector([M] * len(self.components))
            self.g = self._stacked_vector(g)
            if self.trace is not None:
                self._couple_master([self._matrix_free(f) for f in forms["B"]], lift)
            self.bounds: list[np.ndarray | None] = [None] * len(self.components)
            if "bound" in forms:
                b = self._vector(forms["bound"])
                self.bounds = [None] + [b.array.copy() for _ in self.components[1:]]
                b.destroy()
        self.ncp_scale = check_ncp_scale(ncp_scale)
        if self.ncp_scale == "physical":
            fdim = disc.mesh.topology.dim - 1
            size = M_owned.copy()
            size = size if fdim == 1 else np.sqrt(size)
            c_n = self._facet_modulus(form, mu, M_owned) / size
        else:
            c_n = np.full(len(M_owned), self.ncp_scale)
        self.c_n = np.tile(c_n, len(self.components))

    def _gap_rate(self) -> np.ndarray | None:
        """M = int dg/ddelta psi on the owned normal rows (force control), else None."""
        if self._gap_forms[2] is None:
            return None
        vec = self._vector(self._gap_forms[2])
        out = vec.array.copy()
        vec.destroy()
        return out

    def _owned_rows(self, forms: list[fem.Form]) -> np.ndarray:
        """The owned rows of one linear form per component, stacked as the multipliers."""
        out = []
        for f in forms:
            vec = self._vector(f)
            out.append(vec.array.copy())
            vec.destroy()
        return np.concatenate(out) if out else np.zeros(0)

    def frame_change(self) -> float:
        """How far N's contact frame is from that of the force-controlled obstacle's delta now.

        N's rows are assembled in the frame at the delta of the assembly; where the frame
        turns with delta (a curved obstacle whose point met by a normal ray moves), N at the
        current delta differs. Collective.

        Returns:
            ||N(delta) - N|| / ||N|| (Frobenius), 0 without force control or where delta has
            not changed since the assembly.
        """
        if self._framed is None or self.disc.fields.obstacle_displacement.value == (
                self._framed[1]):
            return 0.0
        now = self._stacked([self._matrix(f) for f in self._framed[0]], rows=True)
        size = self.N.norm(PETSc.NormType.FROBENIUS)
        now.axpy(-1.0, self.N, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        change = now.norm(PETSc.NormType.FROBENIUS) / max(size, 1e-300)
        now.destroy()
        return change

    def set_obstacle_displacement(self, delta: float) -> None:
        """Move the force-controlled obstacle to ``delta``: g and :attr:`gap_rate` anew.

        Sets the Constant of the discretisation's fields (so every form of the gap, the
        estimator's too, sees the obstacle there) and reassembles the normal rows of g (with
        the lifting -N u_D, as in the constructor), m = int dg/ddelta psi and, with friction,
        the tangential offsets g_l = B_l (u_old + (delta - delta_0) d) (their rate in delta,
        :attr:`slip_rate`, is int (d . e_l) psi). Collective.

        Args:
            delta: The obstacle's rigid displacement along its direction of approach.
        """
        self.disc.fields.obstacle_displacement.value = delta
        g_form, lifting, _ = self._gap_forms
        vec = self._vector(g_form, lifting, self.prescribed_bcs)
        self.g.array_w[: self.n_q] = vec.array[: self.n_q]
        vec.destroy()
        for k, parts in enumerate(self._offset_forms, start=1):
            vec = self._offset(*parts)
            self.g.array_w[k * self.n_q : (k + 1) * self.n_q] = vec.array[: self.n_q]
            vec.destroy()
        self.gap_rate = self._gap_rate()

    def _couple_master(self, B: list[PETSc.Mat], lift: bool) -> None:
        """N <- N (I - P) and N^T its transpose, g <- g + B_W P u_D (:mod:`~.pairs`).

        B_W (the components' rows stacked) maps the trace space W to the multiplier rows; P
        projects the master trace onto W. The columns of the Dirichlet dofs are dropped from
        P as from N; with prescribed values the master part of the lifting enters g.
        """
        B_W = self._stacked(B, rows=True)
        P = self.trace.P
        if lift:
            u_D = self.f.duplicate()
            u_D.set(0.0)
            self.set_prescribed(u_D.array_w)
            w, lifted = P.createVecLeft(), B_W.createVecLeft()
            P.mult(u_D, w)
            B_W.mult(w, lifted)
            self.g.axpy(1.0, lifted)
            for obj in (u_D, w, lifted):
                obj.destroy()
        mask = self.f.duplicate()
        mask.set(1.0)
        for bc in self.bcs:
            bc.set(mask.array_w)
        free = P.copy()
        free.diagonalScale(R=mask)
        coupling = B_W.matMult(free)
        self.N.axpy(-1.0, coupling, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        self.NT.destroy()
        self.NT = PETSc.Mat()
        self.N.transpose(self.NT)  # into a new matrix (without one, in place)
        for obj in (B_W, free, coupling, mask):
            obj.destroy()

    def _matrix_free(self, form: fem.Form) -> PETSc.Mat:
        """A matrix of ``form`` without Dirichlet rows or columns (its spaces have none)."""
        A = fem_petsc.assemble_matrix(form)
        A.assemble()
        return A

    def _offset(
        self, layout: fem.Form, lifting: fem.Form | None, u_old: fem.Form | None = None
    ) -> PETSc.Vec:
        """g_k of a tangential component: B_k u_old (0 outside a load path), -B_k u_D.

        Args:
            layout: A linear form on Lambda_H (for the vector's layout, with ghosts).
            lifting: The component's coupling form B_k, or None without prescribed values.
            u_old: The form (u_old . e_k, psi)_GC of a load step's slip increment, or None.
        """
        vec = fem_petsc.assemble_vector(layout if u_old is None else u_old)
        if u_old is None:
            with vec.localForm() as local:
                local.set(0.0)
        if lifting is not None:
            fem_petsc.apply_lifting(vec, [lifting], bcs=[list(self.prescribed_bcs)])
        if lifting is not None or u_old is not None:
            vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return vec

    def _stacked(self, mats: list[PETSc.Mat], rows: bool) -> PETSc.Mat:
        """One matrix of the components' blocks (rows of N, or columns of N^T), per rank."""
        if len(mats) == 1:
            return mats[0]
        blocks = [[m] for m in mats] if rows else [mats]
        nest = PETSc.Mat().createNest(blocks, comm=self.disc.comm)
        out = PETSc.Mat()
        nest.convert("aij", out=out)
        for obj in (nest, *mats):
            obj.destroy()
        return out

    def _stacked_vector(self, vecs: list[PETSc.Vec]) -> PETSc.Vec:
        """One vector of the components' rows, per rank (the vectors are consumed)."""
        if len(vecs) == 1:
            return vecs[0]
        out = PETSc.Vec().createMPI((self.n_lam, None), comm=self.disc.comm)
        out.array_w[:] = np.concatenate([v.array for v in vecs])
        for v in {id(v): v for v in vecs}.values():
            v.destroy()
        return out

    def components_of(self, values: np.ndarray) -> list[np.ndarray]:
        """The owned multiplier rows split into the components' rows (normal first)."""
        return [values[r] for r in self._rows()]

    def _matrix(self, form: fem.Form) -> PETSc.Mat:
        A = fem_petsc.assemble_matrix(form, bcs=self.bcs)
        A.assemble()
        return A

    @staticmethod
    def _vector(
        form: fem.Form, lifting: fem.Form | None = None, bcs: list[fem.DirichletBC] = ()
    ) -> PETSc.Vec:
        """Assemble ``form``; with ``lifting`` (a bilinear form), subtract ``lifting(u_D, .)``."""
        vec = fem_petsc.assemble_vector(form)
        if lifting is not None:
            fem_petsc.apply_lifting(vec, [lifting], bcs=[list(bcs)])
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return vec

    def _facet_modulus(self, form: Any, mu: Any, M: np.ndarray) -> np.ndarray | float:
        """E on the owned macro contact facets (for c_n = E / H).

        The number E, or the facet mean of E from the adjacent cells: the local modulus of a
        material given per cell tag, or of E(x).
        """
        problem, m = self.disc.problem, self.disc.m
        if isinstance(problem.E, float):
            return problem.E
        E, _ = self.disc.fields.material(m.x)
        vec = self._vector(
            form(with_quadrature_degrees(E * mu * m.ds_contact, problem.quadrature_degree))
        )
        out = vec.array / M
        vec.destroy()
        return out

    def set_prescribed(self, u: np.ndarray) -> None:
        """Set the prescribed Dirichlet values into the array ``u`` of a function on V."""
        for bc in self.prescribed_bcs:
            bc.set(u)

    @property
    def comm(self) -> MPI.Comm:
        """The communicator of the mesh."""
        return self.disc.comm

    def destroy(self) -> None:
        """Destroy the PETSc objects (collective: call on all ranks at the same point)."""
        destroy_attributes(self, self._petsc_objects)

    # -- the algebraic NCP (eq. 19-21) ---------------------------------------------------------
    def gap_residual(self, u: PETSc.Vec) -> np.ndarray:
        """(N u - g) on the owned multiplier rows."""
        Nu = self.N.createVecLeft()
        self.N.mult(u, Nu)
        out = Nu.array - self.g.array
        Nu.destroy()
        return out

    def ncp_residual(self, u: PETSc.Vec, lam: np.ndarray) -> np.ndarray:
        """C(u, lam) of eq. (20), each condition's rows with its NCP function, owned rows."""
        Mlam = self.M.array * lam
        x = Mlam + self.c_n * self.gap_residual(u)
        rows = self._rows()
        out = np.empty_like(Mlam)
        active = x[rows[0]] > 0.0
        for idx, cond in self.conditions:
            bound = self._bound(idx, active)
            r = [rows[k] for k in idx]
            if len(idx) == 1:
                out[r[0]] = cond.ncp(Mlam[r[0]], x[r[0]], bound)
            else:
                values = cond.ncp(
                    np.array([Mlam[k] for k in r]), np.array([x[k] for k in r]), bound
                )
                for k, v in zip(r, values, strict=True):
                    out[k] = v
        return out

    def _bound(self, idx: tuple[int, ...], active: np.ndarray) -> np.ndarray | None:
        """The threshold data on the rows of the condition of components ``idx``.

        None for the normal condition alone; a condition on tangential components gets the
        law's :meth:`~dwr_signorini.laws.ContactLaw.row_bound`.
        """
        if idx == (0,):
            return None
        M = self.M.array[: self.n_q]
        return self.disc.problem.law.row_bound(self.bounds[idx[-1]], active, M)

    def newton_sets(
        self, u: PETSc.Vec, lam: np.ndarray, u_max: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[Coupling]]:
        """The set test of every condition of the law (eq. 21 and its analogues), owned rows.

        Args:
            u: The displacement iterate.
            lam: The owned multiplier rows.
            u_max: max |u| over all ranks.

        Returns:
            ``(constrained, free, ncp, size, couplings)`` as
            :meth:`~dwr_signorini.laws.Component.newton_set`, the components' rows stacked,
            and the coupled rows of conditions on several components
            (:class:`~dwr_signorini.laws.Coupling`, empty for a symmetric law).
        """
        Mlam = self.M.array * lam
        residual = self.gap_residual(u)
        M, g, c = self.M.array, self.g.array, self.c_n
        rows = self._rows()
        out = [np.empty(self.n_lam, dtype=bool), np.empty(self.n_lam), np.empty(self.n_lam),
               np.empty(self.n_lam)]
        couplings: list[Coupling] = []
        for idx, cond in self.conditions:
            bound = self._bound(idx, out[0][rows[0]])
            r = [rows[k] for k in idx]
            force_size = self.comm.allreduce(
                float(max(np.max(np.abs(Mlam[k]), initial=0.0) for k in r)), op=MPI.MAX
            )
            if len(idx) == 1:
                k = r[0]
                parts = cond.newton_set(Mlam[k], residual[k], c[k], M[k], g[k], u_max,
                                        force_size, bound)
                for o, p in zip(out, parts, strict=True):
                    o[k] = p
                continue
            stack = [np.array([a[k] for k in r]) for a in (Mlam, residual, g)]
            *parts, (slip, J, rhs) = cond.newton_set(
                stack[0], stack[1], c[r[0]], M[r[0]], stack[2], u_max, force_size, bound
            )
            for o, p in zip(out, parts, strict=True):
                for k, v in zip(r, p, strict=True):
                    o[k] = v
            facets = np.flatnonzero(slip)
            local = np.array([np.arange(self.n_lam)[k][facets] for k in r]).T
            couplings.append(Coupling(local.reshape(-1, len(idx)), J, rhs))
        return (*out, couplings)

    def _rows(self) -> list[slice]:
        """The owned rows of each component (normal first)."""
        return [slice(k * self.n_q, (k + 1) * self.n_q) for k in range(len(self.components))]

    def coupling_force(self, lam: np.ndarray) -> PETSc.Vec:
        """N^T lam for the owned multiplier values ``lam`` (a new vector; destroy it)."""
        lam_vec = self.N.createVecLeft()
        lam_vec.array_w[:] = lam
        out = self.f.duplicate()
        self.NT.mult(lam_vec, out)
        lam_vec.destroy()
        return out

    def equilibrium_residual(self, u: PETSc.Vec, lam: np.ndarray) -> float:
        """||K u + N^T lam - f||."""
        r = self.coupling_force(lam)
        tmp = self.f.duplicate()
        self.K.mult(u, tmp)
        r.axpy(1.0, tmp)
        r.axpy(-1.0, self.f)
        norm = r.norm()
        for obj in (r, tmp):
            obj.destroy()
        return norm

    def stiffness_norm(self) -> float:
        """Max row sum of |K| over the rows that are not Dirichlet rows (collective).

        Dirichlet rows hold a lone 1 on the diagonal, so their row sum is 1: PETSc's infinity
        norm (the max row sum over all rows) is the wanted one whenever it exceeds 1. Only
        otherwise (no coupled row sums to more than 1, e.g. a small modulus) are the rows of K
        summed here, without the Dirichlet rows; every row of K holds its diagonal entry, so no
        row is empty.
        """
        norm = self.K.norm(PETSc.NormType.INFINITY)
        if norm > 1.0:
            return norm
        rows, _, values = self.K.getValuesCSR()
        row_sum = np.add.reduceat(np.abs(values), rows[:-1]) if len(rows) > 1 else np.zeros(0)
        diagonal = self.K.getDiagonal()
        coupled = row_sum > np.abs(diagonal.array) * (1.0 + 1e-14)
        diagonal.destroy()
        local = float(np.max(row_sum[coupled], initial=0.0))
        return self.comm.allreduce(local, op=MPI.MAX)
