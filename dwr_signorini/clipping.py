"""The 3D mortar rule of many slave facets at once: numpy over all candidate pairs.

:func:`~dwr_signorini.mortar.mortar_rule` cuts each slave facet F into its pieces in a Python
loop (:func:`~dwr_signorini.mortar._pieces_3d`): the facing master facets projected onto F's
plane along n_F and clipped against F (Sutherland-Hodgman), those behind the window dropped,
and from each piece the pieces crossed first cut away where two of them overlap.
:func:`batched_rule` does the same for all (slave facet, candidate master facet) pairs at once,
on polygons padded to a fixed number of vertices: the clipping, the areas, the window and the
separating-axes test of the pieces of each facet. Where no two pieces of a facet overlap (every
facet of a surface whose projected master facets tile it) the pieces are the rule's, and their
Gauss points (a fan of triangles each) are placed at once; a facet whose pieces overlap (two
master layers) is left to the per-facet rule. The points, their order and the pieces are the
per-facet rule's (the same operations in the same order).

:func:`place` puts the Gauss points of any degree on the pieces of a rule of degree None (the
search once per mesh, each degree's rule from its pieces).
"""

from __future__ import annotations

import numpy as np

from .mortar import (
    _PIECE_TOL,
    _REFERENCE_MEASURE,
    MortarRule,
    bilinear,
    facet_reach,
    piece_rule,
)

__all__ = ["batched_rule", "place", "rays"]


def _ring(facets: np.ndarray) -> np.ndarray:
    """Facets' vertices in order around them (a quadrilateral's 0, 1, 3, 2)."""
    return facets if facets.shape[1] == 3 else facets[:, [0, 1, 3, 2]]


def _shoelace(poly: np.ndarray) -> np.ndarray:
    """Signed areas of polygons (k, nv, 2), padded with repeats of their last vertex."""
    x, y = poly[..., 0], poly[..., 1]
    return 0.5 * (np.einsum("kv,kv->k", x, np.roll(y, -1, axis=1))
                  - np.einsum("kv,kv->k", y, np.roll(x, -1, axis=1)))


def _pad(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Each polygon's vertices beyond its ``count`` replaced by its last one."""
    size = poly.shape[1]
    last = np.maximum(count - 1, 0)
    index = np.minimum(np.arange(size)[None], last[:, None])
    return np.take_along_axis(poly, index[..., None], axis=1)


def _half(poly: np.ndarray, count: np.ndarray, a: np.ndarray, b: np.ndarray):
    """One Sutherland-Hodgman step for all polygons: the part left of the line a -> b.

    The vertices kept and the crossings, in the order of the per-facet step
    (:func:`~dwr_signorini.mortar._half`). The polygons are closed: vertex ``count`` repeats
    vertex 0 (so each vertex's successor is the next slot), the result's likewise.
    """
    k, size = poly.shape[0], poly.shape[1] - 1
    e = b - a
    side = e[:, None, 0] * (poly[..., 1] - a[:, None, 1]) - e[:, None, 1] * (
        poly[..., 0] - a[:, None, 0])
    p, q, sp, sq = poly[:, :-1], poly[:, 1:], side[:, :-1], side[:, 1:]
    valid = np.arange(size)[None] < count[:, None]
    inside = sp >= 0.0
    keep = valid & inside
    cross = valid & (inside != (sq >= 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(cross, sp / np.where(cross, sp - sq, 1.0), 0.0)
    meet = p + (q - p) * t[..., None]
    slots = np.stack([p, meet], axis=2).reshape(k, 2 * size, 2)
    used = np.stack([keep, cross], axis=2).reshape(k, 2 * size)
    # the used slots moved to the front, in order, then vertex 0 again (the rest zero)
    row, col = np.nonzero(used)
    out = np.zeros((k, 2 * size + 1, 2))
    out[row, (np.cumsum(used, axis=1) - 1)[row, col]] = slots[row, col]
    new = used.sum(axis=1)
    out[np.arange(k), new] = out[:, 0]
    return out, new


def _clip(subject: np.ndarray, count: np.ndarray, clip: np.ndarray):
    """Convex ``subject`` polygons (padded) clipped by convex ``clip`` ones (ccw, one size).

    Returns:
        The pieces (padded) and their numbers of vertices.
    """
    m, size = clip.shape[1], subject.shape[1]
    subject = np.concatenate([subject, subject[:, :1]], axis=1)
    subject[np.arange(len(count)), count] = subject[:, 0]  # closed (:func:`_half`)
    for i in range(m):
        subject, count = _half(subject, count, clip[:, i], clip[:, (i + 1) % m])
        subject = subject[:, :size + i + 2]  # each half-plane adds at most one vertex
    return subject[:, :-1], count


def _pairs_within(group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All pairs (a < b) of indices with the same (sorted) ``group``."""
    n = len(group)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    end = np.searchsorted(group, group, side="right")
    counts = end - np.arange(n) - 1
    a = np.repeat(np.arange(n), counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    return a, a + 1 + (np.arange(len(a)) - start)


def _overlap(poly: np.ndarray, a: np.ndarray, b: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """Whether the padded convex polygons a and b may overlap in more than an edge.

    The separating-axes test of :func:`~dwr_signorini.mortar._overlaps`, pair by pair; the
    axes of each polygon and its own extent on them are computed once per polygon.
    """
    edges = np.roll(poly, -1, axis=1) - poly
    ax, ay = edges[..., 1], -edges[..., 0]  # (k, a)
    length = np.hypot(ax, ay)
    valid = length > 0.0
    ax, ay = ax / np.where(valid, length, 1.0), ay / np.where(valid, length, 1.0)
    own = _extent(poly, ax, ay)

    def separated(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        lo, hi = _extent(poly[q], ax[p], ay[p])
        own_lo, own_hi = own[0][p], own[1][p]
        apart = ((own_hi <= lo + tol[:, None]) | (hi <= own_lo + tol[:, None])) & valid[p]
        return apart.any(axis=1)

    return ~(separated(a, b) | separated(b, a))


def _extent(r: np.ndarray, ax: np.ndarray, ay: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least and largest projections of the vertices of polygons r (k, v, 2) on axes (k, a)."""
    lo = hi = ax * r[:, None, 0, 0] + ay * r[:, None, 0, 1]
    for v in range(1, r.shape[1]):
        on = ax * r[:, None, v, 0] + ay * r[:, None, v, 1]
        lo, hi = np.minimum(lo, on), np.maximum(hi, on)
    return lo, hi


def batched_rule(
    slave: np.ndarray, slave_normals: np.ndarray, master: np.ndarray,
    master_normals: np.ndarray, degree: int | None, windows: np.ndarray, facet: np.ndarray,
    candidate: np.ndarray,
) -> tuple[MortarRule, np.ndarray]:
    """The 3D mortar rule of every slave facet against its candidates (module docstring).

    Args:
        slave: The slave facets' vertices, shape (m_s, nv, 3).
        slave_normals: Their outward unit normals.
        master: The master facets' vertices, shape (m_m, nv, 3).
        master_normals: Their outward unit normals.
        degree: The polynomial degree integrated exactly on each piece (None: the pieces,
            :func:`~dwr_signorini.mortar.piece_rule`).
        windows: The penetration window of each slave facet.
        facet: The slave facet of each candidate pair, sorted.
        candidate: The master facet of each pair, each facet's in the order it meets them.

    Returns:
        The rule of the facets whose pieces do not overlap (``facet`` indexing ``slave``,
        ``master`` indexing ``master``, in the order of the pairs), and the facets whose pieces
        overlap (to the per-facet rule).
    """
    points, weights = piece_rule(2, degree, bilinear(slave, master))
    n = slave_normals
    e1 = slave[:, 1] - slave[:, 0]
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    frame = np.stack([e1, np.cross(n, e1)], axis=1)  # (m_s, 2, 3)
    origin = slave[:, 0]
    ring = np.einsum("fvd,fkd->fvk", _ring(slave) - origin[:, None], frame)
    ring = np.where((_shoelace(ring) >= 0.0)[:, None, None], ring, ring[:, ::-1])
    area_F = _shoelace(ring)
    # the per-facet rule's filters: in the shadow, facing, the boxes meet
    centres, reach = facet_reach(master)
    slave_centres, slave_reach = facet_reach(slave)
    nf = n[facet]
    d = centres[candidate] - slave_centres[facet]
    along = _dot(d, nf)
    lateral = np.linalg.norm(d - along[:, None] * nf, axis=1)
    s_reach = reach[candidate] + slave_reach[facet]
    facing = _dot(master_normals[candidate], nf) < 0.0
    ok = facing & (lateral <= (1.0 + 1e-9) * s_reach) & (along >= -(windows[facet] + s_reach))
    facet, candidate = facet[ok], candidate[ok]
    relative, axes = _ring(master[candidate]) - origin[facet][:, None], frame[facet]
    proj = np.stack([_dot(relative, axes[:, None, k]) for k in range(2)], axis=2)
    lo, hi = ring.min(axis=1)[facet], ring.max(axis=1)[facet]
    ok = np.all(proj.max(axis=1) > lo, axis=1) & np.all(proj.min(axis=1) < hi, axis=1)
    facet, candidate, proj = facet[ok], candidate[ok], proj[ok]
    proj = np.where((_shoelace(proj) >= 0.0)[:, None, None], proj, proj[:, ::-1])
    piece, count = _clip(proj, np.full(len(proj), proj.shape[1]), ring[facet])
    piece = _pad(piece, count)
    tol = _PIECE_TOL * area_F[facet]
    ok = (count >= 3) & (_shoelace(piece) > tol)
    # the window, at the centre of the piece's vertices
    used = np.arange(piece.shape[1])[None] < count[:, None]
    centre = np.stack([_dot(piece[..., k], used) for k in range(2)], axis=1)
    centre /= np.maximum(count, 1)[:, None]
    x = origin[facet] + _dot(centre[:, None], frame[facet].transpose(0, 2, 1))
    ok &= rays(x, n[facet], master[candidate, 0], master_normals[candidate]) >= -windows[facet]
    facet, candidate, piece, count = facet[ok], candidate[ok], piece[ok], count[ok]
    a, b = _pairs_within(facet)
    clash = _overlap(piece, a, b, 1e-9 * np.sqrt(area_F[facet[a]]))
    overlapping = np.unique(facet[a[clash]])
    fast = ~np.isin(facet, overlapping)
    rule = _fan(piece[fast], count[fast], facet[fast], candidate[fast], origin, frame,
                (points, weights), area_F)
    gap = rays(rule.points, n[rule.facet], master[rule.master, 0], master_normals[rule.master])
    return MortarRule(rule.facet, rule.points, rule.weights, rule.master, gap), overlapping


def _fan(piece: np.ndarray, count: np.ndarray, facet: np.ndarray, master: np.ndarray,
         origin: np.ndarray, frame: np.ndarray, rule: tuple, area_F: np.ndarray) -> MortarRule:
    """The Gauss points of the pieces: fans of triangles (v_0, v_k, v_k+1).

    As the per-facet :func:`~dwr_signorini.mortar._fan`; ``gap`` left empty.
    """
    points, weights = rule
    size = piece.shape[1]
    b, c = piece[:, 1:-1] - piece[:, :1], piece[:, 2:] - piece[:, :1]  # (k, size - 2, 2)
    area = 0.5 * (b[..., 0] * c[..., 1] - b[..., 1] * c[..., 0])
    keep = (np.arange(size - 2)[None] < (count - 2)[:, None]) & (
        area > _PIECE_TOL * area_F[facet][:, None])
    k, t = np.nonzero(keep)  # row-major: the pieces' order, then their triangles'
    xy = (piece[k, 0][:, None] + points[None, :, :1] * b[k, t][:, None]
          + points[None, :, 1:] * c[k, t][:, None])  # (triangles, q, 2)
    q = len(weights)
    f = np.repeat(facet[k], q)
    x = origin[f] + _dot(xy.reshape(-1, 1, 2), frame[f].transpose(0, 2, 1))
    w = ((2.0 * area[k, t])[:, None] * weights[None]).ravel()
    return MortarRule(f, x, w, np.repeat(master[k], q), np.zeros(0))


def place(
    pieces: MortarRule, degree: int, quadrilaterals: bool, slave_normals: np.ndarray,
    master: np.ndarray, master_normals: np.ndarray,
) -> MortarRule:
    """The mortar rule of degree ``degree`` on the pieces of a rule of degree None.

    Args:
        pieces: The rule of degree None (:func:`~dwr_signorini.mortar.mortar_rule`).
        degree: The Gauss rule's degree.
        quadrilaterals: Whether a side has quadrilateral facets
            (:func:`~dwr_signorini.mortar.bilinear`).
        slave_normals: The slave facets' outward unit normals (``pieces.facet`` indexes them).
        master: The master facets' vertices (``pieces.master`` indexes them).
        master_normals: Their outward unit normals.

    Returns:
        The :class:`~dwr_signorini.mortar.MortarRule` of degree ``degree``, its points in the
        order of the pieces.

    Each simplex S of a piece (its vertices v_0, ..., v_d: d + 1 consecutive points of
    ``pieces``) gets the Gauss points x_q = v_0 + sum_k X_qk (v_k - v_0) of
    :func:`~dwr_signorini.mortar.piece_rule` with weights meas(S) w_q / meas(S_ref), and each
    point its gap along its slave facet's normal. The pieces (the search) do not depend on the
    degree: one search serves every degree.
    """
    gdim = pieces.points.shape[1]
    k = gdim  # vertices per simplex
    X, w = piece_rule(gdim - 1, degree, quadrilaterals)
    v = pieces.points.reshape(-1, k, gdim)
    x = (v[:, None, 0] + np.einsum("qj,pjd->pqd", X, v[:, 1:] - v[:, :1])).reshape(-1, gdim)
    measure = pieces.weights.reshape(-1, k).sum(axis=1)
    weights = (measure[:, None] * (w / _REFERENCE_MEASURE[gdim - 1])[None]).ravel()
    facet = np.repeat(pieces.facet[::k], len(w))
    partner = np.repeat(pieces.master[::k], len(w))
    gap = rays(x, slave_normals[facet], master[partner, 0], master_normals[partner])
    return MortarRule(facet, x, weights, partner, gap)


def rays(x: np.ndarray, n: np.ndarray, p0: np.ndarray, nm: np.ndarray) -> np.ndarray:
    """The ray parameters t of x + t n on the planes through p0 with normals nm, row by row."""
    return _dot(p0 - x, nm) / _dot(n, nm)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sum_i a[..., i] b[..., i], broadcast (on a few components faster than einsum)."""
    out = a[..., 0] * b[..., 0]
    for i in range(1, a.shape[-1]):
        out = out + a[..., i] * b[..., i]
    return out
