"""2D Cattaneo-Mindlin contact: a half-cylinder (half-disc) of radius R on a rigid flat, sheared.

The half x in (-R, R) below y = R of the disc of radius R centred at (0, R): the lower arc from
(-R, R) through (0, 0) to (R, R) is the possible contact boundary, the top y = R is pressed down
and then sheared by a prescribed displacement. There is no symmetry plane (the shear breaks the
symmetry). The arc is made of two quarter arcs that meet at the first contact point (0, 0), a
vertex of the mesh, and the mesh is refined around it (facets of ``h_contact`` within
``refine_radius``, growing to ``h`` at four times that distance). Tags: 1 ``contact`` (arc),
2 ``top``; cells 1 ``body``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_body_groups, main, onto_round, refine_near

CONTACT, TOP = 1, 2
BODY = 1
RADIUS = 1.0


def build(
    model: Any, radius: float = RADIUS, h: float = 0.2, h_contact: float = 0.01,
    refine_radius: float = 0.15,
) -> None:
    """The geometry, physical groups and a triangle mesh in ``model`` (gmsh API, OCC)."""
    occ = model.occ
    R = radius
    center = occ.addPoint(0.0, R, 0.0)
    left, origin, right = (occ.addPoint(x, y, 0.0) for x, y in ((-R, R), (0.0, 0.0), (R, R)))
    arcs = [occ.addCircleArc(left, center, origin), occ.addCircleArc(origin, center, right)]
    top = occ.addLine(right, left)
    surface = occ.addPlaneSurface([occ.addCurveLoop([*arcs, top])])
    occ.remove([(0, center)])
    occ.synchronize()
    add_body_groups(model, [(2, surface)], {
        TOP: ("top", lambda c: abs(c[1] - R) < 1e-9 * R),
        CONTACT: ("contact", lambda c: True),
    }, BODY)
    refine_near(model, [origin], h_contact, h, refine_radius * R)
    model.mesh.generate(2)


def projections(radius: float = RADIUS) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{CONTACT: points -> the nearest points of the circle}`` for ``boundary_projection``."""
    return {CONTACT: onto_round((0.0, radius, 0.0), radius, axes=(0, 1))}


if __name__ == "__main__":
    main("cattaneo_2d", build, radius=RADIUS, h=0.2, h_contact=0.01, refine_radius=0.15)
