"""One finite-strain Newton step against one linear-elastic semi-smooth Newton step, same mesh.

A block (unit square in plane strain, unit cube in 3D, macro mesh n x n (x n)), its top clamped
and moved down by 10 % of its height, its bottom in frictionless contact with the rigid plane
below it (E = 10, nu = 0.3). Two problems on the same mesh, differing only in ``material``:
``ds.LinearElastic()`` and ``ds.NeoHookean()``. Each is solved once (the finite-strain one in
two load steps), so that the step timed is a step at the converged active set, as the last
Newton step of a solve; then, ``--repeat`` times, the minimum kept:

* **linear** (``method="block"``, :class:`~dwr_signorini.linalg.NewtonSystem`, every step
  factored): *assembly* = K, N, N^T, M, f, g (once per mesh) and the symmetric Newton matrix
  A_s of the active set; *factorisation* = MUMPS's LDL^T of A_s with its analysis (the first
  step); *solve*. A later step of the same solve assembles only A_s (K is the same) and reuses
  the analysis (``numeric``): columns ``later`` of the table.
* **finite strain** (:class:`~dwr_signorini.finite_strain.FiniteStrainSystem`): *assembly* =
  the residual (P(F) : grad v, the loads, the contact force, the gaps G) and the Jacobian
  (dR/du, B, B^T, the saddle matrix, as ``newton_matrix``: refilled in the kept matrices);
  *factorisation* = MUMPS's LU of it with its analysis (the KSP reset first, as in the first
  step of a solve); *solve*. A later step refills the same matrix and reuses the analysis
  (``numeric``): columns ``fs later``, against the linear ``later``.

Times are wall-clock seconds, the maximum over ranks, JIT compilation excluded (the forms are
compiled by the solves before). Prints a table of ratios (finite strain / linear) and writes
``benchmarks/results/finite_strain_step[_np<N>].csv`` and ``.json``::

    scripts/fenicsx python3 benchmarks/finite_strain_step.py
    scripts/fenicsx python3 benchmarks/finite_strain_step.py --sizes-2d 16 32 --sizes-3d 3
    scripts/fenicsx mpirun -n 2 python3 benchmarks/finite_strain_step.py
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

import dwr_signorini as ds
from dwr_signorini import timing
from dwr_signorini.linalg import NewtonSystem
from dwr_signorini.linalg.factor import ReusePolicy
from dwr_signorini.spaces import discretize

BOTTOM, TOP = 1, 2
E, NU, PRESS = 10.0, 0.3, 0.1
RESULTS = Path(__file__).resolve().parent / "results"


def block(comm: MPI.Comm, dim: int, n: int, material: Any) -> ds.SignoriniProblem:
    """The block of the module docstring on an n x n (x n) macro mesh."""
    if dim == 2:
        msh = dmesh.create_unit_square(comm, n, n)
    else:
        msh = dmesh.create_unit_cube(comm, n, n, n)
    fdim = dim - 1
    msh.topology.create_connectivity(fdim, dim)
    facets = dmesh.exterior_facet_indices(msh.topology)
    height = dmesh.compute_midpoints(msh, fdim, facets)[:, dim - 1]
    tag = np.where(np.isclose(height, 0.0), BOTTOM, np.where(np.isclose(height, 1.0), TOP, 0))
    keep = tag > 0
    tags = dmesh.meshtags(msh, fdim, facets[keep], tag[keep].astype(np.int32))
    normal = [0.0] * dim
    normal[-1] = -1.0
    top = (0.0,) * (dim - 1) + (-PRESS,)
    return ds.SignoriniProblem(
        msh, tags, contact=BOTTOM, dirichlet={TOP: top}, E=E, nu=NU,
        model="plane_strain" if dim == 2 else "3d", material=material,
        gap=ds.obstacles.Plane([0.0] * dim, normal),
    )


def wall(comm: MPI.Comm, work: Callable[[], object]) -> float:
    """Seconds of ``work()`` between barriers, the maximum over ranks."""
    comm.barrier()
    tic = time.perf_counter()
    work()
    return comm.allreduce(time.perf_counter() - tic, op=MPI.MAX)


def phases(comm: MPI.Comm, work: Callable[[], object]) -> dict[str, float]:
    """The package's timed phases (:mod:`dwr_signorini.timing`) charged during ``work()``."""
    comm.barrier()
    before = timing.snapshot()
    work()
    after = timing.snapshot()
    return {k: comm.allreduce(after[k] - before[k], op=MPI.MAX)
            for k in ("assemble", "factorize", "newton solve")}


def linear_step(problem: ds.SignoriniProblem, active: np.ndarray) -> dict[str, float]:
    """Assembly, factorisation and solve of the linear block path's step (module docstring)."""
    comm = problem.mesh.comm
    disc = discretize(problem)
    out: dict[str, float] = {}
    holder: list[NewtonSystem] = []
    build = phases(comm, lambda: holder.append(NewtonSystem(disc, reuse=ReusePolicy(-1.0))))
    system = holder[0]
    try:
        first = phases(comm, lambda: system.solve_active(active))
        later = phases(comm, lambda: system.solve_active(active))
    finally:
        system.destroy()
    out["assembly"] = build["assemble"] + first["assemble"]
    out["factorisation"] = first["factorize"]
    out["solve"] = first["newton solve"]
    out["later_assembly"] = later["assemble"]
    out["numeric"] = later["factorize"]
    out["later_solve"] = later["newton solve"]
    return out


def finite_strain_step(sol) -> dict[str, float]:
    """Assembly, factorisation and solve of a finite-strain step at ``sol`` (module docstring)."""
    system, comm = sol.system, sol.disc.comm
    residual: list = []

    def assemble() -> None:
        residual[:] = system.residuals()
        system.newton_matrix(sol.active)

    def factor() -> None:
        system.ksp.reset()  # the analysis is redone, as in a solve's first step
        system.ksp.setOperators(system._J)
        system.ksp.setUp()

    out = {"assembly": wall(comm, assemble), "factorisation": wall(comm, factor)}
    R, G, _ = residual
    rhs = system._J.createVecLeft()
    rhs.array_w[:] = np.concatenate([-R, np.where(sol.active, G, 0.0)])
    x = rhs.duplicate()
    try:
        out["solve"] = wall(comm, lambda: system.ksp.solve(rhs, x))
        system._J.scale(-1.0)  # the values change (twice), the pattern not: numeric only
        system._J.scale(-1.0)

        def refactor() -> None:
            system.ksp.setOperators(system._J)
            system.ksp.setUp()

        out["numeric"] = wall(comm, refactor)
        step = np.abs(x.array_r)
        out["update_max"] = comm.allreduce(float(step.max(initial=0.0)), op=MPI.MAX)
    finally:
        rhs.destroy()
        x.destroy()
    return out


def measure(comm: MPI.Comm, dim: int, n: int, repeat: int) -> dict:
    """One row: sizes, the minima over ``repeat`` runs of both steps."""
    linear = block(comm, dim, n, ds.LinearElastic())
    with ds.solve(linear, method="block") as sol:
        active, num_active = sol.active.copy(), sol.num_active
        num_dofs, num_cells = sol.disc.num_dofs, sol.disc.num_cells
        multipliers = sol.disc.num_contact_elements
    lin = [linear_step(linear, active) for _ in range(repeat)]
    nonlinear = block(comm, dim, n, ds.NeoHookean())
    with ds.solve_path(nonlinear, None, load_factors=[0.5, 1.0]) as path:
        sol = path.solutions[-1]
        fs_active = sol.num_active
        fs = [finite_strain_step(sol) for _ in range(repeat)]
    row = {"dim": dim, "n": n, "cells": num_cells, "dofs": num_dofs,
           "multipliers": multipliers, "active_linear": num_active, "active_fs": fs_active,
           "processes": comm.size, "repeat": repeat}
    for prefix, runs in (("lin", lin), ("fs", fs)):
        for key in runs[0]:
            row[f"{prefix}_{key}"] = min(r[key] for r in runs)
    for prefix in ("lin", "fs"):
        row[f"{prefix}_step"] = sum(row[f"{prefix}_{k}"] for k in
                                    ("assembly", "factorisation", "solve"))
    row["lin_later_step"] = row["lin_later_assembly"] + row["lin_numeric"] + row["lin_later_solve"]
    row["fs_later_step"] = row["fs_assembly"] + row["fs_numeric"] + row["fs_solve"]
    for key in ("assembly", "factorisation", "solve", "numeric", "step", "later_step"):
        row[f"ratio_{key}"] = row[f"fs_{key}"] / row[f"lin_{key}"]
    return row


COLUMNS = [  # (header, key, format)
    ("dim", "dim", "{:>3d}"), ("n", "n", "{:>3d}"), ("cells", "cells", "{:>7d}"),
    ("dofs", "dofs", "{:>7d}"), ("|A|", "active_fs", "{:>4d}"),
    ("lin asm", "lin_assembly", "{:>8.4f}"), ("fs asm", "fs_assembly", "{:>8.4f}"),
    ("x", "ratio_assembly", "{:>5.1f}"),
    ("lin fact", "lin_factorisation", "{:>8.4f}"), ("fs fact", "fs_factorisation", "{:>8.4f}"),
    ("x", "ratio_factorisation", "{:>5.1f}"),
    ("lin num", "lin_numeric", "{:>8.4f}"), ("fs num", "fs_numeric", "{:>8.4f}"),
    ("x", "ratio_numeric", "{:>5.1f}"),
    ("lin sol", "lin_solve", "{:>7.4f}"), ("fs sol", "fs_solve", "{:>7.4f}"),
    ("x", "ratio_solve", "{:>5.1f}"),
    ("lin step", "lin_step", "{:>8.4f}"), ("fs step", "fs_step", "{:>8.4f}"),
    ("x", "ratio_step", "{:>5.1f}"),
    ("lin later", "lin_later_step", "{:>9.4f}"), ("fs later", "fs_later_step", "{:>8.4f}"),
    ("x", "ratio_later_step", "{:>5.1f}"),
]


def print_row(row: dict | None) -> None:
    """The table's header (``None``) or a row."""
    cells = []
    for header, key, fmt in COLUMNS:
        width = len(fmt.format(0 if "d}" in fmt else 0.0))
        cells.append(f"{header:>{width}}" if row is None else fmt.format(row[key]))
    print(" ".join(cells), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes-2d", type=int, nargs="*", default=[16, 32, 64],
                        help="macro cells per side of the unit square")
    parser.add_argument("--sizes-3d", type=int, nargs="*", default=[3, 6, 10],
                        help="macro cells per side of the unit cube")
    parser.add_argument("--repeat", type=int, default=3, help="runs per step, the minimum kept")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = []
    if comm.rank == 0:
        print(f"one Newton step, finite strain (Neo-Hookean) / linear, {comm.size} process(es), "
              f"seconds (max over ranks), min of {args.repeat}")
        print_row(None)
    for dim, sizes in ((2, args.sizes_2d), (3, args.sizes_3d)):
        for n in sizes:
            row = measure(comm, dim, n, args.repeat)
            rows.append(row)
            if comm.rank == 0:
                print_row(row)
    if comm.rank == 0:
        RESULTS.mkdir(parents=True, exist_ok=True)
        name = "finite_strain_step" + ("" if comm.size == 1 else f"_np{comm.size}")
        with open(RESULTS / f"{name}.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        (RESULTS / f"{name}.json").write_text(json.dumps({"rows": rows}, indent=1))
        print(f"wrote {RESULTS / name}.csv and .json")


if __name__ == "__main__":
    main()
