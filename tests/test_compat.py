"""dwr_signorini.compat: the wrappers over dolfinx 0.9 / 0.11 differences give the same results.

Run on both suites (``make test`` and ``make test-current``); the ``mpi`` ones also on 2 ranks.
"""

import warnings

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc

from dwr_signorini import compat

from . import fem_compat


def _macro(tdim, comm=MPI.COMM_WORLD, ghost_mode=mesh.GhostMode.shared_facet):
    if tdim == 2:
        return mesh.create_unit_square(comm, 4, 3, mesh.CellType.triangle, ghost_mode=ghost_mode)
    return mesh.create_unit_cube(comm, 3, 2, 2, mesh.CellType.tetrahedron, ghost_mode=ghost_mode)


def _barycentric(msh, cells, points):
    tdim = msh.topology.dim
    x = msh.geometry.x[compat.geometry_dofmap(msh)[cells]][:, :, :tdim]
    T = np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1))
    lam = np.linalg.solve(T, (points[:, :tdim] - x[:, 0])[..., None])[..., 0]
    return np.concatenate([1 - lam.sum(axis=1, keepdims=True), lam], axis=1)


def _fine_to_macro_facet(macro, fine, parent_cell, parent_facet):
    """Macro facet of each fine facet (-1 inside macro cells), from the refinement's maps."""
    tdim = macro.topology.dim
    fdim, nf = tdim - 1, tdim + 1
    for m in (macro, fine):
        m.topology.create_connectivity(tdim, fdim)
    f_c2f = fine.topology.connectivity(tdim, fdim).array.reshape(-1, nf)
    m_c2f = macro.topology.connectivity(tdim, fdim).array.reshape(-1, nf)
    out = np.full(compat._num_entities(fine, fdim), -1, dtype=np.int32)
    pf = parent_facet.reshape(-1, nf)
    c, j = np.nonzero(pf >= 0)
    out[f_c2f[c, j]] = m_c2f[parent_cell[c], pf[c, j]]
    return out


@pytest.mark.mpi
@pytest.mark.parametrize("tdim", [2, 3])
@pytest.mark.parametrize("marked", [False, True])
def test_refine_parents_in_local_order_and_no_ghosts(tdim, marked):
    macro = _macro(tdim)
    edges = None
    if marked:
        macro.topology.create_entities(1)
        macro.topology.create_connectivity(tdim, 1)
        cells = np.arange(0, macro.topology.index_map(tdim).size_local, 2, dtype=np.int32)
        edges = mesh.compute_incident_entities(macro.topology, cells, tdim, 1)
        edges = np.unique(edges).astype(np.int32)
    fine, parent_cell, parent_facet = compat.refine(macro, edges, facets=True)
    cells = fine.topology.index_map(tdim)
    assert cells.num_ghosts == 0
    assert parent_cell.shape == (cells.size_local,)
    mids = mesh.compute_midpoints(fine, tdim, np.arange(cells.size_local, dtype=np.int32))
    assert np.all(_barycentric(macro, parent_cell, mids) > -1e-12)
    # A fine facet with a parent facet lies in that facet's hyperplane.
    fdim = tdim - 1
    fine.topology.create_connectivity(fdim, tdim)
    macro.topology.create_connectivity(fdim, tdim)
    to_macro = _fine_to_macro_facet(macro, fine, parent_cell, parent_facet)
    ff = np.flatnonzero(to_macro >= 0).astype(np.int32)
    if len(ff):
        p = mesh.compute_midpoints(fine, fdim, ff)
        v = macro.geometry.x[mesh.entities_to_geometry(macro, fdim, to_macro[ff], False)]
        if tdim == 2:
            t = v[:, 1] - v[:, 0]
            normal = np.stack([-t[:, 1], t[:, 0], np.zeros(len(t))], axis=1)
        else:
            normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        assert np.max(np.abs(np.sum((p - v[:, 0]) * normal, axis=1))) < 1e-12
    num = fine.comm.allreduce(cells.size_local)
    expected = macro.topology.index_map(tdim).size_global * 2**tdim
    assert (num < expected) if marked else (num == expected)
    _, no_facets, none = compat.refine(macro, edges)
    assert none is None and np.array_equal(no_facets, parent_cell)


@pytest.mark.mpi
@pytest.mark.parametrize("tdim", [2, 3])
def test_many_to_one_entity_map_couples_fine_facets_to_macro_facet_submesh(tdim):
    """The multiplier coupling of spaces.py: DG0 on the submesh of macro facets x = 1, used in
    forms on the fine mesh through fine facet -> macro facet (2 or 4 fine facets per cell)."""
    comm = MPI.COMM_WORLD
    macro = _macro(tdim)
    fdim = tdim - 1
    macro.topology.create_entities(fdim)
    fine, parent_cell, parent_facet = compat.refine(macro, facets=True)
    fine.topology.create_entities(fdim)
    right = mesh.locate_entities_boundary(macro, fdim, lambda x: np.isclose(x[0], 1.0))
    sub, sub_to_macro, sub_vertices, _ = compat.create_submesh(macro, fdim, right)
    assert sub_to_macro.dtype == np.int32 and sub_vertices.dtype == np.int32
    assert np.allclose(
        mesh.compute_midpoints(sub, fdim, np.arange(len(sub_to_macro), dtype=np.int32)),
        mesh.compute_midpoints(macro, fdim, sub_to_macro),
    )
    macro_to_sub = np.full(compat._num_entities(macro, fdim), -1, dtype=np.int32)
    macro_to_sub[sub_to_macro] = np.arange(len(sub_to_macro), dtype=np.int32)
    to_macro = _fine_to_macro_facet(macro, fine, parent_cell, parent_facet)
    fine_to_sub = np.where(to_macro >= 0, macro_to_sub[np.maximum(to_macro, 0)], -1)
    fine_to_sub = fine_to_sub.astype(np.int32)
    contact = np.flatnonzero(fine_to_sub >= 0).astype(np.int32)
    counts = np.bincount(fine_to_sub[contact], minlength=len(sub_to_macro))
    assert set(counts[: sub.topology.index_map(fdim).size_local]) <= {0, 2 ** (tdim - 1)}

    tags = mesh.meshtags(fine, fdim, contact, np.full(len(contact), 3, dtype=np.int32))
    ds = ufl.Measure("ds", domain=fine, subdomain_data=tags)(3)
    V = fem.functionspace(fine, ("Lagrange", 1, (tdim,)))
    Q = fem.functionspace(sub, ("DG", 0))
    n = ufl.FacetNormal(fine)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    lam, mu = ufl.TrialFunction(Q), ufl.TestFunction(Q)
    maps = compat.entity_maps(fine, {sub: fine_to_sub})
    N = fem_petsc.assemble_matrix(compat.form(ufl.inner(mu, ufl.dot(u, n)) * ds, maps))
    NT = fem_petsc.assemble_matrix(
        compat.form(ufl.inner(lam, ufl.dot(v, n)) * ds, {sub: fine_to_sub})
    )
    for A in (N, NT):
        A.assemble()
    # N e_x: the measure of each macro facet (n = e_x on x = 1); total 1.
    ex = fem.Function(V)
    ex.interpolate(lambda x: np.vstack([np.ones(x.shape[1])] + [np.zeros(x.shape[1])] * fdim))
    y = N.createVecLeft()
    N.mult(ex.x.petsc_vec, y)
    assert y.sum() == pytest.approx(1.0, rel=1e-12)
    # The same measures from a linear form with the multiplier's test function.
    b = fem_petsc.assemble_vector(compat.form(mu * ds, maps))
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    assert np.allclose(b.array_r, y.array_r, rtol=1e-12, atol=1e-15)
    # N^T assembled from its own form is the transpose of N.
    D = NT.transpose(PETSc.Mat())
    D.axpy(-1.0, N)
    assert D.norm() < 1e-14
    # A multiplier as a coefficient: int lam ds on T_h equals it on T_H.
    lam_h = fem.Function(Q)
    lam_h.interpolate(lambda x: 1.0 + x[1] + 2 * x[tdim - 1] ** 2)
    fine_value = comm.allreduce(
        fem.assemble_scalar(compat.form(lam_h * ds, {sub: fine_to_sub})), op=MPI.SUM
    )
    macro_tags = mesh.meshtags(
        macro, fdim, np.sort(right).astype(np.int32), np.full(len(right), 3, dtype=np.int32)
    )
    ds_H = ufl.Measure("ds", domain=macro, subdomain_data=macro_tags)(3)
    macro_value = comm.allreduce(
        fem.assemble_scalar(compat.form(lam_h * ds_H, {sub: macro_to_sub})), op=MPI.SUM
    )
    assert fine_value == pytest.approx(macro_value, rel=1e-12)
    # Dirichlet conditions on V in the coupling block (rows of N^T), as newton assembles it.
    left = mesh.locate_entities_boundary(fine, fdim, lambda x: np.isclose(x[0], 0.0))
    bc = fem.dirichletbc(np.zeros(tdim), fem.locate_dofs_topological(V, fdim, left), V)
    NTb = fem_petsc.assemble_matrix(compat.form(ufl.inner(lam, ufl.dot(v, n)) * ds, maps), [bc])
    NTb.assemble()
    assert NTb.norm() == pytest.approx(NT.norm(), rel=1e-12)
    for obj in (N, NT, D, NTb, y, b):
        obj.destroy()


def test_entity_maps_checks_the_size():
    if not compat.HAS_ENTITY_MAP:
        pytest.skip("dolfinx 0.9 takes the dict as it is")
    macro = _macro(2)
    right = mesh.locate_entities_boundary(macro, 1, lambda x: np.isclose(x[0], 1.0))
    sub, *_ = compat.create_submesh(macro, 1, right)
    with pytest.raises(ValueError, match="entity map has"):
        compat.entity_maps(macro, {sub: np.zeros(3, dtype=np.int32)})


@pytest.mark.mpi
def test_create_mesh_argument_order_and_partitioner():
    comm = MPI.COMM_WORLD
    cells = np.array([[0, 1, 2], [1, 3, 2]], dtype=np.int64) if comm.rank == 0 else np.zeros(
        (0, 3), dtype=np.int64
    )
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]) if comm.rank == 0 else (
        np.zeros((0, 2))
    )
    domain = _macro(2).ufl_domain()
    msh = compat.create_mesh(
        comm, cells, x, ufl.Mesh(domain.ufl_coordinate_element()),
        partitioner=compat.cell_partitioner(mesh.GhostMode.none),
    )
    assert msh.topology.index_map(2).size_global == 2
    one = fem.form(fem.Constant(msh, 1.0) * ufl.dx(domain=msh))
    assert comm.allreduce(fem.assemble_scalar(one), op=MPI.SUM) == pytest.approx(1.0)


@pytest.mark.mpi
def test_python_partitioner_keeps_cells_on_their_rank():
    """A Python partitioner (as tensor_refine's) returning compat.cpp_adjacencylist."""
    comm = MPI.COMM_WORLD
    r = comm.rank
    # Rank r contributes the two triangles of the square [r, r + 1] x [0, 1].
    x = np.array([[r, 0.0], [r + 1, 0.0], [r, 1.0], [r + 1, 1.0]])
    cells = (np.array([[0, 1, 2], [1, 3, 2]], dtype=np.int64) + 4 * r)

    def keep(comm_, nparts, cell_types, cells_):
        n = sum(np.asarray(c).size for c in cells_) // 3
        return compat.cpp_adjacencylist(
            np.full(n, comm_.rank, dtype=np.int32), np.arange(n + 1, dtype=np.int32)
        )

    domain = ufl.Mesh(_macro(2, MPI.COMM_SELF).ufl_domain().ufl_coordinate_element())
    msh = compat.create_mesh(comm, cells, x, domain, partitioner=keep)
    assert msh.topology.index_map(2).size_local == 2
    assert msh.topology.index_map(2).num_ghosts == 0
    one = fem.form(fem.Constant(msh, 1.0) * ufl.dx(domain=msh))
    assert comm.allreduce(fem.assemble_scalar(one), op=MPI.SUM) == pytest.approx(comm.size)


def test_cell_partitioner_in_a_mesh_constructor():
    part = compat.cell_partitioner(mesh.GhostMode.none)
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 3, 3, partitioner=part)
    assert msh.topology.index_map(2).size_global == 18


def test_geometry_accessors_without_deprecation_warnings():
    msh = _macro(3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        dofmap = compat.geometry_dofmap(msh)
        cmap = compat.geometry_cmap(msh)
    assert dofmap.shape[1] == 4 and cmap.degree == 1


def test_interpolation_points_and_is_simplex():
    msh = _macro(2)
    V = fem.functionspace(msh, ("DG", 0))
    points = compat.interpolation_points(V.element)
    assert points.shape == (1, 2)
    f = fem.Function(V)
    x = ufl.SpatialCoordinate(msh)
    f.interpolate(fem.Expression(x[0] + 2 * x[1], points))
    assert np.all(np.isfinite(f.x.array))
    assert compat.is_simplex(msh.ufl_cell())
    quad = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2, mesh.CellType.quadrilateral)
    assert not compat.is_simplex(quad.ufl_cell())


@pytest.mark.mpi
def test_linear_problem_and_prefixes():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 8, 8)
    V = fem.functionspace(msh, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    facets = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    bc = fem.dirichletbc(0.0, fem.locate_dofs_topological(V, 1, facets), V)
    a = ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx
    L = v * ufl.dx
    options = {"ksp_type": "preonly", "pc_type": "lu"}
    sols = []
    for prefix in (None, None, "compat_test_"):
        problem = fem_compat.linear_problem(a, L, bcs=[bc], petsc_options=options,
                                        petsc_options_prefix=prefix)
        sols.append(problem.solve())
        assert isinstance(sols[-1], fem.Function)
    for s in sols[1:]:
        assert np.allclose(s.x.array, sols[0].x.array)
    mean = msh.comm.allreduce(fem.assemble_scalar(fem.form(sols[0] * ufl.dx)), op=MPI.SUM)
    assert 0.03 < mean < 0.0352  # int u = 0.035144 for -Laplace u = 1 on the unit square


def test_create_vector_and_block_matrix():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    V = fem.functionspace(msh, ("Lagrange", 1))
    Q = fem.functionspace(msh, ("DG", 0))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    p, q = ufl.TrialFunction(Q), ufl.TestFunction(Q)
    L = fem.form(v * ufl.dx)
    b = fem_compat.create_vector(L)
    assert b.getSize() == V.dofmap.index_map.size_global
    blocks = [[fem.form(u * v * ufl.dx), fem.form(p * v * ufl.dx)],
              [fem.form(u * q * ufl.dx), fem.form(p * q * ufl.dx)]]
    A = fem_compat.assemble_matrix_block(blocks)
    assert A.getSize() == (V.dofmap.index_map.size_global + Q.dofmap.index_map.size_global,) * 2
    norms = []
    for row in blocks:
        for f in row:
            M = fem_petsc.assemble_matrix(f)
            M.assemble()
            norms.append(M.norm() ** 2)
            M.destroy()
    assert A.norm() == pytest.approx(np.sqrt(sum(norms)), rel=1e-12)
    A.destroy()
    b.destroy()


def test_bb_tree_and_interpolation_data_fields():
    coarse = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    fine = mesh.create_unit_square(MPI.COMM_WORLD, 5, 3)
    owned = np.arange(coarse.topology.index_map(2).size_local, dtype=np.int32)
    tree = fem_compat.bb_tree(coarse, 2, owned, padding=0.0)
    assert tree.num_bboxes == max(2 * len(owned) - 1, 0)  # leaves and inner nodes
    V_from = fem.functionspace(coarse, ("Lagrange", 1))
    V_to = fem.functionspace(fine, ("Lagrange", 1))
    cells = np.arange(fine.topology.index_map(2).size_local, dtype=np.int32)
    data = fem.create_interpolation_data(V_to, V_from, cells, padding=1e-10)
    assert fem_compat.ownership_field(data, "dest_cells").ndim == 1
    src, dst = fem.Function(V_from), fem.Function(V_to)
    src.interpolate(lambda x: 1 + x[0] - 2 * x[1])
    dst.interpolate_nonmatching(src, cells, data)
    dst.x.scatter_forward()
    exact = fem.Function(V_to)
    exact.interpolate(lambda x: 1 + x[0] - 2 * x[1])
    assert np.allclose(dst.x.array, exact.x.array)


def test_gmsh_model_to_mesh():
    gmsh = pytest.importorskip("gmsh")
    comm = MPI.COMM_WORLD
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.occ.addRectangle(0, 0, 0, 2, 1)
            gmsh.model.occ.synchronize()
            gmsh.model.addPhysicalGroup(2, [1], 1)
            gmsh.model.addPhysicalGroup(1, [c for _, c in gmsh.model.getEntities(1)], 3)
            gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
            gmsh.model.mesh.generate(2)
        msh, cell_tags, facet_tags = compat.gmsh_model_to_mesh(
            gmsh.model, comm, 0, gdim=2,
            partitioner=compat.cell_partitioner(mesh.GhostMode.none),
        )
    finally:
        gmsh.finalize()
    assert isinstance(msh, mesh.Mesh)
    assert isinstance(facet_tags, mesh.MeshTags) and facet_tags.dim == 1
    assert isinstance(cell_tags, mesh.MeshTags) and cell_tags.dim == 2
    ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags)
    one = fem.Constant(msh, 1.0)
    perimeter = comm.allreduce(fem.assemble_scalar(fem.form(one * ds(3))), op=MPI.SUM)
    assert perimeter == pytest.approx(6.0, rel=1e-12)
