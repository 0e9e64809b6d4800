r"""Where the master surface lies along each slave facet's normal: the mortar rule of a pair.

Two bodies in contact, small sliding in the reference configuration (:class:`~dwr_signorini.pairs.
ContactPair`). A slave point x of a facet F with outward unit normal n_F meets the master surface
at Pi(x) = x + g(x) n_F: g is the gap of x (negative where the bodies overlap), Pi(x) the master
point whose displacement the slave point is compared with.

**The search (which master point is x's partner).** The line x + t n_F meets the master surface
at several points in general (a closed master surface is crossed twice, a wavy one many times).
A crossing counts only if

* the master facet G crossed faces F (n_G . n_F < 0: the ray enters the master body there), and
* it lies in front of x (t >= 0), or behind x by at most the *penetration window* w_F
  (t >= -w_F; w_F is of the order of the local mesh size, settable per pair, see
  :class:`~dwr_signorini.pairs.ContactPair`);

and the partner is the first of those crossings along the ray (the smallest such t): the ray's
entry point into the master body, as for the rigid obstacles of :mod:`~dwr_signorini.obstacles`
(whose convex solids the line enters once, so that no window is needed there). Facets on the far
side of the master body, or a master surface behind the slave one by more than w_F, are no
partners; a point without partner is *uncovered* (the master is not there).

**The rule.** On a piece of F whose points have their partner in one master facet G, Pi is affine
(both facets are flat), so a master function of degree k composed with Pi is a polynomial of
degree k there. The rule cuts F into such pieces (2D: the intervals between the projections of the
master facets' ends onto F; 3D: each master facet projected onto F's plane along n_F and clipped
against F, minus the projections of the master facets in front of it, as convex polygons cut into
triangles) and puts on each a Gauss rule of degree 2k: integrals over F of a slave polynomial of
degree k times (v o Pi), v of degree k on the master mesh, are then exact, and so is the
transmission of a uniform pressure (the contact patch test). Quadrilateral facets (hexahedra)
must be planar; their bilinear maps make theta and v o Pi rational on a piece, integrated by a
rule of degree 2k + :data:`NONAFFINE_EXTRA_DEGREE` (to round-off in the patch test). The window
is decided per piece, at its centre. The weights of the pieces of F sum to the measure of its
covered part.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import basix
import numpy as np

__all__ = [
    "FacetBasis", "FacetMap", "MortarRule", "bilinear", "check_planar", "entry", "facet_normals",
    "facet_reach", "in_shadow", "mortar_rule", "piece_rule", "tabulate", "warp",
]

#: Relative size below which a piece of a slave facet is dropped (a touching corner).
_PIECE_TOL = 1e-10
#: Relative uncovered measure below which a facet counts as covered (the rule drops pieces of
#: relative size :data:`_PIECE_TOL`).
_COVERED_TOL = 1e-9
#: The degree added to the rule where a side has quadrilateral facets: their maps are bilinear,
#: so theta and v o Pi are rational on a piece (measured on the hexahedral patch test with
#: trapezoid-like faces: lambda to 1.5e-5, 6e-8, 4e-10, 3e-14 with 0, 2, 4, 8 added).
NONAFFINE_EXTRA_DEGREE = 8


@dataclass(frozen=True)
class MortarRule:
    """The quadrature points of a mortar rule on the slave facets.

    Attributes:
        facet: The slave facet of each point (an index into the slave facets given).
        points: The points x_q on the slave facets, shape (q, gdim).
        weights: Their weights (lengths or areas of the pieces times the Gauss weights).
        master: The master facet each point's ray meets (an index into the master facets).
        gap: g(x_q): the distance from x_q along n_F to the master facet.
    """

    facet: np.ndarray
    points: np.ndarray
    weights: np.ndarray
    master: np.ndarray
    gap: np.ndarray


def entry(t: np.ndarray, window: float) -> int:
    """The partner among a ray's crossings of facing master facets (module docstring).

    Args:
        t: The ray parameters of the crossings (x + t n_F on the master facet).
        window: The penetration window w_F >= 0.

    Returns:
        The index of the smallest t >= -window, or -1 if there is none.
    """
    ok = np.flatnonzero(t >= -window)
    return int(ok[np.argmin(t[ok])]) if len(ok) else -1


def facet_normals(vertices: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """Outward unit normals of flat facets.

    Args:
        vertices: The facets' vertices, shape (m, nv, gdim), in dolfinx's reference order
            (a quadrilateral's are 0, 1, 3, 2 around it).
        inside: A point inside each facet's cell, shape (m, gdim) (orients the normal).

    Returns:
        The unit normals, shape (m, gdim), pointing away from ``inside``.
    """
    gdim = vertices.shape[2]
    if gdim == 2:
        t = vertices[:, 1] - vertices[:, 0]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    elif vertices.shape[1] == 3:
        n = np.cross(vertices[:, 1] - vertices[:, 0], vertices[:, 2] - vertices[:, 0])
    else:  # the quadrilateral's diagonals
        n = np.cross(vertices[:, 3] - vertices[:, 0], vertices[:, 2] - vertices[:, 1])
    n /= np.linalg.norm(n, axis=1)[:, None]
    outward = np.einsum("ij,ij->i", vertices.mean(axis=1) - inside, n)
    return n * np.where(outward < 0.0, -1.0, 1.0)[:, None]


def mortar_rule(
    slave: np.ndarray,
    slave_normals: np.ndarray,
    master: np.ndarray,
    master_normals: np.ndarray,
    degree: int | None,
    window: np.ndarray | float,
) -> MortarRule:
    """The mortar rule of degree ``degree`` on the slave facets (module docstring).

    Args:
        slave: The slave facets' vertices, shape (m_s, nv, gdim).
        slave_normals: Their outward unit normals.
        master: The master facets' vertices, shape (m_m, nv, gdim).
        master_normals: Their outward unit normals.
        degree: The polynomial degree integrated exactly on each piece; None: the pieces
            (:func:`piece_rule`, placed on with :func:`~dwr_signorini.clipping.place`).
        window: The penetration window w_F of each slave facet (or one for all), >= 0.

    Returns:
        The :class:`MortarRule`.

    Raises:
        ValueError: Warped quadrilateral facets (:func:`check_planar`).
    """
    gdim = slave.shape[2]
    check_planar(max(warp(slave), warp(master)))
    pieces = _pieces_2d if gdim == 2 else _pieces_3d
    rule = piece_rule(gdim - 1, degree, bilinear(slave, master))
    windows = np.broadcast_to(np.asarray(window, dtype=float), (len(slave),))
    out: list[list[np.ndarray]] = [[], [], [], [], []]
    # bounding spheres: a master facet whose sphere's shadow along n misses F's cannot meet F
    centres, reach = facet_reach(master)
    slave_centres, slave_reach = facet_reach(slave)
    for i in range(len(slave)):
        n = slave_normals[i]
        near = np.flatnonzero(in_shadow(centres, reach, master_normals, slave_centres[i], n,
                                        slave_reach[i], windows[i]))
        if len(near) == 0:
            continue
        found = pieces(slave[i], n, master[near], master_normals[near], rule, windows[i])
        for x, w, c in found:
            g = int(near[c])
            k = len(w)
            out[0].append(np.full(k, i, dtype=np.int64))
            out[1].append(x)
            out[2].append(w)
            out[3].append(np.full(k, g, dtype=np.int64))
            out[4].append(_ray(x, n, master[g, 0], master_normals[g]))
    if not out[0]:
        empty = np.zeros(0)
        return MortarRule(empty.astype(np.int64), np.zeros((0, gdim)), empty,
                          empty.astype(np.int64), empty)
    return MortarRule(*(np.concatenate(a) for a in out))


def facet_reach(facets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centres of facets (m, nv, gdim) and the largest distance of a vertex from its centre."""
    centres = facets.mean(axis=1)
    return centres, np.linalg.norm(facets - centres[:, None], axis=2).max(axis=1) if len(
        facets) else np.zeros(0)


def in_shadow(
    centres: np.ndarray, reach: np.ndarray, normals: np.ndarray, centre: np.ndarray,
    n: np.ndarray, slave_reach: float, window: float,
) -> np.ndarray:
    """Which master facets may meet a slave facet's rays (the rule looks at no others).

    A master facet (bounding sphere: ``centres``, ``reach``) that faces the slave facet (centre
    ``centre``, normal ``n``, reach ``slave_reach``), whose sphere's shadow along n meets the
    facet's, and which is not wholly behind the window.

    Returns:
        A boolean mask over the master facets.
    """
    d = centres - centre
    along = d @ n
    lateral = np.linalg.norm(d - np.outer(along, n), axis=1)
    return ((normals @ n < 0.0)
            & (lateral <= (1.0 + 1e-9) * (reach + slave_reach))
            & (along >= -(window + reach + slave_reach)))


def _ray(x: np.ndarray, n: np.ndarray, p0: np.ndarray, nm: np.ndarray) -> np.ndarray:
    """The ray parameter t of x + t n on the plane through p0 with normal nm."""
    return ((p0 - x) @ nm) / (n @ nm)


def bilinear(slave: np.ndarray, master: np.ndarray) -> bool:
    """Whether a side's facets (m, nv, gdim) are quadrilaterals (bilinear maps)."""
    gdim = slave.shape[2]
    return slave.shape[1] != gdim or master.shape[1] != gdim


def piece_rule(
    fdim: int, degree: int | None, quadrilaterals: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """The reference rule put on each simplex of a piece (a triangle of its fan, 2D: a segment).

    Args:
        fdim: The facets' dimension.
        degree: The Gauss rule's degree (plus :data:`NONAFFINE_EXTRA_DEGREE` on
            ``quadrilaterals``); None: the simplex's vertices, each with its share of the
            measure. A rule of those is the pieces themselves, independent of any degree, on
            which :func:`~dwr_signorini.clipping.place` puts the Gauss points of each degree.
        quadrilaterals: Whether a side has quadrilateral facets (:func:`bilinear`).

    Returns:
        The reference points and weights.
    """
    if degree is None:
        cell = basix.CellType.interval if fdim == 1 else basix.CellType.triangle
        vertices = basix.geometry(cell)
        return vertices, np.full(len(vertices), _REFERENCE_MEASURE[fdim] / len(vertices))
    return _reference_rule(fdim, degree + (NONAFFINE_EXTRA_DEGREE if quadrilaterals else 0))


def _reference_rule(fdim: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss points and weights of degree ``degree`` on [0, 1] (fdim 1) or the triangle."""
    cell = basix.CellType.interval if fdim == 1 else basix.CellType.triangle
    points, weights = basix.make_quadrature(cell, max(degree, 1))
    return points, weights


#: The measure of the reference interval and triangle.
_REFERENCE_MEASURE = {1: 1.0, 2: 0.5}


def _pieces_2d(
    F: np.ndarray, n: np.ndarray, M: np.ndarray, Mn: np.ndarray, rule: tuple, window: float
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The pieces of the slave segment F = [a, b]: (points, weights, master facet) each."""
    a, b = F[0], F[1]
    length = float(np.linalg.norm(b - a))
    tau = (b - a) / length
    facing = np.flatnonzero(Mn @ n < 0.0)
    if len(facing) == 0:
        return []
    s = ((M[facing] - a) @ tau) / length  # (c, 2): the master ends projected onto F
    lo, hi = s.min(axis=1), s.max(axis=1)
    keep = (hi > _PIECE_TOL) & (lo < 1.0 - _PIECE_TOL) & (hi - lo > _PIECE_TOL)
    facing, lo, hi = facing[keep], lo[keep], hi[keep]
    if len(facing) == 0:
        return []
    breaks = np.unique(np.clip(np.concatenate([lo, hi, [0.0, 1.0]]), 0.0, 1.0))
    # breaks closer than the tolerance are one (no sliver between two master facets is lost)
    breaks = breaks[np.r_[True, np.diff(breaks) > _PIECE_TOL]]
    breaks[-1] = 1.0
    points, weights = rule
    out = []
    for s0, s1 in pairwise(breaks):
        if s1 - s0 <= _PIECE_TOL:
            continue
        mid = 0.5 * (s0 + s1)
        cover = facing[(lo <= mid) & (mid <= hi)]
        if len(cover) == 0:
            continue
        x_mid = a + mid * length * tau
        t = np.einsum("ij,ij->i", M[cover, 0] - x_mid, Mn[cover]) / (Mn[cover] @ n)
        first = entry(t, window)
        if first < 0:
            continue
        s_q = s0 + (s1 - s0) * points[:, 0]
        out.append((a + np.outer(s_q * length, tau), weights * (s1 - s0) * length,
                    int(cover[first])))
    return out


def _polygon(F: np.ndarray) -> np.ndarray:
    """A facet's vertices in order around it (a quadrilateral's 0, 1, 3, 2)."""
    return F if len(F) == 3 else F[[0, 1, 3, 2]]


def _pieces_3d(
    F: np.ndarray, n: np.ndarray, M: np.ndarray, Mn: np.ndarray, rule: tuple, window: float
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The pieces of the slave facet F: its overlaps with the projected master facets.

    Each facing master facet G projected onto F's plane along n and clipped against F is a
    convex polygon; those whose centre lies behind the window are dropped, and from each of the
    others the polygons of the master facets in front of it (a smaller t where they overlap)
    are cut away: every point of F keeps its first crossing (:func:`entry`).
    """
    origin = F[0]
    e1 = F[1] - origin
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    frame = np.stack([e1, e2])

    def plane(points: np.ndarray) -> np.ndarray:
        return (points - origin) @ frame.T

    def t_at(g: int, xy: np.ndarray) -> float:
        return float(_ray(origin + xy @ frame, n, M[g, 0], Mn[g]))

    slave = _ccw(plane(_polygon(F)))
    facing = np.flatnonzero(Mn @ n < 0.0)
    if len(facing) == 0:
        return []
    proj = plane(M[facing])  # (c, nv, 2): along n onto F's plane
    box_lo, box_hi = slave.min(axis=0), slave.max(axis=0)
    keep = np.all(proj.max(axis=1) > box_lo, axis=1) & np.all(proj.min(axis=1) < box_hi, axis=1)
    area_F = _area(slave)
    found = []
    for c in np.flatnonzero(keep):
        g = int(facing[c])
        piece = _clip(_ccw(proj[c] if len(proj[c]) == 3 else proj[c][[0, 1, 3, 2]]), slave)
        if len(piece) < 3 or _area(piece) <= _PIECE_TOL * area_F:
            continue
        if t_at(g, piece.mean(axis=0)) >= -window:
            found.append((piece, g))
    out = []
    overlap = _overlaps([f[0] for f in found], area_F)
    for k, (piece, g) in enumerate(found):
        parts = [piece]
        for j in np.flatnonzero(overlap[k]):
            other, h = found[j]
            common = _clip(piece, other)
            if len(common) < 3 or _area(common) <= _PIECE_TOL * area_F:
                continue
            centre = common.mean(axis=0)
            t_k, t_j = t_at(g, centre), t_at(h, centre)
            if t_j < t_k or (t_j == t_k and j < k):  # ``other`` is crossed first there
                parts = [p for q in parts for p in _difference(q, other, area_F)]
        for p in parts:
            out.append(_fan(p, origin, frame, rule, area_F, g))
    return [o for o in out if o is not None]


def _fan(
    piece: np.ndarray, origin: np.ndarray, frame: np.ndarray, rule: tuple, area_F: float, g: int
) -> tuple[np.ndarray, np.ndarray, int] | None:
    """The Gauss points of a convex piece: a fan of triangles (piece[0], piece[k], piece[k+1])."""
    points, weights = rule
    b, c = piece[1:-1] - piece[0], piece[2:] - piece[0]
    area = 0.5 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
    keep = area > _PIECE_TOL * area_F
    if not np.any(keep):
        return None
    b, c, area = b[keep], c[keep], area[keep]
    xy = piece[0] + points[None, :, :1] * b[:, None] + points[None, :, 1:] * c[:, None]
    w = (2.0 * area)[:, None] * weights[None]
    return origin + xy.reshape(-1, 2) @ frame, w.ravel(), g


def _area(polygon: np.ndarray) -> float:
    """The signed area of a planar polygon (positive counter-clockwise)."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(x[:-1] @ y[1:] - y[:-1] @ x[1:] + x[-1] * y[0] - y[-1] * x[0])


def _ccw(polygon: np.ndarray) -> np.ndarray:
    """The polygon counter-clockwise."""
    return polygon if _area(polygon) >= 0.0 else polygon[::-1]


def _overlaps(pieces: list[np.ndarray], area_F: float) -> np.ndarray:
    """Which pairs of convex polygons (ccw) may overlap in more than an edge (separating axes).

    Args:
        pieces: The polygons, (n_k, 2) each.
        area_F: The slave facet's area (scales the tolerance).

    Returns:
        A symmetric boolean matrix (False on the diagonal).
    """
    k = len(pieces)
    if k < 2:
        return np.zeros((k, k), dtype=bool)
    size = max(len(p) for p in pieces)
    # padded with the last vertex: repeats change no projection's extent
    V = np.stack([np.concatenate([p, np.repeat(p[-1:], size - len(p), axis=0)]) for p in pieces])
    edges = np.roll(V, -1, axis=1) - V
    axes = np.stack([edges[..., 1], -edges[..., 0]], axis=2)  # (k, size, 2)
    length = np.linalg.norm(axes, axis=2)
    valid = length > 0.0
    axes = axes / np.where(valid, length, 1.0)[..., None]
    proj = np.einsum("iad,jvd->iajv", axes, V)  # piece j's vertices on piece i's axes
    lo, hi = proj.min(axis=3), proj.max(axis=3)  # (k, size, k)
    own_lo = np.einsum("iai->ia", lo)[:, :, None]
    own_hi = np.einsum("iai->ia", hi)[:, :, None]
    tol = 1e-9 * np.sqrt(area_F)
    apart = ((own_hi <= lo + tol) | (hi <= own_lo + tol)) & valid[:, :, None]
    separated = apart.any(axis=1)  # (i, j): an axis of i separates them
    out = ~(separated | separated.T)
    np.fill_diagonal(out, False)
    return out


def _half(subject: list, a: tuple, b: tuple) -> list:
    """Sutherland-Hodgman step: the part of ``subject`` left of the line a -> b."""
    ax, ay = a
    ex, ey = b[0] - ax, b[1] - ay
    side = [ex * (y - ay) - ey * (x - ax) for x, y in subject]
    new = []
    for j, (p, sp) in enumerate(zip(subject, side, strict=True)):
        q, sq = subject[(j + 1) % len(subject)], side[(j + 1) % len(subject)]
        if sp >= 0.0:
            new.append(p)
        if (sp >= 0.0) != (sq >= 0.0):
            t = sp / (sp - sq)
            new.append((p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t))
    return new


def _clip(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: the convex ``subject`` clipped by the convex ``clip`` (both ccw)."""
    out = [(float(x), float(y)) for x, y in subject]  # a few vertices: plain floats are faster
    corners = [(float(x), float(y)) for x, y in clip]
    for i, a in enumerate(corners):
        if not out:
            break
        out = _half(out, a, corners[(i + 1) % len(corners)])
    return np.array(out) if out else np.zeros((0, 2))


def _difference(p: np.ndarray, q: np.ndarray, area_F: float) -> list[np.ndarray]:
    """The convex ``p`` minus the convex ``q`` (both ccw), as convex polygons.

    p minus q is the union over the edges e_i of q of the parts of p outside e_i and inside
    e_0, ..., e_{i-1}: disjoint convex pieces.
    """
    out = []
    inside = [(float(x), float(y)) for x, y in p]
    corners = [(float(x), float(y)) for x, y in q]
    for i, a in enumerate(corners):
        if not inside:
            break
        b = corners[(i + 1) % len(corners)]
        outside = _half(inside, b, a)
        if len(outside) >= 3 and _area(np.array(outside)) > _PIECE_TOL * area_F:
            out.append(np.array(outside))
        inside = _half(inside, a, b)
    return out


def warp(vertices: np.ndarray) -> float:
    """The largest out-of-plane distance of a quadrilateral facet's vertices over its diagonal.

    Args:
        vertices: Facets' vertices, shape (m, nv, gdim) (0 for intervals and triangles).

    Returns:
        The relative warp (0 for planar facets).
    """
    if vertices.shape[1] != 4 or len(vertices) == 0:
        return 0.0
    n = np.cross(vertices[:, 3] - vertices[:, 0], vertices[:, 2] - vertices[:, 1])
    n /= np.linalg.norm(n, axis=1)[:, None]
    off = np.abs(np.einsum("fvd,fd->fv", vertices - vertices[:, :1], n)).max(axis=1)
    return float((off / np.linalg.norm(vertices[:, 3] - vertices[:, 0], axis=1)).max())


def check_planar(relative_warp: float) -> None:
    """Refuse warped quadrilateral facets (the rule cuts facets as flat polygons).

    Raises:
        ValueError: ``relative_warp`` (of :func:`warp`) above 1e-8.
    """
    if relative_warp > 1e-8:
        raise ValueError(
            "contact pairs need planar quadrilateral facets: a hexahedron's face on a contact "
            f"pair is warped (out of its plane by {relative_warp:.3g} of its diagonal); use "
            "flat faces or tetrahedra there"
        )


class FacetMap:
    r"""The coordinate map of P1 / Q1 facets: x(X) = sum_i phi_i(X) x_i on the reference facet.

    An interval or a triangle maps affinely; a quadrilateral bilinearly, with a Jacobian that
    varies over it (a trapezoid). Its pull-back is Newton's method on x(X) = x (one step for an
    affine facet). A quadrilateral must be planar: the mortar rule cuts facets as flat polygons.

    Args:
        vertices: The facets' vertices, shape (m, nv, gdim), in dolfinx's reference order.

    Raises:
        ValueError: A quadrilateral facet that is not planar (a warped face).
    """

    def __init__(self, vertices: np.ndarray) -> None:
        self.vertices = vertices
        _, nv, gdim = vertices.shape
        cell = {2: basix.CellType.interval, 3: basix.CellType.triangle,
                4: basix.CellType.quadrilateral}[nv]
        self.cell = cell
        self.element = basix.create_element(basix.ElementFamily.P, cell, 1,
                                            basix.LagrangeVariant.equispaced)
        self.affine = nv == gdim
        self._inverse: np.ndarray | None = None  # (A^T A)^{-1} A^T per affine facet, once
        check_planar(warp(vertices))

    def push(self, facet: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x(X) and the Jacobian dx/dX, shape (q, gdim) and (q, gdim, fdim), at X on ``facet``."""
        gdim = self.vertices.shape[2]
        if len(X) == 0:  # (basix aborts on no points)
            return np.zeros((0, gdim)), np.zeros((0, gdim, X.shape[1]))
        tab = self.element.tabulate(1, np.ascontiguousarray(X, dtype=np.float64))[..., 0]
        nodes = self.vertices[facet]  # (q, nv, gdim)
        x = np.einsum("qi,qid->qd", tab[0], nodes)
        J = np.stack([np.einsum("qi,qid->qd", tab[1 + k], nodes) for k in range(X.shape[1])],
                     axis=2)
        return x, J

    def pull(self, facet: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The reference points X with x(X) = x on ``facet`` (x on the facets' planes).

        An affine facet: X = (A^T A)^{-1} A^T (x - x_0), A's columns x_k - x_0 (vertex k at
        e_k on the reference facet), the matrix formed once per facet; a quadrilateral:
        Newton's method.
        """
        if self.affine:
            if self._inverse is None:
                A = np.swapaxes(self.vertices[:, 1:] - self.vertices[:, :1], 1, 2)
                At = np.swapaxes(A, 1, 2)
                self._inverse = np.linalg.solve(At @ A, At) if len(A) else At
            return np.einsum("qkd,qd->qk", self._inverse[facet], x - self.vertices[facet, 0])
        fdim = 2
        X = np.full((len(x), fdim), 1.0 / (fdim + 1.0))
        for _ in range(20):
            y, J = self.push(facet, X)
            step = np.linalg.solve(np.einsum("qdk,qdl->qkl", J, J),
                                   np.einsum("qdk,qd->qk", J, x - y)[..., None])[..., 0]
            X = X + step
            if np.max(np.abs(step), initial=0.0) < 1e-14:
                break
        return X

    def quadrature(self, degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A Gauss rule on every facet: (facet, X, x, weights with |det J|), q points each."""
        points, weights = basix.make_quadrature(self.cell, degree + (0 if self.affine else 2))
        m, q = len(self.vertices), len(weights)
        facet = np.repeat(np.arange(m), q)
        X = np.tile(points, (m, 1))
        x, J = self.push(facet, X)
        det = np.sqrt(np.abs(np.linalg.det(np.einsum("qdk,qdl->qkl", J, J))))
        return facet, X, x, np.tile(weights, m) * det


class FacetBasis:
    """A scalar basix element's basis on the slave facets, pulled back with their coordinate map.

    theta_a at the rule's points, and on a Gauss rule over each whole facet (``full_*``), the
    mass matrices, int_F theta_a, |F| and the covered measure of each facet.
    """

    def __init__(self, element: Any, facets: FacetMap, rule: MortarRule) -> None:
        num = len(facets.vertices)
        self.theta = tabulate(element, facets.pull(rule.facet, rule.points)) if len(
            rule.facet) else np.zeros((0, element.dim))
        f, X, x, w = facets.quadrature(2 * max(element.degree, 1))
        self.full_facet, self.full_points, self.full_weights = f, x, w
        self.full_theta = tabulate(element, X) if len(f) else np.zeros((0, element.dim))
        self.mass = np.zeros((num, element.dim, element.dim))
        np.add.at(self.mass, f, np.einsum("q,qa,qb->qab", w, self.full_theta, self.full_theta))
        self.integrals = np.zeros((num, element.dim))
        np.add.at(self.integrals, f, w[:, None] * self.full_theta)
        #: |F| and the measure of its covered part
        self.measure = self.integrals.sum(axis=1)
        self.covered = np.zeros(num)
        np.add.at(self.covered, rule.facet, rule.weights)
        #: facets covered fully (up to the pieces the rule drops), and in part (P and the gap
        #: project onto constants there)
        self.full = self.covered >= (1.0 - _COVERED_TOL) * self.measure
        self.partial = (self.covered > 0.0) & ~self.full


def tabulate(element: Any, X: np.ndarray) -> np.ndarray:
    """A scalar basix element's basis values at the reference points X, shape (points, dofs)."""
    values = element.tabulate(0, np.ascontiguousarray(X, dtype=np.float64))
    return values.reshape(values.shape[1], values.shape[2])
