"""The patch-wise reconstructions: local parent-map path against point-location interpolation,
exactness on macro P2 functions, and the multiplier recovery on linear data."""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import fem, mesh

import dwr_signorini as ds
from dwr_signorini import compat
from dwr_signorini import examples as ex
from dwr_signorini.reconstruction import Reconstructor, _Transfer


def _disc(kind: str) -> ds.Discretization:
    comm = MPI.COMM_WORLD
    if kind == "triangle":
        problem = ex.analytic_problem(comm, 6, 4, mesh.CellType.triangle, E=1.0, body_force=None,
                                      gap=0.0)
    else:
        problem = ex.obstacle_problem(comm, (1, 4, 4), E=1.0, gap=0.0)
    return ds.discretize(problem)


def _smooth(x: np.ndarray) -> np.ndarray:
    rows = [np.sin(3 * x[0]) * np.cos(2 * x[1]) + x[2] ** 2, x[0] * x[1], x[2]]
    return np.vstack(rows[: 2 if np.allclose(x[2], 0) else 3])


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["triangle", "tetrahedron"])
def test_parent_map_reconstruction_equals_point_location(kind):
    """i_2h^(2) by the parent map equals fine P1 -> macro P2 -> fine P2 by interpolation."""
    disc = _disc(kind)
    rec = Reconstructor(disc)
    v = fem.Function(disc.V)
    gdim = disc.mesh.geometry.dim
    v.interpolate(lambda x: _smooth(x)[:gdim])
    fast = rec.patch_quadratic(v)
    macro = fem.Function(rec.V2H)
    _Transfer(rec.V2H, disc.V)(macro, v)
    slow = _Transfer(rec.V2h, rec.V2H)(fem.Function(rec.V2h), macro)
    assert np.allclose(fast.x.array, slow.x.array, atol=1e-12 * np.abs(slow.x.array).max())


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["triangle", "tetrahedron"])
def test_reconstruction_is_exact_for_quadratics(kind):
    """A global quadratic sampled at the fine vertices is reproduced exactly in P2."""
    disc = _disc(kind)
    rec = Reconstructor(disc)
    gdim = disc.mesh.geometry.dim

    def quad(x):
        return np.vstack(
            [x[0] ** 2 - 2 * x[0] * x[1] + 0.5, x[1] ** 2 + x[0] + x[2] * x[0]][:gdim]
            + ([x[2] ** 2] if gdim == 3 else [])
        )[:gdim]

    v = fem.Function(disc.V)
    v.interpolate(quad)
    exact = fem.Function(rec.V2h)
    exact.interpolate(quad)
    assert np.allclose(rec.patch_quadratic(v).x.array, exact.x.array, atol=1e-12)


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["triangle", "tetrahedron"])
def test_patch_weight_is_the_quadratic_minus_its_linear_interpolant(kind):
    """For v = I_h q of a global quadratic q, i_2h^(2) v - v = q - I_h q, zero at the vertices.

    Both sides in fine P2: q interpolated there exactly, I_h q by interpolation of v (not the
    package's P1-in-P2 map). For a smooth v the weight also equals i_2h^(2) v by point location
    (fine P1 -> macro P2 -> fine P2 by interpolation) minus v interpolated into fine P2.
    """
    disc = _disc(kind)
    rec = Reconstructor(disc)
    gdim = disc.mesh.geometry.dim

    def quad(x):
        rows = [x[0] ** 2 - 3 * x[0] * x[1] + x[2], 2 * x[1] ** 2 + x[0] * x[2] - 1, x[2] * x[1]]
        return np.vstack(rows[:gdim])

    v = fem.Function(disc.V)
    v.interpolate(quad)
    q2, v2 = fem.Function(rec.V2h), fem.Function(rec.V2h)
    q2.interpolate(quad)
    v2.interpolate(v)
    weight = rec.patch_weight(v)
    assert np.allclose(weight.x.array, q2.x.array - v2.x.array, atol=1e-12)
    bs = rec.V2h.dofmap.index_map_bs
    nodes = np.unique(rec.V2h.dofmap.list[:, : gdim + 1])
    assert np.all(weight.x.array.reshape(-1, bs)[nodes] == 0.0)
    assert np.max(np.abs(weight.x.array)) > 1e-3  # the edge midpoints carry the surplus

    s = fem.Function(disc.V)
    s.interpolate(lambda x: _smooth(x)[:gdim])
    macro = _Transfer(rec.V2H, disc.V)(fem.Function(rec.V2H), s)
    slow = _Transfer(rec.V2h, rec.V2H)(fem.Function(rec.V2h), macro)
    s2 = fem.Function(rec.V2h)
    s2.interpolate(s)
    expected = slow.x.array - s2.x.array
    scale = np.abs(slow.x.array).max()
    assert np.allclose(rec.patch_weight(s).x.array, expected, atol=1e-12 * scale)


@pytest.mark.mpi
def test_multiplier_recovery_reproduces_constants():
    """The vertex-averaged recovery of a constant P0 multiplier is that constant on Gamma_C."""
    disc = _disc("triangle")
    rec = Reconstructor(disc)
    lam = fem.Function(disc.Q)
    lam.x.array[:] = 2.5
    r = rec.patch_linear_multiplier(lam)
    facets = disc.facet_tags.find(disc.problem.contact)
    dofs = fem.locate_dofs_topological(r.function_space, disc.mesh.topology.dim - 1, facets)
    assert dofs.size == 0 or np.allclose(r.x.array[dofs], 2.5)


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["triangle", "tetrahedron"])
def test_multiplier_recovery_on_the_fine_mesh_equals_point_location(kind):
    """The macro P1 recovery written at the fine vertices through the parent map equals it
    interpolated into fine P1 by point location (Gamma_C vertices, where it is used)."""
    disc = _disc(kind)
    rec = Reconstructor(disc)
    lam = fem.Function(disc.Q)
    mid = disc.contact_mesh.geometry.x[compat.geometry_dofmap(disc.contact_mesh)].mean(axis=1)
    cells = disc.Q.dofmap.list[:, 0]
    lam.x.array[cells] = 1.0 + mid[:, 1] ** 2 + np.sin(5 * mid[:, 2]) + np.cos(3 * mid[:, 1])
    fast = rec.patch_linear_multiplier(lam)
    slow = _Transfer(rec.P1h, rec.P1H)(fem.Function(rec.P1h), rec.macro_linear_multiplier(lam))
    facets = disc.facet_tags.find(disc.problem.contact)
    dofs = fem.locate_dofs_topological(rec.P1h, disc.mesh.topology.dim - 1, facets)
    assert disc.comm.allreduce(dofs.size, op=MPI.SUM) > 0
    assert np.allclose(fast.x.array[dofs], slow.x.array[dofs], atol=1e-12)
    assert disc.comm.allreduce(np.ptp(slow.x.array[dofs]) if dofs.size else 0.0, op=MPI.MAX) > 0.1


@pytest.mark.mpi
def test_multiplier_recovery_serial_equals_parallel_3d():
    """On a mesh one macro cell thick, ranks share Gamma_C vertices without sharing contact
    facets; the recovery must still be the same as in serial."""
    results = []
    for comm in (MPI.COMM_WORLD, MPI.COMM_SELF):
        disc = ds.discretize(ex.obstacle_problem(comm, n=(1, 8, 8)))
        lam = fem.Function(disc.Q)
        mid = disc.contact_mesh.geometry.x[compat.geometry_dofmap(disc.contact_mesh)].mean(axis=1)
        n_loc = disc.Q.dofmap.index_map.size_local
        lam.x.array[:n_loc] = 1.0 + mid[:n_loc, 1] ** 2 + np.sin(5 * mid[:n_loc, 2])
        lam.x.scatter_forward()
        r = Reconstructor(disc).patch_linear_multiplier(lam)
        local = fem.assemble_scalar(fem.form(r**2 * disc.m.ds_contact))
        results.append(comm.allreduce(local, op=MPI.SUM))
    assert np.isclose(results[0], results[1], rtol=1e-12)


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["strip", "obstacle"])
def test_warm_start_by_parent_maps_equals_point_location(kind):
    """transfer_solution through the parent maps (no point location) gives what interpolating
    the same reconstructions with point location gives, after a marked (non-uniform) refinement,
    on a strip whose contact boundary is cut by the partition and on the 3D obstacle."""
    from dwr_signorini.spaces import refine_marked
    from dwr_signorini.transfer import transfer_solution
    from tests.problems import strip_problem

    comm = MPI.COMM_WORLD
    problem = (
        strip_problem(comm, 16, 4) if kind == "strip" else ex.obstacle_problem(comm, (1, 4, 4))
    )
    sol = ds.solve(problem)
    rec = Reconstructor(sol.disc)
    macro = problem.mesh
    tdim = macro.topology.dim
    num_cells = macro.topology.index_map(tdim).size_local
    mids = mesh.compute_midpoints(macro, tdim, np.arange(num_cells, dtype=np.int32))
    marked = np.flatnonzero(mids[:, 1] < 0.4 * mids[:, 1].max()).astype(np.int32)
    new_problem, macro_parent = refine_marked(problem, marked)
    disc = ds.discretize(new_problem)

    u_fast, lam_fast = transfer_solution(sol, disc, rec, macro_parent)
    _, lam_slow = transfer_solution(sol, disc, rec)
    u_slow = _Transfer(disc.V, rec.V2h)(fem.Function(disc.V), rec.patch_quadratic(sol.u))

    scale = comm.allreduce(np.abs(u_slow.x.array).max(initial=0.0), op=MPI.MAX)
    assert scale > 0
    assert np.allclose(u_fast.x.array, u_slow.x.array, rtol=0, atol=1e-12 * scale)
    lam_scale = comm.allreduce(np.abs(lam_slow.x.array).max(initial=0.0), op=MPI.MAX)
    assert lam_scale > 0
    assert np.allclose(lam_fast.x.array, lam_slow.x.array, rtol=0, atol=1e-12 * lam_scale)


@pytest.mark.mpi
@pytest.mark.parametrize("tdim", [2, 3])
@pytest.mark.parametrize("shape", [(), (3,)])
def test_p1_in_p2_matrix_equals_interpolation(tdim, shape):
    """P1 written in P2 by the sparse map equals dolfinx's interpolation, ghosted mesh."""
    from dwr_signorini.reconstruction import p1_in_p2_matrix

    comm = MPI.COMM_WORLD
    msh = (mesh.create_unit_square(comm, 5, 4) if tdim == 2
           else mesh.create_unit_cube(comm, 3, 2, 2))
    V = fem.functionspace(msh, ("Lagrange", 1, shape))
    V2 = fem.functionspace(msh, ("Lagrange", 2, shape))
    v = fem.Function(V)
    v.interpolate(lambda x: np.vstack([np.sin(3 * x[0] + x[i % tdim]) + i for i in
                                       range(max(1, np.prod(shape, dtype=int)))]))
    expected = fem.Function(V2)
    expected.interpolate(v)
    bs = V2.dofmap.index_map_bs
    mapped = (p1_in_p2_matrix(V, V2) @ v.x.array.reshape(-1, bs)).ravel()
    assert np.abs(expected.x.array).max() > 0.5
    assert np.allclose(mapped, expected.x.array, rtol=1e-14, atol=1e-14)
