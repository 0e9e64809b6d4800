"""2D Hertz contact of two elastic cylinders: two quarter discs touching at the origin.

The lower body is the quarter x >= 0, y >= -R1 of the disc of radius R1 centred at (0, -R1) (its
arc ends at the origin, cells 1), the upper body the quarter x >= 0, y <= R2 of the disc of
radius R2 centred at (0, R2) (cells 2); x = 0 is a symmetry plane of both. The two are separate
gmsh surfaces (no shared node at the origin), refined around the contact point. Tags: 1
``lower_arc``, 2 ``upper_arc`` (the possible contact), 3 ``lower_flat`` (y = -R1), 4
``upper_flat`` (y = R2, pressed down), 5 ``lower_symmetry``, 6 ``upper_symmetry``.

With ``full=True`` the bodies are the half discs (|x| <= R1, y >= -R1 and |x| <= R2, y <= R2:
no symmetry plane, the tags 5 and 6 absent), which can be sheared along x; the mesh is refined
within ``refine_radius`` min(R1, R2) of the origin (the contact point is then no gmsh vertex).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_groups, boundary_of, main, onto_round, refine_near

LOWER_ARC, UPPER_ARC, LOWER_FLAT, UPPER_FLAT, LOWER_SYMMETRY, UPPER_SYMMETRY = 1, 2, 3, 4, 5, 6
LOWER, UPPER = 1, 2


def build(
    model: Any, r_lower: float = 1.0, r_upper: float = 1.5, h: float = 0.15,
    h_contact: float = 0.01, refine_radius: float = 0.15, full: bool = False,
) -> None:
    """The two quarter discs (half discs if ``full``), their groups and a mesh in ``model``."""
    occ = model.occ
    bodies = []
    for sign, radius in ((-1.0, r_lower), (1.0, r_upper)):
        disc = occ.addDisk(0.0, sign * radius, 0.0, radius, radius)
        x0, width = (-radius, 2.0 * radius) if full else (0.0, radius)
        box = occ.addRectangle(x0, min(0.0, sign * radius), 0.0, width, radius)
        surface, _ = occ.intersect([(2, disc)], [(2, box)])
        bodies.append(surface)
    occ.synchronize()
    eps = 1e-9
    for surface, radius, sign, (arc, flat, sym) in (
        (bodies[0], r_lower, -1.0, (LOWER_ARC, LOWER_FLAT, LOWER_SYMMETRY)),
        (bodies[1], r_upper, 1.0, (UPPER_ARC, UPPER_FLAT, UPPER_SYMMETRY)),
    ):
        side = "lower" if sign < 0 else "upper"
        groups = {
            flat: (f"{side}_flat", lambda c, r=radius, s=sign: abs(c[1] - s * r) < eps * r),
            sym: (f"{side}_symmetry", lambda c, r=radius: abs(c[0]) < eps * r),
            arc: (f"{side}_arc", lambda c: True),
        }
        if full:
            del groups[sym]
        add_groups(model, 1, groups, boundary_of(model, surface))
    model.addPhysicalGroup(2, [e for _, e in bodies[0]], LOWER, name="lower")
    model.addPhysicalGroup(2, [e for _, e in bodies[1]], UPPER, name="upper")
    dist = refine_radius * min(r_lower, r_upper)
    if full:
        _refine_near_origin(model, h_contact, h, dist)
    else:
        origin = [p for _, p in model.getEntities(0)
                  if np.linalg.norm(model.getValue(0, p, [])) < eps]
        refine_near(model, origin, h_contact, h, dist)
    model.mesh.generate(2)


def _refine_near_origin(model: Any, h_min: float, h_max: float, dist: float) -> None:
    """Mesh size h_min within ``dist`` of the origin, growing to h_max at 4 dist."""
    field = model.mesh.field
    d = field.add("MathEval")
    field.setString(d, "F", "Sqrt(x^2 + y^2)")
    t = field.add("Threshold")
    field.setNumber(t, "InField", d)
    field.setNumber(t, "SizeMin", h_min)
    field.setNumber(t, "SizeMax", h_max)
    field.setNumber(t, "DistMin", dist)
    field.setNumber(t, "DistMax", 4 * dist)
    field.setAsBackgroundMesh(t)


def projections(
    r_lower: float = 1.0, r_upper: float = 1.5
) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{arc tag: points -> the nearest points of its circle}`` for ``boundary_projection``."""
    return {LOWER_ARC: onto_round((0.0, -r_lower, 0.0), r_lower, axes=(0, 1)),
            UPPER_ARC: onto_round((0.0, r_upper, 0.0), r_upper, axes=(0, 1))}


if __name__ == "__main__":
    main("hertz_cylinders_2d", build, r_lower=1.0, r_upper=1.5, h=0.15, h_contact=0.01)
