"""Geometry input checked (issue 58): boundary projections and gmsh models without groups.

* ``boundary_projection`` onto a circle of the wrong radius (80 for a body of radius 8) is
  refused when the problem is built, naming the tag, the vertex and the distance; so is a move
  of the new vertices after a refinement (:func:`dwr_signorini.refine.project_boundary`), the
  mesh then unchanged; the right radius passes, its moves being round-off.
* A projection undefined at a vertex (the circle's centre on the contact face) names the vertex;
  one that inverts a cell names the vertex that moves most and its distance.
* ``ds.read_mesh`` of a gmsh model without physical groups gives the documented ValueError.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import obstacles as ob
from dwr_signorini.mesh_validation import MAX_PROJECTION_MOVE
from dwr_signorini.refine import project_boundary
from tests.problems import from_model, mesh_script, top_clamped_tags

pytestmark = pytest.mark.mpi

HERTZ = mesh_script("hertz_2d")
R = 8.0


def _onto_circle(center, radius):
    c = np.array([*center, 0.0])[:, None]

    def f(x):
        d = x - c
        d[2] = 0.0
        return c + radius * d / np.linalg.norm(d, axis=0)

    return f


def _hertz(projection):
    msh, cells, facets = from_model(HERTZ.build, radius=R, h=0.25 * R, h_contact=0.05 * R,
                                    refine_radius=0.2)
    return ds.SignoriniProblem(
        msh, facets, contact=HERTZ.CONTACT,
        dirichlet={HERTZ.TOP: (None, -0.01), HERTZ.SYMMETRY: (0.0, None)},
        E=200.0, nu=0.3, gap=ob.Plane((0.0, 0.0), (0.0, -1.0)), cell_tags=cells,
        boundary_projection={HERTZ.CONTACT: projection},
    )


def test_projection_radius_typo_refused():
    with pytest.raises(ValueError) as info:
        _hertz(_onto_circle((0.0, R), 10 * R))
    text = str(info.value)
    assert text.startswith(f"boundary_projection[{HERTZ.CONTACT}] moves the vertex at (")
    distance = float(text.split(" by ")[1].split(",")[0])
    assert distance == pytest.approx(9 * R, rel=1e-6)  # every vertex of the arc moves 72
    assert f"at most {MAX_PROJECTION_MOVE}" in text


def test_projection_right_radius_passes():
    problem = _hertz(_onto_circle((0.0, R), R))
    assert HERTZ.CONTACT in problem.boundary_projection


@pytest.mark.filterwarnings("ignore:invalid value encountered")
def test_projection_undefined_at_a_vertex_names_it():
    with pytest.raises(ValueError, match=r"returned NaN or Inf for the vertex at \(0\.0, 0\.0\)"):
        _hertz(_onto_circle((0.0, 0.0), R))  # the centre is the arc's lowest vertex


def test_projection_after_refinement_refused_and_mesh_unchanged():
    msh = mesh.create_rectangle(MPI.COMM_WORLD, [(0.0, 0.0), (2.0, 1.0)], [8, 4],
                                ghost_mode=mesh.GhostMode.none)
    tags = top_clamped_tags(msh, 1.0)
    before = msh.geometry.x.copy()
    h = 0.5  # the diameter of the rectangle's cells (0.25 x 0.25 squares cut in two: 0.354)
    lift = 0.6 * h  # more than half the local mesh size anywhere
    with pytest.raises(ValueError, match=rf"boundary_projection\[{ex.CONTACT}\] moves the vertex"):
        project_boundary(msh, tags, {ex.CONTACT: lambda p: p + np.array([[0.0], [lift], [0.0]])})
    assert np.array_equal(msh.geometry.x, before)
    small = 0.01  # a small move passes and is made
    project_boundary(msh, tags, {ex.CONTACT: lambda p: p - np.array([[0.0], [small], [0.0]])})
    moved = np.isclose(before[:, 1], 0.0)
    assert np.allclose(msh.geometry.x[moved, 1], -small)
    assert np.array_equal(msh.geometry.x[~moved], before[~moved])


def _unit_square(model, groups):
    model.occ.addRectangle(0.0, 0.0, 0.0, 1.0, 1.0)
    model.occ.synchronize()
    if "cells" in groups:
        model.addPhysicalGroup(2, [1], 7)
    model.mesh.setSize(model.getEntities(0), 0.5)
    model.mesh.generate(2)


@pytest.mark.parametrize("groups, missing", [((), "cells"), (("cells",), "facets")])
def test_read_mesh_without_physical_groups(groups, missing):
    with pytest.raises(ValueError, match=rf"the mesh has no physical groups of {missing}"):
        from_model(_unit_square, groups=groups)


def test_projection_inverting_a_cell_names_the_vertex():
    """Flat cells (1 x 1/16): lifting the bottom by 0.1 < half their size inverts the bottom row."""
    msh = mesh.create_rectangle(MPI.COMM_WORLD, [(0.0, 0.0), (2.0, 1.0)], [2, 16],
                                ghost_mode=mesh.GhostMode.none)
    tags = top_clamped_tags(msh, 1.0)
    before = msh.geometry.x.copy()
    lift = np.array([[0.0], [0.1], [0.0]])
    with pytest.raises(RuntimeError, match=r"invert or flatten \d+ cell\(s\) .*\(the vertex at "
                       r"\([0-9.]+, 0\.0\) would move by 0\.1\)"):
        project_boundary(msh, tags, {ex.CONTACT: lambda p: p + lift})
    assert np.array_equal(msh.geometry.x, before)
