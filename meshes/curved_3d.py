"""A 3D part with a curved contact face: half a cylinder lying on a rigid flat (line contact).

The cylinder of radius R with axis {x = 0, z = R} along y, of length L, cut at z = R and at
x = 0 (symmetry plane). The cylindrical face is the possible contact boundary, the top z = R is
pressed down, the ends y = 0 and y = L are free. Tags: 1 ``contact`` (cylinder), 2 ``top``,
3 ``symmetry`` (x = 0), 4 ``ends``; cells 1 ``body``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_body_groups, main, onto_round

CONTACT, TOP, SYMMETRY, ENDS = 1, 2, 3, 4
BODY = 1
RADIUS, LENGTH = 1.0, 1.0


def build(model: Any, radius: float = RADIUS, length: float = LENGTH, h: float = 0.2) -> None:
    """The geometry, physical groups and a tetrahedral mesh in ``model`` (gmsh API, OCC)."""
    occ = model.occ
    R = radius
    cylinder = occ.addCylinder(0.0, 0.0, R, 0.0, length, 0.0, R)
    box = occ.addBox(0.0, 0.0, 0.0, R, length, R)
    volume, _ = occ.intersect([(3, cylinder)], [(3, box)])
    occ.synchronize()
    tol = 1e-9 * R
    add_body_groups(model, volume, {
        TOP: ("top", lambda c: abs(c[2] - R) < tol),
        SYMMETRY: ("symmetry", lambda c: abs(c[0]) < tol),
        ENDS: ("ends", lambda c: abs(c[1]) < tol or abs(c[1] - length) < tol),
        CONTACT: ("contact", lambda c: True),
    }, BODY)
    model.mesh.setSize(model.getEntities(0), h)
    model.mesh.generate(3)


def projections(radius: float = RADIUS) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{CONTACT: points -> the nearest points of the cylinder}`` for ``boundary_projection``."""
    return {CONTACT: onto_round((0.0, 0.0, radius), radius, axes=(0, 2))}


if __name__ == "__main__":
    main("curved_3d", build, radius=RADIUS, length=LENGTH, h=0.2)
