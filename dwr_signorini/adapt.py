"""The adaptive loop: solve, estimate, mark, refine (the only loop over levels).

Each level solves Signorini's problem on T_h (warm-started from the previous level), estimates the
error in J with eta or eta_p, sums the indicators over the patches (macro cells), marks them, and
refines the macro mesh T_H with the edges of the marked cells; the next fine mesh is one uniform
refinement of the new macro mesh.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc

from .estimator import ESTIMATORS, WEIGHTS, Estimate, estimate
from .goal import Goal
from .io import OutputDirectory, check_output_dir, write_csv, write_json
from .marking import STRATEGIES, mark
from .newton import METHODS, Solution, solve
from .problem import SignoriniProblem
from .reconstruction import Reconstructor
from .spaces import Discretization, discretize, refine_marked
from .timing import timed

__all__ = ["AdaptiveResult", "LevelRecord", "solve_adaptive", "transfer_solution"]

logger = logging.getLogger(__name__)

REFINEMENTS = ("adaptive", "uniform")


@dataclass
class LevelRecord:
    """One row of the table of an adaptive or uniform run (the paper's Tables 1-3)."""

    level: int
    num_cells: int
    num_macro_cells: int
    num_contact_elements: int
    num_dofs: int
    num_active: int
    J_h: float
    eta_p: float
    eta: float | None
    estimate: float
    contact_term: float
    newton_iterations: int
    num_marked: int = 0
    time: dict[str, float] = field(default_factory=dict)
    rel_error: float | None = None
    ieff_p: float | None = None
    ieff: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """The record as a plain dict (timings nested under ``time``)."""
        return asdict(self)


@dataclass
class AdaptiveResult:
    """The levels of a run and the last solution and estimate."""

    levels: list[LevelRecord]
    solution: Solution | None = field(default=None, repr=False)
    estimate: Estimate | None = field(default=None, repr=False)
    problem: SignoriniProblem | None = field(default=None, repr=False)
    meta: dict[str, Any] = field(default_factory=dict)
    comm: MPI.Comm = field(default_factory=lambda: MPI.COMM_WORLD, repr=False)

    def rows(self) -> list[dict[str, Any]]:
        """The table as a list of dicts."""
        return [r.as_dict() for r in self.levels]

    def to_csv(self, path: str | Path) -> None:
        """Write the table as CSV (rank 0 of the mesh communicator writes)."""
        if self.comm.rank == 0:
            write_csv(path, self.rows())

    def to_json(self, path: str | Path) -> None:
        """Write the table and the run's settings as JSON (rank 0 of the mesh communicator)."""
        if self.comm.rank == 0:
            write_json(path, {"meta": self.meta, "levels": self.rows()})


def transfer_solution(
    old: Solution,
    disc: Discretization,
    rec: Reconstructor | None = None,
    macro_parent: npt.NDArray[np.int32] | None = None,
) -> tuple[fem.Function, fem.Function]:
    """Warm start on a new discretisation.

    lambda_0 on each new macro contact facet is the facet mean of the old vertex-averaged linear
    recovery i_2H^(1) lambda_H. u_0 is, with ``macro_parent``, the old i_2h^(2) u_h (the fine
    nodal values read as macro P2 values, Section 4) evaluated at the new fine nodes, and
    otherwise u_h interpolated.

    Args:
        old: The solution on the previous level.
        disc: The new discretisation.
        rec: The old level's :class:`Reconstructor` (built if not given).
        macro_parent: The old macro cell of each cell of the new macro mesh, as returned by
            :func:`~dwr_signorini.spaces.refine_marked`. With it (simplices) every point is
            evaluated in its known old macro cell: no point location. Without it, or on
            quadrilaterals/hexahedra, the reconstructions are interpolated with point location.

    Returns:
        ``(u0, lam0)`` on ``disc.V`` and ``disc.Q``.
    """
    rec = rec or Reconstructor(old.disc)
    if macro_parent is not None and rec.simplex:
        return _transfer_by_parents(old, disc, rec, macro_parent)
    u0 = fem.Function(disc.V, name="u")
    cells = np.arange(
        disc.mesh.topology.index_map(disc.mesh.topology.dim).size_local, dtype=np.int32
    )
    data = fem.create_interpolation_data(disc.V, old.u.function_space, cells, padding=1e-10)
    u0.interpolate_nonmatching(old.u, cells, data)
    u0.x.scatter_forward()

    lam_rec_old = rec.patch_linear_multiplier(old.lam)
    P1 = fem.functionspace(disc.mesh, ("Lagrange", 1))
    lam_rec = fem.Function(P1)
    data = fem.create_interpolation_data(P1, lam_rec_old.function_space, cells, padding=1e-10)
    lam_rec.interpolate_nonmatching(lam_rec_old, cells, data)
    lam_rec.x.scatter_forward()

    mu = ufl.TestFunction(disc.Q)
    num = fem_petsc.assemble_vector(disc.form(lam_rec * mu * disc.m.ds_contact))
    den = fem_petsc.assemble_vector(disc.form(mu * disc.m.ds_contact))
    lam0 = fem.Function(disc.Q, name="lambda")
    n = disc.Q.dofmap.index_map.size_local
    lam0.x.array[:n] = num.array[:n] / den.array[:n]
    lam0.x.scatter_forward()
    num.destroy()
    den.destroy()
    return u0, lam0


def _transfer_by_parents(
    old: Solution, disc: Discretization, rec: Reconstructor, macro_parent: npt.NDArray[np.int32]
) -> tuple[fem.Function, fem.Function]:
    """:func:`transfer_solution` through the parent maps (simplices, no point location).

    A new fine cell lies in the old macro cell ``macro_parent[disc.parent_cell[c]]``; a new
    macro contact facet in the old macro cell of its new macro cell. Refined meshes carry no
    ghost cells, so every local entity has a local, owned cell to evaluate in.
    """
    u0 = fem.Function(disc.V, name="u")
    dofs = disc.V.dofmap.list[: len(disc.parent_cell)]
    nodes, first = np.unique(dofs.ravel(), return_index=True)
    cells = macro_parent[disc.parent_cell[first // dofs.shape[1]]]
    x = disc.V.tabulate_dof_coordinates()[nodes]
    bs = disc.V.dofmap.index_map_bs
    u0.x.array.reshape(-1, bs)[nodes] = rec.macro_quadratic(old.u).eval(x, cells)
    u0.x.scatter_forward()

    macro = disc.macro_mesh
    tdim = macro.topology.dim
    facets = disc.contact_mesh_to_macro
    f2c = macro.topology.connectivity(tdim - 1, tdim)
    cells = macro_parent[f2c.array[f2c.offsets[facets]]]
    mids = dmesh.compute_midpoints(macro, tdim - 1, facets)
    lam0 = fem.Function(disc.Q, name="lambda")
    lam_H = rec.macro_linear_multiplier(old.lam)
    lam0.x.array[disc.Q.dofmap.list[:, 0]] = lam_H.eval(mids, cells)[:, 0]
    lam0.x.scatter_forward()
    return u0, lam0


def _validate(
    problem: Any,
    goal: Any,
    refinement: str,
    fraction: Any,
    strategy: str,
    max_levels: Any,
    max_cells: Any,
    tol: Any,
    estimator: str,
    weights: str,
    method: str,
    exact: Any,
    callback: Any,
) -> None:
    if not isinstance(problem, SignoriniProblem):
        raise TypeError(f"problem must be a SignoriniProblem, got {type(problem).__name__}")
    if not callable(goal):
        raise TypeError(f"goal must be a callable goal(u, lam, m) -> ufl.Form, got {goal!r}")
    if refinement not in REFINEMENTS:
        raise ValueError(f"refinement must be one of {REFINEMENTS}, got {refinement!r}")
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy must be one of {STRATEGIES}, got {strategy!r}")
    if (
        isinstance(fraction, bool)
        or not isinstance(fraction, (int, float))
        or not 0.0 < fraction <= 1.0
    ):
        raise ValueError(f"fraction must be a number in (0, 1], got {fraction!r}")
    if isinstance(max_levels, bool) or not isinstance(max_levels, int) or max_levels < 1:
        raise ValueError(f"max_levels must be an integer >= 1, got {max_levels!r}")
    if max_cells is not None and (not isinstance(max_cells, int) or max_cells < 1):
        raise ValueError(f"max_cells must be a positive integer or None, got {max_cells!r}")
    if tol is not None and (not isinstance(tol, (int, float)) or not tol > 0):
        raise ValueError(f"tol must be a positive number or None, got {tol!r}")
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if weights not in WEIGHTS:
        raise ValueError(f"weights must be one of {WEIGHTS}, got {weights!r}")
    if exact is not None and (not isinstance(exact, (int, float)) or not math.isfinite(exact)):
        raise ValueError(f"exact must be a finite number (the exact J) or None, got {exact!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {callback!r}")
    simplex = problem.mesh.topology.cell_type in (
        dmesh.CellType.triangle,
        dmesh.CellType.tetrahedron,
    )
    if refinement == "adaptive" and not simplex:
        raise ValueError(
            "adaptive refinement needs a simplex mesh (triangles/tetrahedra); "
            "quadrilateral/hexahedral meshes support refinement='uniform' only"
        )


def _progress(comm: MPI.Comm, record: LevelRecord) -> None:
    if comm.rank == 0:
        print(
            f"level {record.level:2d}  cells {record.num_cells:8d}  dofs {record.num_dofs:8d}  "
            f"J_h {record.J_h: .6e}  estimate {record.estimate: .3e}  "
            f"newton {record.newton_iterations:2d}  {record.time['total']:7.2f} s",
            flush=True,
        )


def solve_adaptive(
    problem: SignoriniProblem,
    goal: Goal,
    refinement: str = "adaptive",
    fraction: float = 0.2,
    strategy: str = "fixed_fraction",
    max_levels: int = 8,
    max_cells: int | None = None,
    tol: float | None = None,
    estimator: str = "eta",
    weights: str = "patch",
    exact: float | None = None,
    output_dir: str | Path | None = None,
    callback: Callable[[LevelRecord, Solution, Estimate], None] | None = None,
    petsc_options: dict[str, Any] | None = None,
    method: str = "block",
    verbose: bool = True,
) -> AdaptiveResult:
    """Goal-oriented adaptive (or uniform) refinement for Signorini's problem.

    Args:
        problem: The problem on the initial macro mesh.
        goal: ``goal(u, lam, m) -> ufl.Form``, the quantity of interest J.
        refinement: ``"adaptive"`` (mark and refine, simplices only) or ``"uniform"``.
        fraction: Marking fraction in (0, 1] (of cells, or of indicator mass for Doerfler).
        strategy: ``"fixed_fraction"`` or ``"doerfler"``.
        max_levels: Number of levels (solves) at most.
        max_cells: Stop before a level whose fine mesh would exceed this many cells.
        tol: Stop when |estimate| <= tol.
        estimator: ``"eta"`` or ``"eta_p"``: drives marking and the stopping test.
        weights: ``"patch"`` or ``"higher_order"`` (see :func:`~dwr_signorini.estimate`).
        exact: The exact J(w), if known: fills rel_error and the effectivity indices.
        output_dir: Where to write the table (CSV, JSON, after every level) and fields (XDMF).
        callback: Called as ``callback(record, solution, estimate)`` after every level.
        petsc_options: Linear solver options.
        method: Linear algebra of the Newton steps, ``"block"`` or ``"schur"`` (see
            :func:`~dwr_signorini.solve`).
        verbose: Print a progress line per level on rank 0.

    Returns:
        The :class:`AdaptiveResult` with one :class:`LevelRecord` per level.
    """
    _validate(
        problem,
        goal,
        refinement,
        fraction,
        strategy,
        max_levels,
        max_cells,
        tol,
        estimator,
        weights,
        method,
        exact,
        callback,
    )
    comm = problem.mesh.comm
    meta = {
        "refinement": refinement,
        "fraction": fraction,
        "strategy": strategy,
        "estimator": estimator,
        "weights": weights,
        "method": method,
        "exact": exact,
        "num_processes": comm.size,
    }
    out = None
    if output_dir is not None:
        check_output_dir(output_dir, comm)
        out = OutputDirectory(output_dir, comm, name=refinement)

    result = AdaptiveResult(levels=[], meta=meta, comm=comm)
    previous: Solution | None = None
    previous_rec = None
    macro_parent = None
    current = problem
    for level in range(max_levels):
        t_start = time.perf_counter()
        with timed("discretize"):
            disc = discretize(current)
        with timed("transfer"):
            guess = (
                None
                if previous is None
                else transfer_solution(previous, disc, previous_rec, macro_parent)
            )
        if previous is not None:
            # PETSc destruction is collective: free the last level's solver on all ranks here
            # rather than whenever each rank's garbage collector gets to it.
            previous.system.destroy()
        t_setup = time.perf_counter() - t_start

        tic = time.perf_counter()
        sol = solve(disc, petsc_options=petsc_options, initial_guess=guess, method=method)
        t_solve = time.perf_counter() - tic
        est = estimate(sol, goal, estimator=estimator, weights=weights, petsc_options=petsc_options)

        value = est.value
        stop = (tol is not None and abs(value) <= tol) or level == max_levels - 1
        marked = np.zeros(0, dtype=np.int32)
        t_refine = 0.0
        next_problem = None
        if not stop:
            tic = time.perf_counter()
            if refinement == "adaptive":
                with timed("mark"):
                    marked = mark(disc, est.indicators.x.array, strategy, fraction)
            with timed("refine"):
                if refinement == "adaptive":
                    next_problem, macro_parent = refine_marked(current, marked)
                else:  # T_h, the uniform refinement of T_H, is the next macro mesh
                    next_problem = current.with_mesh(disc.mesh, disc.facet_tags)
                    macro_parent = disc.parent_cell
            t_refine = time.perf_counter() - tic
            next_cells = (
                next_problem.mesh.topology.index_map(next_problem.mesh.topology.dim).size_global
                * 2**next_problem.mesh.topology.dim
            )
            if max_cells is not None and next_cells > max_cells:
                stop = True

        record = LevelRecord(
            level=level,
            num_cells=disc.num_cells,
            num_macro_cells=disc.num_macro_cells,
            num_contact_elements=disc.num_contact_elements,
            num_dofs=disc.num_dofs,
            num_active=sol.num_active,
            J_h=est.J_h,
            eta_p=est.eta_p,
            eta=est.eta,
            estimate=value,
            contact_term=est.contact_term,
            newton_iterations=sol.newton_iterations,
            num_marked=comm.allreduce(len(marked), op=MPI.SUM),
            time={
                "setup": t_setup,
                "solve": t_solve,
                "dual": est.timings["dual"],
                "estimate": est.timings["estimate"],
                "refine": t_refine,
            },
        )
        record.time["total"] = time.perf_counter() - t_start
        if exact is not None:
            err = exact - est.J_h
            record.rel_error = abs(err) / abs(exact) if exact != 0 else abs(err)
            record.ieff_p = err / est.eta_p if est.eta_p != 0 else math.inf
            if est.eta is not None:
                record.ieff = err / est.eta if est.eta != 0 else math.inf
        result.levels.append(record)
        if out is not None:
            with timed("output"):
                out.append(record.as_dict(), meta)
                fields = [sol.u, est.indicators, est.dual.y]
                out.write_fields(level, fields, [sol.lam, est.dual.xi])
        if verbose:
            _progress(comm, record)
        if callback is not None:
            callback(record, sol, est)
        result.solution, result.estimate, result.problem = sol, est, current
        if stop:
            break
        previous, previous_rec, current = sol, est.reconstructor, next_problem
    return result
