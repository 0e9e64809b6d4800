"""The data of the paper's three examples (Section 5): meshes and tags, the exact solution of
Example 5.1 and its reference values, obstacles and quantities of interest."""

import warnings
from types import SimpleNamespace

from mpi4py import MPI

import basix.ufl
import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from scipy import integrate

from dwr_signorini import examples as ex

E, NU = 10.0, 0.3

# Reference values (two Gauss rules and scipy's adaptive quad agree to >= 14 digits).
J_A1_REF = 4.780557554046855e-4
J_A2_REF = 2.503102036599229e-2


def _measure(form_integrand, msh, tags=None, degree=2) -> float:
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags, metadata={"quadrature_degree": degree})
    value = fem.assemble_scalar(fem.form(form_integrand(ds)))
    return msh.comm.allreduce(value, op=MPI.SUM)


def _owned_count(msh, tags, value) -> int:
    num_owned = msh.topology.index_map(msh.topology.dim - 1).size_local
    local = int(np.sum((tags.values == value) & (tags.indices < num_owned)))
    return msh.comm.allreduce(local, op=MPI.SUM)


# --------------------------------------------------------------------------------------------------
# Meshes and facet tags
# --------------------------------------------------------------------------------------------------

MESH_CASES = [
    # builder, kwargs, {tag: (measure, number of facets)}
    (
        ex.analytic_2d_mesh,
        {"cell_type": mesh.CellType.quadrilateral},
        {1: (2, 8), 2: (6, 24), 3: (2, 8)},
    ),
    (
        ex.analytic_2d_mesh,
        {"nx": 6, "ny": 4, "cell_type": mesh.CellType.triangle},
        {1: (2, 4), 2: (6, 12), 3: (2, 4)},
    ),
    (ex.bar_2d_mesh, {}, {1: (0.05, 4), 2: (0.4, 32), 3: (0.05, 4)}),
    (
        ex.bar_2d_mesh,
        {"nx": 2, "ny": 8, "cell_type": mesh.CellType.quadrilateral},
        {1: (0.05, 2), 2: (0.4, 16), 3: (0.05, 2)},
    ),
    (ex.obstacle_3d_mesh, {}, {1: (1.0, 128), 2: (1.75, 224), 3: (0.25, 32)}),
    (
        ex.obstacle_3d_mesh,
        {"n": (1, 4, 6), "cell_type": mesh.CellType.hexahedron},
        {1: (1.0, 24), 2: (1.75, 38), 3: (0.25, 6)},
    ),
]


@pytest.mark.mpi
@pytest.mark.parametrize(("builder", "kwargs", "expected"), MESH_CASES)
def test_facet_tags_measure_and_count(builder, kwargs, expected):
    msh, tags = builder(MPI.COMM_WORLD, **kwargs)
    tdim = msh.topology.dim
    assert msh.topology.index_map(tdim).num_ghosts == 0  # GhostMode.none
    assert tags.dim == tdim - 1
    # Every exterior facet carries exactly one of the tags 1, 2, 3.
    exterior = mesh.exterior_facet_indices(msh.topology)
    assert np.array_equal(np.sort(tags.indices), exterior)
    assert set(np.unique(tags.values)) <= {ex.DIRICHLET, ex.NEUMANN, ex.CONTACT}
    one = fem.Constant(msh, 1.0)
    for tag, (length, count) in expected.items():
        assert np.isclose(_measure(lambda ds, t=tag: one * ds(t), msh, tags), length, rtol=1e-12)
        assert _owned_count(msh, tags, tag) == count
    total = sum(v[0] for v in expected.values())
    assert np.isclose(_measure(lambda ds: one * ds, msh, tags), total, rtol=1e-12)


def test_mesh_builders_reject_unresolved_contact_boundary():
    with pytest.raises(ValueError, match="multiple of 4"):
        ex.bar_2d_mesh(MPI.COMM_SELF, ny=10)
    with pytest.raises(ValueError, match="even"):
        ex.obstacle_3d_mesh(MPI.COMM_SELF, n=(2, 7, 8))
    with pytest.raises(ValueError, match="cell_type"):
        ex.analytic_2d_mesh(MPI.COMM_SELF, cell_type=mesh.CellType.tetrahedron)
    with pytest.raises(ValueError, match="cell_type"):
        ex.obstacle_3d_mesh(MPI.COMM_SELF, cell_type=mesh.CellType.triangle)


def test_lame_parameters():
    mu, lmbda = ex.lame_parameters(E, NU)
    assert np.isclose(mu, E / (2 * (1 + NU)))
    assert np.isclose(lmbda, E * NU / ((1 + NU) * (1 - 2 * NU)))
    _, lmbda_ps = ex.BAR_MATERIAL.lame()
    assert np.isclose(lmbda_ps, 10.0 * 0.33 / (1 - 0.33**2))  # plane stress: E nu / (1 - nu^2)
    assert ex.ANALYTIC_MATERIAL.lame() == ex.lame_parameters(10.0, 0.3)


# --------------------------------------------------------------------------------------------------
# Example 5.1: the exact solution, UFL against numpy
# --------------------------------------------------------------------------------------------------


def _fd_grad(f, x, y, h=1e-6):
    """Central differences of a numpy field f(x, y) -> (k, ...): shape (k, 2, ...)."""
    return np.stack(
        [(f(x + h, y) - f(x - h, y)) / (2 * h), (f(x, y + h) - f(x, y - h)) / (2 * h)], axis=1
    )


def _fd_body_force(x, y, direction, h=1e-5):
    """-div sigma(u) by one-sided second-order differences of the numpy stress.

    One-sided (direction = +1 forward, -1 backward) rather than central differences: across
    |y| = 1/2 the stress is only C^1, where a central difference has an O(h) error; each
    one-sided stencil stays on one smooth piece when the point lies on the kink.
    """

    def s(x_, y_):
        return ex.exact_stress_np(x_, y_, E, NU)

    k = direction * h
    s0 = s(x, y)
    ds_dx = (-3 * s0 + 4 * s(x + k, y) - s(x + 2 * k, y)) / (2 * k)
    ds_dy = (-3 * s0 + 4 * s(x, y + k) - s(x, y + 2 * k)) / (2 * k)
    return -np.stack([ds_dx[0, 0] + ds_dy[0, 1], ds_dx[1, 0] + ds_dy[1, 1]])


def test_numpy_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    x = rng.uniform(-3, 0, 400)
    y = rng.uniform(-1, 1, 400)
    grad = ex.exact_displacement_gradient_np(x, y)
    fd = _fd_grad(ex.exact_displacement_np, x, y)
    assert np.allclose(grad, fd, rtol=0, atol=1e-7 * np.abs(grad).max())


@pytest.fixture(scope="module")
def ufl_values():
    """UFL data of Example 5.1 evaluated by dolfinx.fem.Expression at points of every cell
    (including points on cell boundaries, hence on the boundary of Omega)."""
    msh, _ = ex.analytic_2d_mesh(MPI.COMM_SELF, 12, 8)
    x = ufl.SpatialCoordinate(msh)
    u = ex.analytic_displacement(x)
    s = ex.analytic_stress(x, E, NU)
    f = ex.analytic_body_force(x, E, NU)
    lam = ex.analytic_contact_pressure(x, E, NU)
    g = ex.analytic_gap(x)
    values = ufl.as_vector(
        [x[0], x[1], u[0], u[1], s[0, 0], s[0, 1], s[1, 0], s[1, 1], f[0], f[1], lam, g]
    )
    ref = np.array(
        [
            [0.0, 0.0],
            [1.0, 0.0],
            [0.0, 1.0],
            [1.0, 1.0],
            [0.5, 0.0],
            [0.0, 0.5],
            [1.0, 0.5],
            [0.5, 1.0],
            [0.21, 0.37],
            [0.5, 0.5],
            [0.83, 0.64],
        ]
    )
    expr = fem.Expression(values, ref)
    num_cells = msh.topology.index_map(2).size_local
    out = expr.eval(msh, np.arange(num_cells, dtype=np.int32)).reshape(-1, 12)
    names = ["x", "y", "u1", "u2", "s00", "s01", "s10", "s11", "f0", "f1", "lam", "g"]
    return {k: out[:, i] for i, k in enumerate(names)}


def test_ufl_displacement_and_stress_match_numpy(ufl_values):
    v = ufl_values
    u = ex.exact_displacement_np(v["x"], v["y"])
    s = ex.exact_stress_np(v["x"], v["y"], E, NU)
    assert np.allclose(v["u1"], u[0], rtol=1e-12, atol=1e-14)
    assert np.allclose(v["u2"], u[1], rtol=1e-12, atol=1e-14)
    scale = np.abs(s).max()
    for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)):
        assert np.allclose(v[f"s{i}{j}"], s[i, j], rtol=0, atol=1e-12 * scale)
    assert np.allclose(v["lam"], -s[0, 0], rtol=0, atol=1e-12 * scale)


def test_ufl_body_force_matches_finite_differences(ufl_values):
    v = ufl_values
    f = np.stack([v["f0"], v["f1"]])
    assert np.abs(f).max() > 1.0  # not trivially zero
    for direction in (1, -1):  # f is continuous: both one-sided values agree with it
        fd = _fd_body_force(v["x"], v["y"], direction)
        assert np.allclose(f, fd, rtol=0, atol=1e-6 * np.abs(f).max())


def test_ufl_data_satisfy_boundary_conditions(ufl_values):
    """Signorini conditions (2), (3) on Gamma_C, traction-free Gamma_N, u = 0 on Gamma_D."""
    v = ufl_values
    mu, lmbda = ex.lame_parameters(E, NU)
    scale = 6 * (lmbda + 2 * mu) / 4**4  # max of lambda_n, at y = 0
    on_c = np.isclose(v["x"], 0.0)
    y = v["y"][on_c]
    assert on_c.sum() > 20
    u_n, g, lam = v["u1"][on_c], v["g"][on_c], v["lam"][on_c]
    assert np.all(u_n - g <= 1e-14)  # in fact u_n = g on all of Gamma_C
    assert np.allclose(u_n, g, rtol=0, atol=1e-14)
    assert np.allclose(g, np.where(np.abs(y) < 0.5, -9 * (y**2 - 0.25) ** 4, 0.0), atol=1e-14)
    assert np.all(lam >= -1e-12 * scale)
    assert np.all(lam[np.abs(y) < 0.49] > 0)  # strictly active for |y| < 1/2
    assert np.allclose(lam * (u_n - g), 0.0, atol=1e-14)
    assert np.allclose(
        lam,
        6 * (lmbda + 2 * mu) * np.where(np.abs(y) < 0.5, (y**2 - 0.25) ** 4, 0),
        rtol=0,
        atol=1e-12 * scale,
    )
    assert np.allclose(v["s01"][on_c], 0.0, atol=1e-12 * scale)  # frictionless: sigma_nt = 0
    on_n = np.isclose(np.abs(v["y"]), 1.0) & (v["x"] > -3 + 1e-12)
    assert on_n.sum() > 20
    assert np.allclose(v["s01"][on_n], 0.0, atol=1e-14)  # sigma n = (s01, s11) (+-1)
    assert np.allclose(v["s11"][on_n], 0.0, atol=1e-14)
    on_d = np.isclose(v["x"], -3.0)
    assert on_d.sum() > 20
    assert np.allclose(v["u1"][on_d], 0.0, atol=1e-14)
    assert np.allclose(v["u2"][on_d], 0.0, atol=1e-13)


def test_numpy_exact_solution_signorini_conditions():
    """The same on a dense line, with the numpy exact solution."""
    mu, lmbda = ex.lame_parameters(E, NU)
    y = np.linspace(-1, 1, 2001)
    zero = np.zeros_like(y)
    u_n = ex.exact_displacement_np(zero, y)[0]
    g = np.where(np.abs(y) < 0.5, -9 * (y**2 - 0.25) ** 4, 0.0)
    lam = ex.exact_contact_pressure_np(y, E, NU)
    assert np.all(u_n - g <= 0) and np.allclose(u_n, g, atol=1e-15)
    assert (
        np.all(lam >= 0) and np.all(lam[np.abs(y) < 0.5] > 0) and np.all(lam[np.abs(y) >= 0.5] == 0)
    )
    assert np.allclose(lam * (u_n - g), 0)
    assert np.allclose(lam, 6 * (lmbda + 2 * mu) * np.where(np.abs(y) < 0.5, (y**2 - 0.25) ** 4, 0))
    assert np.allclose(ex.exact_sigma_nn_np(y, E, NU), -lam)
    assert np.allclose(ex.exact_stress_np(zero, y, E, NU)[0, 1], 0, atol=1e-13)
    x = np.linspace(-3, 0, 301)
    for yb in (-1.0, 1.0):
        s = ex.exact_stress_np(x, np.full_like(x, yb), E, NU)
        assert np.allclose(s[:, 1], 0, atol=1e-14)
    assert np.allclose(ex.exact_displacement_np(np.full_like(y, -3.0), y), 0, atol=1e-13)


# --------------------------------------------------------------------------------------------------
# Example 5.1: exact reference values
# --------------------------------------------------------------------------------------------------


def _scipy_J_a(m, tol=1e-11):
    """Independent adaptive (QUADPACK) nested quadrature, split at the kinks."""

    def w(x, y):
        return 0.5 * (np.tanh(20 * (0.5 - np.hypot(x - m, y))) + 1)

    def u1_sq(y, x):
        return ((x + 3) ** 2 * (y - x**2 / 18 - 0.5) ** 4 * (y + x**2 / 18 + 0.5) ** 4) ** 2 * w(
            x, y
        )

    def u2_sq(y, x):
        q = (y - 0.5) ** 3 * (y + 0.5) ** 4 + (y - 0.5) ** 4 * (y + 0.5) ** 3
        return (27 / np.pi * np.sin(4 * np.pi * (x + 3) / 3) * q) ** 2 * w(x, y)

    opts = {"epsabs": 0.0, "epsrel": tol, "limit": 200}

    def inner(x, f, half_width):
        return integrate.quad(f, -half_width, half_width, args=(x,), points=[0.0], **opts)[0]

    pts = [m] if -3 < m < 0 else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        i1 = integrate.quad(lambda x: inner(x, u1_sq, x**2 / 18 + 0.5), -3, 0, points=pts, **opts)[
            0
        ]
        i2 = integrate.quad(lambda x: inner(x, u2_sq, 0.5), -3, 0, points=pts, **opts)[0]
    return i1 + i2


def test_exact_values_regression():
    assert np.isclose(ex.exact_J_a(), J_A1_REF, rtol=1e-13, atol=0)
    assert np.isclose(ex.exact_J_a(-0.5), J_A1_REF, rtol=1e-13, atol=0)
    assert np.isclose(ex.exact_J_a2(), J_A2_REF, rtol=1e-13, atol=0)


@pytest.mark.parametrize("m", [-0.5, 0.0, -3.0])
def test_exact_J_a_against_scipy(m):
    assert np.isclose(ex.exact_J_a(m), _scipy_J_a(m), rtol=1e-10, atol=0)


def test_exact_J_a2_against_scipy():
    mu, lmbda = ex.lame_parameters(E, NU)

    def integrand(y):
        w = 0.5 * np.tanh(20 * (0.25 - abs(y - 0.125))) + 0.5
        return w * (6 * (lmbda + 2 * mu) * (y**2 - 0.25) ** 4) ** 2

    ref = integrate.quad(integrand, -0.5, 0.5, points=[0.125], epsabs=0, epsrel=1e-13, limit=200)[0]
    assert np.isclose(ex.exact_J_a2(), ref, rtol=1e-12, atol=0)
    # lambda_n scales with lambda + 2 mu, i.e. linearly with E.
    assert np.isclose(ex.exact_J_a2(20.0, NU), 4 * ex.exact_J_a2(), rtol=1e-12)


def _goal_context(msh, tags, degree, material=ex.ANALYTIC_MATERIAL):
    md = {"quadrature_degree": degree}
    return SimpleNamespace(
        x=ufl.SpatialCoordinate(msh),
        dx=ufl.Measure("dx", domain=msh, metadata=md),
        ds_contact=ufl.Measure("ds", domain=msh, subdomain_data=tags, metadata=md)(ex.CONTACT),
        sigma=material.sigma,
    )


def _assemble(form, comm) -> float:
    return comm.allreduce(fem.assemble_scalar(fem.form(form)), op=MPI.SUM)


@pytest.mark.mpi
def test_exact_values_against_dolfinx_assembly():
    """The goal builders applied to the UFL exact solution, assembled on a fine mesh.

    ny = 32: y = +-1/2 (kinks of u2) and y = 0.125 (kink of the J_{a,2} weight) are mesh lines.
    """
    msh, tags = ex.analytic_2d_mesh(MPI.COMM_WORLD, 48, 32)
    m = _goal_context(msh, tags, degree=14)
    u = ex.analytic_displacement(m.x)
    lam = ex.analytic_contact_pressure(m.x, E, NU)
    j_a1 = _assemble(ex.goal_a()(u, lam, m), msh.comm)
    j_a2 = _assemble(ex.goal_a2()(u, lam, m), msh.comm)
    assert np.isclose(j_a1, ex.exact_J_a(-0.5), rtol=1e-9, atol=0)
    assert np.isclose(j_a2, ex.exact_J_a2(), rtol=1e-9, atol=0)


# --------------------------------------------------------------------------------------------------
# Examples 5.2 and 5.3: obstacle and quantities of interest
# --------------------------------------------------------------------------------------------------


def _coordinate_3d():
    return ufl.SpatialCoordinate(
        ufl.Mesh(basix.ufl.element("Lagrange", "tetrahedron", 1, shape=(3,)))
    )


def test_obstacle_gap():
    x = _coordinate_3d()
    gap, psi = ex.obstacle_gap(x), ex.obstacle_psi(x)
    assert np.isclose(gap((0.25, 0.25, 0.25)), -0.05, rtol=1e-14)
    assert np.isclose(psi((0.1, 0.25, 0.25)), 0.2, rtol=1e-14)
    rng = np.random.default_rng(0)
    for _ in range(50):
        p = (0.25, *rng.uniform(0, 1, 2))
        z = np.hypot(p[1] - 0.25, p[2] - 0.25)
        g = float(gap(p))
        assert np.isclose(float(psi(p)) - 0.25, g, atol=1e-15)
        assert -0.05 <= g <= 0.0
        if z >= 0.25:
            assert g == 0.0
        else:
            assert np.isclose(g, 0.05 * ((4 * z) ** 8 - 1), atol=1e-15)
    for angle in np.linspace(0, 2 * np.pi, 9):  # continuity at z = 0.25
        c, s = np.cos(angle), np.sin(angle)
        inside = float(gap((0.25, 0.25 + (0.25 - 1e-9) * c, 0.25 + (0.25 - 1e-9) * s)))
        outside = float(gap((0.25, 0.25 + (0.25 + 1e-9) * c, 0.25 + (0.25 + 1e-9) * s)))
        assert outside == 0.0 and abs(inside) < 1e-8


def test_weights():
    x = ufl.SpatialCoordinate(ufl.Mesh(basix.ufl.element("Lagrange", "triangle", 1, shape=(2,))))
    w = ex.omega(x, -0.5)
    assert np.isclose(w((-0.5, 0.0)), 1.0, atol=1e-8)
    assert np.isclose(w((-0.5, 0.5)), 0.5)
    assert np.isclose(w((0.0, 0.0)), 0.5)
    assert w((-2.0, 0.0)) < 1e-12
    w2 = ex.goal_a2_weight(x)
    assert np.isclose(w2((0.0, 0.125)), 0.5 * np.tanh(5) + 0.5)
    assert np.isclose(w2((0.0, 0.375)), 0.5) and np.isclose(w2((0.0, -0.125)), 0.5)
    assert float(ex.bar_gap(x)) == 0.005


@pytest.mark.mpi
def test_goal_bar_integrates_over_b():
    msh, tags = ex.bar_2d_mesh(MPI.COMM_WORLD, 4, 16)
    m = _goal_context(msh, tags, degree=2, material=ex.BAR_MATERIAL)
    u = ufl.as_vector((m.x[0], 2 * m.x[1]))  # grad u : grad u = 5
    assert np.isclose(_assemble(ex.goal_bar()(u, None, m), msh.comm), 5 * 0.05**2, rtol=1e-12)
    f = ex.bar_body_force(m.x)
    v = ufl.as_vector((1.0, 1.0))
    assert np.isclose(_assemble(ufl.inner(f, v) * m.dx, msh.comm), 0.5 * 0.05 * 0.2, rtol=1e-12)


@pytest.mark.mpi
def test_goal_obstacle_integrates_over_b_and_gamma_c():
    msh, tags = ex.obstacle_3d_mesh(MPI.COMM_WORLD, (2, 8, 8))
    m = _goal_context(msh, tags, degree=1, material=ex.OBSTACLE_MATERIAL)
    m.sigma = lambda u: 2.0 * ufl.Identity(3)  # sigma : sigma = 12, to check the region B
    lam = fem.Constant(msh, 3.0)
    value = _assemble(ex.goal_obstacle()(None, lam, m), msh.comm)
    assert np.isclose(value, 1e-3 * 12 * 0.25 * 0.25**2 + 3.0 * 0.25, rtol=1e-12)


@pytest.mark.mpi
def test_goal_a2_weight_integral():
    """goal_a2 with lam = 1 integrates the weight over Gamma_C = {0} x [-1, 1]."""
    msh, tags = ex.analytic_2d_mesh(MPI.COMM_WORLD, 4, 32)
    m = _goal_context(msh, tags, degree=10)
    value = _assemble(ex.goal_a2()(None, fem.Constant(msh, 1.0), m), msh.comm)
    ref = integrate.quad(
        lambda y: 0.5 * np.tanh(20 * (0.25 - abs(y - 0.125))) + 0.5,
        -1,
        1,
        points=[0.125],
        epsabs=0,
        epsrel=1e-12,
    )[0]
    assert np.isclose(value, ref, rtol=1e-6)
