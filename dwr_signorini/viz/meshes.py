"""Pictures of meshes (paper Figures 7 and 8b): 2D cells as polygons, 3D meshes by their surface."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh

from .canvas import new_figure, save_figure
from .gather import MeshSnapshot, snapshot_mesh
from .render3d import (
    boundary_faces,
    check_backend,
    matplotlib_3d,
    render_pyvista,
    render_with_pyvista,
    unstructured_grid,
    view_3d,
)

__all__ = ["plot_mesh"]


def _polygon_order(cell_type: dmesh.CellType) -> list[int]:
    """Vertex order of a 2D cell as a polygon (dolfinx quadrilaterals are tensor-ordered)."""
    return [0, 1, 3, 2] if cell_type == dmesh.CellType.quadrilateral else [0, 1, 2]


def plot_mesh(
    mesh: dmesh.Mesh | MeshSnapshot | None,
    path: str | os.PathLike,
    title: str | None = None,
    color_by_rank: bool = False,
    backend: str = "auto",
) -> Path | None:
    """Draw a 2D or 3D mesh (paper Figures 7 and 8b).

    Args:
        mesh: The mesh (e.g. ``sol.disc.mesh``, the fine mesh T_h), or a snapshot of it.
        path: The PNG to write (on rank 0).
        title: Figure title (default: the number of cells).
        color_by_rank: Fill the cells with the colour of their owning process.
        backend: ``"auto"``, ``"pyvista"`` or ``"matplotlib"`` (3D only).

    Returns:
        The path on rank 0, ``None`` on the other ranks.

    Raises:
        ValueError: For an unknown ``backend``, or a mesh that is neither 2D nor 3D.

    Collective over the mesh's communicator when given a mesh; given a :class:`MeshSnapshot`
    (or ``None``, as :func:`snapshot_mesh` returns on ranks other than 0) it only draws.
    2D: all cells as polygons (matplotlib). 3D: the boundary of the mesh with its edges, rendered
    by pyvista off screen (see :func:`~.display.virtual_display`), or by matplotlib if pyvista is
    not available or ``backend="matplotlib"``.
    """
    check_backend(backend)
    snap = mesh if mesh is None or isinstance(mesh, MeshSnapshot) else snapshot_mesh(mesh)
    del mesh  # draw without references to dolfinx objects (see dwr_signorini.viz.gather)
    if snap is None:
        return None
    path = Path(path)
    title = title if title is not None else f"mesh: {snap.num_cells} cells"
    ranks = snap.ranks if color_by_rank else None
    if snap.tdim == 2:
        polys = snap.cells[:, _polygon_order(snap.cell_type), :2]
        return _draw_mesh_2d(polys, ranks, path, title)
    if snap.tdim != 3:
        raise ValueError(f"plot_mesh draws 2D and 3D meshes, got dimension {snap.tdim}")
    if render_with_pyvista(
        lambda: _mesh_pyvista(snap.cells, ranks, snap.cell_type, path, title), backend
    ):
        return path
    faces, owner = boundary_faces(snap.cells)
    values = None if ranks is None else ranks[owner].astype(float)
    matplotlib_3d(snap.cells.reshape(-1, 3)[faces], values, path, title, "rank")
    return path


def _draw_mesh_2d(polys: np.ndarray, ranks: np.ndarray | None, path: Path, title: str) -> Path:
    """Cells as polygons (matplotlib), optionally filled with the colour of their rank."""
    from matplotlib.collections import PolyCollection

    lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
    aspect = (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-300)
    width = 7.0 if aspect <= 1.5 else max(2.5, 9.0 / aspect + 1.0)
    height = min(max(width * aspect, 2.5), 11.0)
    fig = new_figure((width, height))
    ax = fig.add_subplot()
    lw = float(np.clip(25.0 / math.sqrt(len(polys)), 0.05, 0.8))
    if ranks is not None:
        from matplotlib import colormaps

        faces = colormaps["Pastel1"](ranks % 9)
    else:
        faces = "white"
    ax.add_collection(PolyCollection(polys, facecolors=faces, edgecolors="k", linewidths=lw))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_title(title)
    return save_figure(fig, path, dpi=200)


def _mesh_pyvista(
    xcells: np.ndarray,
    ranks: np.ndarray | None,
    cell_type: dmesh.CellType,
    path: Path,
    title: str,
) -> None:
    """The boundary surface of a 3D mesh with its edges, rendered by pyvista."""
    num, nv, _ = xcells.shape
    grid = unstructured_grid(np.arange(num * nv).reshape(num, nv), xcells.reshape(-1, 3), cell_type)
    if ranks is not None:
        grid.cell_data["rank"] = ranks
    surface = grid.clean().extract_surface()

    def draw(plotter: Any) -> None:
        kwargs = (
            {"scalars": "rank", "cmap": "Pastel1"} if ranks is not None else {"color": "#d9e0f2"}
        )
        plotter.add_mesh(surface, show_edges=True, edge_color="black", line_width=0.5, **kwargs)
        plotter.add_text(title, font_size=10)
        plotter.add_axes()
        view_3d(plotter, np.array([surface.bounds[0::2], surface.bounds[1::2]]))

    render_pyvista(draw, path, (1200, 1000))
