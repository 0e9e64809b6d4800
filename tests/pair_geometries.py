"""Geometries of the contact-search truths (gmsh builds for ``tests.problems.from_model``).

* :func:`two_annuli`: two annuli (outer radius 1, bore 0.4) touching at (0, 1), the lower one
  centred at the origin, the upper one at (0, 2). Each outer circle is two physical curves: the
  arc facing the other annulus (within 60 degrees of the contact point) and the rest, so that
  the same mesh carries the facing-arcs tags and, retagged, the whole-boundary tags.
* :func:`punch`: a flat punch [-w, w] x [0, 0.4] on a block [-1, 1] x [-1, 0], both structured
  (transfinite); the block's top has 2 n macro facets of 1/n and the punch's edges fall at
  w = 0.5 + 0.3 / n, inside a block facet.
* :func:`tet_boxes`: two stacked boxes of tetrahedra, non-matching (n and n + 1 cells a side).
"""

from __future__ import annotations

import numpy as np

# two annuli: cells 1 (lower), 2 (upper)
LOWER, UPPER = 1, 2
LOWER_FACING, LOWER_REST, LOWER_BORE = 1, 2, 3
UPPER_FACING, UPPER_REST, UPPER_BORE = 4, 5, 6
# the punch: cells 1 (block), 2 (punch)
BLOCK, PUNCH = 1, 2
BLOCK_TOP, BLOCK_BOTTOM, BLOCK_SIDES = 1, 2, 3
PUNCH_BOTTOM, PUNCH_TOP, PUNCH_SIDES = 4, 5, 6


def _annulus(geo, centre, facing_angle, h, h_contact, tags, inner=0.4):
    """One annulus: outer arcs (facing, rest), bore; returns the surface."""
    cx, cy = centre
    c = geo.addPoint(cx, cy, 0.0)

    def on(r, angle, size):
        a = np.radians(angle)
        return geo.addPoint(cx + r * np.cos(a), cy + r * np.sin(a), 0.0, size)

    angles = [facing_angle - 60, facing_angle, facing_angle + 60, facing_angle + 180]
    sizes = [h_contact * 3, h_contact, h_contact * 3, h]
    outer = [on(1.0, a, s) for a, s in zip(angles, sizes, strict=True)]
    arcs = [geo.addCircleArc(outer[k], c, outer[(k + 1) % 4]) for k in range(4)]
    bore_pts = [on(inner, a, h) for a in (0, 120, 240)]
    bore = [geo.addCircleArc(bore_pts[k], c, bore_pts[(k + 1) % 3]) for k in range(3)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(arcs), geo.addCurveLoop(bore)])
    facing, rest, bore_tag = tags
    return surface, {facing: arcs[:2], rest: arcs[2:], bore_tag: bore}


def two_annuli(model, h=0.25, h_contact=0.03):
    """The two annuli (module docstring)."""
    geo = model.geo
    lower, lower_curves = _annulus(geo, (0.0, 0.0), 90.0, h, h_contact,
                                   (LOWER_FACING, LOWER_REST, LOWER_BORE))
    upper, upper_curves = _annulus(geo, (0.0, 2.0), 270.0, h, h_contact,
                                   (UPPER_FACING, UPPER_REST, UPPER_BORE))
    geo.synchronize()
    for tag, curves in {**lower_curves, **upper_curves}.items():
        model.addPhysicalGroup(1, curves, tag)
    model.addPhysicalGroup(2, [lower], LOWER)
    model.addPhysicalGroup(2, [upper], UPPER)
    model.mesh.generate(2)


def _rectangle(geo, x0, y0, x1, y1, nx, ny):
    """A transfinite rectangle; returns (surface, bottom, right, top, left)."""
    p = [geo.addPoint(x, y, 0.0) for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
    lines = [geo.addLine(p[k], p[(k + 1) % 4]) for k in range(4)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    return surface, lines, (nx, ny)


def punch(model, n=4, punch_n=None):
    """The block and the punch (module docstring); the punch has ``punch_n`` cells across."""
    geo = model.geo
    w = 0.5 + 0.3 / n
    punch_n = punch_n or round(1.3 * n) + 1
    block, b_lines, (bx, by) = _rectangle(geo, -1.0, -1.0, 1.0, 0.0, 2 * n, n)
    top, t_lines, (tx, ty) = _rectangle(geo, -w, 0.0, w, 0.4, punch_n, max(2, n // 2))
    geo.synchronize()
    mesh = model.mesh
    for lines, (nx, ny), surface in ((b_lines, (bx, by), block), (t_lines, (tx, ty), top)):
        for k, line in enumerate(lines):
            mesh.setTransfiniteCurve(line, (nx if k % 2 == 0 else ny) + 1)
        mesh.setTransfiniteSurface(surface)
    model.addPhysicalGroup(1, [b_lines[2]], BLOCK_TOP)
    model.addPhysicalGroup(1, [b_lines[0]], BLOCK_BOTTOM)
    model.addPhysicalGroup(1, [b_lines[1], b_lines[3]], BLOCK_SIDES)
    model.addPhysicalGroup(1, [t_lines[0]], PUNCH_BOTTOM)
    model.addPhysicalGroup(1, [t_lines[2]], PUNCH_TOP)
    model.addPhysicalGroup(1, [t_lines[1], t_lines[3]], PUNCH_SIDES)
    model.addPhysicalGroup(2, [block], BLOCK)
    model.addPhysicalGroup(2, [top], PUNCH)
    model.mesh.generate(2)


# two stacked hexahedral blocks: cells 1 (lower [0, 1]^2 x [0, 1]), 2 (upper, z in [1, 2])
HEX_BOTTOM, HEX_TOP, HEX_LOWER_TOP, HEX_UPPER_BOTTOM, HEX_X0, HEX_Y0 = 1, 2, 3, 4, 5, 6


def _hex_grid(n: int, z0: float, jitter: float, rng: np.random.Generator):
    """An n x n x n hexahedral grid of [0, 1]^2 x [z0, z0 + 1], its inner vertices moved in x
    and y by up to ``jitter`` cells (the same in every z layer: planar quadrilateral faces)."""
    t = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(t, t, indexing="ij")
    inner = (slice(1, -1), slice(1, -1))
    X[inner] += rng.uniform(-jitter, jitter, X[inner].shape) / n
    Y[inner] += rng.uniform(-jitter, jitter, Y[inner].shape) / n
    layers = [np.stack([X.ravel(), Y.ravel(), np.full(X.size, z0 + k / n)], axis=1)
              for k in range(n + 1)]
    x = np.concatenate(layers)

    def v(i, j, k):  # X, Y are indexed (i, j): x along i
        return k * (n + 1) ** 2 + i * (n + 1) + j

    cells = [[v(i, j, k), v(i + 1, j, k), v(i, j + 1, k), v(i + 1, j + 1, k),
              v(i, j, k + 1), v(i + 1, j, k + 1), v(i, j + 1, k + 1), v(i + 1, j + 1, k + 1)]
             for k in range(n) for j in range(n) for i in range(n)]
    return x, np.array(cells, dtype=np.int64)


def hex_blocks(comm, n_lower=3, n_upper=4, jitter=0.3, seed=7):
    """Two stacked hexahedral blocks, non-matching, their interface faces planar trapezoid-like
    quadrilaterals; returns (mesh, cell tags, facet tags) on ``comm``."""
    import basix.ufl
    import ufl
    from dolfinx import mesh as dmesh

    from dwr_signorini import compat

    if comm.rank == 0:
        rng = np.random.default_rng(seed)
        xl, cl = _hex_grid(n_lower, 0.0, jitter, rng)
        xu, cu = _hex_grid(n_upper, 1.0, jitter, rng)
        x, cells = np.concatenate([xl, xu]), np.concatenate([cl, cu + len(xl)])
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 8), dtype=np.int64)
    domain = ufl.Mesh(basix.ufl.element("Lagrange", "hexahedron", 1, shape=(3,)))
    msh = compat.create_mesh(comm, cells, x, domain,
                             partitioner=compat.cell_partitioner(dmesh.GhostMode.none))
    tdim = 3
    num = msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts
    centre = dmesh.compute_midpoints(msh, tdim, np.arange(num, dtype=np.int32))
    body = np.where(centre[:, 2] < 1.0, 1, 2).astype(np.int32)
    cell_tags = dmesh.meshtags(msh, tdim, np.arange(num, dtype=np.int32), body)
    msh.topology.create_connectivity(tdim - 1, tdim)
    facets = dmesh.exterior_facet_indices(msh.topology)
    mid = dmesh.compute_midpoints(msh, tdim - 1, facets)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    lower = body[[f2c.links(f)[0] for f in facets]] == 1
    eps = 1e-10
    values = np.full(len(facets), -1, dtype=np.int32)
    values[np.abs(mid[:, 0]) < eps] = HEX_X0
    values[np.abs(mid[:, 1]) < eps] = HEX_Y0
    values[np.abs(mid[:, 2]) < eps] = HEX_BOTTOM
    values[np.abs(mid[:, 2] - 2.0) < eps] = HEX_TOP
    values[(np.abs(mid[:, 2] - 1.0) < eps) & lower] = HEX_LOWER_TOP
    values[(np.abs(mid[:, 2] - 1.0) < eps) & ~lower] = HEX_UPPER_BOTTOM
    keep = values > 0
    facet_tags = dmesh.meshtags(msh, tdim - 1, facets[keep].astype(np.int32), values[keep])
    return msh, cell_tags, facet_tags


# two stacked boxes of tetrahedra: facet tags
TET_BOTTOM, TET_TOP, TET_MASTER, TET_SLAVE = 1, 2, 3, 4


def _tet_box(n: int, z0: float, height: float, layers: int = 2):
    """Nodes and tetrahedra of [0, 1]^2 x [z0, z0 + height], n x n x ``layers`` cells of 6."""
    from mpi4py import MPI

    from dolfinx import mesh as dmesh

    from dwr_signorini import compat

    box = dmesh.create_box(MPI.COMM_SELF, [[0.0, 0.0, z0], [1.0, 1.0, z0 + height]],
                           [n, n, layers])
    return box.geometry.x.copy(), compat.geometry_dofmap(box).astype(np.int64)


def tet_boxes(comm, n: int, gap: float = 0.0, layers: int = 2):
    """[0, 1]^2 x [0, 1] (n x n x 2 cells of 6 tetrahedra) under [0, 1]^2 x [1 + gap, 1.5 + gap]
    ((n + 1) x (n + 1) x 2), one mesh whose bodies share no vertex: the contact facets do not
    match. Returns (mesh, facet tags): TET_SLAVE the upper box's bottom, TET_MASTER the
    lower box's top, TET_BOTTOM and TET_TOP the outer faces. ``layers``: the cells across each
    box's height (thin slabs with 1: many contact facets, a small volume)."""
    from mpi4py import MPI

    import ufl
    from dolfinx import mesh as dmesh

    from dwr_signorini import compat

    lower, upper = _tet_box(n, 0.0, 1.0, layers), _tet_box(n + 1, 1.0 + gap, 0.5, layers)
    if comm.rank == 0:
        x = np.concatenate([lower[0], upper[0]])
        cells = np.concatenate([lower[1], upper[1] + len(lower[0])])
    else:
        x, cells = np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int64)
    unit = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    msh = compat.create_mesh(comm, cells, x, ufl.Mesh(unit.ufl_domain().ufl_coordinate_element()))
    fdim = 2
    msh.topology.create_connectivity(fdim, 3)
    eps = 1e-9
    upper_cells = dmesh.locate_entities(msh, 3, lambda p: p[2] > 1.0 + gap - eps)
    upper_facets = dmesh.compute_incident_entities(msh.topology, upper_cells, 3, fdim)
    middle = dmesh.locate_entities_boundary(
        msh, fdim, lambda p: np.isclose(p[2], 1.0) | np.isclose(p[2], 1.0 + gap))
    slave = np.intersect1d(middle, upper_facets)
    master = np.setdiff1d(middle, upper_facets)
    bottom = dmesh.locate_entities_boundary(msh, fdim, lambda p: np.isclose(p[2], 0.0))
    top = dmesh.locate_entities_boundary(msh, fdim, lambda p: np.isclose(p[2], 1.5 + gap))
    indices = np.concatenate([bottom, top, master, slave]).astype(np.int32)
    values = np.concatenate([np.full(len(f), t, dtype=np.int32) for f, t in (
        (bottom, TET_BOTTOM), (top, TET_TOP), (master, TET_MASTER), (slave, TET_SLAVE))])
    order = np.argsort(indices)
    return msh, dmesh.meshtags(msh, fdim, indices[order], values[order])
