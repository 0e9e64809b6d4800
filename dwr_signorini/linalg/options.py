"""PETSc options of the package's solvers: defaults, prefixes, and options that live with a solver.

Every linear solver of the package has an options prefix: the base prefix of a solve
(``solve(..., petsc_options_prefix=...)``, by default ``dwr_signorini_<n>_``, unique per solver,
since several solvers live at once), and documented sub-prefixes under it for inner solvers:

* ``<prefix>``: the linear solver of the Newton steps (the block Newton matrix, or K);
* ``<prefix>schur_``: the CG on S_AA of the Krylov Schur path;
* ``<prefix>p2_``: the higher-order (P2) solves of ``weights="higher_order"`` (and
  ``<prefix>p2_schur_`` for their S_AA).

An :class:`OptionsScope` puts a solver's options into PETSc's options database under its
prefix and keeps them there until the solver's ``destroy()``: a factorisation set up again later
(a new matrix, a new active set) reads its ``mat_mumps_*`` options only then. So
``-<prefix>ksp_view`` or ``-<prefix>ksp_monitor`` on the command line take effect too.

Precedence for one key: the ``petsc_options`` a caller passes win over the command line (as in
dolfinx's ``LinearProblem``), and the command line wins over the package's defaults.
"""

from __future__ import annotations

import itertools
from collections import Counter
from typing import Any

from petsc4py import PETSc

__all__ = [
    "LOOSE_RTOL",
    "SCHUR_KRYLOV_OPTIONS",
    "OptionsScope",
    "default_petsc_options",
    "fieldsplit_petsc_options",
    "iterative_petsc_options",
    "unique_prefix",
]

_counter = itertools.count()

#: How many living scopes set each full option name (prefix + key): a name leaves the database
#: when the last scope that set it is destroyed.
_owners: Counter[str] = Counter()

#: Relative tolerances (K solves, CG on S_AA) of the Newton steps of the Krylov Schur path
#: while the active set still changes (see :func:`dwr_signorini.newton.solve`).
LOOSE_RTOL = (1e-7, 1e-5)


def unique_prefix() -> str:
    """A new default base prefix ``dwr_signorini_<n>_`` (one per solver)."""
    return f"dwr_signorini_{next(_counter)}_"


def default_petsc_options(tdim: int | None = None) -> dict[str, Any]:
    """A direct solver: MUMPS's LDL^T where PETSc has MUMPS, PETSc's LU otherwise.

    Args:
        tdim: Topological dimension of the mesh, if known. On 2D meshes MUMPS orders with
            approximate minimum fill (AMF, ``mat_mumps_icntl_7=2``): on example 5.1's K and
            Newton matrix (50k-790k DoFs) it factored in 0.38-0.60 of the time of MUMPS's
            default, METIS nested dissection, and 0.66-0.89 of that of AMD on 1 rank (about the
            same as AMD on 2), with 15-30 % fewer factor entries than AMD. METIS stays for 3D,
            where it is several times faster than AMD (see ``benchmarks/mumps_ordering.py``).

    Returns:
        A new dict.

    Both matrices the package factors are symmetric: K (``method="schur"``) and the symmetric
    form of the block Newton matrix (``method="block"``, indefinite, see
    :meth:`~dwr_signorini.linalg.block.NewtonSystem.newton_matrix`). MUMPS's LDL^T
    (``pc_type="cholesky"`` on an AIJ matrix; 2 x 2 pivots where needed) stores half the factor
    entries of its LU and factors in less time (see ``benchmarks/mumps_ordering.py``). PETSc's
    own Cholesky does not pivot, so without MUMPS the solver is PETSc's LU.

    MUMPS counts null pivots (``mat_mumps_icntl_24=1``), which the Newton systems report as a
    singular matrix (:func:`~dwr_signorini.linalg.mumps.null_pivots`).
    """
    opts: dict[str, Any] = {"ksp_type": "preonly", "pc_type": "lu"}
    if PETSc.Sys.hasExternalPackage("mumps"):
        opts["pc_type"] = "cholesky"
        opts["pc_factor_mat_solver_type"] = "mumps"
        # ICNTL(24): count null pivots. With 2 x 2 pivots, LDL^T may not fail on a singular
        # matrix, e.g. of linearly dependent active contact constraints.
        opts["mat_mumps_icntl_24"] = 1
        if tdim == 2:
            opts["mat_mumps_icntl_7"] = 2
    return opts


def iterative_petsc_options() -> dict[str, Any]:
    """Krylov solver of K for ``method="schur"`` on large (3D) meshes: CG with GAMG.

    Returns:
        A new dict of PETSc options (keys without prefix), the caller's to change.

    Algebraic multigrid (smoothed aggregation, Chebyshev/Jacobi smoothing) with the rigid body
    modes as near-nullspace; each solve with K reduces the true residual by 1e-10, so that the
    Newton iterates meet the default ``rtol`` of :func:`~dwr_signorini.newton.solve`. S_AA is then
    solved by CG applied matrix-free (:class:`~dwr_signorini.linalg.schur.KrylovSchurComplement`,
    prefix ``<prefix>schur_``, defaults in :data:`SCHUR_KRYLOV_OPTIONS`), and no factorisation
    of the size of K is made. Pass it (or a variant) as ``petsc_options`` together with
    ``method="schur"``.
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

    Returns:
        A new dict of PETSc options (keys without prefix), the caller's to change.

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


#: Defaults of the CG on S_AA of the Krylov Schur path (prefix ``<prefix>schur_``).
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


class OptionsScope:
    """The options of one solver, in PETSc's options database under its prefix, for its lifetime.

    Args:
        prefix: The solver's options prefix (ends with ``_``).
        defaults: The package's defaults: set only where the database (e.g. the command line)
            has no value for the key yet.
        options: The caller's options: set over anything already there.

    Attributes:
        prefix: The prefix.
        options: The options in effect (defaults, then the caller's), without prefix.
    """

    def __init__(
        self,
        prefix: str,
        defaults: dict[str, Any] | None = None,
        options: dict[str, Any] | None = None,
    ) -> None:
        if not isinstance(prefix, str) or not prefix or not prefix.endswith("_"):
            raise ValueError(
                f"an options prefix must be a non-empty string ending with '_', got {prefix!r}"
            )
        self.prefix = prefix
        self.options = {**(defaults or {}), **(options or {})}
        self._names: list[str] = []
        db = PETSc.Options()
        for key, value in (defaults or {}).items():
            name = prefix + key
            if not db.hasName(name):
                self._set(db, key, value)
            elif name in _owners:  # set by another living scope with this prefix: share it
                self._names.append(name)
                _owners[name] += 1
        for key, value in (options or {}).items():
            self._set(db, key, value)

    def _set(self, db: PETSc.Options, key: str, value: Any) -> None:
        name = self.prefix + key
        db[name] = value
        if name not in self._names:
            self._names.append(name)
            _owners[name] += 1

    def apply(self, obj: Any) -> None:
        """Give ``obj`` (a KSP, PC or Mat) this prefix and let it read its options.

        Raises:
            ValueError: PETSc rejected an option (e.g. a misspelt ``pc_type``), naming
                ``petsc_options`` and the options in effect. The caller destroys the scope.
        """
        obj.setOptionsPrefix(self.prefix)
        try:
            obj.setFromOptions()
        except PETSc.Error as err:
            # PETSc's message without the stack: "Unable to find requested PC type lux".
            lines = [line.split("] ", 1)[-1] for line in str(err).splitlines()[1:]]
            detail = "; ".join(line for line in lines if line and "() at " not in line)
            raise ValueError(
                f"petsc_options (prefix {self.prefix!r}): PETSc rejected the options "
                f"{self.options} (PETSc error {err.ierr}: {detail}); expected the "
                "names and values of PETSc's options database, e.g. {'pc_type': 'lu'}"
            ) from err

    def options_under(self, sub: str) -> dict[str, Any]:
        """The options in effect that start with ``sub``, with ``sub`` removed."""
        return {k[len(sub) :]: v for k, v in self.options.items() if k.startswith(sub)}

    def destroy(self) -> None:
        """Remove the options this scope set (those no other living scope set too)."""
        db = PETSc.Options()
        for name in self._names:
            _owners[name] -= 1
            if _owners[name] <= 0:
                del _owners[name]
                if db.hasName(name):
                    db.delValue(name)
        self._names.clear()
