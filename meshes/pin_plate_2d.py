"""A pin pressed into the hole of a plate: conformal contact with clearance, half model.

The plate [-W, W] x [0, W] with a hole of radius ``r_hole`` at the origin (cells 2) and the pin,
an annulus ``r_inner`` <= r <= ``r_pin`` (cells 1) inside the hole, cut by the symmetry plane
y = 0. Two separate gmsh surfaces (no shared node); the clearance is ``r_hole - r_pin``. Tags:
1 ``pin_surface`` (r = r_pin, the possible contact), 2 ``hole`` (r = r_hole), 3 ``pin_bore``
(r = r_inner, where the pin is pushed), 4 ``plate_edge`` (|x| = W or y = W, clamped), 5
``pin_symmetry``, 6 ``plate_symmetry`` (y = 0).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_groups, boundary_of, main, onto_round

PIN_SURFACE, HOLE, PIN_BORE, PLATE_EDGE, PIN_SYMMETRY, PLATE_SYMMETRY = 1, 2, 3, 4, 5, 6
PIN, PLATE = 1, 2


def build(
    model: Any, r_pin: float = 0.95, r_hole: float = 1.0, r_inner: float = 0.4,
    width: float = 3.0, h: float = 0.3, h_contact: float = 0.05,
) -> None:
    """The pin and the plate, their physical groups and a triangle mesh in ``model`` (OCC)."""
    occ = model.occ
    half = occ.addRectangle(-width, 0.0, 0.0, 2 * width, width)
    plate, _ = occ.cut([(2, half)], [(2, occ.addDisk(0.0, 0.0, 0.0, r_hole, r_hole))])
    ring = occ.addDisk(0.0, 0.0, 0.0, r_pin, r_pin)
    ring, _ = occ.cut([(2, ring)], [(2, occ.addDisk(0.0, 0.0, 0.0, r_inner, r_inner))])
    pin, _ = occ.intersect(ring, [(2, occ.addRectangle(-r_pin, 0.0, 0.0, 2 * r_pin, r_pin))])
    occ.synchronize()
    eps = 1e-7

    def radius(c: np.ndarray) -> float:
        return float(np.hypot(c[0], c[1]))

    add_groups(model, 1, {
        PIN_SYMMETRY: ("pin_symmetry", lambda c: abs(c[1]) < eps),
        PIN_BORE: ("pin_bore", lambda c: radius(c) < 0.5 * (r_inner + r_pin)),
        PIN_SURFACE: ("pin_surface", lambda c: True),
    }, boundary_of(model, pin))
    add_groups(model, 1, {
        PLATE_SYMMETRY: ("plate_symmetry", lambda c: abs(c[1]) < eps),
        HOLE: ("hole", lambda c: radius(c) < 0.5 * (r_hole + width)),
        PLATE_EDGE: ("plate_edge", lambda c: True),
    }, boundary_of(model, plate))
    model.addPhysicalGroup(2, [e for _, e in pin], PIN, name="pin")
    model.addPhysicalGroup(2, [e for _, e in plate], PLATE, name="plate")
    field = model.mesh.field
    d = field.add("MathEval")
    field.setString(d, "F", f"{h_contact} + {h} * Fabs(Sqrt(x*x + y*y) - {r_hole}) / {width}")
    field.setAsBackgroundMesh(d)
    model.mesh.generate(2)


def projections(
    r_pin: float = 0.95, r_hole: float = 1.0
) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{tag: points -> the nearest points of its circle}`` for ``boundary_projection``."""
    return {PIN_SURFACE: onto_round((0.0, 0.0, 0.0), r_pin, axes=(0, 1)),
            HOLE: onto_round((0.0, 0.0, 0.0), r_hole, axes=(0, 1))}


if __name__ == "__main__":
    main("pin_plate_2d", build, r_pin=0.95, r_hole=1.0, h=0.3, h_contact=0.05)
