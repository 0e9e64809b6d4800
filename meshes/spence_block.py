"""2D indentation of a large elastic block by a rigid cylinder: a half-plane approximant.

The block ``[-width / 2, width / 2] x [-depth, 0]``: its top y = 0 is flat, the part
``|x| <= contact_half`` of it is the possible contact boundary (a rigid cylinder presses on it
from above), the rest of the top and the two sides are free, the bottom is clamped. The mesh has
facets of ``h_contact`` on the contact boundary and grows linearly with the distance d from it,
``h_contact + growth d``, up to ``h``: the block can be hundreds of contact widths wide at the
cost of a few thousand cells. Tags: 1 ``contact``, 2 ``bottom`` (the face the load path holds,
``TOP`` of the cases' tags), 3 ``free``; cells 1 ``body``.
"""

from __future__ import annotations

import os
import sys
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import add_body_groups, main

CONTACT, BOTTOM, FREE = 1, 2, 3
#: The clamped face under the cases' name for the face a load path drives or holds.
TOP = BOTTOM
BODY = 1


def build(
    model: Any, width: float = 40.0, depth: float = 20.0, contact_half: float = 0.2,
    h_contact: float = 0.005, h: float = 2.0, growth: float = 0.25,
) -> None:
    """The geometry, physical groups and a triangle mesh in ``model`` (gmsh API, OCC)."""
    occ = model.occ
    w, eps = 0.5 * width, 1e-9 * width
    corners = [occ.addPoint(x, y, 0.0) for x, y in (
        (-w, -depth), (w, -depth), (w, 0.0), (contact_half, 0.0), (-contact_half, 0.0),
        (-w, 0.0))]
    lines = [occ.addLine(corners[i], corners[(i + 1) % 6]) for i in range(6)]
    surface = occ.addPlaneSurface([occ.addCurveLoop(lines)])
    occ.synchronize()
    add_body_groups(model, [(2, surface)], {
        CONTACT: ("contact", lambda c: abs(c[1]) < eps and abs(c[0]) < contact_half),
        BOTTOM: ("bottom", lambda c: abs(c[1] + depth) < eps),
        FREE: ("free", lambda c: True),
    }, BODY)
    field = model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "CurvesList", [lines[3]])
    field.setNumber(distance, "Sampling", max(20, int(2 * contact_half / h_contact)))
    size = field.add("MathEval")
    field.setString(size, "F", f"Min({h}, {h_contact} + {growth} * F{distance})")
    field.setAsBackgroundMesh(size)
    import gmsh

    # the size field alone sets the sizes (the session's options restored afterwards)
    options = ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature")
    saved = {name: gmsh.option.getNumber(f"Mesh.{name}") for name in options}
    try:
        for name in options:
            gmsh.option.setNumber(f"Mesh.{name}", 0)
        model.mesh.generate(2)
    finally:
        for name, value in saved.items():
            gmsh.option.setNumber(f"Mesh.{name}", value)


if __name__ == "__main__":
    main("spence_block", build, width=40.0, depth=20.0, contact_half=0.2, h_contact=0.005,
         h=2.0, growth=0.25)
