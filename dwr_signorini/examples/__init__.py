"""Data of the three numerical examples of Section 5 of the paper, one module per example.

* :mod:`~dwr_signorini.examples.analytic_2d`: Example 5.1, a known solution (mesh, exact solution
  in UFL and numpy, quantities of interest J_{a,m} and J_{a,2} with their exact values);
* :mod:`~dwr_signorini.examples.bar_2d`: Example 5.2, a bar in plane stress;
* :mod:`~dwr_signorini.examples.obstacle_3d`: Example 5.3, a box pushed by an obstacle in 3D;
* :mod:`~dwr_signorini.examples.friction_2d`: a block pressed onto a cylinder and sheared, with
  Tresca friction (not in the paper).

Each provides:

* a mesh builder returning ``(mesh, facet_tags)`` with the boundary tags :data:`DIRICHLET` (1),
  :data:`NEUMANN` (2, traction-free) and :data:`CONTACT` (3, the possible contact boundary
  Gamma_C);
* UFL expressions of a :func:`ufl.SpatialCoordinate` ``x``: loads, gaps, obstacle, weights of the
  quantities of interest;
* the quantities of interest as *goal builders*: each returns a function
  ``goal(u, lam, m) -> ufl.Form`` where ``m`` provides ``m.x``, ``m.dx``, ``m.ds_contact`` and
  ``m.sigma(u)`` (see :class:`GoalContext`);
* the problem builder (:func:`analytic_problem`, :func:`bar_problem`, :func:`obstacle_problem`)
  returning a :class:`dwr_signorini.SignoriniProblem`, whose keyword arguments give variants.

Hooke's law is the package's (:func:`dwr_signorini.problem.lame_parameters`,
:func:`dwr_signorini.problem.stress`, re-exported here as :func:`lame_parameters` and
:func:`stress`).

Sign conventions (Section 2): ``n`` is the outer unit normal, ``u_n = u . n``,
``sigma_nn = n . sigma n`` and the contact pressure (Lagrange multiplier) is
``lambda_n = -sigma_nn(u)``; Signorini's conditions (2) and (7) read
``u_n - g <= 0``, ``lambda_n >= 0`` and ``lambda_n (u_n - g) = 0`` on Gamma_C.

The benchmark cases beside them (Cattaneo-Mindlin, the 3D indentation) are
:mod:`dwr_signorini.cases`.
"""

from dolfinx.mesh import CellType

from ..problem import lame_parameters, stress
from ._common import Goal, GoalContext, Material
from ._mesh import CONTACT, DIRICHLET, NEUMANN, tag_block_facets, tag_exterior_facets
from .analytic_2d import (
    ANALYTIC_MATERIAL,
    analytic_2d_mesh,
    analytic_body_force,
    analytic_contact_pressure,
    analytic_displacement,
    analytic_gap,
    analytic_problem,
    analytic_stress,
    exact_contact_pressure_np,
    exact_displacement_gradient_np,
    exact_displacement_np,
    exact_J_a,
    exact_J_a2,
    exact_sigma_nn_np,
    exact_stress_np,
    goal_a,
    goal_a2,
    goal_a2_weight,
    omega,
)
from .bar_2d import (
    BAR_BODY_FORCE,
    BAR_GAP,
    BAR_J_REF,
    BAR_MATERIAL,
    bar_2d_mesh,
    bar_body_force,
    bar_gap,
    bar_problem,
    goal_bar,
)
from .friction_2d import (
    FRICTION_DEFAULTS,
    FRICTION_DEFAULTS_3D,
    friction_gap,
    friction_problem,
    goal_friction_force,
)
from .obstacle_3d import (
    OBSTACLE_MATERIAL,
    goal_obstacle,
    obstacle_3d_mesh,
    obstacle_gap,
    obstacle_problem,
    obstacle_psi,
)

__all__ = [
    "ANALYTIC_MATERIAL",
    "BAR_BODY_FORCE",
    "BAR_GAP",
    "BAR_J_REF",
    "BAR_MATERIAL",
    "CONTACT",
    "DIRICHLET",
    "FRICTION_DEFAULTS",
    "FRICTION_DEFAULTS_3D",
    "NEUMANN",
    "OBSTACLE_MATERIAL",
    "CellType",
    "Goal",
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
    "friction_gap",
    "friction_problem",
    "goal_a",
    "goal_a2",
    "goal_a2_weight",
    "goal_bar",
    "goal_friction_force",
    "goal_obstacle",
    "lame_parameters",
    "obstacle_3d_mesh",
    "obstacle_gap",
    "obstacle_problem",
    "obstacle_psi",
    "omega",
    "stress",
    "tag_block_facets",
    "tag_exterior_facets",
]
