"""The three meshes of the paper's examples (Section 5) as gmsh geometries with named groups.

The demos keep the structured meshes of :mod:`dwr_signorini.examples` (the tables of docs/benchmarks
depend on them); these are the same domains and tags for gmsh users (unstructured triangles /
tetrahedra). Tags as in the examples: 1 ``dirichlet`` (clamped), 2 ``neumann`` (traction free),
3 ``contact``; cells 1 ``body``.

* ``analytic_2d``: Example 5.1, (-3, 0) x (-1, 1), Gamma_D = {x = -3}, Gamma_C = {x = 0}.
* ``bar_2d``: Example 5.2, (0, 0.05) x (0, 0.2), Gamma_D = {y = 0}, Gamma_C = {x = 0.05, y > 0.15}.
* ``obstacle_3d``: Example 5.3, (0, 0.25) x (0, 1)^2, Gamma_D = {x = 0},
  Gamma_C = {x = 0.25, y < 0.5, z < 0.5}.

Run as a script: ``python3 meshes/paper_examples.py [--h H]`` writes the three ``.msh`` files.
"""

from __future__ import annotations

import os
import sys
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import HERE, add_body_groups

DIRICHLET, NEUMANN, CONTACT = 1, 2, 3
BODY = 1
TOL = 1e-9


def analytic_2d(model: Any, h: float = 0.25) -> None:
    """Example 5.1's rectangle in ``model``, meshed with triangles of size h."""
    surface = [(2, model.occ.addRectangle(-3.0, -1.0, 0.0, 3.0, 2.0))]
    model.occ.synchronize()
    add_body_groups(model, surface, {
        DIRICHLET: ("dirichlet", lambda c: abs(c[0] + 3.0) < TOL),
        CONTACT: ("contact", lambda c: abs(c[0]) < TOL),
        NEUMANN: ("neumann", lambda c: True),
    }, BODY)
    model.mesh.setSize(model.getEntities(0), h)
    model.mesh.generate(2)


def bar_2d(model: Any, h: float = 0.0125) -> None:
    """Example 5.2's bar in ``model``; the right side is split at y = 0.15."""
    occ = model.occ
    surface = [(2, occ.addRectangle(0.0, 0.0, 0.0, 0.05, 0.2))]
    cut = occ.addPoint(0.05, 0.15, 0.0)
    surface, _ = occ.fragment(surface, [(0, cut)])
    surface = [e for e in surface if e[0] == 2]
    occ.synchronize()
    add_body_groups(model, surface, {
        DIRICHLET: ("dirichlet", lambda c: abs(c[1]) < TOL),
        CONTACT: ("contact", lambda c: abs(c[0] - 0.05) < TOL and c[1] > 0.15),
        NEUMANN: ("neumann", lambda c: True),
    }, BODY)
    model.mesh.setSize(model.getEntities(0), h)
    model.mesh.generate(2)


def obstacle_3d(model: Any, h: float = 0.125) -> None:
    """Example 5.3's box in ``model``; the face x = 0.25 is split at y = z = 0.5."""
    occ = model.occ
    box = occ.addBox(0.0, 0.0, 0.0, 0.25, 1.0, 1.0)
    inner = occ.addBox(0.125, 0.0, 0.0, 0.125, 0.5, 0.5)
    volume, _ = occ.fragment([(3, box)], [(3, inner)])
    occ.synchronize()
    add_body_groups(model, volume, {
        DIRICHLET: ("dirichlet", lambda c: abs(c[0]) < TOL),
        CONTACT: ("contact", lambda c: abs(c[0] - 0.25) < TOL and c[1] < 0.5 and c[2] < 0.5),
        NEUMANN: ("neumann", lambda c: True),
    }, BODY)
    model.mesh.setSize(model.getEntities(0), h)
    model.mesh.generate(3)


BUILDERS = {"analytic_2d": analytic_2d, "bar_2d": bar_2d, "obstacle_3d": obstacle_3d}


if __name__ == "__main__":
    import argparse

    import gmsh

    parser = argparse.ArgumentParser(description="write the paper examples' .msh files")
    parser.add_argument("--h", type=float, default=None, help="mesh size (default per example)")
    args = parser.parse_args()
    for name, build in BUILDERS.items():
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            gmsh.model.add(name)
            build(gmsh.model, **({} if args.h is None else {"h": args.h}))
            gmsh.write(os.path.join(HERE, f"{name}.msh"))
        finally:
            gmsh.finalize()
        print(f"wrote meshes/{name}.msh")
