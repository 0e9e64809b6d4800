"""Pictures of adaptive runs and of solutions; the code lives in :mod:`dwr_signorini.viz`.

This module only re-exports the public names it has always had (``name as name`` marks each as
a re-export), so that ``from dwr_signorini import plotting; plotting.plot_convergence(...)``
keeps working; see :mod:`dwr_signorini.viz` for the documentation and the module of each name.
"""

from .viz import QUANTITY_LABELS as QUANTITY_LABELS
from .viz import MeshSnapshot as MeshSnapshot
from .viz import __all__ as _names
from .viz import cumulative_time as cumulative_time
from .viz import plot_contact_force as plot_contact_force
from .viz import plot_convergence as plot_convergence
from .viz import plot_effectivity as plot_effectivity
from .viz import plot_friction as plot_friction
from .viz import plot_interval as plot_interval
from .viz import plot_mesh as plot_mesh
from .viz import plot_solution_2d as plot_solution_2d
from .viz import plot_solution_3d as plot_solution_3d
from .viz import plot_sweep as plot_sweep
from .viz import read_rows as read_rows
from .viz import snapshot_mesh as snapshot_mesh
from .viz import virtual_display as virtual_display
from .viz import von_mises_2d as von_mises_2d

__all__ = list(_names)
