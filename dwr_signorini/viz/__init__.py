"""Pictures of adaptive runs and of solutions: the paper's Figures 3-8, off screen.

Two kinds of functions:

* **table plots** (:func:`plot_convergence`, :func:`plot_effectivity`, :func:`plot_interval`,
  :func:`plot_sweep`, in
  :mod:`.tables`; :func:`plot_model_map` in :mod:`.models`) take plain data: lists of row
  dicts as returned by
  :meth:`~dwr_signorini.AdaptiveResult.rows` or read back from the CSV/JSON of a run with
  :func:`read_rows`. They involve no MPI; pass ``comm`` to let only its rank 0 write, or call them
  on rank 0 only;
* **field plots** (:func:`plot_mesh`, :func:`plot_solution_2d`, :func:`plot_solution_3d`,
  :func:`plot_contact_force`) take dolfinx objects. They are *collective* over the mesh's
  communicator: every rank sends the data of its local cells to rank 0 (:mod:`.gather`), which
  draws and writes the file; they return the path on rank 0 and ``None`` elsewhere. Rank 0
  draws without holding references to dolfinx objects, and a mesh met inside a callback is best
  gathered with :func:`snapshot_mesh` and drawn after the run (:mod:`.gather` says why this
  matters in parallel).

Figures are drawn with matplotlib's object API on the Agg canvas (:mod:`.canvas`; no pyplot, so
the global backend of a user's session is left alone). 3D pictures use pyvista off screen when it
works (:mod:`.render3d`): it is imported lazily, and if no X display is set a private ``Xvfb``
server is started for the rendering and stopped afterwards (:mod:`.display`). Without pyvista or
Xvfb (or with the environment variable ``DWR_SIGNORINI_PLOT3D=matplotlib``) they fall back to a
matplotlib 3D plot of the boundary facets.

Modules:

* :mod:`.tables`: reading run tables, cumulative time, convergence / effectivity / sweep plots;
* :mod:`.gather`: the collective phase, mesh and solution arrays gathered on rank 0;
* :mod:`.meshes`: :func:`plot_mesh` (2D polygons, 3D boundary);
* :mod:`.models`: :func:`plot_model_map`, the law of each contact facet per level;
* :mod:`.fields2d`: the deformed 2D body with the obstacle, the contact force;
* :mod:`.fields3d`: the deformed 3D body with the obstacle;
* :mod:`.render3d`: the 3D backends, pyvista and the matplotlib fallback;
* :mod:`.display`: the X display for off-screen rendering (Xvfb);
* :mod:`.canvas`: matplotlib figures on the Agg canvas and saving them.
"""

from .display import virtual_display
from .fields2d import plot_contact_force, plot_friction, plot_solution_2d
from .fields3d import plot_solution_3d
from .gather import MeshSnapshot, snapshot_mesh, von_mises_2d
from .meshes import plot_mesh
from .models import plot_model_map
from .tables import (
    QUANTITY_LABELS,
    cumulative_time,
    plot_convergence,
    plot_effectivity,
    plot_interval,
    plot_sweep,
    read_rows,
)

__all__ = [
    "QUANTITY_LABELS",
    "MeshSnapshot",
    "cumulative_time",
    "plot_contact_force",
    "plot_convergence",
    "plot_effectivity",
    "plot_friction",
    "plot_interval",
    "plot_mesh",
    "plot_model_map",
    "plot_solution_2d",
    "plot_solution_3d",
    "plot_sweep",
    "read_rows",
    "snapshot_mesh",
    "virtual_display",
    "von_mises_2d",
]
