"""The deformed 3D body coloured by ``|u_h|``, with the obstacle (paper Figure 8a).

Collective: the solution is gathered on rank 0 by :mod:`.gather`; rank 0 renders it with one of
the backends of :mod:`.render3d`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh

from .fields2d import auto_scale
from .gather import gather_solution
from .render3d import (
    boundary_faces,
    check_backend,
    matplotlib_3d,
    render_pyvista,
    render_with_pyvista,
    unstructured_grid,
    view_3d,
)

__all__ = ["plot_solution_3d"]


def plot_solution_3d(
    sol: Any,
    path: str | os.PathLike,
    scale: float | None = None,
    obstacle: bool = True,
    title: str | None = None,
    backend: str = "auto",
) -> Path | None:
    """The deformed 3D body coloured by ``|u_h|``, with the obstacle (paper Figure 8a). Collective.

    Args:
        sol: A :class:`~dwr_signorini.Solution` on a 3D mesh.
        path: The PNG to write (on rank 0).
        scale: Displacement magnification (default as in :func:`~.fields2d.plot_solution_2d`).
        obstacle: Draw the obstacle over Gamma_C.
        title: Text in the picture.
        backend: ``"auto"``, ``"pyvista"`` or ``"matplotlib"``.

    Returns:
        The path on rank 0, ``None`` on the other ranks.

    Raises:
        ValueError: For an unknown ``backend``, or a mesh that is not 3D.

    Rendered by pyvista off screen: the boundary of T_h displaced by ``scale * u_h`` with the
    cell edges, and the obstacle surface ``x + scale * g(x) n`` over Gamma_C (translucent).
    Falls back to matplotlib (boundary facets coloured by ``|u_h|``) as
    :func:`~.meshes.plot_mesh` does.
    """
    check_backend(backend)
    if sol.disc.mesh.topology.dim != 3:
        raise ValueError("plot_solution_3d needs a 3D mesh; use plot_solution_2d")
    cell_type = sol.disc.mesh.topology.cell_type
    data = gather_solution(sol, obstacle, von_mises=False, outline=False)
    del sol  # draw without references to dolfinx objects (see dwr_signorini.viz.gather)
    if data is None:
        return None
    path = Path(path)
    nc, nv = data.coords.shape[:2]
    pts = data.coords.reshape(-1, 3)
    u = data.values.reshape(-1, 3)
    umag = np.linalg.norm(u, axis=1)
    size = float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    s = auto_scale(float(umag.max()), size) if scale is None else float(scale)
    text = (
        title
        if title is not None
        else (f"u_h on {nc} cells" + ("" if s == 1.0 else f", displacement x {s:.3g}"))
    )
    obstacle_pts = data.obs_x + s * data.obs_g[:, :, None] * data.obs_n[:, None, :]

    if render_with_pyvista(
        lambda: _solution_pyvista(pts, u, umag, nc, nv, cell_type, obstacle_pts, s, path, text),
        backend,
    ):
        return path
    # matplotlib: boundary faces of the deformed cells, coloured by the mean of |u| on them
    faces, _ = boundary_faces(pts.reshape(nc, nv, 3))
    matplotlib_3d((pts + s * u)[faces], umag[faces].mean(axis=1), path, text, r"$|u_h|$")
    return path


def _solution_pyvista(
    pts: np.ndarray,
    u: np.ndarray,
    umag: np.ndarray,
    nc: int,
    nv: int,
    cell_type: dmesh.CellType,
    obstacle_pts: np.ndarray,
    scale: float,
    path: Path,
    text: str,
) -> None:
    """The deformed boundary of T_h and the obstacle surface, rendered by pyvista."""
    import pyvista

    grid = unstructured_grid(np.arange(nc * nv).reshape(nc, nv), pts, cell_type)
    grid.point_data["u"] = u
    grid.point_data["|u|"] = umag
    surface = grid.clean().extract_surface().warp_by_vector("u", factor=scale)
    obstacle_surface = None
    num, k = obstacle_pts.shape[:2]
    if num:
        faces = np.hstack([np.full((num, 1), k), np.arange(num * k).reshape(num, k)]).ravel()
        obstacle_surface = pyvista.PolyData(obstacle_pts.reshape(-1, 3), faces).clean()

    def draw(plotter: Any) -> None:
        plotter.add_mesh(
            surface,
            scalars="|u|",
            cmap="viridis",
            show_edges=True,
            edge_color="#333333",
            line_width=0.3,
            scalar_bar_args={"title": "|u_h|", "vertical": True},
        )
        if obstacle_surface is not None:
            plotter.add_mesh(obstacle_surface, color="#8c8c8c", opacity=0.45)
        plotter.add_text(text, font_size=10)
        plotter.add_axes()
        view_3d(plotter, np.array([surface.bounds[0::2], surface.bounds[1::2]]))

    render_pyvista(draw, path, (1200, 1000))
