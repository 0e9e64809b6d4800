"""Pictures of adaptive runs and of solutions: the paper's Figures 3-8, off screen.

Two kinds of functions:

* **table plots** (:func:`plot_convergence`, :func:`plot_effectivity`, :func:`plot_sweep`) take
  plain data: lists of row dicts as returned by :meth:`~dwr_signorini.AdaptiveResult.rows` or
  read back from the CSV/JSON of a run with :func:`read_rows`. They involve no MPI; pass
  ``comm`` to let only its rank 0 write, or call them on rank 0 only;
* **field plots** (:func:`plot_mesh`, :func:`plot_solution_2d`, :func:`plot_solution_3d`,
  :func:`plot_contact_force`) take dolfinx objects. They are *collective* over the mesh's
  communicator: every rank sends the data of its local cells to rank 0 (``comm.gather``), which
  draws and writes the file; they return the path on rank 0 and ``None`` elsewhere. Rank 0
  draws without holding references to dolfinx objects, and a mesh met inside a callback is best
  gathered with :func:`snapshot_mesh` and drawn after the run (see the note before
  :class:`MeshSnapshot` on why this matters in parallel).

Figures are drawn with matplotlib's object API on the Agg canvas (no pyplot, so the global
backend of a user's session is left alone). 3D pictures use pyvista off screen when it works: it
is imported lazily, and if no X display is set a private ``Xvfb`` server is started for the
rendering and stopped afterwards. Without pyvista or Xvfb (or with the environment variable
``DWR_SIGNORINI_PLOT3D=matplotlib``) they fall back to a matplotlib 3D plot of the boundary facets.
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import math
import os
import select
import shutil
import subprocess
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.cpp import mesh as _cpp_mesh

__all__ = [
    "QUANTITY_LABELS",
    "MeshSnapshot",
    "cumulative_time",
    "plot_contact_force",
    "plot_convergence",
    "plot_effectivity",
    "plot_mesh",
    "plot_solution_2d",
    "plot_solution_3d",
    "plot_sweep",
    "read_rows",
    "snapshot_mesh",
    "virtual_display",
    "von_mises_2d",
]

logger = logging.getLogger(__name__)

#: Axis labels of the quantities a convergence plot can show. The estimate-type quantities are
#: divided by |J| (the reference value if given, else |J(w_h)| of the row).
QUANTITY_LABELS = {
    "rel_error": r"$E_{rel} = |J(w) - J(w_h)| / |J(w)|$",
    "estimate": r"$|\tilde\eta| / |J|$",
    "eta": r"$|\eta| / |J|$",
    "eta_p": r"$|\eta_p| / |J|$",
    "contact_term": r"$|C(w_h)(\xi_h)| / |J|$",
}
_SHORT = {
    "rel_error": r"$E_{rel}$",
    "estimate": r"$|\tilde\eta|/|J|$",
    "eta": r"$|\eta|/|J|$",
    "eta_p": r"$|\eta_p|/|J|$",
    "contact_term": r"$|C(w_h)(\xi_h)|/|J|$",
}
_LINESTYLES = {"rel_error": "-", "estimate": "--", "eta": "--", "eta_p": "-.", "contact_term": ":"}
_MARKERS = ("o", "s", "^", "v", "D", "P", "X")
_RELATIVE = frozenset({"estimate", "eta", "eta_p", "contact_term"})


# --------------------------------------------------------------------------------------------------
# Tables: reading and plain-data helpers
# --------------------------------------------------------------------------------------------------


def _parse(text: str) -> Any:
    """A CSV cell as int, float, bool or None (empty / "None")."""
    if text in ("", "None"):
        return None
    if text in ("True", "False"):
        return text == "True"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def read_rows(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Read the table of a run back: the CSV or the JSON written by ``solve_adaptive``.

    Args:
        path: A ``.csv`` (flat columns, timings as ``time_<phase>``) or ``.json`` file (with a
            ``levels`` list, timings nested under ``time``).

    Returns:
        The rows as dicts; CSV cells are converted to numbers (empty cells to ``None``).
    """
    path = Path(path)
    if path.suffix == ".json":
        data = json.loads(path.read_text())
        return list(data["levels"] if isinstance(data, dict) else data)
    with open(path, newline="") as fh:
        return [{k: _parse(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def _value(row: Mapping[str, Any], key: str) -> float:
    """``row[key]`` as float (NaN if missing or None); ``time_<phase>`` also reads ``time``."""
    value = row.get(key)
    if value is None and key.startswith("time_") and isinstance(row.get("time"), Mapping):
        value = row["time"].get(key[len("time_") :])
    if value is None or value == "":
        return math.nan
    return float(value)


def _column(rows: Sequence[Mapping[str, Any]], key: str) -> npt.NDArray[np.float64]:
    return np.array([_value(r, key) for r in rows], dtype=float)


def cumulative_time(rows: Sequence[Mapping[str, Any]]) -> npt.NDArray[np.float64]:
    """Wall-clock time spent up to and including each level (sum of ``time_total``).

    An adaptive run needs every earlier level to reach a mesh, so its cost at level L is the
    sum over levels 0..L; the same convention is used for uniform runs.
    """
    return np.cumsum(np.nan_to_num(_column(rows, "time_total")))


def _figure(figsize: tuple[float, float] = (6.4, 4.8)) -> Any:
    """A matplotlib Figure on the Agg canvas (no pyplot, no global state)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: str | os.PathLike, dpi: int = 150) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    return path


def _writer(comm: MPI.Comm | None) -> bool:
    return comm is None or comm.rank == 0


def _slope_label(slope: float, x: str) -> str:
    var = "N" if x == "num_cells" else "t"
    frac = {-1.0: "1", -0.5: "1/2", -2.0 / 3.0: "2/3", -1.0 / 3.0: "1/3", -2.0: "2"}
    for value, text in frac.items():
        if math.isclose(slope, value):
            return rf"$O({var}^{{-{text}}})$"
    return rf"$O({var}^{{{slope:.2g}}})$"


def plot_convergence(
    runs: Mapping[str, Sequence[Mapping[str, Any]]],
    path: str | os.PathLike,
    x: str = "num_cells",
    quantities: Sequence[str] = ("rel_error", "estimate"),
    reference: float | None = None,
    slopes: Sequence[float] | None = None,
    dim: int = 2,
    title: str | None = None,
    comm: MPI.Comm | None = None,
) -> Path | None:
    """Errors and estimates against cells or cumulative run time, log-log (paper Figure 6).

    Each run (e.g. ``{"adaptive": rows, "uniform": rows}``) gets a colour and each quantity a
    line style. Estimate-type quantities (``estimate``, ``eta``, ``eta_p``, ``contact_term``) are
    plotted as ``|value| / |J|`` so that they compare with ``E_rel``; ``J`` is ``reference`` if
    given, else ``J_h`` of each row. Quantities without any finite value (e.g. ``rel_error``
    when the exact J is unknown) are left out. Dotted grey lines show reference slopes, anchored
    at the first point of the first run.

    Args:
        runs: Label -> table rows (dicts from ``AdaptiveResult.rows()`` or :func:`read_rows`).
        path: The PNG to write.
        x: ``"num_cells"`` (M_Omega, cells of T_h) or ``"time"`` (cumulative wall-clock time,
            see :func:`cumulative_time`).
        quantities: Row keys to plot, see :data:`QUANTITY_LABELS`.
        reference: The exact or reference value of J, for the relative estimates.
        slopes: Exponents of the reference lines ``N^s``; default ``(-2/dim, -1/dim)``, i.e.
            O(h^2) (optimal for J with P1 elements) and O(h).
        dim: Space dimension, for the default slopes.
        title: Figure title.
        comm: If given, only its rank 0 draws and writes.

    Returns:
        The path written, or ``None`` on ranks other than 0 of ``comm``.

    Raises:
        ValueError: For an unknown ``x`` or quantity.
    """
    if x not in ("num_cells", "time"):
        raise ValueError(f"x must be 'num_cells' or 'time', got {x!r}")
    unknown = [q for q in quantities if q not in QUANTITY_LABELS]
    if unknown:
        raise ValueError(f"unknown quantities {unknown}; choose from {sorted(QUANTITY_LABELS)}")
    if not _writer(comm):
        return None
    if slopes is None:
        slopes = (-2.0 / dim, -1.0 / dim)

    fig = _figure((6.4, 4.8))
    ax = fig.add_subplot()
    colors = [f"C{i}" for i in range(10)]
    anchor: tuple[float, float] | None = None
    xs_all: list[float] = []
    for i, (label, rows) in enumerate(runs.items()):
        if not rows:
            continue
        xs = _column(rows, "num_cells") if x == "num_cells" else cumulative_time(rows)
        for q in quantities:
            ys = np.abs(_column(rows, q))
            if q in _RELATIVE:
                denom = abs(reference) if reference else np.abs(_column(rows, "J_h"))
                ys = ys / denom
            ok = np.isfinite(ys) & (ys > 0) & np.isfinite(xs) & (xs > 0)
            if not ok.any():
                continue
            ax.loglog(
                xs[ok],
                ys[ok],
                linestyle=_LINESTYLES[q],
                marker=_MARKERS[i % len(_MARKERS)],
                color=colors[i % len(colors)],
                markersize=4,
                label=f"{label}: {_SHORT[q]}",
            )
            xs_all.extend(xs[ok])
            if anchor is None:
                anchor = (float(xs[ok][0]), float(ys[ok][0]))
    if anchor is not None and xs_all:
        x0, y0 = anchor
        x1 = max(xs_all)
        for k, s in enumerate(slopes):
            xr = np.array([x0, x1])
            ax.loglog(
                xr,
                y0 * 0.5 * (xr / x0) ** s,
                color="0.5",
                linestyle=(0, (1, 1 + k)),
                linewidth=1.0,
                label=_slope_label(s, x),
            )
    ax.set_xlabel(
        r"cells $M_\Omega$ of $T_h$" if x == "num_cells" else "cumulative wall-clock time [s]"
    )
    ax.set_ylabel("relative error / estimate")
    ax.grid(True, which="both", alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(fontsize="small")
    return _save(fig, path)


def plot_effectivity(
    runs: Mapping[str, Sequence[Mapping[str, Any]]],
    path: str | os.PathLike,
    x: str = "level",
    references: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    title: str | None = None,
    comm: MPI.Comm | None = None,
) -> Path | None:
    """Effectivity indices Ieff(eta) and Ieff(eta_p) against the level (paper Tables 1-3).

    ``Ieff(J, eta) = (J(w) - J(w_h)) / eta``; 1 is the ideal, drawn as a grey line.

    Args:
        runs: Label -> table rows with ``ieff`` and ``ieff_p`` (rows without them are skipped).
        path: The PNG to write.
        x: ``"level"`` or ``"num_cells"`` (log axis).
        references: Extra series drawn as open grey markers, e.g. the paper's values:
            label -> (x values, Ieff values).
        title: Figure title.
        comm: If given, only its rank 0 draws and writes.

    Returns:
        The path written, or ``None`` on ranks other than 0 of ``comm``.
    """
    if x not in ("level", "num_cells"):
        raise ValueError(f"x must be 'level' or 'num_cells', got {x!r}")
    if not _writer(comm):
        return None
    fig = _figure((6.4, 4.4))
    ax = fig.add_subplot()
    for i, (label, rows) in enumerate(runs.items()):
        xs = _column(rows, x)
        for key, style, name in (
            ("ieff", "-", r"$I_{eff}(\eta)$"),
            ("ieff_p", "--", r"$I_{eff}(\eta_p)$"),
        ):
            ys = _column(rows, key)
            ok = np.isfinite(ys) & np.isfinite(xs)
            if ok.any():
                ax.plot(
                    xs[ok],
                    ys[ok],
                    style,
                    marker=_MARKERS[i % len(_MARKERS)],
                    color=f"C{i}",
                    markersize=4,
                    label=f"{label}: {name}",
                )
    for j, (label, (xs, ys)) in enumerate((references or {}).items()):
        ax.plot(
            xs,
            ys,
            linestyle="none",
            marker=_MARKERS[j % len(_MARKERS)],
            color="0.35",
            markerfacecolor="none",
            markersize=7,
            label=label,
        )
    ax.axhline(1.0, color="0.5", linewidth=0.8)
    if x == "num_cells":
        ax.set_xscale("log")
        ax.set_xlabel(r"cells $M_\Omega$ of $T_h$")
    else:
        ax.set_xlabel("level $L$")
        ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_ylabel(r"effectivity index $I_{eff}$")
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(fontsize="small")
    return _save(fig, path)


def plot_sweep(
    ms: Sequence[float],
    ieffs: Mapping[str, Sequence[float]] | Sequence[float],
    path: str | os.PathLike,
    title: str | None = None,
    comm: MPI.Comm | None = None,
) -> Path | None:
    """Effectivity index against the midpoint m of the weight of J_{a,m} (paper Figure 4).

    Args:
        ms: Midpoints m in [-3, 0].
        ieffs: The effectivity indices, one series (a sequence) or several (label -> sequence,
            e.g. ``{"eta": [...], "eta_p": [...]}``).
        path: The PNG to write.
        title: Figure title.
        comm: If given, only its rank 0 draws and writes.

    Returns:
        The path written, or ``None`` on ranks other than 0 of ``comm``.
    """
    if not _writer(comm):
        return None
    series = dict(ieffs) if isinstance(ieffs, Mapping) else {r"$I_{eff}$": ieffs}
    names = {"eta": r"$I_{eff}(\eta)$", "eta_p": r"$I_{eff}(\eta_p)$"}
    fig = _figure((6.4, 4.0))
    ax = fig.add_subplot()
    for i, (label, values) in enumerate(series.items()):
        ax.plot(
            ms,
            values,
            marker=_MARKERS[i % len(_MARKERS)],
            color=f"C{i}",
            linestyle="-" if i == 0 else "--",
            label=names.get(label, label),
        )
    ax.set_xlabel("midpoint coordinate $m$")
    ax.set_ylabel(r"effectivity index $I_{eff}$")
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(fontsize="small")
    return _save(fig, path)


# --------------------------------------------------------------------------------------------------
# Gathering distributed mesh data on rank 0
# --------------------------------------------------------------------------------------------------


def _gather_arrays(comm: MPI.Comm, *arrays: npt.NDArray[Any]) -> list[npt.NDArray[Any]] | None:
    """Concatenate each array over the ranks on rank 0 (``None`` elsewhere)."""
    gathered = comm.gather(arrays, root=0)
    if comm.rank != 0:
        return None
    return [np.concatenate([g[k] for g in gathered]) for k in range(len(arrays))]


def _num_local_cells(msh: dmesh.Mesh) -> int:
    return msh.topology.index_map(msh.topology.dim).size_local


def _cell_vertices(msh: dmesh.Mesh, dim: int, entities: npt.NDArray[np.int32]) -> np.ndarray:
    """Coordinates of the vertices of ``entities``: shape (num, vertices per entity, 3).

    Empty input gives an empty array of the right shape without calling into dolfinx (some of
    its functions fail on empty entity lists, e.g. a rank without contact facets).
    """
    entities = np.asarray(entities, dtype=np.int32)
    if len(entities) == 0:
        ct = _cpp_mesh.cell_entity_type(msh.topology.cell_type, dim, 0)
        return np.zeros((0, _cpp_mesh.cell_num_vertices(ct), 3))
    nodes = dmesh.entities_to_geometry(msh, dim, entities, False)
    return msh.geometry.x[nodes]


def _polygon_order(cell_type: dmesh.CellType) -> list[int]:
    """Vertex order of a 2D cell as a polygon (dolfinx quadrilaterals are tensor-ordered)."""
    return [0, 1, 3, 2] if cell_type == dmesh.CellType.quadrilateral else [0, 1, 2]


def _triangles(num_cells: int, cell_type: dmesh.CellType) -> np.ndarray:
    """Triangles of per-cell vertex blocks (quadrilaterals split in two)."""
    if cell_type == dmesh.CellType.quadrilateral:
        base = 4 * np.arange(num_cells)[:, None]
        return np.concatenate([base + np.array([0, 1, 3]), base + np.array([0, 3, 2])])
    return 3 * np.arange(num_cells)[:, None] + np.array([0, 1, 2])


def _exterior_facets(msh: dmesh.Mesh) -> npt.NDArray[np.int32]:
    fdim = msh.topology.dim - 1
    msh.topology.create_entities(fdim)
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    return dmesh.exterior_facet_indices(msh.topology)


def _outward_normals(msh: dmesh.Mesh, facets: npt.NDArray[np.int32]) -> np.ndarray:
    """Outer unit normals of exterior facets (2D or 3D, straight facets), shape (num, 3)."""
    tdim = msh.topology.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    if len(facets) == 0:
        return np.zeros((0, 3))
    f2c = msh.topology.connectivity(fdim, tdim)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    x = _cell_vertices(msh, fdim, facets)
    if tdim == 2:
        t = x[:, 1] - x[:, 0]
        n = np.stack([t[:, 1], -t[:, 0], np.zeros(len(t))], axis=1)
    else:
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    inward = dmesh.compute_midpoints(msh, tdim, cells).reshape(-1, 3) - x.mean(axis=1)
    n[np.sum(n * inward, axis=1) > 0] *= -1.0
    return n


def _gap_at(problem: Any, msh: dmesh.Mesh, points: np.ndarray) -> np.ndarray:
    """The problem's gap g evaluated pointwise (UFL evaluation; a few hundred points)."""
    expr = problem.gap_expr(ufl.SpatialCoordinate(msh))
    gdim = msh.geometry.dim
    try:
        return np.full(len(points), float(expr))
    except Exception:  # not a constant: evaluate point by point
        pass
    return np.array([float(expr(tuple(p[:gdim]))) for p in points])


def _contact_obstacle(sol: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local fine contact facets: vertex coordinates, outer normals, gap at the vertices."""
    disc = sol.disc
    msh = disc.mesh
    facets = disc.facet_tags.find(disc.problem.contact)
    facets = np.intersect1d(facets, _exterior_facets(msh)).astype(np.int32)
    x = _cell_vertices(msh, msh.topology.dim - 1, facets)
    n = _outward_normals(msh, facets)
    g = _gap_at(disc.problem, msh, x.reshape(-1, 3)).reshape(x.shape[:2])
    return x, n, g


def _p1_cells(u: fem.Function) -> tuple[np.ndarray, np.ndarray]:
    """Per local cell: dof coordinates and values of a (vector) P1/Q1 function.

    Returns:
        Arrays of shape (cells, dofs per cell, 3) and (cells, dofs per cell, value size).
    """
    V = u.function_space
    n = _num_local_cells(V.mesh)
    dofs = V.dofmap.list[:n]
    coords = V.tabulate_dof_coordinates()[dofs]
    bs = V.dofmap.index_map_bs
    values = u.x.array.reshape(-1, bs)[dofs]
    return coords, values


def _cellwise(msh: dmesh.Mesh, expr: ufl.core.expr.Expr) -> np.ndarray:
    """A scalar UFL expression interpolated into DG0, per local cell."""
    W = fem.functionspace(msh, ("DG", 0))
    f = fem.Function(W)
    f.interpolate(fem.Expression(expr, W.element.interpolation_points()))
    return f.x.array[W.dofmap.list[: _num_local_cells(msh), 0]].copy()


def von_mises_2d(sigma: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """Von Mises equivalent stress of a 2x2 stress tensor (plane stress, sigma_e = 1).

    ``sqrt(s11^2 + s22^2 - s11 s22 + 3 s12^2)``, the paper's sigma_{M,2} of Figure 5.
    """
    s11, s22, s12 = sigma[0, 0], sigma[1, 1], sigma[0, 1]
    return ufl.sqrt(s11**2 + s22**2 - s11 * s22 + 3.0 * s12**2)


# --------------------------------------------------------------------------------------------------
# Off-screen 3D rendering
# --------------------------------------------------------------------------------------------------


@contextlib.contextmanager
def virtual_display(timeout: float = 20.0) -> Iterator[str | None]:
    """Provide an X display for VTK: the current one, or a private Xvfb started and stopped here.

    Xvfb chooses a free display number itself (``-displayfd``), so concurrent runs do not clash.

    Yields:
        The display name, e.g. ``":1"``.

    Raises:
        RuntimeError: If no display is set, and Xvfb is missing or does not start.
    """
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        raise RuntimeError("no X display and no Xvfb executable for off-screen rendering")
    read_fd, write_fd = os.pipe()
    proc = subprocess.Popen(
        [xvfb, "-displayfd", str(write_fd), "-screen", "0", "1600x1200x24", "-nolisten", "tcp"],
        pass_fds=(write_fd,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(write_fd)
    try:
        ready, _, _ = select.select([read_fd], [], [], timeout)
        number = os.read(read_fd, 64).decode().strip() if ready else ""
        if not number.isdigit():
            raise RuntimeError(f"Xvfb did not start (exit code {proc.poll()})")
        os.environ["DISPLAY"] = f":{number}"
        yield os.environ["DISPLAY"]
    finally:
        os.close(read_fd)
        os.environ.pop("DISPLAY", None)
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _use_pyvista() -> bool:
    if os.environ.get("DWR_SIGNORINI_PLOT3D", "").lower() == "matplotlib":
        return False
    try:
        import pyvista  # noqa: F401
    except ImportError:
        return False
    return True


def _unstructured_grid(cells: np.ndarray, points: np.ndarray, cell_type: dmesh.CellType) -> Any:
    """A pyvista grid of gathered cells (per-cell vertex blocks), coincident points merged."""
    import pyvista
    from dolfinx.cpp.io import get_vtk_cell_type, perm_vtk

    num, nv = cells.shape
    perm = np.argsort(perm_vtk(cell_type, nv))
    conn = np.hstack([np.full((num, 1), nv), cells[:, perm]]).ravel()
    vtk_type = get_vtk_cell_type(cell_type, 3)
    types = np.full(num, vtk_type, dtype=np.uint8)
    return pyvista.UnstructuredGrid(conn, types, points)


def _render_pyvista(draw: Callable[[Any], None], path: Path, window: tuple[int, int]) -> None:
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


def _view_3d(plotter: Any, bounds: np.ndarray) -> None:
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


def _boundary_faces(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def _matplotlib_3d(
    polys: np.ndarray, values: np.ndarray | None, path: Path, title: str | None, label: str
) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = _figure((7.0, 6.0))
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
    _save(fig, path)


# --------------------------------------------------------------------------------------------------
# Field plots: gather (collective) first, then draw on rank 0 without dolfinx objects
# --------------------------------------------------------------------------------------------------
#
# Every field plot is two phases. The gather phase (collective) turns dolfinx objects into numpy
# arrays on rank 0. The draw phase (rank 0 only) sees only those arrays: the public functions drop
# their references to meshes and solutions before drawing. This matters in parallel: matplotlib
# and the import system leave reference cycles (caught exceptions with their tracebacks) that
# keep the frames on the stack alive until the garbage collector runs. Had those frames held a
# solution, rank 0 would destroy its PETSc objects (MUMPS factorisations, a collective operation)
# in a garbage collection of its own, at a moment the other ranks do not, and the program would
# hang. For the same reason a plot of an intermediate mesh inside a callback should gather with
# :func:`snapshot_mesh` and draw later.


@dataclass(frozen=True)
class MeshSnapshot:
    """A mesh gathered on rank 0 for drawing (see :func:`snapshot_mesh`).

    Attributes:
        cells: Vertex coordinates of every cell, shape (cells, vertices per cell, 3).
        ranks: The owning process of each cell.
        cell_type: The dolfinx cell type.
        tdim: Topological dimension.
    """

    cells: np.ndarray
    ranks: np.ndarray
    cell_type: dmesh.CellType
    tdim: int

    @property
    def num_cells(self) -> int:
        """Number of cells."""
        return len(self.cells)


def snapshot_mesh(msh: dmesh.Mesh) -> MeshSnapshot | None:
    """Gather the cells of a mesh on rank 0, to draw now or later. Collective.

    Args:
        msh: A 2D or 3D mesh.

    Returns:
        The snapshot on rank 0, ``None`` on the other ranks.
    """
    cells = np.arange(_num_local_cells(msh), dtype=np.int32)
    data = _gather_arrays(
        msh.comm, _cell_vertices(msh, msh.topology.dim, cells), np.full(len(cells), msh.comm.rank)
    )
    if data is None:
        return None
    return MeshSnapshot(data[0], data[1], msh.topology.cell_type, msh.topology.dim)


def plot_mesh(
    mesh: dmesh.Mesh | MeshSnapshot | None,
    path: str | os.PathLike,
    title: str | None = None,
    color_by_rank: bool = False,
    backend: str = "auto",
) -> Path | None:
    """Draw a 2D or 3D mesh (paper Figures 7 and 8b).

    Collective over the mesh's communicator when given a mesh; given a :class:`MeshSnapshot`
    (or ``None``, as :func:`snapshot_mesh` returns on ranks other than 0) it only draws.
    2D: all cells as polygons (matplotlib). 3D: the boundary of the mesh with its edges, rendered
    by pyvista off screen (see :func:`virtual_display`), or by matplotlib if pyvista is not
    available or ``backend="matplotlib"``.

    Args:
        mesh: The mesh (e.g. ``sol.disc.mesh``, the fine mesh T_h), or a snapshot of it.
        path: The PNG to write (on rank 0).
        title: Figure title (default: the number of cells).
        color_by_rank: Fill the cells with the colour of their owning process.
        backend: ``"auto"``, ``"pyvista"`` or ``"matplotlib"`` (3D only).

    Returns:
        The path on rank 0, ``None`` on the other ranks.
    """
    if backend not in ("auto", "pyvista", "matplotlib"):
        raise ValueError(f"backend must be 'auto', 'pyvista' or 'matplotlib', got {backend!r}")
    snap = mesh if mesh is None or isinstance(mesh, MeshSnapshot) else snapshot_mesh(mesh)
    del mesh  # draw without references to dolfinx objects (see the note above)
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
    if backend == "pyvista" or (backend == "auto" and _use_pyvista()):
        try:
            _mesh_pyvista(snap.cells, ranks, snap.cell_type, path, title)
            return path
        except Exception as err:
            if backend == "pyvista":
                raise
            logger.warning("pyvista rendering failed (%s); using matplotlib", err)
    faces, owner = _boundary_faces(snap.cells)
    values = None if ranks is None else ranks[owner].astype(float)
    _matplotlib_3d(snap.cells.reshape(-1, 3)[faces], values, path, title, "rank")
    return path


def _draw_mesh_2d(polys: np.ndarray, ranks: np.ndarray | None, path: Path, title: str) -> Path:
    from matplotlib.collections import PolyCollection

    lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
    aspect = (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-300)
    width = 7.0 if aspect <= 1.5 else max(2.5, 9.0 / aspect + 1.0)
    height = min(max(width * aspect, 2.5), 11.0)
    fig = _figure((width, height))
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
    return _save(fig, path, dpi=200)


def _mesh_pyvista(
    xcells: np.ndarray,
    ranks: np.ndarray | None,
    cell_type: dmesh.CellType,
    path: Path,
    title: str,
) -> None:
    num, nv, _ = xcells.shape
    grid = _unstructured_grid(
        np.arange(num * nv).reshape(num, nv), xcells.reshape(-1, 3), cell_type
    )
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
        _view_3d(plotter, np.array([surface.bounds[0::2], surface.bounds[1::2]]))

    _render_pyvista(draw, path, (1200, 1000))


def _auto_scale(umax: float, size: float) -> float:
    """Displacement magnification: true scale unless |u| is below 2% of the body's size."""
    if umax <= 0.0:
        return 1.0
    return 1.0 if umax >= 0.02 * size else 0.08 * size / umax


@dataclass(frozen=True)
class _SolutionData:
    """A displacement and the obstacle on Gamma_C, gathered on rank 0."""

    coords: np.ndarray  # (cells, dofs per cell, 3): dof coordinates per cell
    values: np.ndarray  # (cells, dofs per cell, gdim): u_h at those dofs
    cellvalue: np.ndarray  # (cells,): a cell-wise colour (von Mises) or zeros
    obs_x: np.ndarray  # (facets, vertices, 3): fine contact facets
    obs_n: np.ndarray  # (facets, 3): their outer normals
    obs_g: np.ndarray  # (facets, vertices): the gap at their vertices
    outline: np.ndarray  # (facets, 2, 3): exterior facets (2D only)


def _gather_solution(sol: Any, obstacle: bool, von_mises: bool, outline: bool) -> Any:
    disc = sol.disc
    msh = disc.mesh
    coords, values = _p1_cells(sol.u)
    cellvalue = (
        _cellwise(msh, von_mises_2d(disc.problem.sigma(sol.u)))
        if von_mises
        else np.zeros(len(coords))
    )
    if obstacle:
        obs = _contact_obstacle(sol)
    else:
        nv = _cell_vertices(msh, msh.topology.dim - 1, np.zeros(0, np.int32)).shape[1]
        obs = (np.zeros((0, nv, 3)), np.zeros((0, 3)), np.zeros((0, nv)))
    edges = _cell_vertices(msh, 1, _exterior_facets(msh)) if outline else np.zeros((0, 2, 3))
    data = _gather_arrays(msh.comm, coords, values, cellvalue, *obs, edges)
    return None if data is None else _SolutionData(*data)


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

    The fine mesh T_h is drawn displaced by ``scale * u_h``. The obstacle is drawn at
    ``x + scale * g(x) n`` on Gamma_C (g the gap, n the outer normal): with the same
    magnification as the body, so the body touches the obstacle line exactly where
    ``u_n = g`` (the active contact zone). The reference configuration is outlined.

    Args:
        sol: A :class:`~dwr_signorini.Solution` on a 2D mesh.
        path: The PNG to write (on rank 0).
        scale: Displacement magnification; default: 1, or larger so that max |u| is 8% of the
            body's size when the displacement is smaller than 2% of it.
        color: ``"magnitude"`` (|u_h|, continuous) or ``"von_mises"`` (the paper's sigma_{M,2}
            of Figure 5, cell-wise, colour scale clipped at the 99th percentile).
        obstacle: Draw the obstacle on Gamma_C.
        show_mesh: Draw the cell edges.
        title: Figure title.

    Returns:
        The path on rank 0, ``None`` on the other ranks.
    """
    if color not in ("magnitude", "von_mises"):
        raise ValueError(f"color must be 'magnitude' or 'von_mises', got {color!r}")
    if sol.disc.mesh.topology.dim != 2:
        raise ValueError("plot_solution_2d needs a 2D mesh; use plot_solution_3d")
    data = _gather_solution(sol, obstacle, color == "von_mises", outline=True)
    del sol  # draw without references to dolfinx objects (see the note above)
    if data is None:
        return None
    return _draw_solution_2d(data, Path(path), scale, color, show_mesh, title)


def _draw_solution_2d(
    d: _SolutionData,
    path: Path,
    scale: float | None,
    color: str,
    show_mesh: bool,
    title: str | None,
) -> Path:
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    nc, nv = d.coords.shape[:2]
    pts = d.coords.reshape(-1, 3)[:, :2]
    u = d.values.reshape(-1, d.values.shape[-1])[:, :2]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size = float(np.max(hi - lo))
    umag = np.linalg.norm(u, axis=1)
    s = _auto_scale(float(umag.max()), size) if scale is None else float(scale)
    ttype = dmesh.CellType.quadrilateral if nv == 4 else dmesh.CellType.triangle
    tri = Triangulation(*(pts + s * u).T, _triangles(nc, ttype))

    span = hi - lo
    aspect = span[1] / max(span[0], 1e-300)
    width = 7.5 if aspect <= 1.5 else max(3.0, 10.0 / aspect + 2.0)
    fig = _figure((width, min(max(width * aspect * 0.8, 3.0), 10.0)))
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
    return _save(fig, path, dpi=200)


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

    2D: lambda_H is piecewise constant on the macro contact facets (Sigma_H); it is drawn as
    steps over the coordinate along Gamma_C (the coordinate in which Gamma_C extends most),
    active facets shaded. 3D: a map of lambda_H over the contact face, one colour per macro
    facet, in the two tangential coordinates.

    Args:
        sol: A :class:`~dwr_signorini.Solution`.
        path: The PNG to write (on rank 0).
        exact: Optional exact contact force as a function of the coordinate along Gamma_C
            (2D), e.g. ``examples.exact_contact_pressure_np``.
        title: Figure title.

    Returns:
        The path on rank 0, ``None`` on the other ranks.
    """
    data = _gather_contact_force(sol)
    del sol  # draw without references to dolfinx objects (see the note above)
    if data is None:
        return None
    return _draw_contact_force(*data, Path(path), exact, title)


def _gather_contact_force(sol: Any) -> list[np.ndarray] | None:
    sub = sol.disc.contact_mesh
    sdim = sub.topology.dim
    n = sub.topology.index_map(sdim).size_local
    x = _cell_vertices(sub, sdim, np.arange(n, dtype=np.int32))
    dofs = sol.lam.function_space.dofmap.list[:n, 0]
    lam = sol.lam.x.array[dofs].copy()
    active = np.zeros(n, dtype=bool)
    owned = dofs < len(sol.active)
    active[owned] = np.asarray(sol.active, dtype=bool)[dofs[owned]]
    return _gather_arrays(sub.comm, x, lam, active)


def _draw_contact_force(
    x: np.ndarray,
    lam: np.ndarray,
    active: np.ndarray,
    path: Path,
    exact: Callable[[np.ndarray], np.ndarray] | None,
    title: str | None,
) -> Path:
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
        fig = _figure((6.4, 3.8))
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
        return _save(fig, path)

    from matplotlib.collections import PolyCollection

    names = ("$x_1$", "$x_2$", "$x_3$")
    i, j = sorted(int(a) for a in axes_order[:2])
    polys = x[:, :, [i, j]]
    fig = _figure((6.0, 5.0))
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
    return _save(fig, path)


def plot_solution_3d(
    sol: Any,
    path: str | os.PathLike,
    scale: float | None = None,
    obstacle: bool = True,
    title: str | None = None,
    backend: str = "auto",
) -> Path | None:
    """The deformed 3D body coloured by |u_h|, with the obstacle (paper Figure 8a). Collective.

    Rendered by pyvista off screen: the boundary of T_h displaced by ``scale * u_h`` with the
    cell edges, and the obstacle surface ``x + scale * g(x) n`` over Gamma_C (translucent).
    Falls back to matplotlib (boundary facets coloured by |u_h|) as :func:`plot_mesh` does.

    Args:
        sol: A :class:`~dwr_signorini.Solution` on a 3D mesh.
        path: The PNG to write (on rank 0).
        scale: Displacement magnification (default as in :func:`plot_solution_2d`).
        obstacle: Draw the obstacle over Gamma_C.
        title: Text in the picture.
        backend: ``"auto"``, ``"pyvista"`` or ``"matplotlib"``.

    Returns:
        The path on rank 0, ``None`` on the other ranks.
    """
    if backend not in ("auto", "pyvista", "matplotlib"):
        raise ValueError(f"backend must be 'auto', 'pyvista' or 'matplotlib', got {backend!r}")
    if sol.disc.mesh.topology.dim != 3:
        raise ValueError("plot_solution_3d needs a 3D mesh; use plot_solution_2d")
    cell_type = sol.disc.mesh.topology.cell_type
    data = _gather_solution(sol, obstacle, von_mises=False, outline=False)
    del sol  # draw without references to dolfinx objects (see the note above)
    if data is None:
        return None
    path = Path(path)
    nc, nv = data.coords.shape[:2]
    pts = data.coords.reshape(-1, 3)
    u = data.values.reshape(-1, 3)
    umag = np.linalg.norm(u, axis=1)
    size = float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    s = _auto_scale(float(umag.max()), size) if scale is None else float(scale)
    text = (
        title
        if title is not None
        else (f"u_h on {nc} cells" + ("" if s == 1.0 else f", displacement x {s:.3g}"))
    )
    obstacle_pts = data.obs_x + s * data.obs_g[:, :, None] * data.obs_n[:, None, :]

    if backend == "pyvista" or (backend == "auto" and _use_pyvista()):
        try:
            _solution_pyvista(pts, u, umag, nc, nv, cell_type, obstacle_pts, s, path, text)
            return path
        except Exception as err:
            if backend == "pyvista":
                raise
            logger.warning("pyvista rendering failed (%s); using matplotlib", err)
    # matplotlib: boundary faces of the deformed cells, coloured by the mean of |u| on them
    faces, _ = _boundary_faces(pts.reshape(nc, nv, 3))
    _matplotlib_3d((pts + s * u)[faces], umag[faces].mean(axis=1), path, text, r"$|u_h|$")
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
    import pyvista

    grid = _unstructured_grid(np.arange(nc * nv).reshape(nc, nv), pts, cell_type)
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
        _view_3d(plotter, np.array([surface.bounds[0::2], surface.bounds[1::2]]))

    _render_pyvista(draw, path, (1200, 1000))
