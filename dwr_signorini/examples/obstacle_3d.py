"""Example 5.3 of the paper (Section 5.3): a box pushed by a rigid obstacle, in 3D.

Omega = (0, 0.25) x (0, 1) x (0, 1), E = 1e5, nu = 0.3, no loads: clamped on Gamma_D = {x1 = 0},
the obstacle psi under Gamma_C = {x1 = 0.25, 0 <= x2, x3 <= 0.5} penetrates the undeformed body.
Here are its mesh, gap and obstacle, the quantity of interest and the problem builder
:func:`obstacle_problem`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
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
    "OBSTACLE_MATERIAL",
    "goal_obstacle",
    "obstacle_3d_mesh",
    "obstacle_gap",
    "obstacle_problem",
    "obstacle_psi",
]

#: Example 5.3: E = 1e5, nu = 0.3 (3D).
OBSTACLE_MATERIAL = Material(E=1.0e5, nu=0.3, model="3d")


# --------------------------------------------------------------------------------------------------
# Mesh
# --------------------------------------------------------------------------------------------------


def obstacle_3d_mesh(
    comm: MPI.Comm,
    n: Sequence[int] = (2, 8, 8),
    cell_type: CellType = CellType.tetrahedron,
) -> tuple[Mesh, MeshTags]:
    """Mesh of Example 5.3 (Section 5.3): Omega = (0, 0.25) x (0, 1) x (0, 1).

    Args:
        comm: MPI communicator.
        n: Numbers of cells in x1, x2, x3.
        cell_type: ``CellType.tetrahedron`` or ``CellType.hexahedron``.

    Returns:
        The mesh (``GhostMode.none``) and its exterior facet tags.

    Raises:
        ValueError: If ``n[1]`` or ``n[2]`` is odd or the cell type is not 3D.

    Tags: 1 on Gamma_D = {x1 = 0}, 3 on Gamma_C = {x1 = 0.25, 0 <= x2, x3 <= 0.5}, 2 on the rest.
    ``n[1]`` and ``n[2]`` must be even so that Gamma_C is a union of facets; with multiples of 8
    (the default) the region B = {0.625 <= x2, x3 <= 0.875} of the quantity of interest is also
    resolved by the mesh (see :func:`goal_obstacle`).
    """
    check_cell_type(cell_type, (CellType.tetrahedron, CellType.hexahedron))
    n = [int(k) for k in n]
    if len(n) != 3 or n[1] % 2 != 0 or n[2] % 2 != 0:
        raise ValueError(f"n must have 3 entries with n[1], n[2] even, got {n}")
    msh = _mesh.create_box(
        comm,
        [np.array([0.0, 0.0, 0.0]), np.array([0.25, 1.0, 1.0])],
        n,
        cell_type,
        ghost_mode=GhostMode.none,
    )
    tol = 1.0e-10

    def classify(p: npt.NDArray[np.float64]) -> npt.NDArray[np.int32]:
        tags = np.full(p.shape[1], NEUMANN, dtype=np.int32)
        tags[np.abs(p[0]) < tol] = DIRICHLET
        tags[(np.abs(p[0] - 0.25) < tol) & (p[1] < 0.5) & (p[2] < 0.5)] = CONTACT
        return tags

    return msh, tag_exterior_facets(msh, classify)


# --------------------------------------------------------------------------------------------------
# Obstacle, goal, problem
# --------------------------------------------------------------------------------------------------


def obstacle_psi(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Obstacle surface psi of Example 5.3 (Section 5.3).

    Args:
        x: Spatial coordinate of a 3D mesh.

    Returns:
        The scalar expression psi.

    With ``z = sqrt((x2 - 0.25)^2 + (x3 - 0.25)^2)``:
    ``psi = 0.25 + 0.05 (65536 z^8 - 1)`` for ``z <= 0.25`` and 0.25 otherwise. Since
    ``65536 = 4^8``, psi is continuous (and C^0 only) at z = 0.25 and ``psi = 0.2`` at the centre.
    Written in ``z^2`` (no square root).
    """
    z2 = (x[1] - 0.25) ** 2 + (x[2] - 0.25) ** 2
    return ufl.conditional(ufl.le(z2, 0.0625), 0.25 + 0.05 * (65536.0 * z2**4 - 1.0), 0.25)


def obstacle_gap(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Gap of Example 5.3 (Section 5.3): ``g = psi - 0.25``.

    The contact face is flat (x1 = 0.25, outer normal (1, 0, 0)), so ``g = psi - phi`` with
    ``phi = 0.25`` (Section 2); ``g = -0.05`` at (x2, x3) = (0.25, 0.25) (the obstacle penetrates
    the undeformed body) and ``g = 0`` for ``z >= 0.25``.

    Args:
        x: Spatial coordinate of a 3D mesh.

    Returns:
        The scalar gap expression.
    """
    z2 = (x[1] - 0.25) ** 2 + (x[2] - 0.25) ** 2
    return ufl.conditional(ufl.le(z2, 0.0625), 0.05 * (65536.0 * z2**4 - 1.0), 0.0)


def goal_obstacle() -> Goal:
    """Quantity of interest of Example 5.3 (Section 5.3).

    Returns:
        ``goal(u, lam, m) -> 1e-3 * chi_B * inner(m.sigma(u), m.sigma(u)) * m.dx
        + lam * m.ds_contact``.

    ``J(u, lambda_n) = 1e-3 int_B sigma(u) : sigma(u) dx + int_{Gamma_C} lambda_n ds`` with
    B = {0.625 <= x2, x3 <= 0.875}. B is represented by a ``ufl.conditional`` indicator at the
    quadrature points, exact if B is resolved by the mesh (n[1], n[2] multiples of 8 in
    :func:`obstacle_3d_mesh`, preserved under refinement).
    """

    def goal(u: ufl.core.expr.Expr, lam: ufl.core.expr.Expr, m: GoalContext) -> ufl.Form:
        x = m.x
        eps = 1.0e-12
        in_2 = ufl.And(ufl.ge(x[1], 0.625 - eps), ufl.le(x[1], 0.875 + eps))
        in_3 = ufl.And(ufl.ge(x[2], 0.625 - eps), ufl.le(x[2], 0.875 + eps))
        chi_b = ufl.conditional(ufl.And(in_2, in_3), 1.0, 0.0)
        s = m.sigma(u)
        return 1.0e-3 * chi_b * ufl.inner(s, s) * m.dx + lam * m.ds_contact

    return goal


def obstacle_problem(
    comm: MPI.Comm,
    n: Sequence[int] = (2, 8, 8),
    cell_type: CellType = CellType.tetrahedron,
    *,
    E: float = OBSTACLE_MATERIAL.E,
    nu: float = OBSTACLE_MATERIAL.nu,
    body_force: VectorData = None,
    gap: float | Callable[[ufl.SpatialCoordinate], Any] = obstacle_gap,
) -> SignoriniProblem:
    """Example 5.3 (Section 5.3) on the macro mesh :func:`obstacle_3d_mesh`.

    The keyword arguments default to the paper's data (no loads); callers change them for
    variants of the example (e.g. a load with ``gap=1e3`` for a contact-free box).

    Args:
        comm: MPI communicator.
        n: Numbers of macro cells in x1, x2, x3 (``n[1]``, ``n[2]`` even).
        cell_type: ``CellType.tetrahedron`` or ``CellType.hexahedron``.
        E: Young's modulus.
        nu: Poisson's ratio.
        body_force: Volume load, see :class:`~dwr_signorini.SignoriniProblem`.
        gap: Gap on Gamma_C.

    Returns:
        The problem, clamped on :data:`DIRICHLET` with possible contact on :data:`CONTACT`.
    """
    return example_problem(
        obstacle_3d_mesh(comm, n, cell_type),
        E=E,
        nu=nu,
        model=OBSTACLE_MATERIAL.model,
        body_force=body_force,
        gap=gap,
    )
