"""The contact patch test: two stacked blocks, meshed independently (non-matching interface).

The lower block [0, 1] x [0, 1] (cells 1) and the upper block [0, 1] x [1, 2] (cells 2) are two
gmsh surfaces that share no curve, so their meshes meet along y = 1 without common nodes; the
sizes ``h_lower`` and ``h_upper`` differ. Tags: lower block 1 ``bottom``, 3 ``lower_top`` (the
interface), 5 ``lower_left``, 7 ``lower_right``; upper block 2 ``top``, 4 ``upper_bottom`` (the
interface), 6 ``upper_left``, 8 ``upper_right``.
"""

from __future__ import annotations

import os
import sys
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_groups, boundary_of, main

BOTTOM, TOP, LOWER_TOP, UPPER_BOTTOM = 1, 2, 3, 4
LOWER_LEFT, UPPER_LEFT, LOWER_RIGHT, UPPER_RIGHT = 5, 6, 7, 8
LOWER, UPPER = 1, 2


def build(model: Any, h_lower: float = 0.2, h_upper: float = 0.3, quads: int = 0) -> None:
    """The two blocks, their physical groups and meshes in ``model`` (gmsh API, OCC)."""
    occ = model.occ
    lower = occ.addRectangle(0.0, 0.0, 0.0, 1.0, 1.0)
    upper = occ.addRectangle(0.0, 1.0, 0.0, 1.0, 1.0)
    occ.synchronize()
    eps = 1e-9
    for surface, (bottom, top, left, right), y0 in (
        (lower, (BOTTOM, LOWER_TOP, LOWER_LEFT, LOWER_RIGHT), 0.0),
        (upper, (UPPER_BOTTOM, TOP, UPPER_LEFT, UPPER_RIGHT), 1.0),
    ):
        add_groups(model, 1, {
            bottom: ("bottom" if bottom == BOTTOM else "upper_bottom",
                     lambda c, y0=y0: abs(c[1] - y0) < eps),
            top: ("top" if top == TOP else "lower_top",
                  lambda c, y0=y0: abs(c[1] - y0 - 1.0) < eps),
            left: ("left", lambda c: abs(c[0]) < eps),
            right: ("right", lambda c: abs(c[0] - 1.0) < eps),
        }, boundary_of(model, [(2, surface)]))
    model.addPhysicalGroup(2, [lower], LOWER, name="lower")
    model.addPhysicalGroup(2, [upper], UPPER, name="upper")
    for surface, h in ((lower, h_lower), (upper, h_upper)):
        points = model.getBoundary([(2, surface)], combined=False, recursive=True)
        model.mesh.setSize(points, h)
    if quads:
        model.mesh.setRecombine(2, lower)
        model.mesh.setRecombine(2, upper)
    model.mesh.generate(2)


if __name__ == "__main__":
    main("two_blocks_2d", build, h_lower=0.2, h_upper=0.3)
