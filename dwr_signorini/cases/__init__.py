"""Benchmark cases beside the paper's examples: problems the demos, tests and benchmarks measure.

Not in the paper, with gmsh meshes (:mod:`dwr_signorini.meshes`), tags and load paths of their own:

* Cattaneo-Mindlin with Coulomb friction: a cylinder
  (:mod:`~dwr_signorini.cases.cattaneo_mindlin_2d`) or a sphere
  (:mod:`~dwr_signorini.cases.cattaneo_mindlin_3d`) pressed onto a rigid flat and sheared in
  steps (the meshes and the load path they share: :mod:`~dwr_signorini.cases.load_path`),
  measured against the theory (:mod:`~dwr_signorini.cases.cattaneo_mindlin_measure`, with
  :mod:`~dwr_signorini.cases.measurement`);
* Spence's problem (:mod:`~dwr_signorini.cases.spence_block`): a rigid cylinder pressed with
  friction into a large block, the half-plane of the theory;
* :mod:`~dwr_signorini.cases.indentation_3d`: a sphere pressed into a block, the goal the total
  contact force (the benchmarks' 3D problem);
* :mod:`~dwr_signorini.cases.rubber_cylinder`: finite strain, a Neo-Hookean cylinder pressed
  onto a rigid flat and slid along it (the finite-strain demo and the felupe benchmark).

They build on :mod:`dwr_signorini.examples` (its boundary tags, material record and goal
interface) and are installed with the package, so they work outside the checkout.
"""

from .cattaneo_mindlin_2d import (
    CM_DEFAULTS,
    cattaneo_mindlin_mesh,
    cattaneo_mindlin_path,
    cm_traction,
    dundurs_beta,
    hertz_half_width,
    hertz_pressure,
    reversal_stick_half_width,
    reversal_traction,
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
    measure_contact_patch,
    stick_radius,
)
from .cattaneo_mindlin_measure import (
    ContactProfile,
    gather_contact_profile,
    measure_cattaneo_mindlin,
)
from .indentation_3d import INDENTATION_MATERIAL, goal_total_force, indentation_problem
from .load_path import CM_CONTACT, CM_TOP
from .measurement import CMMeasure
from .rubber_cylinder import (
    RC_DEFAULTS,
    ContactMeasure,
    measure_contact,
    rubber_cylinder_mesh,
    rubber_cylinder_problems,
)
from .spence_block import (
    SPENCE_DEFAULTS,
    spence_block_mesh,
    spence_block_path,
    spence_presses,
)

__all__ = [
    "CM_CONTACT",
    "CM_DEFAULTS",
    "CM_DEFAULTS_3D",
    "CM_SYMMETRY_Y",
    "CM_TOP",
    "INDENTATION_MATERIAL",
    "RC_DEFAULTS",
    "SPENCE_DEFAULTS",
    "CMMeasure",
    "ContactMeasure",
    "ContactPatch",
    "ContactProfile",
    "cattaneo_mindlin_mesh",
    "cattaneo_mindlin_mesh_3d",
    "cattaneo_mindlin_path",
    "cattaneo_mindlin_path_3d",
    "cm_traction",
    "cm_traction_3d",
    "dundurs_beta",
    "gather_contact_patch",
    "gather_contact_profile",
    "goal_total_force",
    "hertz_half_width",
    "hertz_pressure",
    "hertz_radius",
    "indentation_problem",
    "measure_cattaneo_mindlin",
    "measure_contact",
    "measure_contact_patch",
    "reversal_stick_half_width",
    "reversal_traction",
    "rubber_cylinder_mesh",
    "rubber_cylinder_problems",
    "spence_block_mesh",
    "spence_block_path",
    "spence_presses",
    "stick_half_width",
    "stick_radius",
]
