"""Named phases of the method, timed with ``time.perf_counter``.

Every costly step runs inside ``timed(phase)``; :func:`snapshot` returns the accumulated
wall-clock seconds of all phases on this process, so a benchmark can price each phase per level
by taking differences. (dolfinx's global timers only resolve 10 ms, too coarse for small levels.)
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["PHASES", "snapshot", "timed"]

PHASES = (
    "discretize",
    "assemble",
    "factorize",
    "newton solve",
    "dual solve",
    "higher-order solve",
    "reconstruct",
    "indicators",
    "mark",
    "refine",
    "transfer",
    "output",
)

_totals: dict[str, float] = dict.fromkeys(PHASES, 0.0)


@contextmanager
def timed(phase: str) -> Iterator[None]:
    """Add the wall-clock time of the ``with`` block to ``phase`` (one of :data:`PHASES`)."""
    if phase not in _totals:
        raise ValueError(f"unknown phase {phase!r}; phases are {PHASES}")
    tic = time.perf_counter()
    try:
        yield
    finally:
        _totals[phase] += time.perf_counter() - tic


def snapshot() -> dict[str, float]:
    """Accumulated wall-clock seconds of every phase on this process."""
    return dict(_totals)
