"""Data of the three numerical examples of Section 5 of the paper.

Everything here is pure problem data; no finite element problem is solved:

* mesh builders returning ``(mesh, facet_tags)`` with the boundary tags :data:`DIRICHLET` (1),
  :data:`NEUMANN` (2, traction-free) and :data:`CONTACT` (3, the possible contact boundary
  Gamma_C);
* UFL expressions of a :func:`ufl.SpatialCoordinate` ``x``: the exact solution of Example 5.1 and
  its body force, gaps, obstacle, weights of the quantities of interest;
* the quantities of interest of Section 5 as *goal builders*: each returns a function
  ``goal(u, lam, m) -> ufl.Form`` where ``m`` provides ``m.x``, ``m.dx``, ``m.ds_contact`` and
  ``m.sigma(u)`` (see :class:`GoalContext`);
* exact reference values of the quantities of interest of Example 5.1, computed with numpy by
  high-order composite Gauss quadrature, independently of any finite element code.

Sign conventions (Section 2): ``n`` is the outer unit normal, ``u_n = u . n``,
``sigma_nn = n . sigma n`` and the contact pressure (Lagrange multiplier) is
``lambda_n = -sigma_nn(u)``; Signorini's conditions (2) and (7) read
``u_n - g <= 0``, ``lambda_n >= 0`` and ``lambda_n (u_n - g) = 0`` on Gamma_C.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import mesh as _mesh
from dolfinx.mesh import CellType, GhostMode, Mesh, MeshTags

__all__ = [
    "ANALYTIC_MATERIAL",
    "BAR_BODY_FORCE",
    "BAR_GAP",
    "BAR_J_REF",
    "BAR_MATERIAL",
    "CONTACT",
    "DIRICHLET",
    "NEUMANN",
    "OBSTACLE_MATERIAL",
    "GoalContext",
    "Material",
    "analytic_2d_mesh",
    "analytic_body_force",
    "analytic_contact_pressure",
    "analytic_displacement",
    "analytic_gap",
    "analytic_problem",
    "analytic_stress",
    "bar_2d_mesh",
    "bar_body_force",
    "bar_gap",
    "bar_problem",
    "exact_J_a",
    "exact_J_a2",
    "exact_contact_pressure_np",
    "exact_displacement_gradient_np",
    "exact_displacement_np",
    "exact_sigma_nn_np",
    "exact_stress_np",
    "goal_a",
    "goal_a2",
    "goal_a2_weight",
    "goal_bar",
    "goal_obstacle",
    "lame_parameters",
    "obstacle_3d_mesh",
    "obstacle_gap",
    "obstacle_problem",
    "obstacle_psi",
    "omega",
    "stress",
]

#: Facet tag of the Dirichlet boundary Gamma_D.
DIRICHLET = 1
#: Facet tag of the (homogeneous, traction-free) Neumann boundary Gamma_N.
NEUMANN = 2
#: Facet tag of the possible contact boundary Gamma_C.
CONTACT = 3


# --------------------------------------------------------------------------------------------------
# Material law
# --------------------------------------------------------------------------------------------------


def lame_parameters(E: float, nu: float, plane_stress: bool = False) -> tuple[float, float]:
    """Lamé parameters ``(mu, lambda)`` of Hooke's law (Section 2).

    Args:
        E: Young's modulus.
        nu: Poisson's ratio.
        plane_stress: If True, return the plane stress parameter
            ``lambda* = 2 mu lambda / (lambda + 2 mu) = E nu / (1 - nu^2)`` (Example 5.2);
            otherwise the 3D / plane strain value ``E nu / ((1 + nu)(1 - 2 nu))``
            (Examples 5.1 and 5.3).

    Returns:
        The shear modulus ``mu = E / (2 (1 + nu))`` and the first Lamé parameter.
    """
    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    if plane_stress:
        lmbda = 2.0 * mu * lmbda / (lmbda + 2.0 * mu)
    return mu, lmbda


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material of one example (Section 5).

    Attributes:
        E: Young's modulus.
        nu: Poisson's ratio.
        plane_stress: Plane stress (True) or plane strain / 3D (False).
    """

    E: float
    nu: float
    plane_stress: bool = False

    def lame(self) -> tuple[float, float]:
        """Return ``(mu, lambda)``, see :func:`lame_parameters`."""
        return lame_parameters(self.E, self.nu, self.plane_stress)

    def sigma(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Return the stress tensor ``sigma(u)``, see :func:`stress`."""
        return stress(u, self.E, self.nu, self.plane_stress)


#: Example 5.1: E = 10, nu = 0.3, plane strain.
ANALYTIC_MATERIAL = Material(E=10.0, nu=0.3, plane_stress=False)
#: Example 5.2: E = 10, nu = 0.33, plane stress.
BAR_MATERIAL = Material(E=10.0, nu=0.33, plane_stress=True)
#: Example 5.3: E = 1e5, nu = 0.3 (3D).
OBSTACLE_MATERIAL = Material(E=1.0e5, nu=0.3, plane_stress=False)

#: Example 5.2: constant volume force f = (0.5, 0).
BAR_BODY_FORCE = (0.5, 0.0)
#: Example 5.2: constant gap g = 0.005.
BAR_GAP = 0.005
#: Example 5.2: the paper's reference value of J(u) = int_B grad u : grad u dx, obtained there by
#: extrapolation of uniformly refined solutions (not an exact value).
BAR_J_REF = 5.934693870188204e-6


def stress(
    u: ufl.core.expr.Expr, E: float, nu: float, plane_stress: bool = False
) -> ufl.core.expr.Expr:
    """Hooke's law ``sigma(u) = 2 mu eps(u) + lambda tr(eps(u)) I`` (Section 2).

    Args:
        u: Displacement (a UFL vector expression, e.g. a ``dolfinx.fem.Function`` or
            :func:`analytic_displacement`).
        E: Young's modulus.
        nu: Poisson's ratio.
        plane_stress: Use the plane stress Lamé parameter (2D only), see
            :func:`lame_parameters`.

    Returns:
        The symmetric stress tensor as a UFL expression.
    """
    mu, lmbda = lame_parameters(E, nu, plane_stress)
    eps = ufl.sym(ufl.grad(u))
    return 2.0 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(ufl.shape(u)[0])


# --------------------------------------------------------------------------------------------------
# Meshes
# --------------------------------------------------------------------------------------------------


def _tag_exterior_facets(
    msh: Mesh, classify: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.int32]]
) -> MeshTags:
    """Tag every exterior facet of ``msh`` by its midpoint.

    Works in parallel: each process tags the exterior facets it sees (owned or ghost); facets on
    process boundaries are interior and are not returned by ``exterior_facet_indices``.

    Args:
        msh: The mesh.
        classify: Maps midpoints, shape ``(3, num_facets)``, to tags in {1, 2, 3}.

    Returns:
        Facet tags on all exterior facets.
    """
    tdim = msh.topology.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    facets = _mesh.exterior_facet_indices(msh.topology)
    midpoints = _mesh.compute_midpoints(msh, fdim, facets).reshape(-1, 3)
    values = np.asarray(classify(midpoints.T), dtype=np.int32)
    if not np.all(np.isin(values, (DIRICHLET, NEUMANN, CONTACT))):
        raise RuntimeError("an exterior facet was not classified as Dirichlet, Neumann or contact")
    order = np.argsort(facets)
    return _mesh.meshtags(msh, fdim, facets[order], values[order])


def _check_cell_type(cell_type: CellType, allowed: Sequence[CellType]) -> None:
    if cell_type not in allowed:
        names = " or ".join(c.name for c in allowed)
        raise ValueError(f"cell_type must be {names}, got {cell_type}")


def analytic_2d_mesh(
    comm: MPI.Comm,
    nx: int = 12,
    ny: int = 8,
    cell_type: CellType = CellType.quadrilateral,
) -> tuple[Mesh, MeshTags]:
    """Mesh of Example 5.1 (Section 5.1): Omega = (-3, 0) x (-1, 1).

    Tags: 1 on Gamma_D = {-3} x [-1, 1], 2 on Gamma_N = (-3, 0) x {-1, 1},
    3 on Gamma_C = {0} x [-1, 1].

    The default 12 x 8 quadrilaterals is the coarsest macro mesh T_H of the paper; its uniform
    refinement (24 x 16, M_Omega = 384 cells, level L = 0 of Tables 1-2) carries the
    displacement, since the paper uses H = 2h (Section 4). With ``ny`` a multiple of 4 the kinks
    of u_2 at y = +-1/2 are mesh lines.

    Args:
        comm: MPI communicator.
        nx: Number of cells in x.
        ny: Number of cells in y.
        cell_type: ``CellType.triangle`` or ``CellType.quadrilateral``.

    Returns:
        The mesh (``GhostMode.none``) and its exterior facet tags.
    """
    _check_cell_type(cell_type, (CellType.triangle, CellType.quadrilateral))
    msh = _mesh.create_rectangle(
        comm,
        [np.array([-3.0, -1.0]), np.array([0.0, 1.0])],
        [nx, ny],
        cell_type,
        ghost_mode=GhostMode.none,
    )
    tol = 1.0e-8

    def classify(p: npt.NDArray[np.float64]) -> npt.NDArray[np.int32]:
        tags = np.full(p.shape[1], NEUMANN, dtype=np.int32)
        tags[np.abs(p[0] + 3.0) < tol] = DIRICHLET
        tags[np.abs(p[0]) < tol] = CONTACT
        return tags

    return msh, _tag_exterior_facets(msh, classify)


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
    _check_cell_type(cell_type, (CellType.triangle, CellType.quadrilateral))
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

    return msh, _tag_exterior_facets(msh, classify)


def obstacle_3d_mesh(
    comm: MPI.Comm,
    n: Sequence[int] = (2, 8, 8),
    cell_type: CellType = CellType.tetrahedron,
) -> tuple[Mesh, MeshTags]:
    """Mesh of Example 5.3 (Section 5.3): Omega = (0, 0.25) x (0, 1) x (0, 1).

    Tags: 1 on Gamma_D = {x1 = 0}, 3 on Gamma_C = {x1 = 0.25, 0 <= x2, x3 <= 0.5}, 2 on the rest.
    ``n[1]`` and ``n[2]`` must be even so that Gamma_C is a union of facets; with multiples of 8
    (the default) the region B = {0.625 <= x2, x3 <= 0.875} of the quantity of interest is also
    resolved by the mesh (see :func:`goal_obstacle`).

    Args:
        comm: MPI communicator.
        n: Numbers of cells in x1, x2, x3.
        cell_type: ``CellType.tetrahedron`` or ``CellType.hexahedron``.

    Returns:
        The mesh (``GhostMode.none``) and its exterior facet tags.

    Raises:
        ValueError: If ``n[1]`` or ``n[2]`` is odd or the cell type is not 3D.
    """
    _check_cell_type(cell_type, (CellType.tetrahedron, CellType.hexahedron))
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

    return msh, _tag_exterior_facets(msh, classify)


# --------------------------------------------------------------------------------------------------
# Example 5.1: exact solution (UFL)
# --------------------------------------------------------------------------------------------------


def _u1_ufl(X: ufl.core.expr.Expr | float, Y: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """u1 of Example 5.1 as a UFL expression of the coordinates X, Y."""
    a = X**2 / 18.0 + 0.5
    return ufl.conditional(ufl.lt(abs(Y), a), -((X + 3.0) ** 2) * (Y - a) ** 4 * (Y + a) ** 4, 0.0)


def _u2_ufl(X: ufl.core.expr.Expr | float, Y: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """u2 of Example 5.1 as a UFL expression of the coordinates X, Y."""
    q = (Y - 0.5) ** 3 * (Y + 0.5) ** 4 + (Y - 0.5) ** 4 * (Y + 0.5) ** 3
    return ufl.conditional(
        ufl.lt(abs(Y), 0.5), 27.0 / np.pi * ufl.sin(4.0 * np.pi * (X + 3.0) / 3.0) * q, 0.0
    )


def analytic_displacement(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Exact displacement u = (u1, u2) of Example 5.1 (Section 5.1).

    ``u1 = -(x+3)^2 (y - x^2/18 - 1/2)^4 (y + x^2/18 + 1/2)^4`` for ``|y| < x^2/18 + 1/2``,
    ``u2 = 27/pi sin(4 pi (x+3)/3) [(y-1/2)^3 (y+1/2)^4 + (y-1/2)^4 (y+1/2)^3]`` for
    ``|y| < 1/2``, both zero elsewhere. The pieces join C^2 (u1 even C^3) across the curves
    ``|y| = x^2/18 + 1/2`` and ``|y| = 1/2``.

    Args:
        x: Spatial coordinate of a 2D mesh.

    Returns:
        The vector expression built with ``ufl.conditional``.
    """
    return ufl.as_vector((_u1_ufl(x[0], x[1]), _u2_ufl(x[0], x[1])))


def analytic_stress(
    x: ufl.SpatialCoordinate, E: float = 10.0, nu: float = 0.3
) -> ufl.core.expr.Expr:
    """Plane strain stress ``sigma(u)`` of the exact solution of Example 5.1 (Section 5.1).

    Args:
        x: Spatial coordinate of a 2D mesh.
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        The stress tensor, obtained by UFL differentiation of :func:`analytic_displacement`.
    """
    return stress(analytic_displacement(x), E, nu, plane_stress=False)


def analytic_body_force(
    x: ufl.SpatialCoordinate, E: float = 10.0, nu: float = 0.3
) -> ufl.core.expr.Expr:
    """Volume force ``f = -div sigma(u)`` of Example 5.1 (Section 5.1), plane strain.

    Computed by UFL differentiation of the exact displacement; ``f`` is continuous (u is C^2).

    Args:
        x: Spatial coordinate of a 2D mesh.
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        The vector expression ``-div(sigma(u))``.
    """
    return -ufl.div(analytic_stress(x, E, nu))


def analytic_gap(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Gap of Example 5.1 (Section 5.1): ``g(y) = u1(0, y)``.

    ``g(y) = -9 (y^2 - 1/4)^4`` for ``|y| < 1/2`` and 0 otherwise; only ``x[1]`` is used. Since
    ``u_n = u1 = g`` on Gamma_C, the exact solution is in contact on all of Gamma_C (strictly
    active for ``|y| < 1/2``, with lambda_n = 0 (bi-active) for ``|y| >= 1/2``).

    Args:
        x: Spatial coordinate of a 2D mesh.

    Returns:
        The scalar gap expression.
    """
    return _u1_ufl(0.0, x[1])


def analytic_contact_pressure(
    x: ufl.SpatialCoordinate, E: float = 10.0, nu: float = 0.3
) -> ufl.core.expr.Expr:
    """Exact contact pressure ``lambda_n = -sigma_nn(u)`` of Example 5.1 (Section 5.1).

    Meaningful on Gamma_C = {x = 0} with n = (1, 0), where it equals
    ``6 (lambda + 2 mu) (y^2 - 1/4)^4 >= 0`` for ``|y| < 1/2`` and 0 otherwise (elsewhere the
    expression is ``-sigma_11(u)``).

    Args:
        x: Spatial coordinate of a 2D mesh.
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        The scalar expression ``-sigma(u)[0, 0]``.
    """
    return -analytic_stress(x, E, nu)[0, 0]


def omega(x: ufl.SpatialCoordinate, m: float, d: float = 0.5) -> ufl.core.expr.Expr:
    """Cut-off function of the quantity of interest J_{a,m} (Section 5.1).

    ``omega_m(x) = 0.5 (tanh(20 (d - |x - (m, 0)|_2)) + 1)``, a smoothed indicator of the disc
    B_d((m, 0)).

    Args:
        x: Spatial coordinate of a 2D mesh.
        m: Abscissa of the centre (m, 0), m in [-3, 0].
        d: Radius of the disc (0.5 in the paper).

    Returns:
        The scalar weight expression.
    """
    r = ufl.sqrt((x[0] - m) ** 2 + x[1] ** 2)
    return 0.5 * (ufl.tanh(20.0 * (d - r)) + 1.0)


def goal_a2_weight(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Weight of J_{a,2} (Section 5.1): ``0.5 tanh(20 (0.25 - |y - 0.125|)) + 0.5``.

    Args:
        x: Spatial coordinate of a 2D mesh (only ``x[1]`` is used).

    Returns:
        The scalar weight expression.
    """
    return 0.5 * ufl.tanh(20.0 * (0.25 - abs(x[1] - 0.125))) + 0.5


# --------------------------------------------------------------------------------------------------
# Examples 5.2 and 5.3: loads and obstacles (UFL)
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


def obstacle_psi(x: ufl.SpatialCoordinate) -> ufl.core.expr.Expr:
    """Obstacle surface psi of Example 5.3 (Section 5.3).

    With ``z = sqrt((x2 - 0.25)^2 + (x3 - 0.25)^2)``:
    ``psi = 0.25 + 0.05 (65536 z^8 - 1)`` for ``z <= 0.25`` and 0.25 otherwise. Since
    ``65536 = 4^8``, psi is continuous (and C^0 only) at z = 0.25 and ``psi = 0.2`` at the centre.
    Written in ``z^2`` (no square root).

    Args:
        x: Spatial coordinate of a 3D mesh.

    Returns:
        The scalar expression psi.
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


# --------------------------------------------------------------------------------------------------
# Quantities of interest
# --------------------------------------------------------------------------------------------------


class GoalContext(Protocol):
    """What a goal builder needs from the solver.

    Attributes:
        x: ``ufl.SpatialCoordinate`` of the mesh.
        dx: Cell measure of the mesh.
        ds_contact: Measure of the contact boundary, e.g. ``ds(CONTACT)``.
        sigma: Callable returning the stress tensor ``sigma(u)`` of the example's material.
    """

    x: ufl.core.expr.Expr
    dx: ufl.Measure
    ds_contact: ufl.Measure
    sigma: Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]


#: A quantity of interest ``J(u, lambda_n)`` as a function returning a UFL form.
Goal = Callable[[ufl.core.expr.Expr, ufl.core.expr.Expr, GoalContext], ufl.Form]


def goal_a(m_center: float = -0.5) -> Goal:
    """Quantity of interest J_{a,m}(u) = int_Omega omega_m(x) |u|^2 dx (Section 5.1).

    ``J_{a,1}`` is ``m_center = -0.5``; Figure 4 varies m in [-3, 0].

    Args:
        m_center: Abscissa m of the centre of the weight :func:`omega`.

    Returns:
        ``goal(u, lam, m) -> omega(m.x, m_center) * inner(u, u) * m.dx``.
    """

    def goal(u: ufl.core.expr.Expr, lam: ufl.core.expr.Expr, m: GoalContext) -> ufl.Form:
        del lam
        return omega(m.x, m_center) * ufl.inner(u, u) * m.dx

    return goal


def goal_a2() -> Goal:
    """Quantity of interest J_{a,2}(lambda_n) (Section 5.1).

    ``J_{a,2} = int_{-1}^{1} (0.5 tanh(20 (0.25 - |y - 0.125|)) + 0.5) lambda_n(y)^2 dy``,
    integrated over Gamma_C. The weight has a kink at y = 0.125, a mesh line when ``ny`` is a
    multiple of 16.

    Returns:
        ``goal(u, lam, m) -> goal_a2_weight(m.x) * lam**2 * m.ds_contact``.
    """

    def goal(u: ufl.core.expr.Expr, lam: ufl.core.expr.Expr, m: GoalContext) -> ufl.Form:
        del u
        return goal_a2_weight(m.x) * lam**2 * m.ds_contact

    return goal


def goal_bar() -> Goal:
    """Quantity of interest of Example 5.2 (Section 5.2): J(u) = int_B grad u : grad u dx.

    B = [0, 0.05]^2 is the part y <= 0.05 of the bar (its clamped end). It is represented by a
    ``ufl.conditional`` indicator evaluated at the quadrature points, which is exact only if B is
    resolved by the mesh: y = 0.05 is a mesh line of :func:`bar_2d_mesh` (``ny`` a multiple of 4)
    and stays one under refinement.

    Returns:
        ``goal(u, lam, m) -> chi_B * inner(grad u, grad u) * m.dx``.
    """

    def goal(u: ufl.core.expr.Expr, lam: ufl.core.expr.Expr, m: GoalContext) -> ufl.Form:
        del lam
        chi_b = ufl.conditional(ufl.le(m.x[1], 0.05 + 1.0e-12), 1.0, 0.0)
        return chi_b * ufl.inner(ufl.grad(u), ufl.grad(u)) * m.dx

    return goal


def goal_obstacle() -> Goal:
    """Quantity of interest of Example 5.3 (Section 5.3).

    ``J(u, lambda_n) = 1e-3 int_B sigma(u) : sigma(u) dx + int_{Gamma_C} lambda_n ds`` with
    B = {0.625 <= x2, x3 <= 0.875}. B is represented by a ``ufl.conditional`` indicator at the
    quadrature points, exact if B is resolved by the mesh (n[1], n[2] multiples of 8 in
    :func:`obstacle_3d_mesh`, preserved under refinement).

    Returns:
        ``goal(u, lam, m) -> 1e-3 * chi_B * inner(m.sigma(u), m.sigma(u)) * m.dx
        + lam * m.ds_contact``.
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


# --------------------------------------------------------------------------------------------------
# Example 5.1: exact solution (numpy) and exact reference values
# --------------------------------------------------------------------------------------------------


def exact_displacement_np(x: npt.ArrayLike, y: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Exact displacement of Example 5.1 (Section 5.1) in numpy.

    Args:
        x: Abscissae (broadcastable with ``y``).
        y: Ordinates.

    Returns:
        Array of shape ``(2, *shape)`` with u1 and u2.
    """
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    a = x**2 / 18.0 + 0.5
    p = y**2 - a**2
    q = y**2 - 0.25
    u1 = np.where(np.abs(y) < a, -((x + 3.0) ** 2) * p**4, 0.0)
    u2 = np.where(
        np.abs(y) < 0.5, 27.0 / np.pi * np.sin(4.0 * np.pi * (x + 3.0) / 3.0) * 2.0 * y * q**3, 0.0
    )
    return np.stack((u1, u2))


def exact_displacement_gradient_np(x: npt.ArrayLike, y: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Gradient ``grad u[i, j] = d u_i / d x_j`` of the exact solution of Example 5.1.

    Hand-differentiated closed form (Section 5.1); with ``a = x^2/18 + 1/2``,
    ``p = y^2 - a^2`` and ``q = y^2 - 1/4``: ``u1 = -(x+3)^2 p^4`` and
    ``u2 = 27/pi sin(4 pi (x+3)/3) 2 y q^3`` on their supports.

    Args:
        x: Abscissae (broadcastable with ``y``).
        y: Ordinates.

    Returns:
        Array of shape ``(2, 2, *shape)``.
    """
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    a = x**2 / 18.0 + 0.5
    p = y**2 - a**2
    q = y**2 - 0.25
    in1 = np.abs(y) < a
    in2 = np.abs(y) < 0.5
    arg = 4.0 * np.pi * (x + 3.0) / 3.0
    du1_dx = -2.0 * (x + 3.0) * p**4 + 8.0 * (x + 3.0) ** 2 * a * (x / 9.0) * p**3
    du1_dy = -8.0 * y * (x + 3.0) ** 2 * p**3
    du2_dx = 36.0 * np.cos(arg) * 2.0 * y * q**3
    du2_dy = 27.0 / np.pi * np.sin(arg) * 2.0 * q**2 * (7.0 * y**2 - 0.25)
    return np.array(
        [
            [np.where(in1, du1_dx, 0.0), np.where(in1, du1_dy, 0.0)],
            [np.where(in2, du2_dx, 0.0), np.where(in2, du2_dy, 0.0)],
        ]
    )


def exact_stress_np(
    x: npt.ArrayLike, y: npt.ArrayLike, E: float = 10.0, nu: float = 0.3
) -> npt.NDArray[np.float64]:
    """Plane strain stress of the exact solution of Example 5.1 in numpy.

    Args:
        x: Abscissae (broadcastable with ``y``).
        y: Ordinates.
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        Array of shape ``(2, 2, *shape)``.
    """
    mu, lmbda = lame_parameters(E, nu)
    g = exact_displacement_gradient_np(x, y)
    eps = 0.5 * (g + np.swapaxes(g, 0, 1))
    tr = eps[0, 0] + eps[1, 1]
    sig = 2.0 * mu * eps
    sig[0, 0] += lmbda * tr
    sig[1, 1] += lmbda * tr
    return sig


def exact_sigma_nn_np(
    y: npt.ArrayLike, E: float = 10.0, nu: float = 0.3
) -> npt.NDArray[np.float64]:
    """Normal stress ``sigma_nn = sigma_11(0, y)`` of the exact solution on Gamma_C (Section 5.1).

    Args:
        y: Ordinates on Gamma_C = {0} x [-1, 1].
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        ``sigma_nn`` at (0, y), computed from :func:`exact_stress_np`.
    """
    y = np.asarray(y, dtype=float)
    return exact_stress_np(np.zeros_like(y), y, E, nu)[0, 0]


def exact_contact_pressure_np(
    y: npt.ArrayLike, E: float = 10.0, nu: float = 0.3
) -> npt.NDArray[np.float64]:
    """Exact contact pressure ``lambda_n(y) = -sigma_nn(0, y)`` of Example 5.1 (Section 5.1).

    In closed form ``6 (lambda + 2 mu) (y^2 - 1/4)^4`` for ``|y| < 1/2``, else 0.

    Args:
        y: Ordinates on Gamma_C.
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        ``lambda_n`` at (0, y).
    """
    return -exact_sigma_nn_np(y, E, nu)


def _breakpoints(lo: float, hi: float, h: float, extra: Sequence[float] = ()) -> np.ndarray:
    """Breakpoints of [lo, hi] including ``extra`` (where inside), subintervals of length <= h."""
    knots = sorted({lo, hi, *(e for e in extra if lo < e < hi)})
    out = [knots[0]]
    for p, q in itertools.pairwise(knots):
        k = max(1, int(np.ceil((q - p) / h - 1.0e-12)))
        out.extend(np.linspace(p, q, k + 1)[1:])
    return np.asarray(out)


def _composite_gauss(breaks: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights of the composite n-point Gauss-Legendre rule on ``breaks``."""
    t, w = np.polynomial.legendre.leggauss(n)
    lo, hi = breaks[:-1, None], breaks[1:, None]
    return (0.5 * (hi - lo) * t + 0.5 * (hi + lo)).ravel(), (0.5 * (hi - lo) * w).ravel()


def _omega_np(x: np.ndarray, y: np.ndarray, m: float, d: float = 0.5) -> np.ndarray:
    return 0.5 * (np.tanh(20.0 * (d - np.hypot(x - m, y))) + 1.0)


def _goal_a2_weight_np(y: np.ndarray) -> np.ndarray:
    return 0.5 * np.tanh(20.0 * (0.25 - np.abs(y - 0.125))) + 0.5


def _J_a_quadrature(m_center: float, h: float, n: int) -> float:
    """J_{a,m} of the exact solution by composite Gauss quadrature, split at the kinks.

    |u|^2 = u1^2 + u2^2 with supp u1 = {|y| <= a(x)}, a = x^2/18 + 1/2, and
    supp u2 = [-3, 0] x [-1/2, 1/2]: each part is integrated over its own support, on which it is
    a polynomial (times sin^2) and smooth. u1^2 uses y = a(x) t, t in [-1, 1], dy = a(x) dt. The
    only remaining non-smoothness, the tip of the cone |x - (m, 0)| in omega_m (of size
    ~1e-7), sits at a corner of the subdivision (x = m, y = 0 are breakpoints).
    """
    x, wx = _composite_gauss(_breakpoints(-3.0, 0.0, h, (m_center,)), n)
    t, wt = _composite_gauss(_breakpoints(-1.0, 1.0, h, (0.0,)), n)
    xx, tt = np.meshgrid(x, t, indexing="ij")
    a = xx**2 / 18.0 + 0.5
    yy = a * tt
    u1 = exact_displacement_np(xx, yy)[0]
    i1 = wx @ (a * u1**2 * _omega_np(xx, yy, m_center)) @ wt
    y, wy = _composite_gauss(_breakpoints(-0.5, 0.5, h, (0.0,)), n)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    u2 = exact_displacement_np(xx, yy)[1]
    i2 = wx @ (u2**2 * _omega_np(xx, yy, m_center)) @ wy
    return float(i1 + i2)


def _J_a2_quadrature(E: float, nu: float, h: float, n: int) -> float:
    """J_{a,2} of the exact solution by composite Gauss quadrature on [-1/2, 1/2].

    lambda_n vanishes for |y| >= 1/2; the weight has a kink at y = 0.125 (a breakpoint).
    """
    y, wy = _composite_gauss(_breakpoints(-0.5, 0.5, h, (0.125,)), n)
    return float(wy @ (_goal_a2_weight_np(y) * exact_contact_pressure_np(y, E, nu) ** 2))


def _agreed(coarse: float, fine: float, what: str) -> float:
    if abs(coarse - fine) > 1.0e-12 * abs(fine):
        raise RuntimeError(f"{what}: quadrature not converged ({coarse!r} vs {fine!r})")
    return fine


@functools.lru_cache(maxsize=64)
def exact_J_a(m_center: float = -0.5) -> float:
    """Exact J_{a,m}(u) = int_Omega omega_m |u|^2 dx of Example 5.1 (Section 5.1).

    Computed with numpy only (no finite elements): composite Gauss-Legendre quadrature on the
    supports of u1 and u2, split at the curves |y| = x^2/18 + 1/2 and |y| = 1/2 and at the centre
    (m, 0) of the weight; two rules (16 points on subintervals <= 0.1, 24 points on subintervals
    <= 0.0625) must agree to 1e-12 relative. J_{a,1} = J_{a,-0.5} = 4.78055755404685e-4.

    Args:
        m_center: Abscissa m of the centre of the weight omega_m, m in [-3, 0].

    Returns:
        The value of the quantity of interest for the exact solution.

    Raises:
        RuntimeError: If the two quadrature rules disagree.
    """
    m_center = float(m_center)
    return _agreed(
        _J_a_quadrature(m_center, 0.1, 16),
        _J_a_quadrature(m_center, 0.0625, 24),
        f"exact_J_a({m_center})",
    )


@functools.lru_cache(maxsize=64)
def exact_J_a2(E: float = 10.0, nu: float = 0.3) -> float:
    """Exact J_{a,2}(lambda_n) of Example 5.1 (Section 5.1).

    ``int_{-1}^{1} (0.5 tanh(20 (0.25 - |y - 0.125|)) + 0.5) lambda_n(y)^2 dy`` with the exact
    ``lambda_n = -sigma_nn(u)`` on x = 0, by composite Gauss-Legendre quadrature split at the
    kinks y = -1/2, 0.125, 1/2; two rules must agree to 1e-12 relative.
    J_{a,2} = 2.50310203659923e-2 for E = 10, nu = 0.3.

    Args:
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        The value of the quantity of interest for the exact solution.

    Raises:
        RuntimeError: If the two quadrature rules disagree.
    """
    return _agreed(
        _J_a2_quadrature(E, nu, 0.1, 16),
        _J_a2_quadrature(E, nu, 0.05, 24),
        f"exact_J_a2({E}, {nu})",
    )


# --------------------------------------------------------------------------------------------
# The three examples as ready SignoriniProblems
# --------------------------------------------------------------------------------------------
def _problem(mesh_and_tags: tuple[Mesh, MeshTags], **kwargs: Any) -> Any:
    from .problem import SignoriniProblem

    msh, tags = mesh_and_tags
    kwargs.setdefault("contact", CONTACT)
    kwargs.setdefault("dirichlet", (DIRICHLET,))
    return SignoriniProblem(msh, tags, **kwargs)


def analytic_problem(
    comm: MPI.Comm,
    nx: int = 12,
    ny: int = 8,
    cell_type: CellType = CellType.quadrilateral,
    **overrides: Any,
) -> Any:
    """Example 5.1 (Section 5.1) on an nx x ny macro mesh; keyword arguments override the data."""
    kwargs = {
        "E": ANALYTIC_MATERIAL.E,
        "nu": ANALYTIC_MATERIAL.nu,
        "model": "plane_strain",
        "body_force": analytic_body_force,
        "gap": analytic_gap,
    }
    kwargs.update(overrides)
    return _problem(analytic_2d_mesh(comm, nx, ny, cell_type), **kwargs)


def bar_problem(
    comm: MPI.Comm,
    nx: int = 4,
    ny: int = 16,
    cell_type: CellType = CellType.triangle,
    **overrides: Any,
) -> Any:
    """Example 5.2 (Section 5.2): the bar, plane stress, pushed towards the obstacle."""
    kwargs = {
        "E": BAR_MATERIAL.E,
        "nu": BAR_MATERIAL.nu,
        "model": "plane_stress",
        "body_force": BAR_BODY_FORCE,
        "gap": BAR_GAP,
    }
    kwargs.update(overrides)
    return _problem(bar_2d_mesh(comm, nx, ny, cell_type), **kwargs)


def obstacle_problem(
    comm: MPI.Comm,
    n: Sequence[int] = (2, 8, 8),
    cell_type: CellType = CellType.tetrahedron,
    **overrides: Any,
) -> Any:
    """Example 5.3 (Section 5.3): a box pushed by a rigid obstacle, no loads."""
    kwargs = {
        "E": OBSTACLE_MATERIAL.E,
        "nu": OBSTACLE_MATERIAL.nu,
        "model": "3d",
        "gap": obstacle_gap,
    }
    kwargs.update(overrides)
    return _problem(obstacle_3d_mesh(comm, n, cell_type), **kwargs)
