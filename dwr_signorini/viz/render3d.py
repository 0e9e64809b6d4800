"""The 3D backends: pyvista off screen, and a matplotlib 3D plot of boundary faces as fallback.

pyvista is imported lazily and renders on a :func:`~.display.virtual_display`. It is used when
``backend="pyvista"``, or with ``backend="auto"`` when it can be imported and the environment
variable ``DWR_SIGNORINI_PLOT3D`` is not ``matplotlib``; with ``"auto"`` a failed rendering is
logged and matplotlib draws instead.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh

from .canvas import new_figure, save_figure
from .display import virtual_display

__all__ = [
    "boundary_faces",
    "check_backend",
    "matplotlib_3d",
    "render_pyvista",
    "render_with_pyvista",
    "unstructured_grid",
    "view_3d",
]

logger = logging.getLogger(__name__)


def _use_pyvista() -> bool:
    """Whether ``backend="auto"`` means pyvista: importable and not disabled."""
    if os.environ.get("DWR_SIGNORINI_PLOT3D", "").lower() == "matplotlib":
        return False
    try:
        import pyvista  # noqa: F401
    except ImportError:
        return False
    return True


def check_backend(backend: str) -> None:
    """Reject an unknown 3D backend.

    Args:
        backend: ``"auto"``, ``"pyvista"`` or ``"matplotlib"``.

    Raises:
        ValueError: For any other value.
    """
    if backend not in ("auto", "pyvista", "matplotlib"):
        raise ValueError(f"backend must be 'auto', 'pyvista' or 'matplotlib', got {backend!r}")


def render_with_pyvista(render: Callable[[], None], backend: str) -> bool:
    """Run ``render`` (a pyvista rendering) if ``backend`` chooses pyvista.

    Args:
        render: Draws the picture with pyvista and writes it.
        backend: ``"pyvista"`` (errors are raised), ``"auto"`` (pyvista if it can be imported
            and ``DWR_SIGNORINI_PLOT3D`` is not ``matplotlib``; errors are logged) or
            ``"matplotlib"`` (``render`` is not called).

    Returns:
        Whether pyvista wrote the picture; if not, the caller draws it with matplotlib.
    """
    if backend == "pyvista" or (backend == "auto" and _use_pyvista()):
        try:
            render()
            return True
        except Exception as err:
            if backend == "pyvista":
                raise
            logger.warning("pyvista rendering failed (%s); using matplotlib", err)
    return False


def unstructured_grid(cells: np.ndarray, points: np.ndarray, cell_type: dmesh.CellType) -> Any:
    """A pyvista grid of gathered cells (per-cell vertex blocks), coincident points merged."""
    import pyvista
    from dolfinx.cpp.io import get_vtk_cell_type, perm_vtk

    num, nv = cells.shape
    perm = np.argsort(perm_vtk(cell_type, nv))
    conn = np.hstack([np.full((num, 1), nv), cells[:, perm]]).ravel()
    vtk_type = get_vtk_cell_type(cell_type, 3)
    types = np.full(num, vtk_type, dtype=np.uint8)
    return pyvista.UnstructuredGrid(conn, types, points)


def render_pyvista(draw: Callable[[Any], None], path: Path, window: tuple[int, int]) -> None:
    """Render off screen with pyvista on a :func:`~.display.virtual_display` and write a PNG.

    Args:
        draw: Adds the picture to the ``pyvista.Plotter`` it is given.
        path: The screenshot to write (its folder is created).
        window: Window size in pixels, (width, height).
    """
    import pyvista

    pyvista.OFF_SCREEN = True
    with virtual_display():
        plotter = pyvista.Plotter(off_screen=True, window_size=list(window))
        try:
            draw(plotter)
            path.parent.mkdir(parents=True, exist_ok=True)
            plotter.screenshot(str(path))
        finally:
            plotter.close()


def view_3d(plotter: Any, bounds: np.ndarray) -> None:
    """Camera looking at the face x1 = max (the contact face of Example 5.3) from above."""
    lo, hi = bounds[0], bounds[1]
    centre = 0.5 * (lo + hi)
    size = float(np.linalg.norm(hi - lo))
    direction = np.array([1.6, -0.9, 1.0])
    plotter.camera_position = [
        tuple(centre + 1.9 * size * direction / np.linalg.norm(direction)),
        tuple(centre),
        (0.0, 0.0, 1.0),
    ]


#: Local vertex indices of the faces of a tetrahedron (4 vertices) and a hexahedron (8).
_CELL_FACES = {
    4: [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]],
    8: [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]],
}


def boundary_faces(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces of gathered 3D cells that belong to one cell only (the boundary).

    Args:
        cells: Vertex coordinates per cell, shape (cells, 4 or 8, 3).

    Returns:
        The local face vertex indices into ``cells.reshape(-1, 3)``, shape (faces, 3 or 4),
        and the cell of each face.
    """
    num, nv, _ = cells.shape
    local = np.asarray(_CELL_FACES[nv])
    faces = (nv * np.arange(num)[:, None, None] + local[None]).reshape(-1, local.shape[1])
    owner = np.repeat(np.arange(num), len(local))
    q = np.round(cells.reshape(-1, 3) * 1e9).astype(np.int64)
    _, vid = np.unique(q, axis=0, return_inverse=True)
    key = np.sort(vid.ravel()[faces], axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = counts[inverse.ravel()] == 1
    return faces[boundary], owner[boundary]


def matplotlib_3d(
    polys: np.ndarray, values: np.ndarray | None, path: Path, title: str | None, label: str
) -> None:
    """Draw 3D polygons with matplotlib (the fallback of the pyvista pictures) and save them.

    Args:
        polys: Vertex coordinates of each polygon, shape (polygons, vertices, 3).
        values: A value per polygon to colour by (viridis, with a colour bar), or ``None`` for
            a plain face colour.
        path: The PNG to write.
        title: Figure title.
        label: Label of the colour bar.
    """
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = new_figure((7.0, 6.0))
    ax = fig.add_subplot(projection="3d")
    lw = float(np.clip(40.0 / math.sqrt(max(len(polys), 1)), 0.05, 0.6))
    coll = Poly3DCollection(polys, linewidths=lw, edgecolors="k")
    if values is not None:
        from matplotlib import colormaps
        from matplotlib.colors import Normalize

        norm = Normalize(vmin=float(values.min()), vmax=float(values.max()))
        coll.set_facecolor(colormaps["viridis"](norm(values)))
        from matplotlib.cm import ScalarMappable

        fig.colorbar(ScalarMappable(norm=norm, cmap="viridis"), ax=ax, shrink=0.6, label=label)
    else:
        coll.set_facecolor((0.85, 0.88, 0.95))
    ax.add_collection3d(coll)
    pts = polys.reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    for setter, a, b in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), lo, hi, strict=True):
        setter(a, b)
    ax.set_box_aspect(tuple(np.maximum(hi - lo, 1e-3 * np.max(hi - lo))))
    ax.view_init(elev=25, azim=-35)
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
    ax.set_zlabel("$x_3$")
    if title:
        ax.set_title(title)
    save_figure(fig, path)
