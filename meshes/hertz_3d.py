"""3D Hertz contact: a hemisphere of radius R pressed onto a rigid flat.

The ball of radius R centred at (0, 0, R), cut at z = R; with ``quarter=True`` (the default) only
x >= 0, y >= 0, with symmetry planes x = 0 and y = 0; with ``half=True`` only y >= 0 (the half a
load along x keeps symmetric: the Cattaneo-Mindlin shear, ``demos/cattaneo_mindlin.py``). The
spherical face is the possible contact boundary, the top z = R is pressed down by a prescribed
displacement. Refined around (0, 0, 0). Tags: 1 ``contact`` (sphere), 2 ``top``, 3
``symmetry_x`` (x = 0), 4 ``symmetry_y`` (y = 0); cells 1 ``body``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_body_groups, boundary_of, main, onto_round, refine_near

CONTACT, TOP, SYMMETRY_X, SYMMETRY_Y = 1, 2, 3, 4
BODY = 1
RADIUS = 1.0


def build(
    model: Any, radius: float = RADIUS, h: float = 0.25, h_contact: float = 0.03,
    refine_radius: float = 0.15, quarter: int = 1, half: int = 0,
) -> None:
    """The geometry, physical groups and a tetrahedral mesh in ``model`` (gmsh API, OCC)."""
    occ = model.occ
    R = radius
    ball = occ.addSphere(0.0, 0.0, R, R)
    lo_x = 0.0 if quarter and not half else -R
    lo_y = 0.0 if quarter or half else -R
    box = occ.addBox(lo_x, lo_y, 0.0, R - lo_x, R - lo_y, R)
    volume, _ = occ.intersect([(3, ball)], [(3, box)])
    occ.synchronize()
    tol = 1e-9 * R
    groups = {
        TOP: ("top", lambda c: abs(c[2] - R) < tol),
        SYMMETRY_X: ("symmetry_x", lambda c: abs(c[0]) < tol),
        SYMMETRY_Y: ("symmetry_y", lambda c: abs(c[1]) < tol),
        CONTACT: ("contact", lambda c: True),
    }
    if half or not quarter:  # no plane x = 0 (the half sphere's centre of mass has x = 0)
        del groups[SYMMETRY_X]
    add_body_groups(model, volume, groups, BODY)
    bottom = [p for _, p in model.getEntities(0)
              if np.linalg.norm(model.getValue(0, p, [])) < tol]
    if not bottom and half:  # the bottom point lies on the arc of the symmetry plane
        bottom = [occ.addPoint(0.0, 0.0, 0.0)]
        occ.synchronize()
        arcs = [c for _, c in model.getEntities(1)
                if abs(occ.getCenterOfMass(1, c)[1]) < tol
                and occ.getCenterOfMass(1, c)[2] < R - tol]
        model.mesh.embed(0, bottom, 1, arcs[0])
    elif not bottom:  # the full hemisphere has no vertex at its bottom point: embed one
        bottom = [occ.addPoint(0.0, 0.0, 0.0)]
        occ.synchronize()
        sphere = [f for _, f in boundary_of(model, volume)
                  if abs(model.occ.getCenterOfMass(2, f)[2] - R) > tol]
        model.mesh.embed(0, bottom, 2, sphere[0])
    refine_near(model, bottom, h_contact, h, refine_radius * R)
    model.mesh.generate(3)


def projections(radius: float = RADIUS) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{CONTACT: points -> the nearest points of the sphere}`` for ``boundary_projection``."""
    return {CONTACT: onto_round((0.0, 0.0, radius), radius)}


if __name__ == "__main__":
    main("hertz_3d", build, radius=RADIUS, h=0.25, h_contact=0.03, refine_radius=0.15,
         quarter=1, half=0)
