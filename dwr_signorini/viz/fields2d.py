"""2D field pictures (matplotlib): the deformed body with the obstacle, and the contact force.

Collective over the mesh's communicator: the data is gathered on rank 0 by :mod:`.gather`, and
rank 0 draws without references to dolfinx objects. The contact force of a 3D run is drawn here
too, as a 2D map over the contact face.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from dolfinx import mesh as dmesh

from .canvas import new_figure, save_figure
from .gather import SolutionData, gather_contact_force, gather_friction, gather_solution

__all__ = ["auto_scale", "plot_contact_force", "plot_solution_2d"]


def _triangles(num_cells: int, cell_type: dmesh.CellType) -> np.ndarray:
    """Triangles of per-cell vertex blocks (quadrilaterals split in two)."""
    if cell_type == dmesh.CellType.quadrilateral:
        base = 4 * np.arange(num_cells)[:, None]
        return np.concatenate([base + np.array([0, 1, 3]), base + np.array([0, 3, 2])])
    return 3 * np.arange(num_cells)[:, None] + np.array([0, 1, 2])


def auto_scale(umax: float, size: float) -> float:
    """Displacement magnification: true scale unless |u| is below 2% of the body's size."""
    if umax <= 0.0:
        return 1.0
    return 1.0 if umax >= 0.02 * size else 0.08 * size / umax


def plot_solution_2d(
    sol: Any,
    path: str | os.PathLike,
    scale: float | None = None,
    color: str = "magnitude",
    obstacle: bool = True,
    show_mesh: bool = False,
    title: str | None = None,
) -> Path | None:
    """The deformed body and the obstacle (paper Figures 3a and 5a). Collective.

    Args:
        sol: A :class:`~dwr_signorini.Solution` on a 2D mesh.
        path: The PNG to write (on rank 0).
        scale: Displacement magnification; default: 1, or larger so that max ``|u|`` is 8% of the
            body's size when the displacement is smaller than 2% of it.
        color: ``"magnitude"`` (``|u_h|``, continuous) or ``"von_mises"`` (the paper's sigma_{M,2}
            of Figure 5, cell-wise, colour scale clipped at the 99th percentile).
        obstacle: Draw the obstacle on Gamma_C.
        show_mesh: Draw the cell edges.
        title: Figure title.

    Returns:
        The path on rank 0, ``None`` on the other ranks.

    Raises:
        ValueError: For another ``color``, or a mesh that is not 2D.

    The fine mesh T_h is drawn displaced by ``scale * u_h``. The obstacle is drawn at
    ``x + scale * g(x) n`` on Gamma_C (g the gap, n the outer normal): with the same
    magnification as the body, so the body touches the obstacle line exactly where
    ``u_n = g`` (the active contact zone). The reference configuration is outlined.
    """
    if color not in ("magnitude", "von_mises"):
        raise ValueError(f"color must be 'magnitude' or 'von_mises', got {color!r}")
    if sol.disc.mesh.topology.dim != 2:
        raise ValueError("plot_solution_2d needs a 2D mesh; use plot_solution_3d")
    data = gather_solution(sol, obstacle, color == "von_mises", outline=True)
    del sol  # draw without references to dolfinx objects (see dwr_signorini.viz.gather)
    if data is None:
        return None
    return _draw_solution_2d(data, Path(path), scale, color, show_mesh, title)


def _draw_solution_2d(
    d: SolutionData,
    path: Path,
    scale: float | None,
    color: str,
    show_mesh: bool,
    title: str | None,
) -> Path:
    """The deformed body coloured by |u_h| or von Mises, the outline and the obstacle."""
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    nc, nv = d.coords.shape[:2]
    pts = d.coords.reshape(-1, 3)[:, :2]
    u = d.values.reshape(-1, d.values.shape[-1])[:, :2]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size = float(np.max(hi - lo))
    umag = np.linalg.norm(u, axis=1)
    s = auto_scale(float(umag.max()), size) if scale is None else float(scale)
    ttype = dmesh.CellType.quadrilateral if nv == 4 else dmesh.CellType.triangle
    tri = Triangulation(*(pts + s * u).T, _triangles(nc, ttype))

    span = hi - lo
    aspect = span[1] / max(span[0], 1e-300)
    width = 7.5 if aspect <= 1.5 else max(3.0, 10.0 / aspect + 2.0)
    fig = new_figure((width, min(max(width * aspect * 0.8, 3.0), 10.0)))
    ax = fig.add_subplot()
    edge = {"edgecolors": "k", "linewidth": 0.1} if show_mesh else {}
    if color == "magnitude":
        art = ax.tripcolor(tri, umag, shading="gouraud", cmap="viridis")
        label = r"$|u_h|$"
        if show_mesh:
            ax.triplot(tri, color="k", linewidth=0.1)
    else:
        faces = np.concatenate([d.cellvalue, d.cellvalue]) if nv == 4 else d.cellvalue
        # the corner singularities would use up the colour scale: clip at the 99th percentile
        vmax = float(np.percentile(faces, 99.0))
        art = ax.tripcolor(tri, facecolors=faces, cmap="jet", vmin=0.0, vmax=vmax, **edge)
        label = r"von Mises stress $\sigma_{M,2}$ (clipped at 99th percentile)"
    fig.colorbar(
        art, ax=ax, label=label, shrink=0.8, extend="max" if color == "von_mises" else "neither"
    )
    ax.add_collection(
        LineCollection(
            d.outline[:, :, :2],
            colors="0.4",
            linewidths=0.6,
            linestyles="dashed",
            label="reference configuration",
        )
    )
    if len(d.obs_x):
        _draw_obstacle_2d(ax, d.obs_x, d.obs_n, d.obs_g, s, size)
    ax.set_aspect("equal")
    ax.autoscale_view()
    # a fixed place: loc="best" scans every path of the collection (minutes on 10^5 cells)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize="small")
    scale_text = "" if s == 1.0 else f", displacement x {s:.3g}"
    ax.set_title(title if title is not None else f"$u_h$ on {nc} cells{scale_text}")
    return save_figure(fig, path, dpi=200)


def _draw_obstacle_2d(
    ax: Any, x: np.ndarray, n: np.ndarray, g: np.ndarray, scale: float, size: float
) -> None:
    """Obstacle line x + scale g n along Gamma_C with a hatched band behind it."""
    pts = x.reshape(-1, 3)[:, :2]
    normals = np.repeat(n[:, :2], x.shape[1], axis=0)
    gaps = g.reshape(-1)
    tangent = pts.max(axis=0) - pts.min(axis=0)
    tangent /= np.linalg.norm(tangent)
    order = np.argsort(pts @ tangent, kind="stable")
    pts, normals, gaps = pts[order], normals[order], gaps[order]
    _, first = np.unique(np.round(pts @ tangent, 12), return_index=True)
    pts, normals, gaps = pts[first], normals[first], gaps[first]
    line = pts + scale * gaps[:, None] * normals
    band = line + 0.04 * size * normals
    poly = np.concatenate([line, band[::-1]])
    ax.fill(poly[:, 0], poly[:, 1], facecolor="0.9", edgecolor="0.5", linewidth=0.0, hatch="////")
    ax.plot(line[:, 0], line[:, 1], color="k", linewidth=1.5, label="obstacle")


def plot_contact_force(
    sol: Any,
    path: str | os.PathLike,
    exact: Callable[[np.ndarray], np.ndarray] | None = None,
    title: str | None = None,
) -> Path | None:
    """The contact force lambda_H on Gamma_C (paper Figures 3b and 5b). Collective.

    Args:
        sol: A :class:`~dwr_signorini.Solution`.
        path: The PNG to write (on rank 0).
        exact: Optional exact contact force as a function of the coordinate along Gamma_C
            (2D), e.g. ``examples.exact_contact_pressure_np``.
        title: Figure title.

    Returns:
        The path on rank 0, ``None`` on the other ranks.

    2D: lambda_H is piecewise constant on the macro contact facets (Sigma_H); it is drawn as
    steps over the coordinate along Gamma_C (the coordinate in which Gamma_C extends most),
    active facets shaded. 3D: a map of lambda_H over the contact face, one colour per macro
    facet, in the two tangential coordinates.
    """
    data = gather_contact_force(sol)
    del sol  # draw without references to dolfinx objects (see dwr_signorini.viz.gather)
    if data is None:
        return None
    return _draw_contact_force(*data, Path(path), exact, title)


def _draw_contact_force(
    x: np.ndarray,
    lam: np.ndarray,
    active: np.ndarray,
    path: Path,
    exact: Callable[[np.ndarray], np.ndarray] | None,
    title: str | None,
) -> Path:
    """lambda_H as steps along Gamma_C (2D) or as a map over the contact face (3D)."""
    num, nv = x.shape[:2]
    pts = x.reshape(-1, 3)
    extent = pts.max(axis=0) - pts.min(axis=0)
    axes_order = np.argsort(extent)[::-1]
    if nv == 2:  # 2D: Gamma_C is a line
        names = ("x", "y", "z")
        k = int(axes_order[0])
        s = np.sort(x[:, :, k], axis=1)
        order = np.argsort(s[:, 0])
        s, lam_s, act = s[order], lam[order], active[order]
        fig = new_figure((6.4, 3.8))
        ax = fig.add_subplot()
        for a, b, on in zip(s[:, 0], s[:, 1], act, strict=True):
            if on:
                ax.axvspan(a, b, color="C1", alpha=0.12, linewidth=0)
        if np.allclose(s[1:, 0], s[:-1, 1]):
            ax.stairs(
                lam_s,
                np.append(s[:, 0], s[-1, 1]),
                baseline=None,
                color="C0",
                linewidth=1.5,
                label=r"$\lambda_{n,H}$",
            )
        else:
            ax.hlines(lam_s, s[:, 0], s[:, 1], color="C0", linewidth=1.5, label=r"$\lambda_{n,H}$")
        if exact is not None:
            t = np.linspace(s[0, 0], s[-1, 1], 801)
            ax.plot(
                t, exact(t), color="k", linestyle="--", linewidth=1.0, label=r"exact $\lambda_n$"
            )
        ax.set_xlabel(f"{names[k]} on $\\Gamma_C$")
        ax.set_ylabel(r"contact force $\lambda_n$")
        ax.grid(True, alpha=0.3)
        from matplotlib.patches import Patch

        handles, _ = ax.get_legend_handles_labels()
        handles.append(Patch(color="C1", alpha=0.12, label="active set"))
        ax.legend(handles=handles, fontsize="small")
        ax.set_title(
            title if title is not None else rf"$\lambda_{{n,H}}$ on $M_C = {num}$ contact elements"
        )
        return save_figure(fig, path)

    from matplotlib.collections import PolyCollection

    names = ("$x_1$", "$x_2$", "$x_3$")
    i, j = sorted(int(a) for a in axes_order[:2])
    polys = x[:, :, [i, j]]
    fig = new_figure((6.0, 5.0))
    ax = fig.add_subplot()
    coll = PolyCollection(
        polys,
        array=lam,
        cmap="viridis",
        edgecolors="k",
        linewidths=float(np.clip(20.0 / math.sqrt(num), 0.05, 0.5)),
    )
    ax.add_collection(coll)
    fig.colorbar(coll, ax=ax, label=r"contact force $\lambda_{n,H}$")
    ax.set_xlim(pts[:, i].min(), pts[:, i].max())
    ax.set_ylim(pts[:, j].min(), pts[:, j].max())
    ax.set_aspect("equal")
    ax.set_xlabel(names[i])
    ax.set_ylabel(names[j])
    ax.set_title(
        title if title is not None else rf"$\lambda_{{n,H}}$ on $M_C = {num}$ contact facets"
    )
    return save_figure(fig, path)


def plot_friction(
    sol: Any,
    path: str | os.PathLike,
    threshold: float | None = None,
    title: str | None = None,
) -> Path | None:
    """lambda_n and lambda_t on Gamma_C with the stick and slip zones. Collective.

    In 2D both tractions along Gamma_C; in 3D a map of the contact face: lambda_n in colour,
    the stick and slip facets outlined, lambda_t as arrows.

    Args:
        sol: A :class:`~dwr_signorini.Solution` of a frictional problem.
        path: The PNG to write (on rank 0).
        threshold: Tresca's s, drawn as +-s, if given.
        title: Figure title.

    Returns:
        The path on rank 0, ``None`` on the other ranks.

    Raises:
        ValueError: A frictionless solution.
    """
    if sol.lam_t is None:
        raise ValueError("plot_friction draws the tractions of a frictional solution")
    data = gather_friction(sol)
    del sol
    if data is None:
        return None
    x, lam_n, lam_t, stick, slip = data
    if lam_t.ndim == 2:
        return _friction_map(x, lam_n, lam_t, stick, slip, path, threshold, title)
    k = int(np.argmax(np.ptp(x.reshape(-1, 3), axis=0)))
    ends = np.sort(x[:, :, k], axis=1)
    order = np.argsort(ends[:, 0])
    ends, lam_n, lam_t = ends[order], lam_n[order], lam_t[order]
    stick, slip = stick[order], slip[order]
    fig = new_figure((6.8, 4.0))
    ax = fig.add_subplot()
    for (a, b), on_stick, on_slip in zip(ends, stick, slip, strict=True):
        if on_stick or on_slip:
            ax.axvspan(a, b, color="C2" if on_stick else "C1", alpha=0.15, linewidth=0)
    ax.hlines(lam_n, ends[:, 0], ends[:, 1], color="C0", linewidth=1.5,
              label=r"$\lambda_{n,H}$")
    ax.hlines(lam_t, ends[:, 0], ends[:, 1], color="C3", linewidth=1.5,
              label=r"$\lambda_{t,H}$")
    if threshold is not None:
        for sign in (1.0, -1.0):
            ax.axhline(sign * threshold, color="grey", linestyle="--", linewidth=0.8,
                       label=r"$\pm s$" if sign > 0 else None)
    from matplotlib.patches import Patch

    handles, _ = ax.get_legend_handles_labels()
    handles += [Patch(color="C2", alpha=0.15, label="stick"),
                Patch(color="C1", alpha=0.15, label="slip (in contact)")]
    ax.legend(handles=handles, fontsize="small")
    ax.set_xlabel(f"{'xyz'[k]} on $\\Gamma_C$")
    ax.set_ylabel("contact traction")
    ax.grid(True, alpha=0.3)
    ax.set_title(title if title is not None else
                 rf"tractions on $M_C = {len(lam_n)}$ contact elements")
    return save_figure(fig, path)


def _friction_map(
    x: np.ndarray, lam_n: np.ndarray, lam_t: np.ndarray, stick: np.ndarray, slip: np.ndarray,
    path: str | os.PathLike, threshold: float | None, title: str | None,
) -> Path:
    """The 3D picture of :func:`plot_friction`: the contact face seen along its normal."""
    from matplotlib.collections import PolyCollection
    from matplotlib.lines import Line2D

    pts = x.reshape(-1, 3)
    i, j = sorted(int(a) for a in np.argsort(np.ptp(pts, axis=0))[::-1][:2])
    polys = x[:, :, [i, j]]
    fig = new_figure((6.4, 5.4))
    ax = fig.add_subplot()
    coll = PolyCollection(polys, array=lam_n, cmap="Blues", edgecolors="none")
    ax.add_collection(coll)
    fig.colorbar(coll, ax=ax, label=r"contact force $\lambda_{n,H}$")
    for mask, color in ((stick, "C2"), (slip, "C1")):
        if mask.any():
            ax.add_collection(PolyCollection(polys[mask], facecolors="none", edgecolors=color,
                                             linewidths=0.8))
    mid = polys.mean(axis=1)
    contact = stick | slip
    if contact.any():
        ax.quiver(mid[contact, 0], mid[contact, 1], lam_t[contact, i], lam_t[contact, j],
                  color="C3", angles="xy", width=0.003)
    ax.set_xlim(pts[:, i].min(), pts[:, i].max())
    ax.set_ylim(pts[:, j].min(), pts[:, j].max())
    ax.set_aspect("equal")
    names = ("$x_1$", "$x_2$", "$x_3$")
    ax.set_xlabel(names[i])
    ax.set_ylabel(names[j])
    handles = [Line2D([], [], color="C2", label="stick"), Line2D([], [], color="C1", label="slip"),
               Line2D([], [], color="C3", marker=">", label=r"$\lambda_{t,H}$ (in contact)")]
    ax.legend(handles=handles, fontsize="small", loc="upper right")
    limit = "" if threshold is None else f", $|\\lambda_t| \\le s = {threshold:g}$"
    ax.set_title(title if title is not None else
                 rf"tractions on $M_C = {len(lam_n)}$ contact facets{limit}")
    return save_figure(fig, path)
