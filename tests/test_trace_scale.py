"""The trace that scales: the same rule and trace, computed another way.

* The batched 3D rule (dwr_signorini.clipping, behind search.candidate_rule) against the
  per-facet rule (mortar.mortar_rule, every master facet): the integrals of polynomials times
  the master facet met, per slave facet, on non-matching, two-layer, steep and partly covered
  masters.
* The rule of each degree placed on the pieces of one search (clipping.place) against the rule
  of that degree (2D and 3D).
* The candidates from balls along each slave facet's normal axis (search._candidates) against
  every master facet tested for the search ball and the shadow, on random facets.
* The basis values in affine simplices (pair_facets.cell_basis) reproduce quadratics.
* The master trace on 2 ranks is the serial one: each rank holds only the master facets its
  slave facets need (dwr_signorini.exchange), and the trace does not depend on the partition.
* The search shared between the ranks (dwr_signorini.trace_balance) gives the trace of each rank
  searching its own slave facets: P, the gap, the frame, the coverage and the share; its split
  levels the modelled loads.
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini import compat, pairs, search, trace_balance
from dwr_signorini.clipping import place
from dwr_signorini.mortar import facet_reach, in_shadow, mortar_rule
from dwr_signorini.pair_facets import cell_basis
from dwr_signorini.search import candidate_rule
from dwr_signorini.spaces import discretize
from tests import pair_geometries as G
from tests.test_mortar import _normals, _polyline, _random_breaks, _triangles

COMM = MPI.COMM_WORLD


def _moments(rule, m: int) -> np.ndarray:
    """Per slave facet: int f(x) c(G) over its pieces, f in 1, x, y^2, x y z, gap, gap x, and
    c(G) = 1 or the index of the master facet G met."""
    x = rule.points
    fs = [np.ones(len(x)), x[:, 0], x[:, 1] ** 2, x[:, 0] * x[:, 1] * x[:, 2], rule.gap,
          rule.gap * x[:, 0]]
    out = np.zeros((m, 2 * len(fs)))
    for k, f in enumerate(fs):
        for j, c in enumerate((1.0, 1.0 + rule.master)):
            np.add.at(out[:, 2 * k + j], rule.facet, rule.weights * f * c)
    return out


def _layers(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slave facets (up), master facets and their normals of one configuration."""
    slave = _triangles(6, 0.0)
    if kind == "flat":
        master = _triangles(7, 0.05, -0.05, 1.05)
    elif kind == "partly covered":
        master = _triangles(5, 0.05, 0.23, 0.71)
    elif kind == "two layers":
        master = np.concatenate([_triangles(5, 0.4, -0.1, 1.1), _triangles(3, 0.1, -0.1, 0.55)])
    else:  # steep, 60 degrees
        slope = np.tan(np.radians(60.0))
        master = _triangles(12, 0.0, -0.1, 1.1)
        master[..., 2] = 0.2 + slope * (master[..., 0] + 0.1)
        normal = np.array([slope, 0.0, -1.0]) / np.hypot(slope, 1.0)
        return slave, master, np.tile(normal, (len(master), 1))
    return slave, master, _normals(master, -1.0)


@pytest.mark.parametrize("kind", ["flat", "partly covered", "two layers", "steep"])
@pytest.mark.parametrize("degree", [2, 4])
def test_batched_rule_is_the_per_facet_rule(kind, degree):
    """The candidate search with the batched clipping gives the per-facet rule's integrals per
    slave facet and master facet to 1e-12 (relative to the facet's measure)."""
    slave, master, master_normals = _layers(kind)
    normals = _normals(slave, 1.0)
    batched = candidate_rule(slave, normals, master, master_normals, degree, 0.1)
    per_facet = mortar_rule(slave, normals, master, master_normals, degree, 0.1)
    a, b = _moments(batched, len(slave)), _moments(per_facet, len(slave))
    assert np.abs(b).max() > 0.0
    scale = (1.0 + len(master)) * (1.0 / len(slave))
    assert np.abs(a - b).max() < 1e-12 * scale


@pytest.mark.parametrize("kind", ["flat", "partly covered", "two layers", "steep", "2d"])
@pytest.mark.parametrize("degree", [2, 4])
def test_rule_placed_on_the_pieces_is_the_rule_of_the_degree(kind, degree):
    """One search (degree None: the pieces) serves every degree: the Gauss points placed on
    its pieces integrate as the rule of that degree, per slave facet and master facet, to
    1e-12 (x, y^2, x y z, the gap: degree <= 3)."""
    if kind == "2d":
        slave = _polyline(_random_breaks(7), 0.0)
        master = _polyline(_random_breaks(9, -0.1, 1.1), 0.05)
        master_normals = _normals(master, -1.0)
        pieces = mortar_rule(slave, _normals(slave, 1.0), master, master_normals, None, 0.1)
        direct = mortar_rule(slave, _normals(slave, 1.0), master, master_normals, degree, 0.1)
        x = np.c_[direct.points, np.zeros(len(direct.points))]  # (as 3D points for _moments)
        direct = type(direct)(direct.facet, x, direct.weights, direct.master, direct.gap)
    else:
        slave, master, master_normals = _layers(kind)
        pieces = candidate_rule(slave, _normals(slave, 1.0), master, master_normals, None, 0.1)
        direct = mortar_rule(slave, _normals(slave, 1.0), master, master_normals, degree, 0.1)
    placed = place(pieces, degree, False, _normals(slave, 1.0), master, master_normals)
    if kind == "2d":
        x = np.c_[placed.points, np.zeros(len(placed.points))]
        placed = type(placed)(placed.facet, x, placed.weights, placed.master, placed.gap)
    assert len(pieces.facet) % slave.shape[2] == 0
    a, b = _moments(placed, len(slave)), _moments(direct, len(slave))
    assert np.abs(b).max() > 0.0
    assert np.abs(a - b).max() < 1e-12 * (1.0 + len(master))


def test_candidates_are_every_master_in_the_ball_and_the_shadow():
    """The candidates found with balls along each slave facet's normal axis are exactly the
    master facets within the search radius that pass the shadow test, on random facets with
    random normals, sizes and windows."""
    rng = np.random.default_rng(57)

    def facets(m: int) -> tuple[np.ndarray, np.ndarray]:
        centre = rng.uniform(0.0, 1.0, (m, 1, 3))
        tri = centre + rng.uniform(0.01, 0.08, (m, 1, 1)) * rng.normal(size=(m, 3, 3))
        n = rng.normal(size=(m, 3))
        return tri, n / np.linalg.norm(n, axis=1)[:, None]

    slave, normals = facets(300)
    master, master_normals = facets(2000)
    windows = rng.uniform(0.0, 0.2, len(slave))
    centres, reach = facet_reach(master)
    radius = search.search_radius(slave, windows, reach.max())
    keys = rng.permutation(len(master))
    f, c = search._candidates(search.cKDTree(centres), slave, normals, windows, radius,
                              (centres, reach, master_normals, keys))
    slave_centres, slave_reach = facet_reach(slave)
    expected = []
    for i in range(len(slave)):
        near = np.linalg.norm(centres - slave_centres[i], axis=1) <= radius[i]
        near &= in_shadow(centres, reach, master_normals, slave_centres[i], normals[i],
                          slave_reach[i], windows[i])
        expected += [(i, j) for j in np.flatnonzero(near)[np.argsort(keys[near])]]
    assert len(expected) > 3 * len(slave)  # the random facets do meet
    assert list(zip(f.tolist(), c.tolist(), strict=True)) == expected


@pytest.mark.parametrize("degree", [1, 2])
def test_cell_basis_in_affine_simplices_reproduces_quadratics(degree):
    """sum_j phi_j(y) f(x_j) = f(y) at random points y of random cells of a tetrahedral mesh,
    f of degree <= ``degree`` (x_j the dofs' coordinates)."""
    from dolfinx import mesh as dmesh

    msh = dmesh.create_unit_cube(MPI.COMM_SELF, 2, 3, 2, dmesh.CellType.tetrahedron)
    msh.geometry.x[:, 0] += 0.2 * msh.geometry.x[:, 1] ** 2  # cells of different shapes
    V = fem.functionspace(msh, ("Lagrange", degree, (3,)))  # (a displacement space)
    rng = np.random.default_rng(3)
    geometry = msh.geometry.x[compat.geometry_dofmap(msh)][:, :, :3]
    which = rng.integers(0, len(geometry), 200)
    bary = rng.dirichlet(np.ones(4), len(which))
    y = np.einsum("qv,qvd->qd", bary, geometry[which])
    phi = cell_basis(msh, V, geometry, which, y)

    def f(x):
        return 1.0 + x[0] - 2.0 * x[1] + 0.5 * x[2] + (degree - 1) * (x[0] * x[2] - x[1] ** 2)

    values = V.tabulate_dof_coordinates()[V.dofmap.list[which]]  # (q, nodes, 3)
    interpolated = np.einsum("qj,qj->q", phi, f(values.transpose(2, 0, 1)))
    assert interpolated == pytest.approx(f(y.T), abs=1e-12)


def _field(x):
    return np.stack([np.sin(3.0 * x[0]) + x[1] * x[2], np.cos(2.0 * x[1]) * x[0],
                     np.exp(x[2]) * (1.0 + x[0] * x[1])])


def _trace_values(comm, n: int = 3) -> np.ndarray:
    """Integrals over the slave facets of P v . w (P1 and P2 traces, three weights w), the
    gap, the contact frame, the covered measure and the facets' shares."""
    msh, tags = G.tet_boxes(comm, n, gap=0.01)
    problem = ds.SignoriniProblem(msh, tags, contact=ds.ContactPair(slave=G.TET_SLAVE,
                                                                    master=G.TET_MASTER),
                                  E=1.0, nu=0.3, model="3d",
                                  dirichlet={G.TET_BOTTOM: 0.0, G.TET_TOP: (0.0, 0.0, -0.01)})
    disc = discretize(problem)
    sub = disc.slave_mesh
    x = ufl.SpatialCoordinate(sub)
    dx = ufl.dx(domain=sub)
    weights = [ufl.as_vector([1.0, 0.0, 0.0]), ufl.as_vector([x[0], x[1] ** 2, 1.0]),
               ufl.as_vector([x[1] * x[0], 0.0, ufl.sin(4.0 * x[0])])]
    forms = []
    for degree in (1, 2):
        v = fem.Function(disc.vector_space(degree))
        v.interpolate(_field)
        Pv = disc.trace_image(v)
        forms += [ufl.inner(Pv, w) * dx for w in weights]
    trace = disc.master_trace()
    forms += [trace.gap * (1.0 + x[0]) * dx,
              ufl.inner(trace.frame, ufl.as_vector([x[1], 1.0, x[0]])) * dx]
    values = [comm.allreduce(fem.assemble_scalar(fem.form(f)), op=MPI.SUM) for f in forms]
    geometry = trace.geometry
    values.append(comm.allreduce(float(geometry.covered.sum()), op=MPI.SUM))
    moved = geometry.share(geometry.measure,
                           fem.functionspace(disc.mesh, ("DG", 0)))
    values.append(comm.allreduce(float(np.abs(moved).sum()), op=MPI.SUM))
    disc.destroy()
    return np.array(values)


@pytest.mark.mpi
def test_trace_on_two_ranks_is_the_serial_trace():
    """Every integral of the trace, the gap, the frame, the coverage and the share equal on
    COMM_WORLD and on one rank (COMM_SELF) to 1e-12 relative (the master facets each rank
    holds come from the exchange on COMM_WORLD, all of them on COMM_SELF)."""
    serial = _trace_values(MPI.COMM_SELF)
    parallel = _trace_values(COMM)
    assert np.all(np.abs(serial) > 1e-3)  # no trivial zero compared
    assert parallel == pytest.approx(serial, rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("counts", [[64, 904], [4500, 108], [7, 0, 0, 100], [5, 5], [0, 0, 3]])
def test_search_split_levels_the_search(counts):
    """Every rank searches as many slave facets as the others to one, all of them in all, and
    the transfers (each from a rank owning more to one owning fewer) move c - k."""
    c = np.array(counts)
    k = trace_balance.search_counts(c)
    assert k.sum() == c.sum() and k.max() - k.min() <= 1
    moved = np.zeros(len(c), np.int64)
    for source, dest, n in trace_balance.transfers(c, k):
        assert n > 0 and c[source] > k[source] and c[dest] < k[dest]
        moved[source] -= n
        moved[dest] += n
    assert np.array_equal(c + moved, k)


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that share the search")
@pytest.mark.parametrize("kind", ["flat", "partly covered", "two layers", "steep"])
def test_shared_search_is_the_owners_search(kind):
    """Rank 0 owns every slave facet, each rank holds the master facets in its own order: the
    search shared between the ranks returns rank 0 its own search's pieces, point by point,
    and the same facets left over (the other ranks: nothing)."""
    slave, master, master_normals = COMM.bcast(_layers(kind) if COMM.rank == 0 else None)
    mine = slave if COMM.rank == 0 else slave[:0]
    order = np.random.default_rng(COMM.rank).permutation(len(master))  # held, numbered
    held = (master[order], master_normals[order], order)
    reach = float(facet_reach(master)[1].max())
    args = (mine, _normals(mine, 1.0), np.full(len(mine), 0.1), held, reach)
    shared, alone = (trace_balance.search_parts(COMM, *args, balance=b) for b in (True, False))
    counts = np.array(COMM.allgather(len(mine)))
    assert trace_balance.transfers(counts, trace_balance.search_counts(counts))
    assert np.array_equal(shared[1], alone[1])
    a, b = (search.merge_rules(r[0], 3) for r in (shared, alone))
    assert len(b.facet) > 0 if COMM.rank == 0 else len(b.facet) == 0
    for field in ("facet", "points", "weights", "master", "gap"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field


def _owned_csr(mat) -> tuple[np.ndarray, ...]:
    """The owned rows of a PETSc matrix as (row pointers, columns, values)."""
    return mat.getValuesCSR()


def _built(disc, balance: bool) -> tuple[pairs.TraceGeometry, pairs.MasterTrace]:
    geometry = pairs.TraceGeometry(disc, balance=balance)
    return geometry, pairs.MasterTrace(disc, disc.V, geometry)


@pytest.mark.mpi
@pytest.mark.skipif(COMM.size == 1, reason="needs ranks that share the search")
def test_shared_search_gives_the_trace_of_the_owners():
    """On 2 ranks, whose slave facets are unevenly owned (the split moves some): the trace
    with the search shared equals the one each rank searches alone, entry by entry: P (P1),
    the gap, the contact frame, the covered measure, and the share matrices S^T and H^T."""
    msh, tags = G.tet_boxes(COMM, 4, gap=0.01)
    problem = ds.SignoriniProblem(msh, tags, contact=ds.ContactPair(slave=G.TET_SLAVE,
                                                                    master=G.TET_MASTER),
                                  E=1.0, nu=0.3, model="3d",
                                  dirichlet={G.TET_BOTTOM: 0.0, G.TET_TOP: (0.0, 0.0, -0.01)})
    disc = discretize(problem)
    counts = np.array(COMM.allgather(len(disc.master_trace().geometry.vertices)))
    assert trace_balance.transfers(counts, trace_balance.search_counts(counts))  # work moves
    built = [_built(disc, balance) for balance in (False, True)]
    (g0, t0), (g1, t1) = built
    for a, b in [(t0.P, t1.P), (g0.share_weights, g1.share_weights), (g0._home, g1._home)]:
        (ia, ja, va), (ib, jb, vb) = _owned_csr(a), _owned_csr(b)
        assert np.array_equal(ia, ib) and np.array_equal(ja, jb)
        assert vb == pytest.approx(va, rel=1e-13, abs=1e-15)
    for a, b in [(t0.gap.x.array, t1.gap.x.array), (g0.frame.x.array, g1.frame.x.array),
                 (g0.covered, g1.covered)]:
        assert b == pytest.approx(a, rel=1e-13, abs=1e-15)
    assert COMM.allreduce(float(np.abs(t0.gap.x.array).sum()), op=MPI.SUM) > 0.0
    for geometry, trace in reversed(built):
        trace.destroy()
        geometry.destroy()
    disc.destroy()
