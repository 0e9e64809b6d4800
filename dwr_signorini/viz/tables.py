"""Plots of the tables of adaptive runs: convergence, effectivity indices, sweeps (matplotlib).

The paper's Figures 4 and 6 and Tables 1-3. These functions take plain data: lists of row dicts
as returned by :meth:`~dwr_signorini.AdaptiveResult.rows` or read back from the CSV/JSON of a
run with :func:`read_rows`. They involve no MPI; pass ``comm`` to let only its rank 0 write, or
call them on rank 0 only.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt

from .canvas import new_figure, save_figure

__all__ = [
    "QUANTITY_LABELS",
    "cumulative_time",
    "plot_convergence",
    "plot_effectivity",
    "plot_interval",
    "plot_sweep",
    "read_rows",
]


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
    """One key of every row as a float array (see :func:`_value`)."""
    return np.array([_value(r, key) for r in rows], dtype=float)


def cumulative_time(rows: Sequence[Mapping[str, Any]]) -> npt.NDArray[np.float64]:
    """Wall-clock time spent up to and including each level (sum of ``time_total``).

    Args:
        rows: Table rows with ``time_total`` (a missing or NaN time counts as 0).

    Returns:
        The cumulative times, one per row.

    An adaptive run needs every earlier level to reach a mesh, so its cost at level L is the
    sum over levels 0..L; the same convention is used for uniform runs.
    """
    return np.cumsum(np.nan_to_num(_column(rows, "time_total")))


def _writer(comm: MPI.Comm | None) -> bool:
    """Whether this process writes: no communicator, or its rank 0."""
    return comm is None or comm.rank == 0


def _slope_label(slope: float, x: str) -> str:
    """Legend text of a reference slope, e.g. ``O(N^{-1})``."""
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

    Where the rows have ``J_low`` and ``J_high``, the ``estimate`` series carries error bars:
    the least and the largest ``|J - J_h| / |J|`` over the interval [J_low, J_high] (down to the
    axis where J_h lies inside it).

    Each run (e.g. ``{"adaptive": rows, "uniform": rows}``) gets a colour and each quantity a
    line style. Estimate-type quantities (``estimate``, ``eta``, ``eta_p``, ``contact_term``) are
    plotted as ``|value| / |J|`` so that they compare with ``E_rel``; ``J`` is ``reference`` if
    given, else ``J_h`` of each row. Quantities without any finite value (e.g. ``rel_error``
    when the exact J is unknown) are left out. Dotted grey lines show reference slopes, anchored
    at the first point of the first run.
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

    fig = new_figure((6.4, 4.8))
    ax = fig.add_subplot()
    anchor, xs_all = _plot_runs(ax, runs, x, quantities, reference)
    if anchor is not None and xs_all:
        _reference_slopes(ax, anchor, max(xs_all), slopes, x)
    if xs_all:  # the data's range (error bars on a log axis can widen matplotlib's own)
        ax.set_xlim(min(xs_all) / 1.5, max(xs_all) * 1.5)
    ax.set_xlabel(
        r"cells $M_\Omega$ of $T_h$" if x == "num_cells" else "cumulative wall-clock time [s]"
    )
    ax.set_ylabel("relative error / estimate")
    return _finish(fig, ax, path, title)


def _finish(fig: Any, ax: Any, path: str | os.PathLike, title: str | None) -> Path | None:
    """Grid, title and legend of a log-scale figure; write it to ``path``."""
    ax.grid(True, which="both", alpha=0.3)
    if title:
        ax.set_title(title)
    ax.legend(fontsize="small")
    return save_figure(fig, path)


def _plot_runs(
    ax: Any,
    runs: Mapping[str, Sequence[Mapping[str, Any]]],
    x: str,
    quantities: Sequence[str],
    reference: float | None,
) -> tuple[tuple[float, float] | None, list[float]]:
    """The series of :func:`plot_convergence`: one colour per run, one line style per quantity.

    Returns:
        The first point drawn (the reference slopes' anchor) and every abscissa drawn.
    """
    colors = [f"C{i}" for i in range(10)]
    anchor: tuple[float, float] | None = None
    xs_all: list[float] = []
    for i, (label, rows) in enumerate(runs.items()):
        if not rows:
            continue
        xs = _column(rows, "num_cells") if x == "num_cells" else cumulative_time(rows)
        for q in quantities:
            ys, denom = np.abs(_column(rows, q)), 1.0
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
            if q == "estimate":
                _interval_error_bars(ax, rows, xs, ok, ys, denom, colors[i % len(colors)])
            xs_all.extend(xs[ok])
            if anchor is None:
                anchor = (float(xs[ok][0]), float(ys[ok][0]))
    return anchor, xs_all


def _reference_slopes(
    ax: Any, anchor: tuple[float, float], x1: float, slopes: Sequence[float], x: str
) -> None:
    """Dotted grey lines ``N^s`` from ``anchor`` to ``x1``, at half the anchor's value."""
    x0, y0 = anchor
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


def _error_range(rows: Sequence[Mapping[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """The least and the largest |J - J_h| over J in [J_low, J_high], per row (NaN without)."""
    J_h, lo, hi = _column(rows, "J_h"), _column(rows, "J_low"), _column(rows, "J_high")
    least = np.maximum(np.maximum(lo - J_h, J_h - hi), 0.0)
    largest = np.maximum(np.abs(lo - J_h), np.abs(hi - J_h))
    return least, largest


def _interval_error_bars(
    ax: Any, rows: Sequence[Mapping[str, Any]], xs: np.ndarray, ok: np.ndarray,
    ys: np.ndarray, denom: Any, color: str,
) -> None:
    """Vertical bars from the least to the largest error that the interval allows."""
    least, largest = (r / denom for r in _error_range(rows))
    bar = ok & np.isfinite(largest) & (largest > 0)
    if not bar.any():
        return
    # A log axis has no 0: a bar whose interval holds J_h reaches down to the axis.
    low = np.where(least[bar] > 0, least[bar], ys[bar] * 1e-6)
    ax.errorbar(
        xs[bar], ys[bar], yerr=[ys[bar] - np.minimum(low, ys[bar]),
                                np.maximum(largest[bar] - ys[bar], 0.0)],
        fmt="none", ecolor=color, elinewidth=0.8, capsize=2, alpha=0.6,
    )


def plot_interval(
    runs: Mapping[str, Sequence[Mapping[str, Any]]],
    path: str | os.PathLike,
    reference: float | None = None,
    title: str | None = None,
    comm: MPI.Comm | None = None,
    ylim: tuple[float, float] | None = None,
) -> Path | None:
    """J_h per level with its interval [J_low, J_high] as error bar, against cells (log x).

    Where the rows have ``J_best`` (the interval's centre, J_h corrected by the estimate: the
    number to use) it is drawn as a cross; J_h is often outside its own interval.

    Args:
        runs: Label -> table rows with ``J_h``, ``J_low``, ``J_high`` and ``num_cells``
            (``J_best`` optional).
        path: The PNG to write.
        reference: A reference or exact value of J, drawn as a grey line.
        title: Figure title.
        ylim: The range of J shown (bars of wider intervals leave the picture); default: all.
        comm: If given, only its rank 0 draws and writes.

    Returns:
        The path written, or ``None`` on ranks other than 0 of ``comm``.
    """
    if not _writer(comm):
        return None
    fig = new_figure((6.4, 4.4))
    ax = fig.add_subplot()
    for i, (label, rows) in enumerate(runs.items()):
        xs, J_h = _column(rows, "num_cells"), _column(rows, "J_h")
        lo, hi = _column(rows, "J_low"), _column(rows, "J_high")
        ok = np.isfinite(xs) & np.isfinite(J_h) & np.isfinite(lo) & np.isfinite(hi)
        if not ok.any():
            continue
        # Shift the runs apart a little along x so that their bars do not overlap.
        shift = 1.0 + 0.04 * i
        ax.errorbar(
            xs[ok] * shift, J_h[ok], yerr=[J_h[ok] - np.minimum(lo[ok], J_h[ok]),
                                           np.maximum(hi[ok] - J_h[ok], 0.0)],
            fmt=_MARKERS[i % len(_MARKERS)] + "-", color=f"C{i}", markersize=4, capsize=3,
            label=rf"{label}: $J(w_h)$ and $[J_{{low}}, J_{{high}}]$",
        )
        best = _column(rows, "J_best")  # the interval's centre, the number to use
        if np.isfinite(best[ok]).any():
            ax.plot(xs[ok] * shift, best[ok], "x", color=f"C{i}", markersize=6,
                    label=rf"{label}: $J_{{best}}$")
    if reference is not None:
        ax.axhline(reference, color="0.4", linewidth=1.0, linestyle="--", label="reference J")
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.set_xscale("log")
    ax.set_xlabel(r"cells $M_\Omega$ of $T_h$")
    ax.set_ylabel(r"$J$")
    return _finish(fig, ax, path, title)


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

    Raises:
        ValueError: If ``x`` is neither ``"level"`` nor ``"num_cells"``.
    """
    if x not in ("level", "num_cells"):
        raise ValueError(f"x must be 'level' or 'num_cells', got {x!r}")
    if not _writer(comm):
        return None
    fig = new_figure((6.4, 4.4))
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
    return save_figure(fig, path)


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
    fig = new_figure((6.4, 4.0))
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
    return save_figure(fig, path)
