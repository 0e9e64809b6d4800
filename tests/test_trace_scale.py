"""The trace that scales: the same rule and trace, computed another way.

* The batched 3D rule (dwr_signorini.clipping, behind search.candidate_rule) against the
  per-facet rule (mortar.mortar_rule, every master facet): the integrals of polynomials times
  the master facet met, per slave facet, on non-matching, two-layer, steep and partly covered
  masters.
* The master trace on 2 ranks is the serial one: each rank holds only the master facets its
  slave facets need (dwr_signorini.exchange), and the trace does not depend on the partition.
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem

import dwr_signorini as ds
from dwr_signorini.mortar import mortar_rule
from dwr_signorini.search import candidate_rule
from dwr_signorini.spaces import discretize
from tests import pair_geometries as G
from tests.test_mortar import _normals, _triangles

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
