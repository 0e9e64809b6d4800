"""Candidate master facets of each slave facet: the contact search without a scan of all.

:func:`~dwr_signorini.mortar.mortar_rule` compares each slave facet with every master facet
(a vectorised distance test, then the pieces of the nearby ones), a cost of (slave facets) x
(master facets). :func:`candidate_rule` asks a KD-tree of the master facets' centres for the
ones near each slave facet and runs the rule against those only; a facet that they do not cover
within the searched depth is searched against all master facets, so the rule is the same.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

from .clipping import _dot, batched_rule
from .mortar import MortarRule, facet_reach, mortar_rule

__all__ = [
    "SEARCH_DEPTH", "candidate_parts", "candidate_rule", "merge_rules",
    "search_depth", "search_radius",
]


#: How deep the candidate search looks along a slave facet's normal, in facet diameters: the
#: master facets whose centres lie within SEARCH_DEPTH diameters (plus both facets' reach) of
#: the slave facet's centre are its candidates (:func:`candidate_rule`).
SEARCH_DEPTH = 4.0


def candidate_rule(
    slave: np.ndarray,
    slave_normals: np.ndarray,
    master: np.ndarray,
    master_normals: np.ndarray,
    degree: int | None,
    window: np.ndarray | float,
) -> MortarRule:
    """The mortar rule of each slave facet against its candidate master facets only.

    :func:`~dwr_signorini.mortar.mortar_rule` of every slave facet against the master facets
    that a KD-tree of their centres finds near it (:func:`candidate_parts`); a facet that they
    do not cover within the searched depth is searched against every master facet. The rule is
    the full search's, up to round-off where a master outside the ball cuts a piece of F without
    being chosen for it.

    Args:
        slave: The slave facets' vertices, shape (m_s, nv, gdim).
        slave_normals: Their outward unit normals.
        master: The master facets' vertices, shape (m_m, nv, gdim).
        master_normals: Their outward unit normals.
        degree: The polynomial degree integrated exactly on each piece (None: the pieces).
        window: The penetration window w_F of each slave facet (or one for all), >= 0
            (:func:`~dwr_signorini.mortar.mortar_rule`).

    Returns:
        The :class:`~dwr_signorini.mortar.MortarRule`, its points in the order of the slave
        facets.
    """
    windows = np.broadcast_to(np.asarray(window, dtype=float), (len(slave),))
    parts, full = candidate_parts(slave, slave_normals, master, master_normals, degree, windows)
    if len(full):
        r = mortar_rule(slave[full], slave_normals[full], master, master_normals, degree,
                        windows[full])
        parts.append(MortarRule(full[r.facet], r.points, r.weights, r.master, r.gap))
    return merge_rules(parts, slave.shape[2])


def search_depth(slave: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """D = max(:data:`SEARCH_DEPTH` d, w_F + d) per slave facet, d its diameter."""
    diameter = 2.0 * facet_reach(slave)[1]
    return np.maximum(SEARCH_DEPTH * diameter, windows + diameter)


def search_radius(slave: np.ndarray, windows: np.ndarray, master_reach: float) -> np.ndarray:
    """The radius around each slave facet's centre within which its candidates' centres lie.

    D + reach(F) + ``master_reach`` (:func:`search_depth`, :func:`candidate_parts`).
    """
    return (1.0 + 1e-9) * (search_depth(slave, windows) + facet_reach(slave)[1] + master_reach)


def candidate_parts(
    slave: np.ndarray,
    slave_normals: np.ndarray,
    master: np.ndarray,
    master_normals: np.ndarray,
    degree: int | None,
    windows: np.ndarray,
    master_reach: float | None = None,
    keys: np.ndarray | None = None,
) -> tuple[list[MortarRule], np.ndarray]:
    """The rules of the slave facets that their candidates cover, and the facets left over.

    A slave facet F of diameter d is searched against the master facets whose centres lie
    within :func:`search_radius` of F's centre: every master facet that a ray of F meets at
    |t| <= D is among them, and none outside is met at |t| <= D. The result is kept where those
    candidates cover F and every point's |gap| <= D - d (so no master outside the ball could
    be nearer, nor in the layer of the nearest, nor within the window behind F: D - d >= w_F);
    the other facets (covered in part or not at all, or a gap larger than the search) are
    left for a search against every master facet.

    Args:
        slave: The slave facets' vertices, shape (m_s, nv, gdim).
        slave_normals: Their outward unit normals.
        master: The master facets' vertices, shape (m_m, nv, gdim).
        master_normals: Their outward unit normals.
        degree: The polynomial degree integrated exactly on each piece (None: the pieces,
            :func:`~dwr_signorini.mortar.piece_rule`).
        windows: The penetration window of each slave facet.
        master_reach: The largest reach of a master facet (default: of those given; the
            largest over all ranks where the masters are distributed).
        keys: The master facets' global numbers, the order in which each facet meets its
            candidates (default: their index; the same order on any number of ranks).

    Returns:
        The rules of the kept facets (``facet`` indexing ``slave``) and the facets left over.
    """
    if len(slave) == 0 or len(master) == 0:
        return [], np.arange(len(slave), dtype=np.int64)
    centres, reach = facet_reach(master)
    reach_max = reach.max() if master_reach is None else master_reach
    keys = np.arange(len(master)) if keys is None else keys
    facet, candidate = _candidates(cKDTree(centres), slave, slave_normals, windows,
                                   search_radius(slave, windows, reach_max),
                                   (centres, reach, master_normals, keys))
    args = (slave, slave_normals, master, master_normals, degree, windows)
    lo, hi = np.searchsorted(facet, np.arange(len(slave))), np.searchsorted(
        facet, np.arange(len(slave)), side="right")
    if slave.shape[2] == 3:
        rule, alone = batched_rule(*args, facet, candidate)
        parts = [rule]
    else:
        parts, alone = [], np.unique(facet)
    parts += [_one(args, i, candidate[lo[i]:hi[i]]) for i in alone]
    rule = merge_rules(parts, slave.shape[2])
    kept = _kept(rule, slave, search_depth(slave, windows) - 2.0 * facet_reach(slave)[1])
    at = kept[rule.facet]
    kept_rule = MortarRule(*(getattr(rule, k)[at] for k in _FIELDS))
    return [kept_rule], np.flatnonzero(~kept)


#: The fields of a :class:`~dwr_signorini.mortar.MortarRule`.
_FIELDS = ("facet", "points", "weights", "master", "gap")

#: How many slave facets ask the KD-tree at once (bounds the lists it returns).
_QUERY_CHUNK = 4096


def _candidates(
    tree: cKDTree, slave: np.ndarray, normals: np.ndarray, windows: np.ndarray,
    radius: np.ndarray, masters: tuple[np.ndarray, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """The (slave facet, master facet) pairs that the rule reads, each facet's sorted by keys.

    The master facets whose centres lie within ``radius`` of each slave facet's centre, of
    which those in its shadow (:func:`~dwr_signorini.mortar.in_shadow`: the rule looks at no
    others). Those lie in a cylinder around the facet's normal axis (:func:`_axis_balls`), which
    the KD-tree is asked for instead of the whole ball: a few small balls along the axis meet
    far fewer master facets than the ball of the search radius (which reaches D along the
    master surface too), and the tests below keep the same pairs.

    Args:
        tree: The KD-tree of the master facets' centres.
        slave: The slave facets' vertices.
        normals: Their outward unit normals.
        windows: Their penetration windows.
        radius: Their search radii.
        masters: The master facets' centres, reaches, normals and keys.
    """
    centres, reach, master_normals, keys = masters
    slave_centres, slave_reach = facet_reach(slave)
    tol = 1.0 + 1e-9
    lateral = tol * (reach.max(initial=0.0) + slave_reach)  # the shadow's largest radius
    behind = windows + reach.max(initial=0.0) + slave_reach
    facets, found = [], []
    for lo in range(0, len(slave), _QUERY_CHUNK):
        at = slice(lo, lo + _QUERY_CHUNK)
        f, c = _axis_balls(tree, slave_centres[at], normals[at], lateral[at], -behind[at],
                           radius[at])
        f += lo
        n = normals[f]
        d = centres[c] - slave_centres[f]
        along = _dot(d, n)
        side = np.linalg.norm(d - along[:, None] * n, axis=1)
        both = reach[c] + slave_reach[f]
        ok = ((_dot(master_normals[c], n) < 0.0)
              & (side <= tol * both) & (along >= -(windows[f] + both))
              & (_dot(d, d) <= radius[f] ** 2))
        f, c = f[ok], c[ok]
        order = np.lexsort((keys[c], f))
        facets.append(f[order])
        found.append(c[order])
    if not facets:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(facets), np.concatenate(found)


def _axis_balls(
    tree: cKDTree, centres: np.ndarray, normals: np.ndarray, lateral: np.ndarray,
    near: np.ndarray, far: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The points of ``tree`` in cylinders around axes (and some around them), once per pair.

    The cylinder of an axis x + t n holds the points within ``lateral`` of it with
    near <= t <= far. It is covered by k = ceil((far - near) / lateral) balls centred on the
    axis at spacing h = (far - near) / k, of radius sqrt(lateral^2 + h^2 / 4): a point of the
    cylinder lies within h / 2 of a ball's centre along the axis.

    Args:
        tree: A KD-tree of points.
        centres: A point of each axis, shape (m, gdim).
        normals: The axes' unit directions.
        lateral: The cylinders' radii (> 0).
        near: Where each cylinder begins along its axis.
        far: Where each ends.

    Returns:
        The (cylinder, point) pairs, sorted.
    """
    m = len(centres)
    if m == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    k = np.maximum(np.ceil((far - near) / lateral), 1.0).astype(np.int64)
    f = np.repeat(np.arange(m), k)
    j = np.arange(len(f)) - np.repeat(np.cumsum(k) - k, k)
    h = ((far - near) / k)[f]
    points = centres[f] + (near[f] + (j + 0.5) * h)[:, None] * normals[f]
    hits = tree.query_ball_point(points, (1.0 + 1e-9) * np.sqrt(lateral[f] ** 2 + 0.25 * h**2))
    sizes = np.fromiter(map(len, hits), dtype=np.int64, count=len(hits))
    c = np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64, count=int(sizes.sum()))
    key = np.unique(np.repeat(f, sizes) * tree.n + c)
    return key // tree.n, key % tree.n


def _one(args: tuple, i: int, c: np.ndarray) -> MortarRule:
    """The per-facet rule of slave facet i against the master facets c (in that order)."""
    slave, slave_normals, master, master_normals, degree, windows = args
    r = mortar_rule(slave[i:i + 1], slave_normals[i:i + 1], master[c], master_normals[c],
                    degree, windows[i])
    return MortarRule(np.full(len(r.facet), i, dtype=np.int64), r.points, r.weights,
                      c[r.master], r.gap)


def merge_rules(parts: list[MortarRule], gdim: int) -> MortarRule:
    """The rules of disjoint sets of facets as one, its points in the order of the facets."""
    fields = _FIELDS
    if not parts:
        empty = np.zeros(0)
        return MortarRule(empty.astype(np.int64), np.zeros((0, gdim)), empty,
                          empty.astype(np.int64), empty)
    rule = MortarRule(*(np.concatenate([getattr(p, k) for p in parts]) for k in fields))
    order = np.argsort(rule.facet, kind="stable")
    return MortarRule(*(getattr(rule, k)[order] for k in fields))


def _kept(rule: MortarRule, slave: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Which facets the candidates' rule covers within ``depth`` (per facet)."""
    m = len(slave)
    covered = np.bincount(rule.facet, weights=rule.weights, minlength=m)
    far = np.zeros(m)
    np.maximum.at(far, rule.facet, np.abs(rule.gap))
    if slave.shape[1] == 2:
        measure = np.linalg.norm(slave[:, 1] - slave[:, 0], axis=1)
    else:
        measure = _facet_areas(slave)
    hit = np.bincount(rule.facet, minlength=m) > 0
    return hit & (far <= depth) & (covered >= (1.0 - 1e-9) * measure)


def _facet_areas(facets: np.ndarray) -> np.ndarray:
    """The areas of flat triangle or quadrilateral facets (vertices in dolfinx's order)."""
    ring = facets if facets.shape[1] == 3 else facets[:, [0, 1, 3, 2]]
    fan = sum(np.cross(ring[:, k] - ring[:, 0], ring[:, k + 1] - ring[:, 0])
              for k in range(1, ring.shape[1] - 1))
    return 0.5 * np.linalg.norm(fan, axis=1)
