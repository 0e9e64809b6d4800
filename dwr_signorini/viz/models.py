"""The model map of a per-region run: which contact facets ran which law, level by level.

A table plot (no MPI): it takes the plain data of ``AdaptiveResult.model_map`` or of the
``model_map.json`` a run writes (``{"levels": [...]}``), one dict per level with the vertices of
every macro contact facet and its flag (:meth:`~dwr_signorini.model_regions.RegionMap.as_dict`).
Each level is a row; each facet is drawn as the interval it covers along the axis in which
Gamma_C is longest (in 3D the facets of a row overlap where they share that coordinate).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np

from .canvas import new_figure, save_figure

__all__ = ["plot_model_map"]

#: The colours of the two laws.
COLOURS = {0: "#9ecae1", 1: "#d6604d"}


def plot_model_map(
    maps: Sequence[Mapping[str, Any]] | Mapping[str, Any],
    path: str | os.PathLike,
    title: str | None = None,
    comm: MPI.Comm | None = None,
) -> Path | None:
    """Plot which facets ran Coulomb (red) and which frictionless (blue), one row per level.

    Args:
        maps: ``AdaptiveResult.model_map``, or the content of ``model_map.json``.
        path: The PNG to write.
        title: The figure's title (default: none).
        comm: Only its rank 0 writes (default: the caller writes).

    Returns:
        ``path`` where written, else None.

    Raises:
        ValueError: No level in ``maps``.
    """
    levels = list(maps["levels"] if isinstance(maps, Mapping) else maps)
    if not levels:
        raise ValueError("plot_model_map: maps holds no level")
    if comm is not None and comm.rank != 0:
        return None
    facets = [np.asarray(m["facets"], dtype=float) for m in levels]
    every = np.concatenate([f.reshape(-1, f.shape[-1]) for f in facets])
    axis = int(np.argmax(np.ptp(every, axis=0)))
    fig = new_figure((7.0, 0.45 * len(levels) + 1.2))
    ax = fig.add_subplot(1, 1, 1)
    for row, (level, f) in enumerate(zip(levels, facets, strict=True)):
        low, high = f[:, :, axis].min(axis=1), f[:, :, axis].max(axis=1)
        for flag in (0, 1):
            pick = np.asarray(level["rich"]) == flag
            ax.broken_barh(
                list(zip(low[pick], high[pick] - low[pick], strict=True)), (row - 0.35, 0.7),
                facecolors=COLOURS[flag], edgecolors="white", linewidth=0.3,
            )
    ax.set_yticks(range(len(levels)),
                  [f"level {m['level']} ({m['share']:.0%})" for m in levels])
    ax.invert_yaxis()
    ax.set_xlabel("xyz"[axis] + " along the contact boundary")
    from matplotlib.patches import Patch

    handles = [Patch(color=COLOURS[k], label=name)
               for k, name in ((0, "frictionless"), (1, "Coulomb"))]
    ax.legend(handles=handles, fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if title:
        ax.set_title(title)
    return save_figure(fig, path)
