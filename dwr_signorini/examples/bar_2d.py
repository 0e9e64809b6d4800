"""Example 5.2 of the paper (Section 5.2): a bar pushed towards a rigid obstacle, plane stress.

The bar Omega = (0, 0.05) x (0, 0.2), E = 10, nu = 0.33, is clamped at y = 0 and pushed by the
volume force f = (0.5, 0) towards the obstacle at distance g = 0.005 from
Gamma_C = {0.05} x [0.15, 0.2]. Here are its mesh, data, quantity of interest and the paper's
reference value, and the problem builder :func:`bar_problem`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import mesh as _mesh
from dolfinx.mesh import CellType, GhostMode, Mesh, MeshTags

from ..problem import SignoriniProblem, VectorData
from ._common import Goal, GoalContext, Material, example_problem
from ._mesh import CONTACT, DIRICHLET, NEUMANN, check_cell_type, tag_exterior_facets

__all__ = [
    "BAR_BODY_FORCE",
    "BAR_GAP",
    "BAR_J_REF",
    "BAR_MATERIAL",
    "bar_2d_mesh",
    "bar_body_force",
    "bar_gap",
    "bar_problem",
    "goal_bar",
]

#: Example 5.2: E = 10, nu = 0.33, plane stress.
BAR_MATERIAL = Material(E=10.0, nu=0.33, model="plane_stress")
#: Example 5.2: constant volume force f = (0.5, 0).
BAR_BODY_FORCE = (0.5, 0.0)
#: Example 5.2: constant gap g = 0.005.
BAR_GAP = 0.005
#: Example 5.2: the paper's reference value of J(u) = int_B grad u : grad u dx, obtained there by
#: extrapolation of uniformly refined solutions (not an exact value).
BAR_J_REF = 5.934693870188204e-6


# --------------------------------------------------------------------------------------------------
# Mesh
# --------------------------------------------------------------------------------------------------


def bar_2d_mesh(
    comm: MPI.Comm,
    nx: int = 4,
    ny: int = 16,
    cell_type: CellType = CellType.triangle,
) -> tuple[Mesh, MeshTags]:
    """Mesh of Example 5.2 (Section 5.2): the bar Omega = (0, 0.05) x (0, 0.2).

    Tags: 1 on Gamma_D = [0, 0.05] x {0}, 3 on Gamma_C = {0.05} x [0.15, 0.2], 2 on the rest.
    ``ny`` must be a multiple of 4, so that y = 0.15 (end of Gamma_C) and y = 0.05 (top of the
    region B = [0, 0.05]^2 of the quantity of interest, see :func:`goal_bar`) are mesh lines.

    Args:
        comm: MPI communicator.
        nx: Number of cells in x.
        ny: Number of cells in y, a multiple of 4.
        cell_type: ``CellType.triangle`` or ``CellType.quadrilateral``.

    Returns:
        The mesh (``GhostMode.none``) and its exterior facet tags.

    Raises:
        ValueError: If ``ny`` is not a multiple of 4 or the cell type is not 2D.
    """
    check_cell_type(cell_type, (CellType.triangle, CellType.quadrilateral))
    if ny % 4 != 0:
        raise ValueError(f"ny must be a multiple of 4 (Gamma_C a union of facets), got {ny}")
    msh = _mesh.create_rectangle(
        comm,
        [np.array([0.0, 0.0]), np.array([0.05, 0.2])],
        [nx, ny],
        cell_type,
        ghost_mode=GhostMode.none,
    )
    tol = 1.0e-10

    def classify(p: npt.NDArray[np.float64]) -> npt.NDArray[np.int32]:
        tags = np.full(p.shape[1], NEUMANN, dtype=np.int32)
        tags[np.abs(p[1]) < tol] = DIRICHLET
        tags[(np.abs(p[0] - 0.05) < tol) & (p[1] > 0.15)] = CONTACT
        return tags

    return msh, tag_exterior_facets(msh, classify)


# --------------------------------------------------------------------------------------------------
# Data, goal, problem
# --------------------------------------------------------------------------------------------------


def bar_body_force(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Constant volume force ``f = (0.5, 0)`` of Example 5.2 (Section 5.2).

    Args:
        x: Spatial coordinate of a 2D mesh (unused; for a uniform interface).

    Returns:
        The constant vector expression.
    """
    del x
    return ufl.as_vector(BAR_BODY_FORCE)


def bar_gap(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Constant gap ``g = 0.005`` of Example 5.2 (Section 5.2).

    Args:
        x: Spatial coordinate of a 2D mesh (unused; for a uniform interface).

    Returns:
        The constant scalar expression.
    """
    del x
    return ufl.as_ufl(BAR_GAP)


def goal_bar() -> Goal:
    """Quantity of interest of Example 5.2 (Section 5.2): J(u) = int_B grad u : grad u dx.

    Returns:
        ``goal(u, lam, m) -> chi_B * inner(grad u, grad u) * m.dx``.

    B = [0, 0.05]^2 is the part y <= 0.05 of the bar (its clamped end). It is represented by a
    ``ufl.conditional`` indicator evaluated at the quadrature points, which is exact only if B is
    resolved by the mesh: y = 0.05 is a mesh line of :func:`bar_2d_mesh` (``ny`` a multiple of 4)
    and stays one under refinement.
    """

    def goal(u: ufl.core.expr.Expr, lam: ufl.core.expr.Expr, m: GoalContext) -> ufl.Form:
        del lam
        chi_b = ufl.conditional(ufl.le(m.x[1], 0.05 + 1.0e-12), 1.0, 0.0)
        return chi_b * ufl.inner(ufl.grad(u), ufl.grad(u)) * m.dx

    return goal


def bar_problem(
    comm: MPI.Comm,
    nx: int = 4,
    ny: int = 16,
    cell_type: CellType = CellType.triangle,
    *,
    E: float = BAR_MATERIAL.E,
    nu: float = BAR_MATERIAL.nu,
    model: str = BAR_MATERIAL.model,
    body_force: VectorData = BAR_BODY_FORCE,
    gap: float | Callable[[ufl.SpatialCoordinate], Any] = BAR_GAP,
) -> SignoriniProblem:
    """Example 5.2 (Section 5.2) on the macro mesh :func:`bar_2d_mesh`.

    The keyword arguments default to the paper's data; callers change them for variants of the
    example (e.g. ``model="plane_strain"`` with ``nu`` near 1/2).

    Args:
        comm: MPI communicator.
        nx: Number of macro cells in x.
        ny: Number of macro cells in y, a multiple of 4.
        cell_type: ``CellType.triangle`` or ``CellType.quadrilateral``.
        E: Young's modulus.
        nu: Poisson's ratio.
        model: ``"plane_stress"`` or ``"plane_strain"``.
        body_force: Volume load, see :class:`~dwr_signorini.SignoriniProblem`.
        gap: Gap on Gamma_C.

    Returns:
        The problem, clamped on :data:`DIRICHLET` with possible contact on :data:`CONTACT`.
    """
    return example_problem(
        bar_2d_mesh(comm, nx, ny, cell_type),
        E=E,
        nu=nu,
        model=model,
        body_force=body_force,
        gap=gap,
    )
