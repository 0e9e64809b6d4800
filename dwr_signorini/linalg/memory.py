"""What fits: MUMPS's prediction of a factorisation's memory and the memory each rank may use.

A direct factorisation of a 3D stiffness matrix grows like N^(4/3) in memory (nested dissection)
and outgrows a machine long before the mesh does; the Krylov path
(``method="krylov"``: K by CG with algebraic multigrid, S_AA matrix-free, see
:mod:`~dwr_signorini.linalg.schur`) needs memory linear in N. ``method=None``
(:func:`dwr_signorini.solve`) decides between them, before anything is factored, from

* :func:`predicted_factor_memory`: MUMPS's own estimate after its analysis (the ordering and
  the symbolic factorisation, no numbers yet): INFOG(16), the in-core memory of the numerical
  factorisation, the largest over the ranks. The analysis takes a small part of a factorisation
  (0.38 s against 4.7 s at 94k DoFs of example 5.3, 1 rank); on that mesh MUMPS predicted
  680 MB and used 572 MB (INFOG(21));
* :func:`available_memory`: the memory a rank may still take, the smaller of the node's
  ``MemAvailable`` (``/proc/meminfo``) and what the control group (a container's limit) leaves,
  shared by the ranks on the node, the smallest over the ranks.

A factorisation is taken to fit (:func:`factorization_fits`) when its prediction, and the dense
Schur complement of ``method="schur"`` where that is the path, stay below
:data:`FACTOR_FRACTION` of that memory: the rest is left for what a level holds besides (the
mesh, its refinement, the forms, the dual solve, the estimator's reconstructions and weights).
The probe runs only where ``method=None`` would factor a 3D level of at least
:data:`PROBE_MIN_DOFS` DoFs, below which every path fits on any machine that runs FEniCSx, and
where a rough estimate from the size alone (:func:`surely_fits`, four times the usual memory)
does not already fit: the analysis costs about a twelfth of a factorisation.
"""

from __future__ import annotations

import ctypes
import functools
import os
from pathlib import Path

from mpi4py import MPI
from petsc4py import PETSc

from .options import OptionsScope, default_petsc_options, unique_prefix

__all__ = [
    "FACTOR_FRACTION",
    "MEMORY_BUDGET",
    "PROBE_MIN_DOFS",
    "available_memory",
    "factorization_fits",
    "predicted_factor_memory",
    "surely_fits",
]

#: Bytes per rank that the solver may use; ``None``: measured by :func:`available_memory`.
MEMORY_BUDGET: int | None = None

#: The share of :func:`available_memory` a factorisation may take (the rest is the level's).
FACTOR_FRACTION = 0.6

#: 3D levels with fewer displacement DoFs are factored without a probe (from
#: :data:`~dwr_signorini.linalg.AUTO_KRYLOV_MIN_DOFS` on, ``method=None`` takes the Krylov path
#: anyway).
PROBE_MIN_DOFS = 50_000

#: MUMPS's LDL^T of a 3D P1 stiffness matrix took about this many bytes times N^(4/3) (its
#: analysis predicted 43 MB at 13k DoFs and 680 MB at 94k DoFs of example 5.3, 1 rank) ...
ROUGH_BYTES = 160.0
#: ... and :func:`surely_fits` allows this many times that before it asks MUMPS.
ROUGH_MARGIN = 4.0

_MEGABYTE = 10**6


def _meminfo_available(path: Path = Path("/proc/meminfo")) -> int | None:
    """The node's ``MemAvailable`` in bytes, or None where there is no such file."""
    try:
        for line in path.read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _cgroup_available(root: Path = Path("/sys/fs/cgroup")) -> int | None:
    """What the control group's memory limit leaves (cgroup v2), or None without a limit."""
    try:
        limit = (root / "memory.max").read_text().strip()
        if limit == "max":
            return None
        return max(0, int(limit) - int((root / "memory.current").read_text().strip()))
    except (OSError, ValueError):
        return None


def available_memory(comm: MPI.Comm) -> int:
    """The bytes each rank of ``comm`` may still take (collective).

    :data:`MEMORY_BUDGET` if set; else the node's available memory (the smaller of
    ``MemAvailable`` and the control group's remainder) divided among the ranks of ``comm`` on
    that node, the smallest value over the ranks.

    Args:
        comm: The communicator of the solver.

    Returns:
        Bytes per rank (0 where nothing could be read: then nothing counts as fitting).
    """
    if MEMORY_BUDGET is not None:
        return int(MEMORY_BUDGET)
    values = [v for v in (_meminfo_available(), _cgroup_available()) if v is not None]
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        share = min(values) // node.size if values else 0
    finally:
        node.Free()
    return comm.allreduce(share, op=MPI.MIN)


@functools.cache
def _symbolic_cholesky() -> tuple[ctypes._CFuncPtr, ctypes._CFuncPtr] | None:
    """PETSc's ``MatCholeskyFactorSymbolic`` and ``MatFactorInfoInitialize`` (not in petsc4py)."""
    try:
        lib = ctypes.CDLL(PETSc.__file__)
        symbolic, initialize = lib.MatCholeskyFactorSymbolic, lib.MatFactorInfoInitialize
    except (OSError, AttributeError):
        return None
    symbolic.argtypes = [ctypes.c_void_p] * 4
    symbolic.restype = ctypes.c_int
    initialize.argtypes = [ctypes.c_void_p]
    initialize.restype = ctypes.c_int
    return symbolic, initialize


def predicted_factor_memory(A: PETSc.Mat, tdim: int = 3) -> int | None:
    """MUMPS's estimate of the memory of factoring ``A`` by LDL^T, from its analysis alone.

    Runs MUMPS's analysis (ordering and symbolic factorisation, with the package's default
    options of :func:`~dwr_signorini.linalg.options.default_petsc_options`) and reads INFOG(16),
    the in-core memory of the numerical factorisation on the rank that needs most. Collective.

    Args:
        A: A symmetric matrix (the stiffness matrix K).
        tdim: The topological dimension of the mesh (it selects MUMPS's ordering).

    Returns:
        Bytes (the same on every rank), or None where there is no MUMPS or PETSc's symbolic
        factorisation cannot be reached.

    Raises:
        RuntimeError: MUMPS's analysis failed.
    """
    functions = _symbolic_cholesky()
    options = default_petsc_options(tdim)
    if functions is None or options.get("pc_factor_mat_solver_type") != "mumps":
        return None
    symbolic, initialize = functions
    scope = OptionsScope(unique_prefix(), options)
    ksp = PETSc.KSP().create(A.getComm())
    try:
        scope.apply(ksp)
        ksp.setOperators(A)
        pc = ksp.getPC()
        pc.setFactorSetUpSolverType()  # the MUMPS factor, not yet analysed
        factor = pc.getFactorMatrix()
        info = (ctypes.c_double * 64)()  # MatFactorInfo: a few PetscReals; ample room
        initialize(info)
        code = symbolic(factor.handle, A.handle, None, info)
        if code != 0 or factor.getMumpsInfog(1) < 0:
            raise RuntimeError(
                f"MUMPS's analysis failed (PETSc error {code}, INFOG(1) = "
                f"{factor.getMumpsInfog(1)})"
            )
        return factor.getMumpsInfog(16) * _MEGABYTE
    finally:
        ksp.destroy()
        scope.destroy()


def factorization_fits(
    A: PETSc.Mat, tdim: int, dense_rows: int = 0
) -> tuple[bool, int | None, int]:
    """Whether factoring ``A``, and a dense matrix of ``dense_rows`` rows, fits (collective).

    Args:
        A: The matrix to factor (K).
        tdim: The topological dimension of the mesh.
        dense_rows: Rows of a dense symmetric matrix held on one rank besides the factors
            (``method="schur"``: S = N K^-1 N^T and the Cholesky factor of S_AA, 16 bytes per
            entry), 0 for none.

    Returns:
        ``(fits, predicted, available)``: the predicted bytes on the rank that needs most
        (None where MUMPS cannot predict: then it counts as fitting, as before this probe) and
        the bytes per rank available (:func:`available_memory`).
    """
    predicted = predicted_factor_memory(A, tdim)
    available = available_memory(A.getComm().tompi4py())
    if predicted is None:
        return True, None, available
    need = predicted + 16 * dense_rows**2
    return need <= FACTOR_FRACTION * available, need, available


def surely_fits(num_dofs: int, comm: MPI.Comm, dense_rows: int = 0) -> bool:
    """Whether a 3D factorisation fits even at a margin over its usual memory (no analysis then).

    The margin is :data:`ROUGH_MARGIN` times the usual memory, :data:`ROUGH_BYTES` N^(4/3)
    over the ranks (nested dissection), half as much again on the rank that needs most
    (collective).

    Args:
        num_dofs: Displacement DoFs N (global).
        comm: The solver's communicator.
        dense_rows: As in :func:`factorization_fits`.

    Returns:
        True if even the margin fits; False if MUMPS should be asked.
    """
    rough = ROUGH_MARGIN * 1.5 * ROUGH_BYTES * num_dofs ** (4 / 3) / comm.size
    return rough + 16 * dense_rows**2 <= FACTOR_FRACTION * available_memory(comm)


if os.environ.get("DWR_SIGNORINI_MEMORY_BUDGET"):  # bytes per rank, e.g. for a batch job
    MEMORY_BUDGET = int(float(os.environ["DWR_SIGNORINI_MEMORY_BUDGET"]))
