"""Example 5.1 of the paper (Section 5.1): a known solution on Omega = (-3, 0) x (-1, 1).

Plane strain, E = 10, nu = 0.3; clamped on Gamma_D = {-3} x [-1, 1], traction-free on
Gamma_N = (-3, 0) x {-1, 1}, possible contact on Gamma_C = {0} x [-1, 1]. Here are its mesh, the
exact solution with its body force and gap (UFL, and numpy for checks), the quantities of
interest J_{a,m} and J_{a,2} with their exact values (numpy composite Gauss quadrature,
independent of any finite element code), and the problem builder :func:`analytic_problem`.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Sequence
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import mesh as _mesh
from dolfinx.mesh import CellType, GhostMode, Mesh, MeshTags

from ..problem import SignoriniProblem, VectorData, lame_parameters, stress
from ._common import Goal, GoalContext, Material, example_problem
from ._mesh import CONTACT, DIRICHLET, NEUMANN, check_cell_type, tag_exterior_facets

__all__ = [
    "ANALYTIC_MATERIAL",
    "analytic_2d_mesh",
    "analytic_body_force",
    "analytic_contact_pressure",
    "analytic_displacement",
    "analytic_gap",
    "analytic_problem",
    "analytic_stress",
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
    "omega",
]

#: Example 5.1: E = 10, nu = 0.3, plane strain.
ANALYTIC_MATERIAL = Material(E=10.0, nu=0.3, model="plane_strain")


# --------------------------------------------------------------------------------------------------
# Mesh
# --------------------------------------------------------------------------------------------------


def analytic_2d_mesh(
    comm: MPI.Comm,
    nx: int = 12,
    ny: int = 8,
    cell_type: CellType = CellType.quadrilateral,
) -> tuple[Mesh, MeshTags]:
    """Mesh of Example 5.1 (Section 5.1): Omega = (-3, 0) x (-1, 1).

    Args:
        comm: MPI communicator.
        nx: Number of cells in x.
        ny: Number of cells in y.
        cell_type: ``CellType.triangle`` or ``CellType.quadrilateral``.

    Returns:
        The mesh (``GhostMode.none``) and its exterior facet tags.

    Tags: 1 on Gamma_D = {-3} x [-1, 1], 2 on Gamma_N = (-3, 0) x {-1, 1},
    3 on Gamma_C = {0} x [-1, 1].

    The default 12 x 8 quadrilaterals is the coarsest macro mesh T_H of the paper; its uniform
    refinement (24 x 16, M_Omega = 384 cells, level L = 0 of Tables 1-2) carries the
    displacement, since the paper uses H = 2h (Section 4). With ``ny`` a multiple of 4 the kinks
    of u_2 at y = +-1/2 are mesh lines.
    """
    check_cell_type(cell_type, (CellType.triangle, CellType.quadrilateral))
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

    return msh, tag_exterior_facets(msh, classify)


# --------------------------------------------------------------------------------------------------
# Exact solution, data and weights (UFL)
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

    Args:
        x: Spatial coordinate of a 2D mesh.

    Returns:
        The vector expression built with ``ufl.conditional``.

    ``u1 = -(x+3)^2 (y - x^2/18 - 1/2)^4 (y + x^2/18 + 1/2)^4`` for ``|y| < x^2/18 + 1/2``,
    ``u2 = 27/pi sin(4 pi (x+3)/3) [(y-1/2)^3 (y+1/2)^4 + (y-1/2)^4 (y+1/2)^3]`` for
    ``|y| < 1/2``, both zero elsewhere. The pieces join C^2 (u1 even C^3) across the curves
    ``|y| = x^2/18 + 1/2`` and ``|y| = 1/2``.
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
    return stress(analytic_displacement(x), E, nu, "plane_strain")


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
# Quantities of interest
# --------------------------------------------------------------------------------------------------


def goal_a(m_center: float = -0.5) -> Goal:
    """Quantity of interest ``J_{a,m}(u) = int_Omega omega_m(x) |u|^2 dx`` (Section 5.1).

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
    """Exact ``J_{a,m}(u) = int_Omega omega_m |u|^2 dx`` of Example 5.1 (Section 5.1).

    Args:
        m_center: Abscissa m of the centre of the weight omega_m, m in [-3, 0].

    Returns:
        The value of the quantity of interest for the exact solution.

    Raises:
        RuntimeError: If the two quadrature rules disagree.

    Computed with numpy only (no finite elements): composite Gauss-Legendre quadrature on the
    supports of u1 and u2, split at the curves ``|y| = x^2/18 + 1/2`` and ``|y| = 1/2`` and at
    the centre (m, 0) of the weight; two rules (16 points on subintervals <= 0.1, 24 points on
    subintervals <= 0.0625) must agree to 1e-12 relative.
    J_{a,1} = J_{a,-0.5} = 4.78055755404685e-4.
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

    Args:
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        The value of the quantity of interest for the exact solution.

    Raises:
        RuntimeError: If the two quadrature rules disagree.

    ``int_{-1}^{1} (0.5 tanh(20 (0.25 - |y - 0.125|)) + 0.5) lambda_n(y)^2 dy`` with the exact
    ``lambda_n = -sigma_nn(u)`` on x = 0, by composite Gauss-Legendre quadrature split at the
    kinks y = -1/2, 0.125, 1/2; two rules must agree to 1e-12 relative.
    J_{a,2} = 2.50310203659923e-2 for E = 10, nu = 0.3.
    """
    return _agreed(
        _J_a2_quadrature(E, nu, 0.1, 16),
        _J_a2_quadrature(E, nu, 0.05, 24),
        f"exact_J_a2({E}, {nu})",
    )


# --------------------------------------------------------------------------------------------------
# The problem
# --------------------------------------------------------------------------------------------------


def analytic_problem(
    comm: MPI.Comm,
    nx: int = 12,
    ny: int = 8,
    cell_type: CellType = CellType.quadrilateral,
    *,
    E: float = ANALYTIC_MATERIAL.E,
    nu: float = ANALYTIC_MATERIAL.nu,
    model: str = ANALYTIC_MATERIAL.model,
    body_force: VectorData = analytic_body_force,
    gap: float | Callable[[ufl.SpatialCoordinate], Any] = analytic_gap,
) -> SignoriniProblem:
    """Example 5.1 (Section 5.1) on the macro mesh :func:`analytic_2d_mesh`.

    The keyword arguments default to the paper's data; callers change them for variants of the
    example (e.g. ``gap=1e3`` for a contact-free run).

    Args:
        comm: MPI communicator.
        nx: Number of macro cells in x.
        ny: Number of macro cells in y.
        cell_type: ``CellType.triangle`` or ``CellType.quadrilateral``.
        E: Young's modulus.
        nu: Poisson's ratio.
        model: ``"plane_strain"`` or ``"plane_stress"``.
        body_force: Volume load, see :class:`~dwr_signorini.SignoriniProblem`
            (default :func:`analytic_body_force`, of E = 10 and nu = 0.3).
        gap: Gap on Gamma_C (default :func:`analytic_gap`).

    Returns:
        The problem, clamped on :data:`DIRICHLET` with possible contact on :data:`CONTACT`.
    """
    return example_problem(
        analytic_2d_mesh(comm, nx, ny, cell_type),
        E=E,
        nu=nu,
        model=model,
        body_force=body_force,
        gap=gap,
    )
