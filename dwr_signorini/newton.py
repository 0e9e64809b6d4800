"""Semi-smooth Newton (primal-dual active set) method for the algebraic NCP (paper eq. 19-22).

Algebra (Section 4): K stiffness, f load, N_ij = int_GC psi_i (phi_j . n), M = diag(|E_i|),
g_i = int_GC g psi_i. The contact conditions (19) are written with the NCP function (20)

    C_N(u, lam)_i = (M lam)_i - max(0, (M lam)_i + c_n,i (N u - g)_i) = 0,

and with the active set A = {i : (M lam + c_n (N u - g))_i > 0} (21) a Newton step solves

    [ K          N^T        ] [u  ]   [ f       ]
    [ -D_A N     D_I M      ] [lam] = [ -D_A g  ],

i.e. K u + N^T lam = f, (N u)_A = g_A, lam_I = 0. The contact rows are the generalised
derivative of C(w)(mu) = (mu, lam - max(0, lam + u_n - g)) of the paper, scaled so that the
transposed system is exactly the discrete dual problem (11)-(12); see :mod:`dwr_signorini.dual`.

Two ways to solve it (``method`` of :func:`solve`): ``"block"`` (:class:`NewtonSystem`, the
reference) assembles and factors a symmetric form of the block matrix in every step (see
:meth:`NewtonSystem.newton_matrix`); ``"schur"``
(:class:`SchurNewtonSystem`) eliminates u,

    S_AA lam_A = (N K^-1 f)_A - g_A,    u = K^-1 (f - N_A^T lam_A),    S = N K^-1 N^T,

either with K factored and the small dense S computed once per mesh, so that a step costs a
dense Cholesky factorisation of S_AA and one solve with the factors of K
(:class:`DenseSchurComplement`), or with a Krylov solver of K (CG + GAMG) and CG on S_AA
applied matrix-free (:class:`KrylovSchurComplement`), which never factors anything of the size
of K: the path for large 3D meshes.

Choice of c_n: c_n,i = E / H_i with H_i the size of macro contact facet i (length in 2D, square
root of the area in 3D). (M lam)_i scales like E u H^(d-2) and c_n (N u)_i like E u H^(d-2) too,
so the active-set test is invariant under scaling E, the loads and the lengths.
"""

from __future__ import annotations

import functools
import itertools
import logging
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.linalg
import scipy.sparse
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .quadrature import with_quadrature_degrees
from .spaces import Discretization
from .timing import timed

__all__ = [
    "LOOSE_RTOL",
    "METHODS",
    "SCHUR_KRYLOV_OPTIONS",
    "SCHUR_MAX_MULTIPLIERS",
    "ConvergenceError",
    "DenseSchurComplement",
    "KrylovSchurComplement",
    "NewtonSystem",
    "SchurNewtonSystem",
    "Solution",
    "clear_options",
    "default_petsc_options",
    "fieldsplit_petsc_options",
    "iterative_petsc_options",
    "mumps_failure",
    "null_pivots",
    "solve",
]

logger = logging.getLogger(__name__)

_counter = itertools.count()

#: Linear solvers of the Newton steps, the ``method`` of :func:`solve`.
METHODS = ("block", "schur")

#: Most multipliers (global) for ``method="schur"``: its dense N K^-1 N^T takes 8 n_lam^2 bytes on
#: rank 0 (3.2 GB at this size), the Cholesky factor of its active block as much again.
SCHUR_MAX_MULTIPLIERS = 20000

#: Entries of one block of right-hand sides N^T[:, block] (dense, global) when computing S: bounds
#: the memory of the multi-RHS solves (MUMPS may gather dense right-hand sides on one rank).
_SCHUR_BLOCK_ENTRIES = 2**24

#: Relative tolerances (K solves, CG on S_AA) of the Newton steps of the Krylov Schur path
#: while the active set still changes (see :func:`solve`).
LOOSE_RTOL = (1e-7, 1e-5)

#: Multigrid preconditioners: for K (``method="schur"``), not for the block Newton matrix.
_MULTIGRID = ("gamg", "hypre", "ml", "mg")

#: A Cholesky pivot of S_AA below this times its diagonal entry means dependent active rows.
_PIVOT_RTOL = 1e-12


class ConvergenceError(RuntimeError):
    """The semi-smooth Newton method did not converge.

    Attributes:
        history: One dict per iteration: iteration, active-set size, changes, residuals.
    """

    def __init__(self, message: str, history: list[dict[str, Any]]) -> None:
        lines = [message, "iteration history:" if history else "(before the first Newton step)"]
        for h in history:
            lines.append(
                "  it {iteration:3d}: |A| = {num_active:6d}, changed = {num_changed:6d}, "
                "equilibrium residual = {residual_equilibrium:.3e}, "
                "NCP residual = {residual_ncp:.3e}".format(**h)
                + (" [least-index safeguard]" if h.get("safeguard") else "")
                + (" [NaN/Inf]" if h.get("nonfinite") else "")
            )
        super().__init__("\n".join(lines))
        self.history = history


def default_petsc_options(tdim: int | None = None) -> dict[str, Any]:
    """A direct solver: MUMPS's LDL^T where PETSc has MUMPS, PETSc's LU otherwise.

    Both matrices the package factors are symmetric: K (``method="schur"``) and the symmetric
    form of the block Newton matrix (``method="block"``, indefinite, see
    :meth:`NewtonSystem.newton_matrix`). MUMPS's LDL^T (``pc_type="cholesky"`` on an AIJ
    matrix; 2 x 2 pivots where needed) stores half the factor entries of its LU and factors in
    less time (see ``benchmarks/mumps_ordering.py``). PETSc's own Cholesky does not pivot, so
    without MUMPS the solver is PETSc's LU.

    MUMPS counts null pivots (``mat_mumps_icntl_24=1``), which the Newton systems report as a
    singular matrix (:func:`null_pivots`).

    Args:
        tdim: Topological dimension of the mesh, if known. On 2D meshes MUMPS orders with AMD
            (``mat_mumps_icntl_7=0``), faster there than its default, METIS nested dissection,
            which stays for 3D, where it is several times faster than AMD (see
            ``benchmarks/mumps_ordering.py``).
    """
    opts: dict[str, Any] = {"ksp_type": "preonly", "pc_type": "lu"}
    if PETSc.Sys.hasExternalPackage("mumps"):
        opts["pc_type"] = "cholesky"
        opts["pc_factor_mat_solver_type"] = "mumps"
        # ICNTL(24): count null pivots (:func:`null_pivots`). With 2 x 2 pivots, LDL^T may not
        # fail on a singular matrix, e.g. of linearly dependent active contact constraints.
        opts["mat_mumps_icntl_24"] = 1
        if tdim == 2:
            opts["mat_mumps_icntl_7"] = 0
    return opts


#: MUMPS's error codes (INFOG(1)) of memory that could not be allocated, and of a workspace
#: that turned out too small (e.g. after delayed pivots), see the MUMPS user guide.
_MUMPS_NO_MEMORY = (-5, -7, -13)
_MUMPS_SMALL_WORKSPACE = (-8, -9, -11, -12, -14, -15, -17, -20)


def _mumps_factor(ksp: PETSc.KSP) -> PETSc.Mat | None:
    """The MUMPS factor of ``ksp``'s preconditioner, None if it is no MUMPS factorisation."""
    pc = ksp.getPC()
    if pc.getType() not in ("lu", "cholesky") or pc.getFactorSolverType() != "mumps":
        return None
    try:
        return pc.getFactorMatrix()
    except PETSc.Error:
        return None


def mumps_failure(ksp: PETSc.KSP) -> str | None:
    """Why MUMPS failed to factor the operator of ``ksp``, from its INFOG(1).

    Local (no communication): MUMPS's INFOG is the same on every rank.

    Returns:
        The reason, or None if MUMPS did not fail or found the matrix singular (the callers say
        what a singular matrix means for them).
    """
    factor = _mumps_factor(ksp)
    if factor is None:
        return None
    try:
        code, detail = factor.getMumpsInfog(1), factor.getMumpsInfog(2)
        megabytes = factor.getMumpsInfog(17)
    except PETSc.Error:
        return None
    if code >= 0:
        return None
    if code in _MUMPS_NO_MEMORY:
        need = f" (its estimate: {megabytes} MB over all ranks)" if megabytes > 0 else ""
        return (
            f"MUMPS could not allocate the memory of the factorisation{need}, INFOG(1) = {code}: "
            "the direct solver does not fit; for large 3D meshes use method='schur' with "
            "iterative_petsc_options()"
        )
    if code in _MUMPS_SMALL_WORKSPACE:
        return (
            f"MUMPS's workspace was too small (INFOG(1) = {code}, INFOG(2) = {detail}), e.g. "
            "after delayed pivots: raise it with petsc_options {'mat_mumps_icntl_14': 100} "
            "(percent of extra workspace; MUMPS's default is 20 to 35)"
        )
    if code == -19:
        return (
            "MUMPS needs more working memory than mat_mumps_icntl_23 allows (INFOG(1) = -19): "
            "raise or drop that option"
        )
    if code in (-6, -10):  # structurally or numerically singular
        return None
    return f"MUMPS failed with INFOG(1) = {code}, INFOG(2) = {detail}"


def null_pivots(ksp: PETSc.KSP) -> int:
    """How many null pivots MUMPS found in the factorisation of ``ksp`` (INFOG(28)).

    Counted only with null pivot detection (``mat_mumps_icntl_24=1``, as in
    :func:`default_petsc_options`), which replaces them and goes on: a positive count means a
    singular matrix. 0 for other solvers (they fail instead). Local: INFOG is the same on every
    rank.
    """
    factor = _mumps_factor(ksp)
    return 0 if factor is None else factor.getMumpsInfog(28)


@functools.cache
def _petsc_function(name: str) -> Any:
    """A PETSc C function of two object handles that petsc4py does not wrap.

    Found in the library petsc4py is linked to; it returns a PetscErrorCode.
    """
    import ctypes

    function = getattr(ctypes.CDLL(PETSc.__file__), name)
    function.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    function.restype = ctypes.c_int
    return function


def mumps_inverse_entries(
    ksp: PETSc.KSP, rows: np.ndarray, columns: np.ndarray
) -> np.ndarray | None:
    """The dense block (A^-1)[rows, columns] of the symmetric operator A factored by MUMPS.

    MUMPS computes selected entries of the inverse (ICNTL(30)) by solves with sparse right-hand
    sides, pruned to the parts of the factors they touch: much less work than full solves with
    the unit vectors. (PETSc's call returns entries of A^-T, hence "symmetric".)

    Args:
        ksp: A KSP whose preconditioner is a MUMPS factorisation of A.
        rows: Sorted global indices, the same on every rank.
        columns: Global indices, the same on every rank.

    Returns:
        The (len(rows), len(columns)) block on rank 0, None on the other ranks.
    """
    factor = _mumps_factor(ksp)
    if factor is None:
        raise ValueError("mumps_inverse_entries needs a MUMPS factorisation")
    comm = ksp.getComm().tompi4py()
    n = ksp.getOperators()[0].getSize()[0]
    m = len(rows)
    # Row j of the request is column j of A^-1: MUMPS wants all n of them (the others empty),
    # the whole request on rank 0.
    local = n if comm.rank == 0 else 0
    counts = np.zeros(local, dtype=PETSc.IntType)
    if comm.rank == 0:
        counts[columns] = m
    request = PETSc.Mat().createAIJ(((local, n), (local, n)), nnz=(counts, 0), comm=comm)
    if comm.rank == 0:
        request.setValuesCSR(
            np.concatenate([[0], np.cumsum(counts)]).astype(PETSc.IntType),
            np.tile(rows, len(columns)).astype(PETSc.IntType),
            np.zeros(m * len(columns)),
        )
    request.assemble()
    # The call leaves ICNTL(30) on and the solution centralised (ICNTL(21) = 0): both are
    # restored for the solves that follow.
    distributed = factor.getMumpsIcntl(21)
    try:
        code = _petsc_function("MatMumpsGetInverseTranspose")(factor.handle, request.handle)
        if code != 0:
            raise RuntimeError(
                f"MUMPS could not compute entries of the inverse (PETSc error {code}, "
                f"INFOG(1) = {factor.getMumpsInfog(1)})"
            )
        # Rows of the request in increasing column index, each with the entries at ``rows``.
        order = np.argsort(np.argsort(columns))
        block = request.getValuesCSR()[2].reshape(-1, m)[order].T if comm.rank == 0 else None
    finally:
        factor.setMumpsIcntl(30, 0)
        factor.setMumpsIcntl(21, distributed)
        request.destroy()
    return block


def iterative_petsc_options() -> dict[str, Any]:
    """Krylov solver of K for ``method="schur"`` on large (3D) meshes: CG with GAMG.

    Algebraic multigrid (smoothed aggregation, Chebyshev/Jacobi smoothing) with the rigid body
    modes as near-nullspace; each solve with K reduces the true residual by 1e-10, so that the
    Newton iterates meet the default ``rtol`` of :func:`solve`. S_AA is then solved by CG
    applied matrix-free (:class:`KrylovSchurComplement`, options ``schur_*``, defaults in
    :data:`SCHUR_KRYLOV_OPTIONS`), and no factorisation of the size of K is made. Pass it (or a
    variant) as ``petsc_options`` together with ``method="schur"``.
    """
    return {
        "ksp_type": "cg",
        "ksp_rtol": 1e-10,
        "ksp_atol": 0.0,
        "ksp_max_it": 1000,
        "ksp_norm_type": "unpreconditioned",
        "pc_type": "gamg",
        "pc_gamg_type": "agg",
        "pc_gamg_threshold": 0.01,
        "mg_levels_ksp_type": "chebyshev",
        "mg_levels_pc_type": "jacobi",
    }


def fieldsplit_petsc_options() -> dict[str, Any]:
    """Krylov solver of the block Newton matrix (``method="block"``): Schur field split.

    FGMRES on the block matrix; the displacement block by CG with algebraic multigrid (rigid
    body modes as near-nullspace), the multiplier block by the "selfp" Schur approximation,
    factored (it is small). The inner solves stop at a relative 1e-3 (FGMRES allows a varying
    preconditioner; the outer tolerance decides the accuracy). Every application of the Schur
    complement costs an inner solve with K, and the multigrid is set up anew in every Newton
    step: for large meshes ``method="schur"`` with :func:`iterative_petsc_options` is faster.
    """
    return {
        "ksp_type": "fgmres",
        "ksp_rtol": 1e-10,
        "ksp_atol": 1e-14,
        "ksp_max_it": 500,
        "ksp_gmres_restart": 100,
        "pc_type": "fieldsplit",
        "pc_fieldsplit_type": "schur",
        "pc_fieldsplit_schur_fact_type": "full",
        "pc_fieldsplit_schur_precondition": "selfp",
        "fieldsplit_u_ksp_type": "cg",
        "fieldsplit_u_ksp_rtol": 1e-3,
        "fieldsplit_u_pc_type": "gamg",
        "fieldsplit_u_pc_gamg_type": "agg",
        "fieldsplit_u_pc_gamg_threshold": 0.01,
        "fieldsplit_u_mg_levels_ksp_type": "chebyshev",
        "fieldsplit_u_mg_levels_pc_type": "jacobi",
        "fieldsplit_lam_ksp_type": "gmres",
        "fieldsplit_lam_ksp_rtol": 1e-3,
        "fieldsplit_lam_pc_type": "lu",
    }


#: Defaults of the CG on S_AA of :class:`KrylovSchurComplement` (prefix ``<system prefix>schur_``).
SCHUR_KRYLOV_OPTIONS: dict[str, Any] = {
    "ksp_type": "cg",
    "ksp_rtol": 1e-10,
    "ksp_atol": 0.0,
    "ksp_max_it": 1000,
    "ksp_norm_type": "unpreconditioned",
    "pc_type": "cholesky",
    # ICNTL(24): null pivot detection, to report linearly dependent active constraints.
    **(
        {"pc_factor_mat_solver_type": "mumps", "mat_mumps_icntl_24": 1}
        if PETSc.Sys.hasExternalPackage("mumps")
        else {}
    ),
}


def rigid_body_modes(V: fem.FunctionSpace, n_local: int) -> PETSc.NullSpace:
    """Rigid body modes of V (translations, rotations) as an orthonormal PETSc null space."""
    x = V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local]
    gdim = V.mesh.geometry.dim
    modes = [np.zeros((len(x), gdim)) for _ in range(3 if gdim == 2 else 6)]
    for i in range(gdim):
        modes[i][:, i] = 1.0
    if gdim == 2:
        modes[2][:, 0], modes[2][:, 1] = -x[:, 1], x[:, 0]
    else:
        for k, (i, j) in enumerate([(0, 1), (1, 2), (2, 0)]):
            modes[3 + k][:, i], modes[3 + k][:, j] = -x[:, j], x[:, i]
    vecs = []
    for mode in modes:
        vec = PETSc.Vec().createMPI((n_local, None), comm=V.mesh.comm)
        vec.array[:] = mode.ravel()
        vecs.append(vec)
    for i, vec in enumerate(vecs):  # modified Gram-Schmidt
        for prev in vecs[:i]:
            vec.axpy(-vec.dot(prev), prev)
        vec.scale(1.0 / vec.norm())
    return PETSc.NullSpace().create(vectors=vecs, comm=V.mesh.comm)


def set_options(obj: PETSc.KSP, prefix: str, options: dict[str, Any]) -> list[str]:
    """Put ``options`` under ``prefix`` into PETSc's options database and apply them to ``obj``.

    They stay in the database, because some are read only when ``obj`` is set up (MUMPS reads
    its ``mat_mumps_*`` options at the factorisation); remove them with :func:`clear_options`
    after the first setup.

    Returns:
        The full names of the options.
    """
    obj.setOptionsPrefix(prefix)
    opts = PETSc.Options()
    opts.prefixPush(prefix)
    for key, value in options.items():
        opts[key] = value
    opts.prefixPop()
    obj.setFromOptions()
    return [prefix + key for key in options]


def clear_options(names: list[str]) -> None:
    """Remove the options :func:`set_options` put into PETSc's options database."""
    opts = PETSc.Options()
    for name in names:
        if opts.hasName(name):
            opts.delValue(name)
    names.clear()


def _destroy_attributes(owner: object, names: tuple[str, ...]) -> None:
    """Destroy the objects held in ``owner``'s attributes ``names`` once (collective)."""
    for name in names:
        obj = getattr(owner, name, None)
        if obj is not None:
            obj.destroy()
            setattr(owner, name, None)


class NewtonSystem:
    """The algebraic problem of one mesh and the Newton steps by the block matrix (reference).

    Owns its PETSc objects (destroyed in ``__del__``); K, N, N^T, M, f and g are assembled once per
    mesh and reused in every Newton step and for the dual problem. Each Newton step solves

        [ K          N^T    ] [u  ]   [ f       ]
        [ -D_A N     D_I M  ] [lam] = [ -D_A g  ]

    (``method="block"`` of :func:`solve`) through the symmetric matrix of the same equations
    (:meth:`newton_matrix`), which it assembles and factors.

    :class:`SchurNewtonSystem` solves the same equations by eliminating u.

    Attributes:
        x: Block vector [u; lam] of the last Newton step: owned u dofs, then owned multiplier rows
            (split it with :meth:`split`).
        active: Active set of the last Newton step (owned multiplier rows).
        solved: Whether a Newton step was solved, so that :meth:`solve_transpose` (the dual
            problem) can reuse its factorisation.
        A: Symmetric form of the Newton matrix of the last step (:meth:`newton_matrix`; None
            before the first step).
        ksp: The linear solver (prefix :attr:`prefix`).
    """

    #: Attributes holding PETSc objects, destroyed by :meth:`destroy`.
    _petsc_objects: tuple[str, ...] = (
        "K",
        "N",
        "NT",
        "f",
        "M",
        "g",
        "A0",
        "A",
        "ksp",
        "x",
        "b",
        "is_u",
        "is_lam",
        "_near_nullspace",
    )

    def __init__(
        self,
        disc: Discretization,
        petsc_options: dict[str, Any] | None = None,
        V: fem.FunctionSpace | None = None,
    ) -> None:
        self.disc = disc
        problem = disc.problem
        V = disc.V if V is None else V
        Q, m = disc.Q, disc.m
        self.V = V
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        mu = ufl.TestFunction(Q)

        # Forms, built once.
        a = problem.elastic_form(u, v, m.dx)
        # Non-polynomial loads and gaps at DATA_QUADRATURE_DEGREE, as in the residuals.
        L = with_quadrature_degrees(disc.load_form(v))
        coupling = ufl.inner(mu, ufl.dot(u, m.n)) * m.ds_contact
        self._forms = {
            "a": disc.form(a),
            "L": disc.form(L),
            "N": disc.form(coupling),
            "NT": disc.form(ufl.adjoint(coupling)),
            "M": disc.form(mu * m.ds_contact),
            "g": disc.form(with_quadrature_degrees(problem.gap_expr(m.x) * mu * m.ds_contact)),
        }
        bcs = disc.bcs if V is disc.V else disc.dirichlet_bcs(V)
        self.bcs = bcs
        with timed("assemble"):
            self._assemble(bcs)
        self.A: PETSc.Mat | None = None
        self.solved = False
        self.ksp = PETSc.KSP().create(disc.comm)
        self.prefix = f"dwr_signorini_primal_{next(_counter)}_"
        options = default_petsc_options(disc.mesh.topology.dim)
        options.update(petsc_options or {})
        self.options = options
        self._option_names = set_options(self.ksp, self.prefix, options)
        self.direct = self.ksp.getPC().getType() in ("lu", "cholesky")
        self._setup()

    def _assemble(self, bcs: list[fem.DirichletBC]) -> None:
        """K, N, N^T, f, M, g and c_n (once per mesh)."""
        problem, disc, V, Q = self.disc.problem, self.disc, self.V, self.disc.Q
        self.K = fem_petsc.assemble_matrix(self._forms["a"], bcs=bcs)
        self.K.assemble()
        self.N = fem_petsc.assemble_matrix(self._forms["N"], bcs=bcs)
        self.N.assemble()
        self.NT = fem_petsc.assemble_matrix(self._forms["NT"], bcs=bcs)
        self.NT.assemble()
        self.f = fem_petsc.assemble_vector(self._forms["L"])
        self.f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        for bc in bcs:
            bc.set(self.f.array_w)
        self.M = self._assemble_q_vector(self._forms["M"])
        self.g = self._assemble_q_vector(self._forms["g"])

        # c_n,i = E / H_i (scale-aware, see module docstring).
        fdim = disc.mesh.topology.dim - 1
        size = self.M.array.copy()
        size = size if fdim == 1 else np.sqrt(size)
        self.c_n = problem.E / size

        # Block layout: per rank [u owned dofs, lam owned dofs].
        self.n_u = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.n_lam = Q.dofmap.index_map.size_local
        self.x = PETSc.Vec().createMPI((self.n_u + self.n_lam, None), comm=disc.comm)
        self.active = np.zeros(self.n_lam, dtype=bool)

    def _assemble_q_vector(self, form: fem.Form) -> PETSc.Vec:
        vec = fem_petsc.assemble_vector(form)
        vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return vec

    def _setup(self) -> None:
        """The block pattern A0 of the Newton matrices, and the field split if it is the PC."""
        comm = self.disc.comm
        if self.ksp.getPC().getType() in _MULTIGRID:
            raise ValueError(
                f"pc_type {self.ksp.getPC().getType()!r}: algebraic multigrid suits the "
                "stiffness matrix K, not the block Newton matrix with its zero multiplier "
                "block; use method='schur' with these options (iterative_petsc_options()), or "
                "fieldsplit_petsc_options() on the block matrix"
            )
        with timed("assemble"):
            D = PETSc.Mat().createAIJ(((self.n_lam, None), (self.n_lam, None)), nnz=1, comm=comm)
            D.setDiagonal(self.M)
            D.assemble()
            nest = PETSc.Mat().createNest([[self.K, self.NT], [self.N, D]], comm=comm)
            self.A0 = PETSc.Mat()
            nest.convert("aij", out=self.A0)
            nest.destroy()
            D.destroy()
            self.b = self.A0.createVecLeft()
        if self.ksp.getPC().getType() == "fieldsplit":
            self._setup_fieldsplit()

    def _setup_fieldsplit(self) -> None:
        """Fields "u" and "lam" for PCFIELDSPLIT, rigid body modes as near-nullspace of "u"."""
        lo = self.A0.getOwnershipRange()[0]
        comm = self.disc.comm
        self.is_u = PETSc.IS().createStride(self.n_u, first=lo, step=1, comm=comm)
        self.is_lam = PETSc.IS().createStride(self.n_lam, first=lo + self.n_u, step=1, comm=comm)
        self._near_nullspace = rigid_body_modes(self.V, self.n_u)
        self.is_u.compose("nearnullspace", self._near_nullspace)
        self.ksp.getPC().setFieldSplitIS(("u", self.is_u), ("lam", self.is_lam))

    def destroy(self) -> None:
        """Destroy the PETSc objects (collective: call on all ranks at the same point)."""
        _destroy_attributes(self, self._petsc_objects)
        clear_options(getattr(self, "_option_names", []))

    def __del__(self) -> None:
        self.destroy()

    # -- the algebraic NCP --------------------------------------------------------------------
    def gap_residual(self, u: PETSc.Vec) -> np.ndarray:
        """(N u - g) on the owned multiplier rows."""
        Nu = self.N.createVecLeft()
        self.N.mult(u, Nu)
        out = Nu.array - self.g.array
        Nu.destroy()
        return out

    def active_set(self, u: PETSc.Vec, lam: np.ndarray) -> np.ndarray:
        """A = {i : (M lam + c_n (N u - g))_i > 0} (eq. 21), owned rows."""
        return self.M.array * lam + self.c_n * self.gap_residual(u) > 0.0

    def ncp_residual(self, u: PETSc.Vec, lam: np.ndarray) -> np.ndarray:
        """C_N(u, lam) of eq. (20), owned rows."""
        Mlam = self.M.array * lam
        return Mlam - np.maximum(0.0, Mlam + self.c_n * self.gap_residual(u))

    def equilibrium_residual(self, u: PETSc.Vec, lam: np.ndarray) -> float:
        """||K u + N^T lam - f||."""
        r = self.f.duplicate()
        self.K.mult(u, r)
        lam_vec = self.N.createVecLeft()
        lam_vec.array[:] = lam
        tmp = self.f.duplicate()
        self.NT.mult(lam_vec, tmp)
        r.axpy(1.0, tmp)
        r.axpy(-1.0, self.f)
        norm = r.norm()
        for obj in (r, lam_vec, tmp):
            obj.destroy()
        return norm

    def newton_matrix(self, active: np.ndarray, out: PETSc.Mat | None = None) -> PETSc.Mat:
        """The symmetric matrix A_s of the Newton step of active set A.

        The Newton matrix of the step is A = L A_s with

            A_s = [ K      N_A^T   0   ]        L = [ I   0    N_I^T M_I^-1 ]
                  [ N_A    0       0   ],           [ 0   -I   0            ]
                  [ 0      0       M_I ]            [ 0   0    I            ]

        (rows and columns ordered u, active, inactive multipliers): the inactive columns N_I^T
        only ever multiply lam_I = 0, and the active rows change sign. So A x = b is
        A_s x = L^-1 b, and the dual A^T z = r is A_s w = r, z = L^-T w (:meth:`solve_transpose`):
        one symmetric indefinite matrix, factored by LDL^T, serves both.

        All active sets share one sparsity pattern (that of A0, zeros kept), so with ``out`` the
        values are overwritten in place and the solver reuses its symbolic factorisation.
        """
        if out is None:
            A = self.A0.copy()
        else:
            A = out
            self.A0.copy(A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        scale = A.createVecLeft()
        scale.array_w[: self.n_u] = 1.0
        scale.array_w[self.n_u :] = active
        A.diagonalScale(L=scale, R=scale)
        diagonal = A.getDiagonal()
        diagonal.array_w[self.n_u :] = np.where(active, 0.0, self.M.array)
        A.setDiagonal(diagonal, addv=PETSc.InsertMode.INSERT_VALUES)
        A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        for vec in (scale, diagonal):
            vec.destroy()
        return A

    def solve_active(self, active: np.ndarray) -> None:
        """One Newton step: solve the linear system of active set ``active`` into ``self.x``.

        A x = b with b = [f; -g_A; 0], as A_s x = L^-1 b = [f; g_A; 0] (:meth:`newton_matrix`).
        """
        with timed("assemble"):
            self.A = self.newton_matrix(active, out=self.A)
            self.active = active.copy()
            b = self.b.array_w
            b[: self.n_u] = self.f.array
            b[self.n_u :] = np.where(active, self.g.array, 0.0)
        with timed("factorize"):
            self.ksp.setOperators(self.A)
            self.ksp.setUp()
            clear_options(self._option_names)  # read now (MUMPS's at the factorisation)
        count = null_pivots(self.ksp)
        if count > 0:
            raise np.linalg.LinAlgError(
                f"MUMPS found {count} null pivots: the Newton matrix is singular"
            )
        with timed("newton solve"):
            self.ksp.solve(self.b, self.x)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            cause = mumps_failure(self.ksp)
            raise ConvergenceError(
                f"linear solve of the Newton step failed (KSP reason {reason})"
                + (f": {cause}" if cause else ""),
                [],
            )
        self.solved = True

    def set_loose(self, loose: bool) -> bool:
        """Loose or full-accuracy linear solves; direct solvers are always exact.

        Returns:
            Whether the following Newton steps are solved loosely (here never).
        """
        return False

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """Solve A^T z = rhs with the Newton matrix A of the last step (the dual problem).

        A^T = A_s L^T (:meth:`newton_matrix`): solve A_s w = rhs with the factors of the last
        step (two triangular solves), then z = L^-T w, i.e. z_u = w_u, z_A = -w_A and
        z_I = w_I - (N w_u)_I / M_I.

        Args:
            rhs: Block vector [j_u; j_lam], laid out as :attr:`x`.
            z: Block vector [y; xi] for the solution, laid out as :attr:`x`.

        Raises:
            RuntimeError: No Newton step was solved, or the solve failed.
        """
        self._check_solved()
        self.ksp.solve(rhs, z)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            raise RuntimeError(f"the dual solve failed (KSP reason {reason})")
        w_u = self.N.createVecRight()
        w_u.array_w[:] = self.split(z)[0]
        n_w = self.N.createVecLeft()
        self.N.mult(w_u, n_w)
        w_lam = z.array_w[self.n_u :]
        w_lam[:] = np.where(self.active, -w_lam, w_lam - n_w.array / self.M.array)
        for vec in (w_u, n_w):
            vec.destroy()

    def _check_solved(self) -> None:
        if not self.solved:
            raise RuntimeError("the Newton system has not been solved: no matrix to transpose")

    def split(self, x: PETSc.Vec) -> tuple[np.ndarray, np.ndarray]:
        """Owned parts (u, lam) of a block vector."""
        return x.array_r[: self.n_u], x.array_r[self.n_u :]


class SchurNewtonSystem(NewtonSystem):
    """The Newton steps by elimination of u: K set up once per mesh, S = N K^-1 N^T.

    A Newton step K u + N^T lam = f, (N u)_A = g_A, lam_I = 0 (see :class:`NewtonSystem`) is,
    after eliminating u = K^-1 (f - N_A^T lam_A),

        S_AA lam_A = (N K^-1 f)_A - g_A,    u = K^-1 (f - N_A^T lam_A),    lam_I = 0,

    with S = N K^-1 N^T symmetric positive definite on the active rows when Gamma_D clamps the
    body (the matrix of the linear complementarity problem, see :func:`solve`). The solver of K
    (``petsc_options``) is set up once per mesh and decides how S_AA is solved:

    * a direct solver (``ksp_type="preonly"``, ``pc_type`` ``"lu"`` or ``"cholesky"``; the
      default is MUMPS's LDL^T): :class:`DenseSchurComplement`, S computed once per mesh from the
      factors of K, a Newton step costs a dense Cholesky factorisation of S_AA and one solve
      with the factors of K;
    * a Krylov solver (e.g. :func:`iterative_petsc_options`: CG with GAMG and the rigid body
      modes): :class:`KrylovSchurComplement`, CG on S_AA applied matrix-free (one K solve per
      iteration), preconditioned by the factored sparse N_A diag(K)^-1 N_A^T; nothing of the
      size of S is stored, so this is the path for large 3D meshes.

    The transposed Newton matrix (the dual problem, K symmetric) reads, with eta_A = -xi_A,

        K y + N_A^T eta_A = j_u,    (N y)_A = j_lam,A,    xi_I = (j_lam,I - (N y)_I) / M_I,

    the same saddle-point problem with other data: two solves with K and one with S_AA.

    Raises:
        ValueError: ``petsc_options`` give ``ksp_type="preonly"`` without a factorisation, or
            there are more than :data:`SCHUR_MAX_MULTIPLIERS` multipliers for the dense S.
        ConvergenceError: K could not be factored (the body is not held in place).
    """

    _petsc_objects = (*NewtonSystem._petsc_objects, "_u", "_u_f", "_rhs_u", "_lam_vec", "_schur")

    def _setup(self) -> None:
        """Check and set up the solver of K, compute K^-1 f and the Schur complement."""
        ksp_type, pc_type = self.ksp.getType(), self.ksp.getPC().getType()
        if ksp_type == "preonly" and pc_type not in ("lu", "cholesky"):
            raise ValueError(
                "method='schur' solves with K: with ksp_type 'preonly' petsc_options need "
                f"pc_type 'lu' or 'cholesky' (got {pc_type!r}); for a Krylov solver of K use "
                "e.g. iterative_petsc_options()"
            )
        self.direct = ksp_type == "preonly"
        self.n_lam_global = self.disc.comm.allreduce(self.n_lam, op=MPI.SUM)
        if self.direct and self.n_lam_global > SCHUR_MAX_MULTIPLIERS:
            raise ValueError(
                f"method='schur' with a direct solver stores the dense {self.n_lam_global} x "
                f"{self.n_lam_global} matrix N K^-1 N^T ({8e-9 * self.n_lam_global**2:.1f} GB), "
                f"more than SCHUR_MAX_MULTIPLIERS = {SCHUR_MAX_MULTIPLIERS} multipliers allow; "
                "use method='block' or a Krylov solver of K (iterative_petsc_options())"
            )
        self._u, self._u_f, self._rhs_u = (self.K.createVecRight() for _ in range(3))
        self._lam_vec = self.N.createVecLeft()
        if not self.direct:
            self._near_nullspace = rigid_body_modes(self.V, self.n_u)
            self.K.setNearNullSpace(self._near_nullspace)
        with timed("factorize"):
            self.ksp.setOperators(self.K)
            error: Exception | None = None
            try:
                self.ksp.setUp()
                clear_options(self._option_names)  # read now (MUMPS's at the factorisation)
                self._solve_K(self.f, self._u_f)
            except (PETSc.Error, ConvergenceError) as err:
                error = err
            if error is not None or null_pivots(self.ksp) > 0:
                cause = mumps_failure(self.ksp) or (
                    "K is singular (the body is not held in place, check dirichlet)"
                )
                raise ConvergenceError(
                    f"the factorisation (or preconditioner) of the stiffness matrix K failed: "
                    f"{cause}",
                    [],
                ) from error
            self._schur: DenseSchurComplement | KrylovSchurComplement = (
                DenseSchurComplement(self) if self.direct else KrylovSchurComplement(self)
            )

    def _solve_K(self, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve K x = b with the solver of K (factors, or the set-up Krylov solver)."""
        self.ksp.solve(b, x)
        reason = self.ksp.getConvergedReason()
        if reason < 0:
            raise ConvergenceError(f"the solve with K failed (KSP reason {reason})", [])

    def _saddle(
        self, a: PETSc.Vec, b: np.ndarray, w: PETSc.Vec, guess: np.ndarray | None = None
    ) -> np.ndarray:
        """Solve K u + N_A^T l_A = a, (N u)_A = b_A, l_I = 0 for the last set-up active set.

        Args:
            a: Right-hand side of the displacement rows.
            b: Owned right-hand sides of the multiplier rows (only the active ones count).
            w: K^-1 a (it may be ``self._u``, which is overwritten).
            guess: Owned initial guess of l for a Krylov solve of S_AA (None: zero).

        Returns:
            The owned l; u is left in ``self._u``.
        """
        self.N.mult(w, self._lam_vec)
        l_owned = self._schur.solve(self._lam_vec.array - b, guess)  # S_AA l_A = (N K^-1 a - b)_A
        self._lam_vec.array_w[:] = l_owned
        self.NT.mult(self._lam_vec, self._rhs_u)
        self._rhs_u.aypx(-1.0, a)  # a - N_A^T l_A
        self._solve_K(self._rhs_u, self._u)
        return l_owned

    def set_loose(self, loose: bool) -> bool:
        """Loose tolerances of the Krylov solves (:class:`KrylovSchurComplement`) or full ones.

        Returns:
            Whether the following Newton steps are solved loosely (never with a direct solver).
        """
        return self._schur.set_loose(loose)

    def _write(self, out: PETSc.Vec, u: np.ndarray, lam: np.ndarray) -> None:
        arr = out.array_w
        arr[: self.n_u] = u
        arr[self.n_u :] = lam

    def solve_active(self, active: np.ndarray) -> None:
        """One Newton step: lam_A from S_AA, then u with the solver of K, into ``self.x``."""
        with timed("newton solve"):
            self._schur.set_active(active)
            guess = np.where(active, self.split(self.x)[1], 0.0) if self.solved else None
            self.active = active.copy()
            lam = self._saddle(self.f, self.g.array, self._u_f, guess)
            self._write(self.x, self._u.array_r, lam)
        self.solved = True

    def solve_transpose(self, rhs: PETSc.Vec, z: PETSc.Vec) -> None:
        """Solve A^T z = rhs for the Newton matrix A of the last step, eliminating y.

        Args:
            rhs: Block vector [j_u; j_lam], laid out as :attr:`x`.
            z: Block vector [y; xi] for the solution, laid out as :attr:`x`.

        Raises:
            RuntimeError: No Newton step was solved, or the solve failed.
        """
        self._check_solved()
        j_u, j_lam = self.split(rhs)
        self._rhs_u.array_w[:] = j_u
        j = self._rhs_u.copy()
        try:
            self._solve_K(j, self._u)
            eta = self._saddle(j, j_lam, self._u)
        except (ConvergenceError, PETSc.Error) as err:
            raise RuntimeError(f"the dual solve failed: {err}") from err
        finally:
            j.destroy()
        self.N.mult(self._u, self._lam_vec)
        xi = np.where(self.active, -eta, (j_lam - self._lam_vec.array) / self.M.array)
        self._write(z, self._u.array_r, xi)


def _owned_rows(mat: PETSc.Mat) -> scipy.sparse.csr_matrix:
    """The rows of ``mat`` this rank owns, with global column indices, as a scipy matrix."""
    indptr, indices, values = mat.getValuesCSR()
    shape = (len(indptr) - 1, mat.getSize()[1])
    return scipy.sparse.csr_matrix((values, indices, indptr), shape=shape)


class DenseSchurComplement:
    """S = N K^-1 N^T dense on rank 0, from the factors of K; S_AA by dense Cholesky.

    S is computed once per mesh (8 n_lam^2 bytes on rank 0). N only touches the displacement
    dofs C on Gamma_C, so S = N_C (K^-1)_CC N_C^T: with MUMPS, the block (K^-1)_CC comes from
    MUMPS's entries of the inverse (:func:`mumps_inverse_entries`); with another direct solver,
    from solves with blocks of columns of N^T as right-hand sides. Rank 0 runs the dense algebra
    and scatters the result, so that all ranks use the same numbers.
    """

    def __init__(self, system: SchurNewtonSystem) -> None:
        self.system = system
        self.comm = system.disc.comm
        self.n = system.n_lam_global
        self._offsets = np.cumsum(self.comm.allgather(system.n_lam))[:-1]
        self._factor: tuple[np.ndarray, Any] | None = None
        self.S = self._compute()

    def _compute(self) -> np.ndarray | None:
        """S on rank 0 (None elsewhere): from entries of K^-1 with MUMPS, else by solves."""
        if _mumps_factor(self.system.ksp) is not None:
            return self._compute_from_inverse_entries()
        return self._compute_by_solves()

    def _compute_from_inverse_entries(self) -> np.ndarray | None:
        """S = N_C (K^-1)_CC N_C^T on rank 0 (None elsewhere), C the columns of N."""
        system, comm = self.system, self.comm
        owned = _owned_rows(system.N)
        touched = np.unique(owned.indices[owned.data != 0])
        C = np.unique(np.concatenate(comm.allgather(touched))).astype(PETSc.IntType)
        rows = comm.gather(owned, root=0)
        N_C = scipy.sparse.vstack(rows).tocsc()[:, C] if comm.rank == 0 else None
        S = np.zeros((self.n, self.n)) if comm.rank == 0 else None
        # (K^-1)_CC a block of columns at a time: S += (N_C (K^-1)_{C,block}) N_C[:, block]^T.
        width = max(1, _SCHUR_BLOCK_ENTRIES // max(1, len(C)))
        for start in range(0, len(C), width):
            block = mumps_inverse_entries(system.ksp, C, C[start : start + width])
            if comm.rank == 0:
                S += (N_C @ block) @ N_C[:, start : start + width].T.toarray()
        return None if S is None else 0.5 * (S + S.T)

    def _compute_by_solves(self) -> np.ndarray | None:
        """S on rank 0 (None elsewhere), a block of columns at a time.

        The columns X = K^-1 N^T[:, block] come from one multi-RHS solve, and S[:, block] =
        (N^T)^T X is summed over the ranks' owned rows of N^T.
        """
        system, comm, n = self.system, self.comm, self.n
        NT = _owned_rows(system.NT)
        width = max(1, min(n, _SCHUR_BLOCK_ENTRIES // system.K.getSize()[0]))
        S = np.empty((n, n)) if comm.rank == 0 else None
        B = X = None
        try:
            for start in range(0, n, width):
                stop = min(n, start + width)
                if B is None or B.getSize()[1] != stop - start:
                    for mat in (B, X):
                        if mat is not None:
                            mat.destroy()
                    B = PETSc.Mat().createDense(
                        ((system.n_u, None), (None, stop - start)), comm=comm
                    )
                    B.setUp()
                    X = B.duplicate()
                B.getDenseArray()[:] = NT[:, start:stop].toarray()
                B.assemble()
                system.ksp.matSolve(B, X)
                block = np.ascontiguousarray(NT.T @ X.getDenseArray())
                total = np.empty_like(block) if comm.rank == 0 else None
                comm.Reduce(block, total, op=MPI.SUM, root=0)
                if comm.rank == 0:
                    S[:, start:stop] = total
        finally:
            for mat in (B, X):
                if mat is not None:
                    mat.destroy()
        if comm.rank == 0:
            S = 0.5 * (S + S.T)  # symmetric up to the round-off of the solves
        return S

    def _gather(self, owned: np.ndarray) -> np.ndarray | None:
        """The global multiplier vector on rank 0 from every rank's owned rows."""
        parts = self.comm.gather(owned, root=0)
        return np.concatenate(parts) if parts is not None else None

    def set_active(self, active: np.ndarray) -> None:
        """Cholesky factor of S_AA on rank 0; LinAlgError on every rank if S_AA is singular."""
        mask = self._gather(active)
        error = None
        if self.comm.rank == 0:
            index = np.flatnonzero(mask)
            S_AA = self.S[np.ix_(index, index)]
            factor = None
            try:
                if index.size:
                    factor = scipy.linalg.cho_factor(S_AA)
                    # Pivots relative to the diagonal: a scale-invariant test for dependent rows.
                    if np.any(np.diag(factor[0]) ** 2 <= _PIVOT_RTOL * S_AA.diagonal()):
                        raise np.linalg.LinAlgError
            except np.linalg.LinAlgError:
                error = (
                    "N K^-1 N^T is singular on the active rows: active contact constraints are "
                    "linearly dependent"
                )
            self._factor = (index, factor)
        error = self.comm.bcast(error, root=0)
        if error is not None:
            raise np.linalg.LinAlgError(error)

    def solve(self, r: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """The owned l with S_AA l_A = r_A, l_I = 0 (``guess`` is not needed)."""
        r_all = self._gather(r)
        parts = None
        if self.comm.rank == 0:
            index, factor = self._factor
            full = np.zeros(self.n)
            if index.size:
                full[index] = scipy.linalg.cho_solve(factor, r_all[index])
            parts = np.split(full, self._offsets)
        return self.comm.scatter(parts, root=0)

    def set_loose(self, loose: bool) -> bool:
        """Direct solves are exact: never loose."""
        return False

    def destroy(self) -> None:
        """Nothing to destroy (numpy only)."""


class _MaskedSchurOperator:
    """Context of the python matrix P_A N K^-1 N^T P_A + P_I on the multiplier rows."""

    def __init__(self, system: SchurNewtonSystem) -> None:
        self.system = system
        self.mask = np.zeros(system.n_lam)
        self._lam = system.N.createVecLeft()
        self._w, self._v = system.K.createVecRight(), system.K.createVecRight()

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """The product y = P_A N K^-1 N^T P_A x + P_I x: one solve with K."""
        system = self.system
        self._lam.array_w[:] = self.mask * x.array_r
        system.NT.mult(self._lam, self._w)
        system._solve_K(self._w, self._v)
        system.N.mult(self._v, y)
        y.array_w[:] = self.mask * y.array_r + (1.0 - self.mask) * x.array_r

    def destroy(self, mat: PETSc.Mat) -> None:
        """Destroy the work vectors with the python matrix."""
        for vec in (self._lam, self._w, self._v):
            vec.destroy()


class KrylovSchurComplement:
    """CG on S_AA = (N K^-1 N^T)_AA, matrix-free, preconditioned by (N diag(K)^-1 N^T)_AA.

    The operator is a PETSc python matrix on the multiplier rows: P_A S P_A + P_I with P_A, P_I
    the projections on the active and inactive rows, so that one CG solves S_AA l_A = r_A,
    l_I = r_I = 0 with the distributed layout of the multipliers. Each application costs one
    solve with K by the system's Krylov solver. The preconditioner is the sparse
    N diag(K)^-1 N^T (computed once per mesh) with the inactive rows and columns replaced by the
    identity, factored by MUMPS's LDL^T for each active set. The CG's options have the prefix
    ``<system prefix>schur_`` (pass e.g. ``schur_ksp_rtol`` in ``petsc_options``); defaults in
    :data:`SCHUR_KRYLOV_OPTIONS`. Each K solve is as accurate as ``ksp_rtol`` of K.
    """

    def __init__(self, system: SchurNewtonSystem) -> None:
        self.system = system
        comm = system.disc.comm
        inv_diag = system.K.getDiagonal()
        inv_diag.reciprocal()
        scaled = system.NT.copy()
        scaled.diagonalScale(L=inv_diag)
        self.S_hat = system.N.matMult(scaled)  # N diag(K)^-1 N^T, sparse
        inv_diag.destroy()
        scaled.destroy()
        self.P: PETSc.Mat | None = None
        n = system.n_lam
        self._operator = _MaskedSchurOperator(system)
        self.S = PETSc.Mat().createPython(((n, None), (n, None)), self._operator, comm=comm)
        self.S.setUp()
        self._y = self.S.createVecLeft()
        self.lo = system.N.getOwnershipRange()[0]
        self.ksp = PETSc.KSP().create(comm)
        options = dict(SCHUR_KRYLOV_OPTIONS)
        prefix = "schur_"
        options.update(
            {k[len(prefix) :]: v for k, v in system.options.items() if k.startswith(prefix)}
        )
        self._option_names = set_options(self.ksp, system.prefix + prefix, options)
        self.iterations = 0
        self._rtol = (system.ksp.getTolerances()[0], self.ksp.getTolerances()[0])

    def set_loose(self, loose: bool) -> bool:
        """Loose relative tolerances of the K solves and the CG on S_AA, or those of the options.

        Loose means at least :data:`LOOSE_RTOL`.

        Returns:
            ``loose``.
        """
        solvers = (self.system.ksp, self.ksp)
        for ksp, tight, floor in zip(solvers, self._rtol, LOOSE_RTOL, strict=True):
            ksp.setTolerances(rtol=max(tight, floor) if loose else tight)
        return loose

    def set_active(self, active: np.ndarray) -> None:
        """Build and factor the preconditioner of S_AA for ``active`` (owned rows)."""
        self._operator.mask = active.astype(float)
        if self.P is not None:
            self.P.destroy()
        self.P = self.S_hat.copy()
        rows = (self.lo + np.flatnonzero(~active)).astype(PETSc.IntType)
        self.P.zeroRowsColumns(rows, diag=1.0)
        self.ksp.setOperators(self.S, self.P)
        self.ksp.setUp()
        self._check_independent()
        clear_options(self._option_names)  # read now (MUMPS's at the factorisation)

    def _check_independent(self) -> None:
        """LinAlgError if MUMPS found null pivots in (N diag(K)^-1 N^T)_AA.

        It has the rank of S_AA (both are N_A B N_A^T with B symmetric positive definite on the
        free dofs), so null pivots mean linearly dependent active constraints, for which CG
        would return one of many multipliers.
        """
        if null_pivots(self.ksp) > 0:
            raise np.linalg.LinAlgError(
                "N diag(K)^-1 N^T, and so N K^-1 N^T, is singular on the active rows: active "
                "contact constraints are linearly dependent"
            )

    def solve(self, r: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """The owned l with S_AA l_A = r_A, l_I = 0, by CG from ``guess`` (None: zero)."""
        mask = self._operator.mask
        self._y.array_w[:] = mask * r
        out = self.S.createVecRight()
        if guess is not None:
            out.array_w[:] = mask * guess
        self.ksp.setInitialGuessNonzero(guess is not None)
        try:
            self.ksp.solve(self._y, out)
            reason = self.ksp.getConvergedReason()
            self.iterations += self.ksp.getIterationNumber()
            if reason < 0:
                raise ConvergenceError(f"CG on S_AA did not converge (KSP reason {reason})", [])
            return out.array_r.copy()
        finally:
            out.destroy()

    def destroy(self) -> None:
        """Destroy the PETSc objects (collective)."""
        _destroy_attributes(self, ("ksp", "S", "P", "S_hat", "_y"))
        clear_options(self._option_names)


@dataclass
class Solution:
    """The discrete solution w_h = (u_h, lambda_H) and what the dual problem needs.

    Attributes:
        u: Displacement u_h on T_h.
        lam: Normal contact force lambda_H (DG0 on the macro contact facets).
        active: Active set of the last Newton step (owned multiplier rows).
        newton_iterations: Number of linear solves.
        history: Per-iteration record (active-set size, changes, residuals).
        disc: The discretisation.
        system: The Newton system; its last factorisations serve the dual problem
            (:meth:`NewtonSystem.solve_transpose`).
    """

    u: fem.Function
    lam: fem.Function
    active: np.ndarray
    newton_iterations: int
    history: list[dict[str, Any]]
    disc: Discretization
    system: NewtonSystem = field(repr=False)

    @property
    def num_active(self) -> int:
        """Global number of active macro contact facets."""
        return self.disc.comm.allreduce(int(self.active.sum()), op=MPI.SUM)


def _norm(comm: MPI.Comm, local: np.ndarray) -> float:
    """Euclidean norm of a distributed array given by its owned entries."""
    return float(np.sqrt(comm.allreduce(float(local @ local), op=MPI.SUM)))


def _global_key(comm: MPI.Comm, active: np.ndarray) -> tuple[bytes, ...]:
    """The global active set, exactly (packed bits of every rank's owned rows), as a dict key."""
    return tuple(comm.allgather(np.packbits(active).tobytes() + active.size.to_bytes(8, "little")))


#: Relative round-off level of the two parts of the active-set test (21): (N u - g)_i below it
#: times M_i max|u| + |g_i|, and (M lam)_i below it times max_j |(M lam)_j|, count as zero.
_ROUNDOFF = 1e-10


def solve(
    problem_or_disc: Any,
    petsc_options: dict[str, Any] | None = None,
    initial_guess: tuple[fem.Function, fem.Function] | None = None,
    max_iterations: int = 50,
    rtol: float = 1e-8,
    c_n_scale: float = 1.0,
    method: str = "block",
) -> Solution:
    """Solve Signorini's problem with the semi-smooth Newton method (paper eq. 19-22).

    The active set of step k is A = {i : (M lam + c_n (N u - g))_i > 0} (eq. 21), evaluated at
    the previous iterate, with two safeguards:

    * *Round-off.* In the test (M lam + c_n (N u - g))_i > 0 each part counts as zero below its
      round-off level (``1e-10`` relative to M_i max|u| + |g_i| and to max_j |(M lam)_j|).
      Without it a bi-active index (lambda_i = 0 and (N u - g)_i = 0 at the solution, e.g.
      grazing contact) would change sides on round-off noise and the iteration could cycle; and
      the decisions stay independent of c_n.
    * *Cycling.* If an active set repeats, the update switches to Murty's least-index rule: of the
      indices the rule (21) would change, only the one with the smallest global number changes
      sides. On the multipliers the contact conditions are a linear complementarity problem with
      the matrix N K^-1 N^T, symmetric positive definite (a P-matrix) when Gamma_D clamps the
      body, for which this rule terminates finitely (K. G. Murty, Opsearch 11, 1974, 123-130).

    With a Krylov solver of K (``method="schur"``, :class:`KrylovSchurComplement`) the steps are
    *inexact* while the active set changes: their solves stop at the relative tolerances
    :data:`LOOSE_RTOL`, which are enough to decide the next active set. When it settles, its
    system is solved once more at the tolerances of ``petsc_options`` (one more step, whose
    iterate the convergence test then checks); direct solvers are always exact.

    After the first step every iterate has (N u - g)_A = 0 and lam_I = 0, so the test reduces to
    lam_i > 0 on A and (N u - g)_i > 0 on I whatever c_n is: c_n (``c_n_scale`` times E / H_i)
    only weighs an initial guess against the gap, and the iterates from a zero initial guess do
    not depend on it.

    Args:
        problem_or_disc: A :class:`~dwr_signorini.SignoriniProblem` or a ready
            :class:`~dwr_signorini.spaces.Discretization`.
        petsc_options: Options of the linear solver (prefix ``dwr_signorini_primal_<n>_``),
            merged on top of :func:`default_petsc_options`.
        initial_guess: ``(u0, lam0)`` on this discretisation's V and Q (warm start).
        max_iterations: Most Newton steps before giving up.
        rtol: Tolerance at convergence on the equilibrium residual, relative to the size of
            its terms (max of ||K|| ||u||, ||N^T lam||, ||f||: a backward error, which does not
            grow with lambda/mu or mesh grading), and on the NCP residual (20), entry by entry
            relative to |M lam|_i + c_n,i (M_i max|u| + |g_i|).
        c_n_scale: Factor on the default c_n,i = E / H_i of the NCP function (20), > 0.
        method: Linear solver of the Newton steps, one of :data:`METHODS`. ``"block"``
            (reference, :class:`NewtonSystem`) factors the block Newton matrix in every step
            (``petsc_options`` for the block matrix, e.g. :func:`fieldsplit_petsc_options`);
            ``"schur"`` (:class:`SchurNewtonSystem`) solves S_AA lam_A = (N K^-1 f)_A - g_A,
            S = N K^-1 N^T, with ``petsc_options`` for K: a direct solver (the default, K
            factored once, S dense, at most :data:`SCHUR_MAX_MULTIPLIERS` multipliers) or a
            Krylov solver (:func:`iterative_petsc_options`: CG + GAMG on K, CG on S_AA, for
            large 3D meshes). All give the same iterates up to the solvers' tolerances, and
            the dual problem is solved the same way.

    Returns:
        The :class:`Solution`.

    Raises:
        TypeError, ValueError: Arguments of the wrong type or value, naming the argument.
        ConvergenceError: No convergence in ``max_iterations`` steps, active-set cycling that
            the safeguard could not break, a failed linear solve, NaN/Inf in the data (loads,
            gap) or in an iterate; with the iteration history. Raised on every rank.
    """
    from .problem import SignoriniProblem
    from .spaces import discretize

    if isinstance(problem_or_disc, SignoriniProblem):
        disc = discretize(problem_or_disc)
    elif isinstance(problem_or_disc, Discretization):
        disc = problem_or_disc
    else:
        raise TypeError(
            "solve() takes a SignoriniProblem or a Discretization, got "
            f"{type(problem_or_disc).__name__}"
        )
    if (
        isinstance(max_iterations, bool)
        or not isinstance(max_iterations, int)
        or max_iterations < 1
    ):
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    for name, value in (("rtol", rtol), ("c_n_scale", c_n_scale)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < np.inf:
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if petsc_options is not None and not isinstance(petsc_options, dict):
        raise TypeError(
            "petsc_options must be a dict of PETSc options such as {'pc_type': 'lu'}, got "
            f"{type(petsc_options).__name__}"
        )
    if initial_guess is not None:
        if not isinstance(initial_guess, (tuple, list)) or len(initial_guess) != 2:
            raise TypeError("initial_guess must be a pair (u0, lam0) of dolfinx Functions")
        u0, lam0 = initial_guess
        if (
            getattr(u0, "function_space", None) != disc.V
            or getattr(lam0, "function_space", None) != disc.Q
        ):
            raise ValueError(
                "initial_guess must be functions on this discretisation's V and Q "
                "(transfer them with dwr_signorini.adapt.transfer_solution)"
            )
    comm = disc.comm

    def all_finite(*arrays: np.ndarray) -> bool:
        ok = all(bool(np.all(np.isfinite(a))) for a in arrays)
        return bool(comm.allreduce(ok, op=MPI.LAND))

    system = (SchurNewtonSystem if method == "schur" else NewtonSystem)(disc, petsc_options)
    if c_n_scale != 1.0:
        system.c_n = system.c_n * float(c_n_scale)
    if not all_finite(system.f.array, system.g.array):
        raise ConvergenceError(
            "NaN or Inf in the assembled load vector f or gap vector g: body_force, traction "
            "and gap must be finite everywhere on the mesh",
            [],
        )

    n_u, n_lam = system.n_u, system.n_lam
    M = system.M.array
    u = fem.Function(disc.V, name="u")
    lam = fem.Function(disc.Q, name="lambda")
    if initial_guess is not None:
        u.x.array[:] = initial_guess[0].x.array
        lam.x.array[:] = initial_guess[1].x.array
        if not all_finite(u.x.array, lam.x.array):
            raise ValueError("initial_guess contains NaN or Inf")
    q_start = disc.Q.dofmap.index_map.local_range[0]

    def least_index(mask: np.ndarray) -> np.ndarray:
        """Only the set entry with the smallest global index (on its owning rank)."""
        local = np.flatnonzero(mask)
        mine = q_start + int(local[0]) if local.size else np.iinfo(np.int64).max
        first = comm.allreduce(mine, op=MPI.MIN)
        out = np.zeros_like(mask)
        if local.size and mine == first:
            out[local[0]] = True
        return out

    lam_vec = system.N.createVecLeft()
    nt_lam = system.f.duplicate()
    norm_f = system.f.norm()
    # ||K|| over the rows that are not Dirichlet rows (those hold a lone 1 on the diagonal).
    rows, _, values = system.K.getValuesCSR()
    # Every row of K holds its diagonal entry, so no row is empty for reduceat.
    row_sum = np.add.reduceat(np.abs(values), rows[:-1]) if len(rows) > 1 else np.zeros(0)
    diagonal = system.K.getDiagonal()
    coupled = row_sum > np.abs(diagonal.array) * (1.0 + 1e-14)
    diagonal.destroy()
    norm_K = comm.allreduce(float(np.max(row_sum[coupled], initial=0.0)), op=MPI.MAX)
    history: list[dict[str, Any]] = []
    loose = system.set_loose(True)
    seen: dict[tuple[bytes, ...], int] = {}
    previous: np.ndarray | None = None
    safeguard_since: int | None = None
    try:
        for it in range(max_iterations + 1):
            u_vec = u.x.petsc_vec
            lam_local = lam.x.array[:n_lam]
            Mlam = M * lam_local
            gap_res = system.gap_residual(u_vec)
            test = Mlam + system.c_n * gap_res
            # The terms of the test (21) at their round-off level, entry by entry.
            u_max = comm.allreduce(float(np.max(np.abs(u.x.array), initial=0.0)), op=MPI.MAX)
            gap_size = M * u_max + np.abs(system.g.array)
            force_size = comm.allreduce(float(np.max(np.abs(Mlam), initial=0.0)), op=MPI.MAX)
            size = np.abs(Mlam) + system.c_n * gap_size
            clean = np.where(np.abs(Mlam) > _ROUNDOFF * force_size, Mlam, 0.0) + system.c_n * (
                np.where(np.abs(gap_res) > _ROUNDOFF * gap_size, gap_res, 0.0)
            )
            wanted = clean > 0.0
            if previous is None:
                violated = np.ones_like(wanted)
                rule = wanted
            else:
                violated = wanted != previous
                rule = wanted

            # Residuals as backward errors: the equilibrium residual relative to the size of
            # the terms K u, N^T lam, f; the NCP function (20) entry by entry relative to `size`.
            lam_vec.array_w[:] = lam_local
            system.NT.mult(lam_vec, nt_lam)
            scale_eq = max(norm_f, nt_lam.norm(), norm_K * _norm(comm, u.x.array[:n_u]), 1e-300)
            res_eq = system.equilibrium_residual(u_vec, lam_local) / scale_eq
            ncp = np.abs(Mlam - np.maximum(0.0, test))
            local_ncp = np.max(
                np.divide(ncp, size, out=np.zeros_like(ncp), where=size > 0), initial=0.0
            )
            rel_ncp = comm.allreduce(float(local_ncp), op=MPI.MAX)
            num_changed = comm.allreduce(int(violated.sum()), op=MPI.SUM)
            record = {
                "iteration": it,
                "num_active": comm.allreduce(int(rule.sum()), op=MPI.SUM),
                "num_changed": num_changed,
                "residual_equilibrium": res_eq,
                "residual_ncp": rel_ncp,
                "c_n_scale": float(c_n_scale),
                "safeguard": safeguard_since is not None,
                "loose": loose,
            }
            history.append(record)
            logger.info(
                "Newton %d: |A| = %d, changed %d, residuals %.2e / %.2e",
                it,
                record["num_active"],
                num_changed,
                res_eq,
                rel_ncp,
            )
            settled = previous is not None and num_changed == 0
            resolve = settled and loose
            if resolve:  # the active set has settled: solve its system again, accurately
                loose = system.set_loose(False)
            elif settled:
                if res_eq <= rtol and rel_ncp <= rtol:
                    break
                raise ConvergenceError(
                    f"the active set is stationary but the residuals are not below rtol={rtol:g}: "
                    "the linear solves are inaccurate (check petsc_options; a direct solver is "
                    "the default)",
                    history,
                )
            if it == max_iterations:
                extra = (
                    f" (least-index safeguard active since step {safeguard_since})"
                    if safeguard_since is not None
                    else ""
                )
                raise ConvergenceError(
                    f"no convergence in max_iterations={max_iterations} Newton steps{extra}; "
                    "raise max_iterations or warm-start from a nearby solution",
                    history,
                )

            new = previous if resolve else rule
            key = _global_key(comm, new)
            if key in seen and not resolve:
                if safeguard_since is not None:
                    raise ConvergenceError(
                        f"active-set cycling: the set of step {it} repeats step {seen[key]} "
                        "even under the least-index safeguard (is the body clamped, i.e. is "
                        "N K^-1 N^T positive definite?)",
                        history,
                    )
                logger.warning(
                    "active-set cycling (step %d repeats step %d): least-index safeguard",
                    it,
                    seen[key],
                )
                safeguard_since = it
                seen.clear()
            if safeguard_since is not None and not resolve:
                new = previous ^ least_index(violated)
                key = _global_key(comm, new)
                record["num_active"] = comm.allreduce(int(new.sum()), op=MPI.SUM)
                record["safeguard"] = True
            seen[key] = it

            try:
                system.solve_active(new)
            except (ConvergenceError, PETSc.Error, np.linalg.LinAlgError) as err:
                # LinAlgError: the Cholesky factorisation of S_AA (method="schur") failed.
                reason = system.ksp.getConvergedReason()
                names = vars(PETSc.KSP.ConvergedReason).items()
                name = next((k for k, v in names if v == reason and k.isupper()), str(reason))
                if isinstance(err, PETSc.Error):
                    name = f"PETSc error {err.ierr}"
                elif isinstance(err, np.linalg.LinAlgError):
                    name = str(err)
                cause = mumps_failure(system.ksp)
                if cause is not None:
                    hint = cause
                elif isinstance(err, (PETSc.Error, np.linalg.LinAlgError)) or reason == (
                    PETSc.KSP.ConvergedReason.DIVERGED_PCSETUP_FAILED
                ):
                    hint = (
                        "the factorisation or preconditioner failed: the Newton matrix is "
                        "singular (the body is not held in place, check dirichlet; or active "
                        "contact constraints are linearly dependent, e.g. a contact facet whose "
                        "nodes are all clamped), or the preconditioner in petsc_options does "
                        "not suit this saddle-point system"
                    )
                else:
                    hint = "the linear solver did not converge: check petsc_options"
                raise ConvergenceError(
                    f"Newton step {it}: linear solve failed ({name}); {hint}", history
                ) from err
            previous = new
            u_new, lam_new = system.split(system.x)
            if not all_finite(u_new, lam_new):
                record["nonfinite"] = True
                raise ConvergenceError(
                    f"NaN or Inf in the Newton iterate of step {it} (singular or ill-posed "
                    "linear system?)",
                    history,
                )
            u.x.array[:n_u] = u_new
            u.x.scatter_forward()
            lam.x.array[:n_lam] = lam_new
            lam.x.scatter_forward()
    finally:
        lam_vec.destroy()
        nt_lam.destroy()
    system.set_loose(False)  # the dual problem reuses the system: at full accuracy

    return Solution(
        u=u,
        lam=lam,
        active=system.active.copy(),
        newton_iterations=len(history) - 1,
        history=history,
        disc=disc,
        system=system,
    )
