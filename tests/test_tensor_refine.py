"""Uniform refinement of quadrilateral/hexahedral meshes (``dwr_signorini.tensor_refine``).

Every check compares with an independent truth: analytic areas/volumes/boundary measures and
integrals, entity counts of a conforming refinement (V + E + F + C new vertices), dolfinx's own
topology, geometry, facet midpoints and pull-backs of the *parent* mesh, and serial runs.
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

from dwr_signorini import compat
from dwr_signorini.tensor_refine import refine_uniform_tensor

from .fem_compat import linear_problem

QUAD, HEX = mesh.CellType.quadrilateral, mesh.CellType.hexahedron

# Affine map x -> A x + b for the skewed rectangle (det A = 1.4 > 0).
A_SKEW = np.array([[1.0, 0.5], [0.2, 1.5]])
B_SKEW = np.array([0.3, -0.7])


def _build(kind: str, comm: MPI.Comm = MPI.COMM_WORLD, ghosted: bool = False) -> mesh.Mesh:
    """Test meshes: structured, affinely skewed and non-affinely distorted quads/hexes."""
    ghost_mode = mesh.GhostMode.shared_facet if ghosted else mesh.GhostMode.none
    if kind in ("rect", "skew", "distorted"):
        msh = mesh.create_rectangle(comm, [[0.0, 0.0], [3.0, 2.0]], [3, 2], QUAD,
                                    ghost_mode=ghost_mode)
        x = msh.geometry.x
        if kind == "skew":
            x[:, :2] = x[:, :2] @ A_SKEW.T + B_SKEW
        elif kind == "distorted":  # moves the interior vertices only: the domain is unchanged
            bump = np.sin(np.pi * x[:, 0] / 3.0) * np.sin(np.pi * x[:, 1] / 2.0)
            x[:, 0] += 0.3 * bump
            x[:, 1] -= 0.2 * bump
        return msh
    if kind in ("box", "box_distorted"):
        msh = mesh.create_box(comm, [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], [2, 2, 2], HEX,
                              ghost_mode=ghost_mode)
        if kind == "box_distorted":  # moves the centre vertex only
            x = msh.geometry.x
            bump = np.prod(np.sin(np.pi * x), axis=1)
            x[:, 0] += 0.1 * bump
            x[:, 1] += 0.05 * bump
            x[:, 2] -= 0.075 * bump
        return msh
    raise ValueError(kind)


KINDS = ["rect", "skew", "distorted", "box", "box_distorted"]


def _exact_measures(kind: str) -> tuple[float, float]:
    """Area/volume and boundary length/area of the domain of ``_build(kind)``."""
    if kind in ("rect", "distorted"):
        return 6.0, 10.0
    if kind == "skew":
        e1, e2 = np.linalg.norm(A_SKEW[:, 0]), np.linalg.norm(A_SKEW[:, 1])
        return 6.0 * np.linalg.det(A_SKEW), 2.0 * (3.0 * e1 + 2.0 * e2)
    return 1.0, 6.0


def _linear(x: np.ndarray) -> np.ndarray:
    """f(x) = 1 + 2x + 3y (+ 4z)."""
    return 1.0 + 2.0 * x[0] + 3.0 * x[1] + 4.0 * x[2]


def _exact_integral_f2(kind: str) -> float:
    """int f^2 over the domain of ``_build(kind)``, by tensor Gauss quadrature (exact)."""
    pts, wts = np.polynomial.legendre.leggauss(4)
    if kind in ("box", "box_distorted"):
        q = 0.5 * (pts + 1.0)
        X = np.array(np.meshgrid(q, q, q, indexing="ij")).reshape(3, -1)
        W = np.einsum("i,j,k->ijk", wts, wts, wts).reshape(-1) / 8.0
        return float(np.sum(W * _linear(X) ** 2))
    X = np.array(np.meshgrid(1.5 * (pts + 1.0), pts + 1.0, indexing="ij")).reshape(2, -1)
    W = np.outer(wts, wts).reshape(-1) * 1.5
    jac = 1.0
    if kind == "skew":
        X = A_SKEW @ X + B_SKEW[:, None]
        jac = np.linalg.det(A_SKEW)
    X3 = np.vstack((X, np.zeros(X.shape[1])))
    return float(np.sum(W * _linear(X3) ** 2) * jac)


def _integral(msh: mesh.Mesh, integrand, measure: str = "dx", degree: int = 8) -> float:
    """Global integral of a UFL integrand over ``msh`` (or its boundary with ``measure='ds'``)."""
    d = getattr(ufl, measure)(domain=msh, metadata={"quadrature_degree": degree})
    return msh.comm.allreduce(fem.assemble_scalar(fem.form(integrand * d)), op=MPI.SUM)


def _num_global(msh: mesh.Mesh, dim: int) -> int:
    msh.topology.create_entities(dim)
    return msh.topology.index_map(dim).size_global


def _cell_coords(msh: mesh.Mesh, cell: int) -> np.ndarray:
    gdim = msh.geometry.dim
    return msh.geometry.x[compat.geometry_dofmap(msh)[cell], :gdim]


def _pull_back(msh: mesh.Mesh, cell: int, points: np.ndarray) -> np.ndarray:
    """Reference coordinates in ``cell`` of physical points (dolfinx's own pull-back)."""
    gdim = msh.geometry.dim
    cmap = compat.geometry_cmap(msh)
    return cmap.pull_back(np.atleast_2d(points)[:, :gdim], _cell_coords(msh, cell))


@pytest.mark.mpi
@pytest.mark.parametrize("kind", KINDS)
def test_counts_and_measures(kind):
    msh = _build(kind)
    tdim = msh.topology.dim
    coarse = [_num_global(msh, d) for d in range(tdim + 1)]
    fine, parent_cell, parent_facet = refine_uniform_tensor(msh)
    nc_local = msh.topology.index_map(tdim).size_local
    fmap = fine.topology.index_map(tdim)

    # Cells: 2^d children, kept on the parent's rank, no ghosts.
    assert fmap.size_global == 2**tdim * coarse[tdim]
    assert fmap.size_local == 2**tdim * nc_local
    assert fmap.num_ghosts == 0
    nf = 2 * tdim
    assert parent_cell.dtype == np.int32 and parent_cell.shape == (fmap.size_local,)
    assert parent_facet.dtype == np.int8 and parent_facet.shape == (fmap.size_local * nf,)
    assert np.all(np.bincount(parent_cell, minlength=nc_local) == 2**tdim)

    # A conforming refinement has one new vertex per old vertex, edge, face and cell (no node is
    # duplicated across processes) and the number of edges/faces a uniform split gives.
    V, E, C = coarse[0], coarse[1], coarse[tdim]
    fine_counts = [_num_global(fine, d) for d in range(tdim + 1)]
    if tdim == 2:
        assert fine_counts[0] == V + E + C
        assert fine_counts[1] == 2 * E + 4 * C
    else:
        F = coarse[2]
        assert fine_counts[0] == V + E + F + C
        assert fine_counts[1] == 2 * E + 4 * F + 6 * C
        assert fine_counts[2] == 4 * F + 12 * C

    # Area/volume and boundary measure unchanged (exactly: the multilinear maps are preserved).
    vol, bnd = _exact_measures(kind)
    one = fem.Constant(fine, 1.0)
    assert _integral(fine, one) == pytest.approx(vol, rel=1e-12)
    assert _integral(fine, one, "ds") == pytest.approx(bnd, rel=1e-12)
    assert _integral(msh, fem.Constant(msh, 1.0)) == pytest.approx(vol, rel=1e-12)


@pytest.mark.mpi
@pytest.mark.parametrize("kind", KINDS)
def test_children_fill_their_parent(kind):
    """Pulled back into the parent, the children's midpoints are the 2^d points {1/4, 3/4}^d."""
    msh = _build(kind)
    tdim = msh.topology.dim
    fine, parent_cell, _ = refine_uniform_tensor(msh)
    n = fine.topology.index_map(tdim).size_local
    mid = mesh.compute_midpoints(fine, tdim, np.arange(n, dtype=np.int32))
    seen: dict[int, set] = {}
    for c in range(n):
        X = _pull_back(msh, parent_cell[c], mid[c])[0]
        # The vertex mean of a multilinear cell is the image of its reference centre.
        assert np.all(np.abs(np.abs(X - 0.5) - 0.25) < 1e-8), X
        seen.setdefault(int(parent_cell[c]), set()).add(tuple(X > 0.5))
        lo, hi = _cell_coords(msh, parent_cell[c]).min(0), _cell_coords(msh, parent_cell[c]).max(0)
        assert np.all(mid[c, : lo.size] > lo) and np.all(mid[c, : hi.size] < hi)
    assert all(len(q) == 2**tdim for q in seen.values())

    # Same orientation as the parent (dolfinx 0.9's create_rectangle quadrilaterals have det J < 0,
    # its create_box hexahedra det J > 0), and det J / 2^d for affine cells.
    centre = np.full((1, tdim), 0.5)
    detj_fine = fem.Expression(ufl.JacobianDeterminant(fine), centre).eval(
        fine, np.arange(n, dtype=np.int32)).reshape(-1)
    nc = msh.topology.index_map(tdim).size_local
    detj_coarse = fem.Expression(ufl.JacobianDeterminant(msh), centre).eval(
        msh, np.arange(nc, dtype=np.int32)).reshape(-1)
    assert np.all(detj_fine != 0)
    assert np.all(np.sign(detj_fine) == np.sign(detj_coarse[parent_cell]))
    if kind in ("rect", "skew", "box"):
        assert np.allclose(detj_fine, detj_coarse[parent_cell] / 2**tdim, rtol=1e-12)


@pytest.mark.mpi
@pytest.mark.parametrize("kind", KINDS)
def test_parent_facet(kind):
    msh = _build(kind)
    tdim, fdim = msh.topology.dim, msh.topology.dim - 1
    nf = 2 * tdim
    fine, parent_cell, parent_facet = refine_uniform_tensor(msh)
    n = fine.topology.index_map(tdim).size_local
    pf = parent_facet.reshape(n, nf)
    # Interior facets of a parent: 4 edges x 2 sides (quad), 12 faces x 2 sides (hex).
    assert np.all(np.bincount(parent_cell[np.nonzero(pf == -1)[0]]) == (8 if tdim == 2 else 24))

    fine.topology.create_connectivity(tdim, fdim)
    fine.topology.create_connectivity(fdim, tdim)
    msh.topology.create_connectivity(tdim, fdim)
    c2f = fine.topology.connectivity(tdim, fdim).array.reshape(n, nf)
    f2c = fine.topology.connectivity(fdim, tdim)
    c2f_coarse = msh.topology.connectivity(tdim, fdim).array.reshape(-1, nf)
    fmid = mesh.compute_midpoints(fine, fdim, c2f.reshape(-1)).reshape(n, nf, 3)

    for c in range(n):
        p = parent_cell[c]
        for j in range(nf):
            # Reference coordinates (in the parent) of the fine facet's midpoint.
            X = _pull_back(msh, p, fmid[c, j])[0]
            on_bnd = np.isclose(X, 0.0, atol=1e-10) | np.isclose(X, 1.0, atol=1e-10)
            cells = f2c.links(c2f[c, j])
            if pf[c, j] == -1:
                assert not np.any(on_bnd)
                # Interior to the parent: shared with a sibling.
                assert len(cells) == 2 and parent_cell[cells[0]] == parent_cell[cells[1]]
            else:
                # dolfinx's midpoint of the parent facet, pulled back, is on the same reference
                # facet {X_axis = value} as the fine facet's midpoint.
                parent_f = c2f_coarse[p, pf[c, j]]
                Y = _pull_back(msh, p, mesh.compute_midpoints(msh, fdim, np.array([parent_f],
                                                              dtype=np.int32)))[0]
                y_bnd = np.isclose(Y, 0.0, atol=1e-10) | np.isclose(Y, 1.0, atol=1e-10)
                assert np.count_nonzero(on_bnd) == 1 and np.array_equal(on_bnd, y_bnd), (X, Y)
                assert np.isclose(X[on_bnd][0], Y[y_bnd][0])
                if len(cells) == 2:
                    assert parent_cell[cells[0]] != parent_cell[cells[1]]


@pytest.mark.mpi
@pytest.mark.parametrize("kind", KINDS)
def test_boundary_facets_lie_on_parent_facet(kind):
    """Physical check: each fine exterior facet lies on the parent facet named by parent_facet."""
    msh = _build(kind)
    tdim, fdim = msh.topology.dim, msh.topology.dim - 1
    nf = 2 * tdim
    fine, parent_cell, parent_facet = refine_uniform_tensor(msh)
    fine.topology.create_connectivity(fdim, tdim)
    msh.topology.create_connectivity(fdim, tdim)
    ext_fine = mesh.exterior_facet_indices(fine.topology)
    ext_coarse = set(mesh.exterior_facet_indices(msh.topology).tolist())
    f2c = fine.topology.connectivity(fdim, tdim)
    c2f = fine.topology.connectivity(tdim, fdim).array.reshape(-1, nf)
    c2f_coarse = msh.topology.connectivity(tdim, fdim).array.reshape(-1, nf)
    hits: dict[int, int] = {}
    mids = mesh.compute_midpoints(fine, fdim, ext_fine)
    for f, m in zip(ext_fine, mids, strict=True):
        (c,) = f2c.links(f)
        (j,) = np.flatnonzero(c2f[c] == f)
        local = parent_facet[c * nf + j]
        assert local >= 0
        parent_f = c2f_coarse[parent_cell[c], local]
        assert parent_f in ext_coarse
        hits[parent_f] = hits.get(parent_f, 0) + 1
        verts = msh.geometry.x[mesh.entities_to_geometry(msh, fdim, np.array([parent_f],
                                                                            dtype=np.int32))[0]]
        # On the (planar) parent facet: in its plane/line and within its bounding box.
        edges = verts[1:] - verts[0]
        if tdim == 2:
            normal = np.array([-edges[0, 1], edges[0, 0], 0.0])
        else:
            normal = np.cross(edges[0], edges[1])
        assert abs(np.dot(m - verts[0], normal)) < 1e-12 * np.linalg.norm(normal)
        assert np.all(m >= verts.min(0) - 1e-12) and np.all(m <= verts.max(0) + 1e-12)
    # Each exterior parent facet is split into 2^(d-1) exterior fine facets.
    assert set(hits.values()) <= {2 ** (tdim - 1)}
    assert msh.comm.allreduce(len(ext_fine), op=MPI.SUM) == 2 ** (tdim - 1) * msh.comm.allreduce(
        len(ext_coarse), op=MPI.SUM)


@pytest.mark.mpi
@pytest.mark.parametrize("kind", KINDS)
def test_q1_interpolation_integral(kind):
    """f = 1 + 2x + 3y (+ 4z) is in Q1 on (multi)linear cells: int f^2 identical on both meshes."""
    msh = _build(kind)
    fine, _, _ = refine_uniform_tensor(msh)
    exact = _exact_integral_f2(kind)
    for m in (msh, fine):
        u = fem.Function(fem.functionspace(m, ("Lagrange", 1)))
        u.interpolate(_linear)
        assert _integral(m, u * u) == pytest.approx(exact, rel=1e-12)


def _poisson_l2_error(msh: mesh.Mesh) -> float:
    """L2 error of Q1 for -Δu = f, u = prod sin(pi x_i) (zero on the boundary of the unit cube)."""
    tdim = msh.topology.dim
    x = ufl.SpatialCoordinate(msh)
    u_ex = 1.0
    for i in range(tdim):
        u_ex = u_ex * ufl.sin(ufl.pi * x[i])
    V = fem.functionspace(msh, ("Lagrange", 1))
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    dofs = fem.locate_dofs_topological(V, fdim, mesh.exterior_facet_indices(msh.topology))
    bc = fem.dirichletbc(0.0, dofs, V)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.dx(metadata={"quadrature_degree": 6})
    problem = linear_problem(
        ufl.inner(ufl.grad(u), ufl.grad(v)) * dx, tdim * ufl.pi**2 * u_ex * v * dx, bcs=[bc],
        petsc_options={"ksp_type": "preonly", "pc_type": "lu",
                       "pc_factor_mat_solver_type": "mumps"},
    )
    uh = problem.solve()
    return np.sqrt(_integral(msh, (uh - u_ex) ** 2, degree=6))


@pytest.mark.mpi
@pytest.mark.parametrize(("cell_type", "n0", "levels"), [(QUAD, 4, 3), (HEX, 2, 3)])
def test_poisson_converges(cell_type, n0, levels):
    comm = MPI.COMM_WORLD
    if cell_type == QUAD:
        msh = mesh.create_unit_square(comm, n0, n0, QUAD)
    else:
        msh = mesh.create_unit_cube(comm, n0, n0, n0, HEX)
    # Distort the interior (non-affine cells); the refinement keeps the distortion fixed.
    x = msh.geometry.x
    bump = np.prod(np.sin(np.pi * x[:, : msh.topology.dim]), axis=1)
    x[:, 0] += 0.25 / n0 * bump
    errors = [_poisson_l2_error(msh)]
    for _ in range(levels):
        msh, _, _ = refine_uniform_tensor(msh)
        errors.append(_poisson_l2_error(msh))
    rates = np.array(errors[:-1]) / np.array(errors[1:])
    # Q1: O(h^2) in L2 (observed 3.99-4.07 for every refinement step).
    assert np.all((rates > 3.8) & (rates < 4.3)), rates


def _summary(comm: MPI.Comm, kind: str, ghosted: bool = False, times: int = 2) -> tuple:
    msh = _build(kind, comm, ghosted)
    for _ in range(times):
        msh, _, _ = refine_uniform_tensor(msh)
    tdim = msh.topology.dim
    u = fem.Function(fem.functionspace(msh, ("Lagrange", 1)))
    u.interpolate(_linear)
    return (msh.topology.index_map(tdim).size_global, _num_global(msh, 0),
            _num_global(msh, tdim - 1), _integral(msh, fem.Constant(msh, 1.0)),
            _integral(msh, fem.Constant(msh, 1.0), "ds"), _integral(msh, u * u))


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["distorted", "box_distorted"])
@pytest.mark.parametrize("ghosted", [False, True])
def test_serial_equals_parallel(kind, ghosted):
    """Refined twice on COMM_WORLD and on COMM_SELF: same counts, volume, boundary, int f^2."""
    par = _summary(MPI.COMM_WORLD, kind, ghosted)
    ser = _summary(MPI.COMM_SELF, kind)
    assert par[:3] == ser[:3]
    assert np.allclose(par[3:], ser[3:], rtol=1e-12)
    num_children, num_macro = (8, 8) if kind == "box_distorted" else (4, 6)
    assert par[0] == num_children**2 * num_macro


@pytest.mark.mpi
def test_ghosted_input_refines_owned_cells_only():
    msh = _build("rect", ghosted=True)
    fine, parent_cell, _ = refine_uniform_tensor(msh)
    nc = msh.topology.index_map(2).size_local
    assert fine.topology.index_map(2).size_local == 4 * nc
    assert parent_cell.max(initial=-1) < nc


def test_rejects_simplices():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2, mesh.CellType.triangle)
    with pytest.raises(ValueError, match="quadrilaterals"):
        refine_uniform_tensor(msh)
