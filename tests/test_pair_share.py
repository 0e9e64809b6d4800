"""The master share of the indicators, the lifetime of the master trace, the two-body check.

* The share is a conservation identity: the part of rho and rho* linear in the master trace of
  a weight, localised per fine slave facet, goes from the cell beside the facet to the master
  cells, each facet's weights summing to its covered fraction (1 where the master covers it,
  0 where it misses it; the uncovered part stays on the slave cell); so the shared indicators
  sum to the estimate computed without the share, to round-off, also where a slave cell has
  one covered and one uncovered slave facet (the corner of a slave tag that runs round a
  block).
* One master trace geometry per mesh, one trace per space (P1 of the solve, P2 of the weights),
  the same for every estimate of a solution, released with the solution that discretised.
* Two bodies that share one vertex are refused on any partition (here: each body on its own
  rank).
"""

from __future__ import annotations

import itertools

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh as dmesh

import dwr_signorini as ds
from dwr_signorini import compat, estimate_parts
from dwr_signorini.pairs import MasterTrace, TraceGeometry

COMM = MPI.COMM_WORLD
# the blocks' tags: lower bottom, lower top (master), upper bottom and left (slave), upper top
BOTTOM, MASTER, SLAVE, TOP = 1, 3, 4, 2
LOWER_HEIGHT, UPPER_HEIGHT = 1.0, 0.5


def _grid(x0: float, y0: float, width: float, height: float, nx: int, ny: int, first: int,
          shear: float = 0.0):
    """Nodes and triangles of a structured grid whose squares are cut from (i+1, j) to (i, j+1).

    The cut leaves the triangle of the lower-left corner with both its bottom and left edges;
    with ``shear`` (x moved by shear (y - y0)) its corner angle is acute, so that the uniform
    refinement keeps a child with both edges (the corner is an end of the longest edge).
    """
    xs, ys = np.linspace(x0, x0 + width, nx + 1), np.linspace(y0, y0 + height, ny + 1)
    nodes = np.array([[x + shear * (y - y0), y] for y in ys for x in xs])

    def node(i: int, j: int) -> int:
        return first + j * (nx + 1) + i

    cells = []
    for i, j in itertools.product(range(nx), range(ny)):
        cells += [[node(i, j), node(i + 1, j), node(i, j + 1)],
                  [node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)]]
    return nodes, np.array(cells, dtype=np.int64)


def _mesh(bodies: list[tuple[np.ndarray, np.ndarray]], comm: MPI.Comm) -> dmesh.Mesh:
    """The bodies' cells in one mesh: body k on rank k % size (all nodes given by rank 0)."""
    nodes = np.concatenate([b[0] for b in bodies])
    mine = [b[1] for k, b in enumerate(bodies) if k % comm.size == comm.rank]
    cells = np.concatenate(mine) if mine else np.zeros((0, 3), dtype=np.int64)
    x = nodes if comm.rank == 0 else np.zeros((0, 2))

    def keep(comm_, nparts, cell_types, cells_):
        n = sum(np.asarray(c).size for c in cells_) // 3
        return compat.cpp_adjacencylist(
            np.full(n, comm_.rank, dtype=np.int32), np.arange(n + 1, dtype=np.int32)
        )

    element = ufl.Mesh(dmesh.create_unit_square(MPI.COMM_SELF, 1, 1).ufl_domain()
                       .ufl_coordinate_element())
    return compat.create_mesh(comm, cells, x, element, partitioner=keep)


def _tags(msh: dmesh.Mesh, rules: dict[int, callable]) -> dmesh.MeshTags:
    """Boundary facet tags from ``{tag: x -> bool}`` (the first rule that holds wins)."""
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, fdim + 1)
    indices, values = [], []
    for tag, rule in rules.items():
        found = dmesh.locate_entities_boundary(msh, fdim, rule)
        found = np.setdiff1d(found, np.concatenate(indices) if indices else [])
        indices.append(found)
        values.append(np.full(len(found), tag, dtype=np.int32))
    order = np.argsort(np.concatenate(indices))
    return dmesh.meshtags(msh, fdim, np.concatenate(indices)[order].astype(np.int32),
                         np.concatenate(values)[order])


def blocks_problem(comm: MPI.Comm = COMM, shift: float = 0.0) -> ds.SignoriniProblem:
    """A lower block under an upper block (non-matching grids), the top pressed down.

    The upper block is a parallelogram (its left side leans right at 45 degrees). The slave tag
    runs along its bottom and up its left side: the left side meets no master facet, and the
    corner cell's two slave facets are one covered, one not. ``shift`` moves the upper block
    right: its bottom then overhangs the lower block's top by ``shift`` (a facet covered in
    part).
    """
    lower = _grid(0.0, 0.0, 1.0, LOWER_HEIGHT, 4, 3, 0)
    upper = _grid(shift, LOWER_HEIGHT, 1.0, UPPER_HEIGHT, 3, 2, len(lower[0]), shear=1.0)
    msh = _mesh([lower, upper], comm)
    eps = 1e-9
    tags = _tags(msh, {
        BOTTOM: lambda x: np.isclose(x[1], 0.0, atol=eps),
        TOP: lambda x: np.isclose(x[1], LOWER_HEIGHT + UPPER_HEIGHT, atol=eps),
        MASTER: lambda x: np.isclose(x[1], LOWER_HEIGHT, atol=eps),
    })
    # the slave facets: the upper block's bottom (its cells lie above y = 1) and left side
    fdim = 1
    msh.topology.create_connectivity(fdim, 2)
    upper_cells = dmesh.locate_entities(msh, 2, lambda x: x[1] > LOWER_HEIGHT - eps)
    upper_facets = dmesh.compute_incident_entities(msh.topology, upper_cells, 2, fdim)
    slave = np.intersect1d(upper_facets, dmesh.locate_entities_boundary(
        msh, fdim, lambda x: np.isclose(x[1], LOWER_HEIGHT, atol=eps)
        | (np.isclose(x[0], shift + x[1] - LOWER_HEIGHT, atol=eps) & (x[1] > LOWER_HEIGHT - eps))))
    keep = ~np.isin(tags.indices, slave)
    indices = np.concatenate([tags.indices[keep], slave]).astype(np.int32)
    values = np.concatenate([tags.values[keep], np.full(len(slave), SLAVE, dtype=np.int32)])
    order = np.argsort(indices)
    tags = dmesh.meshtags(msh, fdim, indices[order], values[order])
    return ds.SignoriniProblem(
        msh, tags, contact=ds.ContactPair(slave=SLAVE, master=MASTER), E=1.0, nu=0.3,
        dirichlet={BOTTOM: (0.0, 0.0), TOP: (0.0, -0.02)},
    )


def lower_displacement(u, lam, m):
    """The mean vertical displacement of the lower block's upper half (a goal in the master)."""
    window = ufl.conditional(ufl.And(ufl.gt(m.x[1], 0.5), ufl.lt(m.x[1], LOWER_HEIGHT)), 1.0, 0.0)
    return window * u[1] * m.dx


def _row_sums(geometry: TraceGeometry) -> np.ndarray:
    """The sum of each owned slave facet's share weights (in the facets' order)."""
    S, Fs = geometry.share_weights, geometry.Fs
    num = len(geometry.slave_cells)
    rows = Fs.dofmap.index_map.local_to_global(Fs.dofmap.list[:num, 0].astype(np.int32))
    return np.array([S.getRow(int(r))[1].sum() for r in rows], dtype=float).reshape(num)


def _corner_cells(geometry: TraceGeometry) -> tuple[int, int]:
    """How many slave cells have one covered and one uncovered slave facet; uncovered facets."""
    pairs = geometry.disc.comm.allgather((geometry.slave_cells, _row_sums(geometry)))
    cells = np.concatenate([p[0] for p in pairs])
    covered = np.concatenate([p[1] for p in pairs]) > 0.5
    mixed = [c for c in np.unique(cells)
             if covered[cells == c].any() and not covered[cells == c].all()]
    return len(mixed), int(np.count_nonzero(~covered))


@pytest.mark.mpi
@pytest.mark.parametrize("shift", [0.0, 0.1])
def test_share_weights_of_each_facet_sum_to_its_covered_fraction(shift):
    """Fully covered facets move all of their part, the uncovered side none, and the measure
    moved is the overlap of the two blocks' faces, 1 - shift."""
    with ds.solve(blocks_problem(shift=shift)) as sol:
        geometry = sol.disc.master_trace().geometry
        sums = _row_sums(geometry)
        full = sums > 1.0 - 1e-9
        assert np.allclose(sums[full], 1.0, rtol=0.0, atol=1e-13), sums
        partial = COMM.allreduce(int(np.count_nonzero((sums > 1e-9) & ~full)), op=MPI.SUM)
        assert partial == (1 if shift else 0)  # the overhanging facet
        length = np.linalg.norm(geometry.vertices[:, 1] - geometry.vertices[:, 0], axis=1)
        moved = COMM.allreduce(float(sums @ length), op=MPI.SUM)
        assert moved == pytest.approx(1.0 - shift, rel=1e-12)
        mixed, uncovered = _corner_cells(geometry)
        assert mixed >= 1 and uncovered >= 2, (mixed, uncovered)  # the case of the issue


@pytest.mark.mpi
@pytest.mark.parametrize(("estimator", "shift"), [("eta", 0.0), ("eta_p", 0.0), ("eta", 0.1)])
def test_shared_indicators_sum_to_the_unshared_estimate(estimator, shift, monkeypatch):
    """The share only moves indicators: eta with it equals eta without it to round-off (with
    ``shift`` also where a facet is covered in part)."""
    with ds.solve(blocks_problem(shift=shift)) as sol:
        est = ds.estimate(sol, lower_displacement, estimator=estimator, weights="patch")
        shared = est.value
        total = COMM.allreduce(float(est.indicators.x.array[
            :est.indicators.function_space.dofmap.index_map.size_local].sum()), op=MPI.SUM)
        lower = _master_cells_total(est)
        est.destroy()
        monkeypatch.setattr(
            estimate_parts.MasterShare, "__call__",
            lambda share: np.zeros(
                share.DG0.dofmap.index_map.size_local + share.DG0.dofmap.index_map.num_ghosts),
        )
        with ds.estimate(sol, lower_displacement, estimator=estimator, weights="patch") as e:
            unshared = e.value
            lower_unshared = _master_cells_total(e)
    scale = abs(unshared)
    assert scale > 1e-8  # a nonzero estimate, and a share that moved something
    assert abs(lower - lower_unshared) > 1e-3 * scale
    assert shared == pytest.approx(unshared, rel=1e-10, abs=1e-14 * scale)
    assert total == pytest.approx(shared, rel=1e-10)


def _master_cells_total(est) -> float:
    """The sum of the indicators of the lower block (the master body)."""
    ind = est.indicators
    msh = ind.function_space.mesh
    n = msh.topology.index_map(msh.topology.dim).size_local
    lower = dmesh.locate_entities(msh, msh.topology.dim, lambda x: x[1] < LOWER_HEIGHT + 1e-9)
    lower = lower[lower < n]
    dofs = ind.function_space.dofmap.list[lower, 0]
    return COMM.allreduce(float(ind.x.array[dofs].sum()), op=MPI.SUM)


@pytest.mark.mpi
def test_one_trace_per_mesh_for_every_estimate_released_with_the_solution():
    traces, geometries = MasterTrace.live, TraceGeometry.live
    sol = ds.solve(blocks_problem())
    counts = []
    for _ in range(3):
        with ds.estimate(sol, lower_displacement, weights="patch"):
            counts.append((MasterTrace.live - traces, TraceGeometry.live - geometries))
    assert counts == [(2, 1)] * 3  # P1 and P2 traces of one geometry, for every estimate
    sol.destroy()
    assert (MasterTrace.live, TraceGeometry.live) == (traces, geometries)


@pytest.mark.mpi
def test_two_bodies_sharing_a_vertex_are_refused_on_any_partition():
    """Two squares touching at one corner (1, 1), each on its own rank on 2 ranks."""
    lower = _grid(0.0, 0.0, 1.0, 1.0, 1, 1, 0)
    nodes, cells = _grid(1.0, 1.0, 1.0, 1.0, 1, 1, 4)
    corner = 4  # the upper square's node (1, 1) is the lower square's node 3
    cells = np.where(cells == corner, 3, cells)
    cells = np.where(cells > corner, cells - 1, cells)
    upper = (np.delete(nodes, 0, axis=0), cells)
    msh = _mesh([lower, upper], COMM)
    eps = 1e-9
    tags = _tags(msh, {
        1: lambda x: np.isclose(x[1], 0.0, atol=eps),
        2: lambda x: np.isclose(x[1], 2.0, atol=eps),
        3: lambda x: np.isclose(x[1], 1.0, atol=eps) & (x[0] < 1.0 + eps),
        4: lambda x: np.isclose(x[1], 1.0, atol=eps) & (x[0] > 1.0 - eps),
    })
    with pytest.raises(ValueError, match="1 vertices lie on both sides"):
        ds.SignoriniProblem(msh, tags, contact=ds.ContactPair(slave=4, master=3),
                            dirichlet={1: 0.0, 2: 0.0})


# --------------------------------------------------------------------------------------------------
# The candidate search gives the rule of the full search
# --------------------------------------------------------------------------------------------------


def _surface(n: int, box: tuple[float, float, float, float], height, gdim: int):
    """Flat facets of z = height(x, y) (y = height(x) in 2D) over ``box``, n cells a side.

    Returns the facets' vertices and a point beside each, on the side of -z (-y).
    """
    x0, x1, y0, y1 = box
    if gdim == 2:
        xs = np.linspace(x0, x1, n + 1)
        pts = np.stack([xs, height(xs, 0.0)], axis=1)
        facets = np.stack([pts[:-1], pts[1:]], axis=1)
    else:
        xs, ys = np.linspace(x0, x1, n + 1), np.linspace(y0, y1, n + 1)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        P = np.stack([X, Y, height(X, Y)], axis=-1)
        tris = []
        for i, j in itertools.product(range(n), range(n)):
            tris += [[P[i, j], P[i + 1, j], P[i, j + 1]],
                     [P[i + 1, j], P[i + 1, j + 1], P[i, j + 1]]]
        facets = np.array(tris)
    below = facets.mean(axis=1)
    below[:, -1] -= 0.1
    return facets, below


def _moments(rule, gdim: int, normals: np.ndarray, num: int, num_master: int) -> dict:
    """Per slave facet: measure covered, integrals of the gap and of x^a (Pi x)^b; per (facet,
    master facet): the measure mapped."""
    out = {}
    pi = rule.points + rule.gap[:, None] * normals[rule.facet]
    fields = {"measure": rule.weights, "gap": rule.weights * rule.gap,
              "xy": rule.weights * rule.points[:, 0] * pi[:, gdim - 2] ** 2 * pi[:, 0]}
    for name, values in fields.items():
        total = np.zeros(num)
        np.add.at(total, rule.facet, values)
        out[name] = total
    pairs = np.zeros(num * num_master)
    np.add.at(pairs, rule.facet * num_master + rule.master, rule.weights)
    out["pairs"] = pairs
    return out


@pytest.mark.parametrize("gdim", [2, 3])
@pytest.mark.parametrize("behind", [False, True])
def test_candidate_search_gives_the_rule_of_the_full_search(gdim, behind):
    """A curved master under a flat slave (non-matching), covering it in part; a far one.

    ``behind``: a master surface behind the slave one, far beyond the searched depth of the
    facets but within the pair's window (2), so it is the partner where it lies: the candidate
    search must look as deep as the window.
    """
    from dwr_signorini.mortar import facet_normals, mortar_rule
    from dwr_signorini.search import candidate_rule

    n_s, n_m = (40, 57) if gdim == 2 else (9, 13)
    slave, above = _surface(n_s, (0.0, 1.0, 0.0, 1.0), lambda x, y: 0.0 * x, gdim)
    above[:, -1] += 0.2  # the slave body lies above its facets
    master, below = _surface(n_m, (-0.13, 0.83, -0.07, 0.71),
                             lambda x, y: -0.02 - 0.1 * ((x - 0.4) ** 2 + (y - 0.3) ** 2), gdim)
    # a far master beyond the searched depth, under the corner that the near one leaves (some
    # facets meet both)
    far, far_below = _surface(3, (0.84, 1.1, 0.70, 1.1), lambda x, y: -3.0 + 0.0 * x, gdim)
    master, below = np.concatenate([master, far]), np.concatenate([below, far_below])
    window = 2.0 * np.linalg.norm(slave[:, 1] - slave[:, 0], axis=1)  # as a pair's default
    if behind:
        back, back_below = _surface(3, (0.1, 0.5, 0.1, 0.5), lambda x, y: 1.5 + 0.0 * x, gdim)
        master, below = np.concatenate([master, back]), np.concatenate([below, back_below])
        window = 2.0
    sn, mn = facet_normals(slave, above), facet_normals(master, below)
    full = mortar_rule(slave, sn, master, mn, 4, window)
    fast = candidate_rule(slave, sn, master, mn, 4, window)
    a = _moments(full, gdim, sn, len(slave), len(master))
    b = _moments(fast, gdim, sn, len(slave), len(master))
    assert np.any(a["measure"] < 0.99 * a["measure"].max())  # facets covered in part
    assert np.any(full.gap > 2.0)  # and the far master met (by the fallback)
    assert np.any(full.gap < -1.0) == behind  # the master behind met within the window
    for name in a:
        assert np.allclose(b[name], a[name], rtol=1e-12, atol=1e-14), name
