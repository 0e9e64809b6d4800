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

Also not in the paper, with gmsh meshes, tags and load paths of their own: Cattaneo-Mindlin
with Coulomb friction, a cylinder (:mod:`~dwr_signorini.examples.cattaneo_mindlin_2d`) or a sphere
(:mod:`~dwr_signorini.examples.cattaneo_mindlin_3d`) pressed onto a rigid flat and sheared in
steps, measured against the theory (:mod:`~dwr_signorini.examples.cattaneo_mindlin_measure`).
"""

from dolfinx.mesh import CellType

from ..problem import lame_parameters, stress
from ._common import Goal, GoalContext, Material
from ._mesh import CONTACT, DIRICHLET, NEUMANN, tag_exterior_facets
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
from .cattaneo_mindlin_2d import (
    CM_CONTACT,
    CM_DEFAULTS,
    CM_TOP,
    cattaneo_mindlin_mesh,
    cattaneo_mindlin_path,
    cm_traction,
    dundurs_beta,
    hertz_half_width,
    hertz_pressure,
    stick_half_width,
)
from .cattaneo_mindlin_3d import (
    CM_DEFAULTS_3D,
    CM_SYMMETRY_Y,
    ContactPatch,
    cattaneo_mindlin_mesh_3d,
    cattaneo_mindlin_path_3d,
    cm_traction_3d,
    gather_contact_patch,
    hertz_radius,
    stick_radius,
)
from .cattaneo_mindlin_measure import (
    CMMeasure,
    ContactProfile,
    gather_contact_profile,
    measure_cattaneo_mindlin,
)
from .friction_2d import (
    FRICTION_DEFAULTS,
    FRICTION_DEFAULTS_3D,
    friction_gap,
    friction_problem,
    goal_friction_force,
)
from .indentation_3d import INDENTATION_MATERIAL, goal_total_force, indentation_problem
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
    "CM_CONTACT",
    "CM_DEFAULTS",
    "CM_DEFAULTS_3D",
    "CM_SYMMETRY_Y",
    "CM_TOP",
    "CONTACT",
    "DIRICHLET",
    "FRICTION_DEFAULTS",
    "FRICTION_DEFAULTS_3D",
    "INDENTATION_MATERIAL",
    "NEUMANN",
    "OBSTACLE_MATERIAL",
    "CMMeasure",
    "CellType",
    "ContactPatch",
    "ContactProfile",
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
    "cattaneo_mindlin_mesh",
    "cattaneo_mindlin_mesh_3d",
    "cattaneo_mindlin_path",
    "cattaneo_mindlin_path_3d",
    "cm_traction",
    "cm_traction_3d",
    "dundurs_beta",
    "exact_J_a",
    "exact_J_a2",
    "exact_contact_pressure_np",
    "exact_displacement_gradient_np",
    "exact_displacement_np",
    "exact_sigma_nn_np",
    "exact_stress_np",
    "friction_gap",
    "friction_problem",
    "gather_contact_patch",
    "gather_contact_profile",
    "goal_a",
    "goal_a2",
    "goal_a2_weight",
    "goal_bar",
    "goal_friction_force",
    "goal_obstacle",
    "goal_total_force",
    "hertz_half_width",
    "hertz_pressure",
    "hertz_radius",
    "indentation_problem",
    "lame_parameters",
    "measure_cattaneo_mindlin",
    "obstacle_3d_mesh",
    "obstacle_gap",
    "obstacle_problem",
    "obstacle_psi",
    "omega",
    "stick_half_width",
    "stick_radius",
    "stress",
    "tag_exterior_facets",
]
