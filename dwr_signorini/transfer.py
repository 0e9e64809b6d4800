"""Warm start of the next level: w_h of the old level carried to the new discretisation.

The old solution's reconstructions (Section 4: i_2h^(2) u_h, the fine nodal values read as macro
P2 values, and the linear recovery i_2H^(1) lambda_H) are evaluated on the new mesh, through the
parent maps of the refinement where they are known, so that the semi-smooth Newton method of the
next level starts near its solution.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc

from .newton import Solution
from .partition import CellOrigin
from .reconstruction import Reconstructor, node_occurrences
from .spaces import Discretization

__all__ = ["transfer_solution"]


def transfer_solution(
    old: Solution,
    disc: Discretization,
    rec: Reconstructor | None = None,
    macro_parent: npt.NDArray[np.int32] | CellOrigin | None = None,
) -> tuple[fem.Function, ...]:
    """Warm start on a new discretisation.

    lambda_0 (and lambda_t,0) on each new macro contact facet is the facet mean of the old
    vertex-averaged linear recovery i_2H^(1) lambda_H. u_0 is, with ``macro_parent``, the old
    i_2h^(2) u_h (the fine nodal values read as macro P2 values, Section 4) evaluated at the new
    fine nodes, and otherwise u_h interpolated; its Dirichlet dofs hold the prescribed values.

    Args:
        old: The solution on the previous level.
        disc: The new discretisation.
        rec: The old level's :class:`Reconstructor` (built if not given).
        macro_parent: The old macro cell of each cell of the new macro mesh, as returned by
            :func:`~dwr_signorini.spaces.refine_marked`, or, where the new macro mesh was
            redistributed, the :class:`~dwr_signorini.partition.CellOrigin` of its cells
            (:func:`~dwr_signorini.partition.rebalance_level`). With it (simplices) every point
            is evaluated in its known old macro cell, on the rank that holds it: no point
            location. Without it, or on quadrilaterals/hexahedra, the reconstructions are
            interpolated with point location.

    Returns:
        ``(u0, lam0)`` on ``disc.V`` and ``disc.Q`` (``(u0, lam0, lam_t0)`` with friction; every
        multiplier is transferred as lambda).
    """
    carry_obstacle_displacement(old, disc)
    rec = rec or Reconstructor(old.disc)
    if macro_parent is not None and rec.simplex:
        if isinstance(macro_parent, CellOrigin):
            return _transfer_by_parents(old, disc, rec, macro_parent.evaluate)
        parent = macro_parent
        return _transfer_by_parents(old, disc, rec, lambda f, x, c: f.eval(x, parent[c]))
    u0 = fem.Function(disc.V, name="u")
    cells = np.arange(
        disc.mesh.topology.index_map(disc.mesh.topology.dim).size_local, dtype=np.int32
    )
    data = fem.create_interpolation_data(disc.V, old.u.function_space, cells, padding=1e-10)
    u0.interpolate_nonmatching(old.u, cells, data)
    u0.x.scatter_forward()
    _prescribe(u0, disc)

    return (u0, *(_by_interpolation(f, disc, rec, cells) for f in old.multipliers))


def carry_obstacle_displacement(old: Any, disc: Discretization) -> None:
    """Start a force-controlled obstacle of ``disc`` where it was in ``old`` (a warm start).

    The displacement delta belongs to the warm start like u and lambda: from the transferred
    iterate with delta = 0 the rule (21) would see every facet far off the obstacle.

    Args:
        old: The previous :class:`~dwr_signorini.Solution`.
        disc: The new discretisation.
    """
    constant = disc.fields.obstacle_displacement
    if constant is not None and old.obstacle_displacement is not None:
        constant.value = old.obstacle_displacement


def _by_interpolation(
    old: fem.Function, disc: Discretization, rec: Reconstructor, cells: npt.NDArray[np.int32]
) -> fem.Function:
    """A multiplier's facet means on the new macro contact facets, by point location."""
    lam_rec_old = rec.patch_linear_multiplier(old)
    P1 = fem.functionspace(disc.mesh, ("Lagrange", 1))
    lam_rec = fem.Function(P1)
    data = fem.create_interpolation_data(P1, lam_rec_old.function_space, cells, padding=1e-10)
    lam_rec.interpolate_nonmatching(lam_rec_old, cells, data)
    lam_rec.x.scatter_forward()

    mu = ufl.TestFunction(disc.Q)
    num = fem_petsc.assemble_vector(disc.form(lam_rec * mu * disc.m.ds_contact))
    den = fem_petsc.assemble_vector(disc.form(mu * disc.m.ds_contact))
    lam0 = fem.Function(disc.Q, name=old.name)
    n = disc.Q.dofmap.index_map.size_local
    lam0.x.array[:n] = num.array[:n] / den.array[:n]
    lam0.x.scatter_forward()
    num.destroy()
    den.destroy()
    return lam0


def _prescribe(u0: fem.Function, disc: Discretization) -> None:
    """Set the prescribed Dirichlet values of the new level into the warm start."""
    for bc in disc.prescribed_bcs:
        bc.set(u0.x.array)


#: ``evaluate(f, x, cells)``: ``f`` of the old macro mesh at points ``x`` of new macro cells.
Evaluate = Callable[[fem.Function, np.ndarray, npt.NDArray[np.int32]], np.ndarray]


def _transfer_by_parents(
    old: Solution, disc: Discretization, rec: Reconstructor, evaluate: Evaluate
) -> tuple[fem.Function, ...]:
    """:func:`transfer_solution` through the parent maps (simplices, no point location).

    A new fine cell lies in the old macro cell that contains its new macro cell
    ``disc.parent_cell[c]``; a new macro contact facet in the one of its new macro cell.
    ``evaluate`` finds that old cell (collective where it sends points to other ranks).
    Refined meshes carry no ghost cells, so every local entity has a local, owned cell.
    """
    u0 = fem.Function(disc.V, name="u")
    dofs = disc.V.dofmap.list[: len(disc.parent_cell)]
    # A cell of each node (any: the old macro P2 function is continuous).
    imap = disc.V.dofmap.index_map
    nodes, first = node_occurrences(dofs, imap.size_local + imap.num_ghosts)
    cells = disc.parent_cell[first // dofs.shape[1]]
    x = disc.V.tabulate_dof_coordinates()[nodes]
    bs = disc.V.dofmap.index_map_bs
    u0.x.array.reshape(-1, bs)[nodes] = evaluate(rec.macro_quadratic(old.u), x, cells)
    u0.x.scatter_forward()
    _prescribe(u0, disc)

    macro = disc.macro_mesh
    tdim = macro.topology.dim
    facets = disc.contact_mesh_to_macro
    f2c = macro.topology.connectivity(tdim - 1, tdim)
    cells = f2c.array[f2c.offsets[facets]]
    mids = dmesh.compute_midpoints(macro, tdim - 1, facets)
    lams = []
    for f in old.multipliers:
        lam0 = fem.Function(disc.Q, name=f.name)
        lam_H = rec.macro_linear_multiplier(f)
        lam0.x.array[disc.Q.dofmap.list[:, 0]] = evaluate(lam_H, mids, cells)[:, 0]
        lam0.x.scatter_forward()
        lams.append(lam0)
    return (u0, *lams)
