r"""Where the master surface lies along each slave facet's normal: the mortar rule of a pair.

Two bodies in contact, small sliding in the reference configuration
(:class:`~dwr_signorini.pairs.ContactPair`). A slave point x of a facet F with outward unit
normal n_F meets the master surface at Pi(x) = x + g(x) n_F, the intersection of the line through
x along n_F with the master facets that face F (n_m . n_F < 0) of smallest ``|g|``: g is the
gap of x (negative where the bodies overlap), Pi(x) the master point whose displacement the
slave point is compared with.

On a piece of F whose points land in one master facet G, Pi is affine (both facets are flat), so a
master function of degree k composed with Pi is a polynomial of degree k there. The rule cuts F
into such pieces (2D: the intervals between the projections of G's ends onto F; 3D: G projected
onto F's plane along n_F, clipped against F, as convex polygons cut into triangles) and puts on
each a Gauss rule of degree 2k: integrals over F of a slave polynomial of degree k times
(v o Pi), v of degree k on the master mesh, are then exact, and so is the transmission of a
uniform pressure (the contact patch test). The parts of F whose rays meet no master facet are
left out (the master is not there).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import basix
import numpy as np

__all__ = ["MortarRule", "facet_normals", "mortar_rule"]

#: Relative size below which a piece of a slave facet is dropped (a touching corner).
_PIECE_TOL = 1e-10


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
    degree: int,
) -> MortarRule:
    """The mortar rule of degree ``degree`` on the slave facets (module docstring).

    Args:
        slave: The slave facets' vertices, shape (m_s, nv, gdim).
        slave_normals: Their outward unit normals.
        master: The master facets' vertices, shape (m_m, nv, gdim).
        master_normals: Their outward unit normals.
        degree: The polynomial degree integrated exactly on each piece.

    Returns:
        The :class:`MortarRule`.
    """
    gdim = slave.shape[2]
    pieces = _pieces_2d if gdim == 2 else _pieces_3d
    rule = _reference_rule(gdim - 1, degree)
    out: list[list[np.ndarray]] = [[], [], [], [], []]
    for i in range(len(slave)):
        for x, w, g in pieces(slave[i], slave_normals[i], master, master_normals, rule):
            k = len(w)
            n = slave_normals[i]
            out[0].append(np.full(k, i, dtype=np.int64))
            out[1].append(x)
            out[2].append(w)
            out[3].append(np.full(k, g, dtype=np.int64))
            # the gap along n at each point: the distance to G's plane
            p0, nm = master[g, 0], master_normals[g]
            out[4].append(((p0 - x) @ nm) / (n @ nm))
    if not out[0]:
        empty = np.zeros(0)
        return MortarRule(empty.astype(np.int64), np.zeros((0, gdim)), empty,
                          empty.astype(np.int64), empty)
    return MortarRule(*(np.concatenate(a) for a in out))


def _reference_rule(fdim: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss points and weights of degree ``degree`` on [0, 1] (fdim 1) or the triangle."""
    cell = basix.CellType.interval if fdim == 1 else basix.CellType.triangle
    points, weights = basix.make_quadrature(cell, max(degree, 1))
    return points, weights


def _nearest(t: np.ndarray, size: float) -> np.ndarray:
    """The candidates within ``size`` of the smallest |t| (one layer of the master surface)."""
    a = np.abs(t)
    return a <= a.min() + size


def _pieces_2d(
    F: np.ndarray, n: np.ndarray, M: np.ndarray, Mn: np.ndarray, rule: tuple
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
        g = int(cover[np.argmin(np.abs(t))])
        s_q = s0 + (s1 - s0) * points[:, 0]
        out.append((a + np.outer(s_q * length, tau), weights * (s1 - s0) * length, g))
    return out


def _polygon(F: np.ndarray) -> np.ndarray:
    """A facet's vertices in order around it (a quadrilateral's 0, 1, 3, 2)."""
    return F if len(F) == 3 else F[[0, 1, 3, 2]]


def _pieces_3d(
    F: np.ndarray, n: np.ndarray, M: np.ndarray, Mn: np.ndarray, rule: tuple
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The pieces of the slave facet F: its overlaps with the projected master facets."""
    origin = F[0]
    e1 = F[1] - origin
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    frame = np.stack([e1, e2])

    def plane(points: np.ndarray) -> np.ndarray:
        return (points - origin) @ frame.T

    slave = _ccw(plane(_polygon(F)))
    facing = np.flatnonzero(Mn @ n < 0.0)
    if len(facing) == 0:
        return []
    proj = plane(M[facing])  # (c, nv, 2): along n onto F's plane
    box_lo, box_hi = slave.min(axis=0), slave.max(axis=0)
    keep = np.all(proj.max(axis=1) > box_lo, axis=1) & np.all(proj.min(axis=1) < box_hi, axis=1)
    size = float(np.max(np.linalg.norm(slave - slave[0], axis=1)))
    area_F = _area(slave)
    found = []
    for c in np.flatnonzero(keep):
        g = int(facing[c])
        piece = _clip(_ccw(proj[c] if len(proj[c]) == 3 else proj[c][[0, 1, 3, 2]]), slave)
        if len(piece) < 3 or _area(piece) <= _PIECE_TOL * area_F:
            continue
        centre = origin + piece.mean(axis=0) @ frame
        t = float((M[g, 0] - centre) @ Mn[g] / (Mn[g] @ n))
        found.append((piece, g, t))
    if not found:
        return []
    near = _nearest(np.array([f[2] for f in found]), size)
    points, weights = rule
    out = []
    for (piece, g, _), ok in zip(found, near, strict=True):
        if not ok:
            continue
        for k in range(1, len(piece) - 1):  # a fan of triangles
            tri = piece[[0, k, k + 1]]
            area = _area(tri)
            if area <= _PIECE_TOL * area_F:
                continue
            xy = tri[0] + points @ np.stack([tri[1] - tri[0], tri[2] - tri[0]])
            out.append((origin + xy @ frame, weights * 2.0 * area, g))
    return out


def _area(polygon: np.ndarray) -> float:
    """The signed area of a planar polygon (positive counter-clockwise)."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _ccw(polygon: np.ndarray) -> np.ndarray:
    """The polygon counter-clockwise."""
    return polygon if _area(polygon) >= 0.0 else polygon[::-1]


def _clip(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: the convex ``subject`` clipped by the convex ``clip`` (both ccw)."""
    out = subject
    for i in range(len(clip)):
        if len(out) == 0:
            break
        a, b = clip[i], clip[(i + 1) % len(clip)]
        edge = b - a
        side = edge[0] * (out[:, 1] - a[1]) - edge[1] * (out[:, 0] - a[0])
        new = []
        for j in range(len(out)):
            p, q = out[j], out[(j + 1) % len(out)]
            sp, sq = side[j], side[(j + 1) % len(out)]
            if sp >= 0.0:
                new.append(p)
            if (sp >= 0.0) != (sq >= 0.0):
                new.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(new) if new else np.zeros((0, 2))
    return out
