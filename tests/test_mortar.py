"""The mortar rule of a contact pair (``dwr_signorini.mortar``), pure numpy, against exact values.

* Exactness: on random non-matching meshes of two parallel lines (2D) or planes (3D), the rule of
  degree 2k integrates theta (v o Pi) exactly for polynomials theta, v of degree k (Pi is a
  translation along the slave normal there): against a high-order Gauss rule on each slave facet.
* Coverage: the weights of each slave facet sum to the measure of its covered part (the whole
  facet, or the analytic overlap with a smaller master).
* The search: master facets that face away, or lie behind the slave facet by more than the
  window, are no partners; of two facing layers the first along the ray is; steep masters (up to
  80 degrees to the slave) cover the slave fully, with the analytic gap at every point.
* The facets' coordinate map: a planar trapezoid's pull-back inverts its push-forward, its Gauss
  rule sums to its area, and a warped quadrilateral is refused.
"""

from __future__ import annotations

import numpy as np
import pytest

from dwr_signorini.mortar import FacetMap, entry, mortar_rule

RNG = np.random.default_rng(20261207)


def _polyline(breaks: np.ndarray, y: float) -> np.ndarray:
    """Segments [b_i, b_{i+1}] x {y}, shape (m, 2, 2)."""
    return np.stack([np.stack([breaks[:-1], np.full(len(breaks) - 1, y)], axis=1),
                     np.stack([breaks[1:], np.full(len(breaks) - 1, y)], axis=1)], axis=1)


def _random_breaks(n: int, lo: float = 0.0, hi: float = 1.0) -> np.ndarray:
    inner = np.sort(RNG.uniform(lo, hi, n - 1))
    return np.concatenate([[lo], inner, [hi]])


def _triangles(n: int, z: float, lo=0.0, hi=1.0, jitter=0.3) -> np.ndarray:
    """A perturbed n x n grid of [lo, hi]^2 at height z cut into triangles, shape (2n^2, 3, 3)."""
    t = np.linspace(lo, hi, n + 1)
    X, Y = np.meshgrid(t, t, indexing="ij")
    h = (hi - lo) / n
    inner = (slice(1, -1), slice(1, -1))
    X[inner] += RNG.uniform(-jitter, jitter, X[inner].shape) * h
    Y[inner] += RNG.uniform(-jitter, jitter, Y[inner].shape) * h
    P = np.stack([X, Y, np.full_like(X, z)], axis=2)
    out = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = P[i, j], P[i + 1, j], P[i, j + 1], P[i + 1, j + 1]
            out += [[a, b, d], [a, d, c]] if (i + j) % 2 else [[a, b, c], [b, d, c]]
    return np.array(out)


def _normals(facets: np.ndarray, sign: float) -> np.ndarray:
    n = np.zeros((len(facets), facets.shape[2]))
    n[:, -1] = sign
    return n


def _area(tri: np.ndarray) -> np.ndarray:
    return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def _per_facet(rule, values: np.ndarray, m: int) -> np.ndarray:
    out = np.zeros(m)
    np.add.at(out, rule.facet, values)
    return out


# -- exactness and coverage -----------------------------------------------------------------------


@pytest.mark.parametrize("k", [1, 2])
def test_rule_2d_integrates_slave_times_master_polynomials_exactly(k):
    gap = 0.013
    slave = _polyline(_random_breaks(7), 0.0)
    master = _polyline(_random_breaks(11, -0.1, 1.2), gap)
    rule = mortar_rule(slave, _normals(slave, 1.0), master, _normals(master, -1.0), 2 * k, 0.1)
    assert np.allclose(rule.gap, gap, rtol=1e-13)
    # theta(x) v(Pi x) with theta = x^k and v(y) = (y0 - 0.3)^k + y0 (Pi x = x + gap e_y)
    x = rule.points[:, 0]
    found = _per_facet(rule, rule.weights * x**k * ((x - 0.3) ** k + x), len(slave))
    g, w = np.polynomial.legendre.leggauss(k + 2)
    a, b = slave[:, 0, 0], slave[:, 1, 0]
    xs = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * g[None]
    exact = 0.5 * (b - a) * ((xs**k * ((xs - 0.3) ** k + xs)) @ w)
    assert found == pytest.approx(exact, rel=1e-12, abs=1e-15)
    assert _per_facet(rule, rule.weights, len(slave)) == pytest.approx(b - a, rel=1e-12)


@pytest.mark.parametrize("k", [1, 2])
def test_rule_on_a_tilted_master_integrates_theta_times_v_of_pi_exactly(k):
    """A master plane z = h(x, y) = 0.02 + 0.3 x + 0.1 y over random triangles (slave flat):
    Pi x = (x, y, h) is affine, so theta(x) v(Pi x) with v(p) = (p_x - p_z)^k + p_y and theta of
    degree k is a polynomial of degree 2k, integrated exactly."""
    slave = _triangles(3, 0.0)
    master = _triangles(4, 0.0, -0.1, 1.1)
    h = lambda x, y: 0.02 + 0.3 * x + 0.1 * y  # noqa: E731
    master[..., 2] = h(master[..., 0], master[..., 1])
    normal = np.array([0.3, 0.1, -1.0]) / np.linalg.norm([0.3, 0.1, -1.0])
    rule = mortar_rule(slave, _normals(slave, 1.0), master, np.tile(normal, (len(master), 1)),
                       2 * k, 0.1)
    projected = rule.points + rule.gap[:, None] * np.array([0.0, 0.0, 1.0])
    assert projected[:, 2] == pytest.approx(h(projected[:, 0], projected[:, 1]), rel=1e-12)
    v = (projected[:, 0] - projected[:, 2]) ** k + projected[:, 1]
    found = _per_facet(rule, rule.weights * rule.points[:, 1] ** k * v, len(slave))
    import basix

    ref, wref = basix.make_quadrature(basix.CellType.triangle, 2 * k + 2)
    p = slave[:, None, 0] + ref[None, :, :1] * (slave[:, None, 1] - slave[:, None, 0]) \
        + ref[None, :, 1:] * (slave[:, None, 2] - slave[:, None, 0])
    X, Y = p[..., 0], p[..., 1]
    exact = 2 * _area(slave) * ((Y**k * ((X - h(X, Y)) ** k + Y)) @ wref)
    assert found == pytest.approx(exact, rel=1e-11)


@pytest.mark.parametrize("k", [1, 2])
def test_rule_3d_integrates_slave_times_master_polynomials_exactly(k):
    slave = _triangles(4, 0.0)
    master = _triangles(5, 0.02, -0.05, 1.05)
    rule = mortar_rule(slave, _normals(slave, 1.0), master, _normals(master, -1.0), 2 * k, 0.1)
    x, y = rule.points[:, 0], rule.points[:, 1]
    f = (x + 2 * y) ** k * ((x - y) ** k + y)  # theta of degree k times v o Pi of degree k
    found = _per_facet(rule, rule.weights * f, len(slave))
    import basix

    ref, wref = basix.make_quadrature(basix.CellType.triangle, 2 * k + 2)
    p = slave[:, None, 0] + ref[None, :, :1] * (slave[:, None, 1] - slave[:, None, 0]) \
        + ref[None, :, 1:] * (slave[:, None, 2] - slave[:, None, 0])
    X, Y = p[..., 0], p[..., 1]
    exact = 2 * _area(slave) * ((((X + 2 * Y) ** k) * ((X - Y) ** k + Y)) @ wref)
    assert found == pytest.approx(exact, rel=1e-11)
    assert _per_facet(rule, rule.weights, len(slave)) == pytest.approx(_area(slave), rel=1e-12)


def test_coverage_3d_is_the_overlap_with_a_smaller_master():
    """A master square [0.3, 0.7]^2: each slave facet's weights sum to its overlap (the
    clipped area, computed from a fine sampling-free formula: exact polygon clipping of the
    slave triangle by the square)."""
    slave = _triangles(3, 0.0)
    master = _triangles(2, 0.01, 0.3, 0.7, jitter=0.0)
    rule = mortar_rule(slave, _normals(slave, 1.0), master, _normals(master, -1.0), 2, 0.1)
    covered = _per_facet(rule, rule.weights, len(slave))
    from dwr_signorini.mortar import _area as polygon_area
    from dwr_signorini.mortar import _ccw, _clip

    square = np.array([[0.3, 0.3], [0.7, 0.3], [0.7, 0.7], [0.3, 0.7]])
    exact = [polygon_area(c) if len(c := _clip(_ccw(t[:, :2]), square)) >= 3 else 0.0
             for t in slave]
    assert covered == pytest.approx(exact, abs=1e-14)
    assert covered.sum() == pytest.approx(0.16, rel=1e-12)


# -- the search -----------------------------------------------------------------------------------


def test_entry_is_the_first_crossing_within_the_window():
    t = np.array([0.5, -0.05, -2.0, 3.0])
    assert entry(t, 0.1) == 1
    assert entry(t, 0.01) == 0
    assert entry(np.array([-2.0]), 0.1) == -1


@pytest.mark.parametrize("dim", [2, 3])
def test_faces_behind_the_window_or_facing_away_are_ignored(dim):
    """The far side of a master body 2 behind the slave (it faces the slave's normal the right
    way) is a partner only with a window larger than 2; a master facing away never is."""
    if dim == 2:
        slave = _polyline(_random_breaks(4), 0.0)
        master_at = lambda z: _polyline(_random_breaks(5, -0.1, 1.1), z)  # noqa: E731
        measure = slave[:, 1, 0] - slave[:, 0, 0]
    else:
        slave = _triangles(2, 0.0)
        master_at = lambda z: _triangles(3, z, -0.1, 1.1)  # noqa: E731
        measure = _area(slave)
    n = _normals(slave, 1.0)
    behind = master_at(-2.0)
    for window, found in ((0.5, 0.0), (2.5, 1.0)):
        rule = mortar_rule(slave, n, behind, _normals(behind, -1.0), 2, window)
        assert _per_facet(rule, rule.weights, len(slave)) == pytest.approx(found * measure)
        assert np.allclose(rule.gap, -2.0)
    ahead = master_at(0.3)
    rule = mortar_rule(slave, n, ahead, _normals(ahead, 1.0), 2, 10.0)  # facing away
    assert len(rule.weights) == 0


@pytest.mark.parametrize("dim", [2, 3])
def test_of_two_facing_layers_the_first_along_the_ray_is_the_partner(dim):
    """A layer at 0.4 over half of the slave, a layer at 0.9 over all of it: the near layer
    where it is, the far one elsewhere, each slave facet covered once."""
    if dim == 2:
        slave = _polyline(_random_breaks(5), 0.0)
        near = _polyline(_random_breaks(3, -0.1, 0.55), 0.4)
        far = _polyline(_random_breaks(6, -0.1, 1.1), 0.9)
        measure = slave[:, 1, 0] - slave[:, 0, 0]
        in_near = lambda p: p[:, 0] < 0.55  # noqa: E731
    else:
        slave = _triangles(3, 0.0)
        near = _triangles(2, 0.4, -0.1, 0.55)
        far = _triangles(3, 0.9, -0.1, 1.1)
        measure = _area(slave)
        in_near = lambda p: (p[:, 0] < 0.55) & (p[:, 1] < 0.55)  # noqa: E731
    master = np.concatenate([far, near])  # the far layer first: order does not matter
    rule = mortar_rule(slave, _normals(slave, 1.0), master, _normals(master, -1.0), 2, 0.1)
    assert _per_facet(rule, rule.weights, len(slave)) == pytest.approx(measure, rel=1e-11)
    expect = np.where(in_near(rule.points), 0.4, 0.9)
    assert rule.gap == pytest.approx(expect, rel=1e-12)


@pytest.mark.parametrize("degrees", [30, 60, 80])
def test_steep_master_covers_the_slave_with_the_exact_gap(degrees):
    """A master plane z = 0.2 + tan(a) (x + 0.1) in front of the flat slave (slopes up to
    80 degrees): every slave facet fully covered, the gap the plane's height at each point."""
    slope = np.tan(np.radians(degrees))
    slave = _triangles(4, 0.0)
    master = _triangles(12, 0.0, -0.1, 1.1)
    master[..., 2] = 0.2 + slope * (master[..., 0] + 0.1)
    normal = np.array([slope, 0.0, -1.0]) / np.hypot(slope, 1.0)
    rule = mortar_rule(slave, _normals(slave, 1.0), master,
                       np.tile(normal, (len(master), 1)), 2, 0.1)
    assert _per_facet(rule, rule.weights, len(slave)) == pytest.approx(_area(slave), rel=1e-11)
    height = 0.2 + slope * (rule.points[:, 0] + 0.1)
    assert rule.gap == pytest.approx(height, rel=1e-11)


# -- the facets' coordinate map -------------------------------------------------------------------


def test_trapezoid_map_pull_back_and_area():
    """A planar trapezoid in 3D (dolfinx order 0, 1, 3, 2 around it): pull(push(X)) = X, the
    Gauss rule sums to its area 0.5 (1 + 0.5) 1, and a warped quadrilateral raises."""
    quad = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.25, 1.0, 1.0], [0.75, 1.0, 1.0]]])
    rot = np.linalg.qr(RNG.normal(size=(3, 3)))[0]
    facets = FacetMap(quad @ rot.T)
    X = RNG.uniform(0.0, 1.0, (20, 2))
    which = np.zeros(20, dtype=np.int64)
    x, _ = facets.push(which, X)
    assert facets.pull(which, x) == pytest.approx(X, abs=1e-12)
    _, _, _, w = facets.quadrature(2)
    assert w.sum() == pytest.approx(0.75, rel=1e-13)
    warped = quad.copy()
    warped[0, 3, 2] += 0.01
    with pytest.raises(ValueError, match="planar quadrilateral facets"):
        FacetMap(warped)
