"""Helpers of the gmsh scripts in this folder: physical groups by position, and writing .msh.

Each script ``meshes/<name>.py`` has ``build(model, ...)`` (geometry, physical groups with names,
mesh generation in a gmsh model), its tags as constants, ``projections()`` for curved faces
(``{facet tag: callable}`` for ``boundary_projection``, a .msh file carries no CAD) and, run as
a script, writes ``meshes/<name>.msh``. ``dwr_signorini.read_mesh`` reads the file or the model.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def add_groups(
    model: Any,
    dim: int,
    groups: Mapping[int, tuple[str, Callable[[np.ndarray], bool]]],
    entities: list[tuple[int, int]] | None = None,
) -> None:
    """Physical groups ``{tag: (name, where(center of mass) -> bool)}`` of entities of ``dim``.

    Every entity goes to the first group whose rule holds; an entity in none is an error
    (every boundary facet must be tagged, see ``dwr_signorini.examples.tag_exterior_facets``).
    """
    entities = model.getEntities(dim) if entities is None else entities
    members: dict[int, list[int]] = {tag: [] for tag in groups}
    for _, e in entities:
        c = np.asarray(model.occ.getCenterOfMass(dim, e))
        for tag, (_, where) in groups.items():
            if where(c):
                members[tag].append(e)
                break
        else:
            raise RuntimeError(f"entity ({dim}, {e}) at {c} is in no physical group")
    for tag, (name, _) in groups.items():
        if members[tag]:
            model.addPhysicalGroup(dim, members[tag], tag, name=name)


def add_body_groups(
    model: Any,
    body: list[tuple[int, int]],
    groups: Mapping[int, tuple[str, Callable[[np.ndarray], bool]]],
    body_tag: int = 1,
) -> None:
    """Physical groups of a body: its boundary in ``groups``, the body in one more group.

    The boundary entities of ``body`` go to ``groups`` (:func:`add_groups`); the entities of
    ``body`` form the group ``body_tag``, named "body".
    """
    dim = body[0][0]
    add_groups(model, dim - 1, groups, boundary_of(model, body))
    model.addPhysicalGroup(dim, [e for _, e in body], body_tag, name="body")


def boundary_of(model: Any, volumes: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """The (unoriented) boundary entities of a set of entities."""
    return [(d, abs(e)) for d, e in model.getBoundary(volumes, combined=True, oriented=False)]


def refine_near(model: Any, points: list[int], h_min: float, h_max: float, dist: float) -> None:
    """Mesh size h_min within ``dist`` of the gmsh points, growing to h_max at 4 dist."""
    field = model.mesh.field
    d = field.add("Distance")
    field.setNumbers(d, "PointsList", points)
    t = field.add("Threshold")
    field.setNumber(t, "InField", d)
    field.setNumber(t, "SizeMin", h_min)
    field.setNumber(t, "SizeMax", h_max)
    field.setNumber(t, "DistMin", dist)
    field.setNumber(t, "DistMax", 4 * dist)
    field.setAsBackgroundMesh(t)


def onto_round(
    centre: Sequence[float], radius: float, axes: Sequence[int] = (0, 1, 2)
) -> Callable[[np.ndarray], np.ndarray]:
    """Points -> their nearest points on a circle, sphere or cylinder, for ``boundary_projection``.

    Args:
        centre: A point of the centre (of the axis, for a cylinder), three coordinates.
        radius: The radius.
        axes: The coordinates the distance is measured in: all three for a sphere; two for a
            circle in that plane, or a cylinder along the third.

    Returns:
        The map of points (shape ``(3, n)``) that moves the coordinates ``axes`` radially onto
        the surface and keeps the others.
    """
    axes = list(axes)
    c = np.asarray(centre, dtype=float)[axes][:, None]

    def project(x: np.ndarray) -> np.ndarray:
        out = x.copy()
        d = x[axes] - c
        out[axes] = c + radius * d / np.linalg.norm(d, axis=0)
        return out

    return project


def main(name: str, build: Callable[..., None], **defaults: float) -> None:
    """Command line of a mesh script: options for ``defaults``, writes ``<name>.msh``."""
    import gmsh

    parser = argparse.ArgumentParser(description=f"write meshes/{name}.msh")
    for key, value in defaults.items():
        parser.add_argument(f"--{key.replace('_', '-')}", type=type(value), default=value)
    parser.add_argument("--output", default=os.path.join(HERE, f"{name}.msh"))
    args = vars(parser.parse_args())
    output = args.pop("output")
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        gmsh.model.add(name)
        build(gmsh.model, **args)
        gmsh.write(output)
    finally:
        gmsh.finalize()
    print(f"wrote {output}")
