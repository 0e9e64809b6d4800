"""2D Hertz contact: a half-cylinder (half-disc) of radius R pressed onto a rigid flat.

The quarter x >= 0 of the disc of radius R centred at (0, R), cut at y = R: the arc from (0, 0)
to (R, R) is the possible contact boundary, the top y = R is pressed down by a prescribed
displacement, x = 0 is a symmetry plane. The mesh is refined around the first contact point
(0, 0). Tags: 1 ``contact`` (arc), 2 ``top``, 3 ``symmetry``; cells 1 ``body``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_body_groups, main, onto_round, refine_near

CONTACT, TOP, SYMMETRY = 1, 2, 3
BODY = 1
RADIUS = 1.0


def build(
    model: Any, radius: float = RADIUS, h: float = 0.1, h_contact: float = 0.01,
    refine_radius: float = 0.15,
) -> None:
    """The geometry, physical groups and a triangle mesh in ``model`` (gmsh API, OCC)."""
    occ = model.occ
    disc = occ.addDisk(0.0, radius, 0.0, radius, radius)
    box = occ.addRectangle(0.0, 0.0, 0.0, radius, radius)
    surface, _ = occ.intersect([(2, disc)], [(2, box)])
    occ.synchronize()
    R = radius
    add_body_groups(model, surface, {
        TOP: ("top", lambda c: abs(c[1] - R) < 1e-9 * R),
        SYMMETRY: ("symmetry", lambda c: abs(c[0]) < 1e-9 * R),
        CONTACT: ("contact", lambda c: True),
    }, BODY)
    origin = [p for _, p in model.getEntities(0)
              if np.linalg.norm(model.getValue(0, p, [])) < 1e-9 * R]
    refine_near(model, origin, h_contact, h, refine_radius * R)
    model.mesh.generate(2)


def projections(radius: float = RADIUS) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{CONTACT: points -> the nearest points of the circle}`` for ``boundary_projection``."""
    return {CONTACT: onto_round((0.0, radius, 0.0), radius, axes=(0, 1))}


if __name__ == "__main__":
    main("hertz_2d", build, radius=RADIUS, h=0.1, h_contact=0.01, refine_radius=0.15)
