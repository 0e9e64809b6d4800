"""dwr_signorini: goal-oriented adaptive finite elements for Signorini's contact problem.

Signorini's problem (contact of a linear-elastic body with a rigid obstacle, frictionless or with
Tresca or Coulomb friction, :mod:`dwr_signorini.laws`, also along load paths) in mixed form, solved
by a semi-smooth Newton (primal-dual active set) method; the error in a user's quantity of
interest J(u, lambda) estimated by the dual weighted residual method with the NCP-based error
identities (13) and (15), with an interval for J; adaptive refinement in parallel.
"""

from . import compat, obstacles
from .adapt import solve_adaptive
from .collective import CollectiveError
from .estimator import Estimate, estimate
from .laws import Coulomb, Frictionless, Tresca
from .mesh_io import read_mesh
from .newton import Solution, solve
from .pairs import ContactPair
from .path import PathResult, StepRecord, solve_path
from .problem import SignoriniProblem
from .report import AdaptiveResult, LevelRecord
from .semismooth import ConvergenceError
from .settings import ESTIMATORS, WEIGHTS
from .spaces import Discretization, Measures, discretize
from .stress import stress_fields
from .summary import ContactSummary, contact_summary

# Each FFCx JIT module is loaded from the disk cache once per process, for every form compiled
# from here on (compat.memoize_jit_modules): the one place the memo is switched on.
compat.memoize_jit_modules()

__version__ = "0.1.0"

__all__ = [
    "ESTIMATORS",
    "WEIGHTS",
    "AdaptiveResult",
    "CollectiveError",
    "ContactPair",
    "ContactSummary",
    "ConvergenceError",
    "Coulomb",
    "Discretization",
    "Estimate",
    "Frictionless",
    "LevelRecord",
    "Measures",
    "PathResult",
    "SignoriniProblem",
    "Solution",
    "StepRecord",
    "Tresca",
    "__version__",
    "contact_summary",
    "discretize",
    "estimate",
    "obstacles",
    "read_mesh",
    "solve",
    "solve_adaptive",
    "solve_path",
    "stress_fields",
]
