"""Named phases of the method, timed with ``time.perf_counter``, each interval charged once.

Every costly step runs inside ``timed(phase)``; :func:`snapshot` returns the accumulated
wall-clock seconds of all phases on this process, so a benchmark can price each phase per level
by taking differences. (dolfinx's global timers only resolve 10 ms, too coarse for small levels.)

Phases nest (the higher-order solves contain assembly, factorisation and solves): time is
charged to the innermost open phase only, so the phases partition the timed time and their sum
counts nothing twice. :func:`trace` records the charged segments, to check that structure.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["PHASES", "snapshot", "timed", "trace"]

PHASES = (
    "discretize",
    "assemble",
    "master trace",
    "factorize",
    "newton solve",
    "dual solve",
    "goal",
    "higher-order solve",
    "reconstruct",
    "indicators",
    "mark",
    "refine",
    "transfer",
    "output",
)

_totals: dict[str, float] = dict.fromkeys(PHASES, 0.0)
#: Open phases, innermost last, each with the start of its current segment.
_stack: list[list[object]] = []
#: Lists receiving (phase, start, end) of every charged segment, while :func:`trace` is open.
_traces: list[list[tuple[str, float, float]]] = []


def _charge(phase: str, start: float, end: float) -> None:
    _totals[phase] += end - start
    for segments in _traces:
        segments.append((phase, start, end))


@contextmanager
def timed(phase: str) -> Iterator[None]:
    """Charge the wall-clock time of the ``with`` block to ``phase`` (one of :data:`PHASES`).

    Time spent in a phase opened inside the block is charged to that inner phase instead.
    """
    if phase not in _totals:
        raise ValueError(f"unknown phase {phase!r}; phases are {PHASES}")
    now = time.perf_counter()
    if _stack:  # close the enclosing phase's segment
        outer = _stack[-1]
        _charge(outer[0], outer[1], now)
    _stack.append([phase, now])
    try:
        yield
    finally:
        end = time.perf_counter()
        _, start = _stack.pop()
        _charge(phase, start, end)
        if _stack:  # the enclosing phase goes on
            _stack[-1][1] = end


def snapshot() -> dict[str, float]:
    """Accumulated wall-clock seconds of every phase on this process."""
    return dict(_totals)


@contextmanager
def trace() -> Iterator[list[tuple[str, float, float]]]:
    """Record the segments ``(phase, start, end)`` charged while the block runs."""
    segments: list[tuple[str, float, float]] = []
    _traces.append(segments)
    try:
        yield segments
    finally:
        _traces.remove(segments)
