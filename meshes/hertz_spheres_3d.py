"""3D Hertz contact of two elastic bodies: a quarter ball pressed onto a quarter block or ball.

The upper body is the quarter x >= 0, y >= 0, z <= R1 of the ball of radius R1 centred at
(0, 0, R1) (its lowest point is the origin, cells 2). The lower body (cells 1) is, with
``r_lower = 0`` (the default), the quarter block [0, L] x [0, L] x [-L, 0] of a half-space
(L = ``block`` R1), else the quarter x >= 0, y >= 0, z >= -R2 of the ball of radius R2 = r_lower
centred at (0, 0, -R2). x = 0 and y = 0 are symmetry planes of both. The two are separate gmsh
volumes (no shared node at the origin: non-matching meshes), refined around the contact point.
Tags: 1 ``lower_contact`` (the block's top z = 0 or the lower sphere), 2 ``upper_contact`` (the
upper sphere), 3 ``lower_base`` (z = -L or z = -R2), 4 ``upper_top`` (z = R1, pressed down),
5 ``lower_symmetry_x``, 6 ``upper_symmetry_x`` (x = 0), 7 ``lower_symmetry_y``,
8 ``upper_symmetry_y`` (y = 0), 9 ``lower_side`` (the block's faces x = L and y = L).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_groups, boundary_of, main, onto_round, refine_near

LOWER_CONTACT, UPPER_CONTACT, LOWER_BASE, UPPER_TOP = 1, 2, 3, 4
LOWER_SYMMETRY_X, UPPER_SYMMETRY_X, LOWER_SYMMETRY_Y, UPPER_SYMMETRY_Y = 5, 6, 7, 8
LOWER_SIDE = 9
LOWER, UPPER = 1, 2


def _quarter_ball(occ: Any, centre_z: float, radius: float, sign: float) -> list:
    """The quarter x, y >= 0 of the ball's half towards the origin.

    That half lies below the centre for ``sign`` > 0, above it for ``sign`` < 0.
    """
    ball = occ.addSphere(0.0, 0.0, centre_z, radius)
    z0 = centre_z - radius if sign > 0 else centre_z
    box = occ.addBox(0.0, 0.0, z0, radius, radius, radius)
    volume, _ = occ.intersect([(3, ball)], [(3, box)])
    return volume


def build(
    model: Any, r_upper: float = 1.0, r_lower: float = 0.0, block: float = 1.0, h: float = 0.3,
    h_contact: float = 0.02, refine_radius: float = 0.12,
) -> None:
    """The two quarter bodies, their physical groups and a tetrahedral mesh in ``model`` (OCC)."""
    occ = model.occ
    R1 = r_upper
    upper = _quarter_ball(occ, R1, R1, 1.0)
    if r_lower > 0.0:
        lower = _quarter_ball(occ, -r_lower, r_lower, -1.0)
        depth = r_lower
    else:
        depth = block * R1
        lower = [(3, occ.addBox(0.0, 0.0, -depth, depth, depth, depth))]
    occ.synchronize()
    tol = 1e-9 * R1
    add_groups(model, 2, {
        UPPER_TOP: ("upper_top", lambda c: abs(c[2] - R1) < tol),
        UPPER_SYMMETRY_X: ("upper_symmetry_x", lambda c: abs(c[0]) < tol),
        UPPER_SYMMETRY_Y: ("upper_symmetry_y", lambda c: abs(c[1]) < tol),
        UPPER_CONTACT: ("upper_contact", lambda c: True),
    }, boundary_of(model, upper))
    lower_groups = {
        LOWER_BASE: ("lower_base", lambda c: abs(c[2] + depth) < tol),
        LOWER_SYMMETRY_X: ("lower_symmetry_x", lambda c: abs(c[0]) < tol),
        LOWER_SYMMETRY_Y: ("lower_symmetry_y", lambda c: abs(c[1]) < tol),
    }
    if r_lower > 0.0:
        lower_groups[LOWER_CONTACT] = ("lower_contact", lambda c: True)
    else:
        lower_groups[LOWER_CONTACT] = ("lower_contact", lambda c: abs(c[2]) < tol)
        lower_groups[LOWER_SIDE] = ("lower_side", lambda c: True)
    add_groups(model, 2, lower_groups, boundary_of(model, lower))
    model.addPhysicalGroup(3, [e for _, e in lower], LOWER, name="lower")
    model.addPhysicalGroup(3, [e for _, e in upper], UPPER, name="upper")
    origin = [p for _, p in model.getEntities(0)
              if np.linalg.norm(model.getValue(0, p, [])) < tol]
    refine_near(model, origin, h_contact, h, refine_radius * R1)
    model.mesh.generate(3)


def projections(
    r_upper: float = 1.0, r_lower: float = 0.0
) -> dict[int, Callable[[np.ndarray], np.ndarray]]:
    """``{sphere tag: points -> the nearest points of its sphere}`` for ``boundary_projection``."""
    out = {UPPER_CONTACT: onto_round((0.0, 0.0, r_upper), r_upper)}
    if r_lower > 0.0:
        out[LOWER_CONTACT] = onto_round((0.0, 0.0, -r_lower), r_lower)
    return out


if __name__ == "__main__":
    main("hertz_spheres_3d", build, r_upper=1.0, r_lower=0.0, block=1.0, h=0.3,
         h_contact=0.02, refine_radius=0.12)
