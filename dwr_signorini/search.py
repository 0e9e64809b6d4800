"""Candidate master facets of each slave facet: the contact search without a scan of all.

:func:`~dwr_signorini.mortar.mortar_rule` compares each slave facet with every master facet
(a vectorised distance test, then the pieces of the nearby ones), a cost of (slave facets) x
(master facets). :func:`candidate_rule` asks a KD-tree of the master facets' centres for the
ones near each slave facet and runs the rule against those only; a facet that they do not cover
within the searched depth is searched against all master facets, so the rule is the same.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .mortar import MortarRule, mortar_rule

__all__ = ["SEARCH_DEPTH", "candidate_rule"]


#: How deep the candidate search looks along a slave facet's normal, in facet diameters: the
#: master facets whose centres lie within SEARCH_DEPTH diameters (plus both facets' reach) of
#: the slave facet's centre are its candidates (:func:`candidate_rule`).
SEARCH_DEPTH = 4.0


def candidate_rule(
    slave: np.ndarray,
    slave_normals: np.ndarray,
    master: np.ndarray,
    master_normals: np.ndarray,
    degree: int,
    window: np.ndarray | float,
) -> MortarRule:
    """The mortar rule of each slave facet against its candidate master facets only.

    :func:`~dwr_signorini.mortar.mortar_rule` of every slave facet against the master facets
    that a KD-tree of their centres finds near it. A slave facet F of diameter d is searched
    against the master facets whose centres lie within D + reach(F) + max reach(master) of F's
    centre, D = max(:data:`SEARCH_DEPTH` d, w_F + d) with w_F F's penetration window: every
    master facet that a ray of F meets at |t| <= D is among them, and none outside is met at
    |t| <= D. The result is kept where those candidates cover F and every point's
    |gap| <= D - d (so no master outside the ball could be nearer, nor in the layer of the
    nearest, nor within the window behind F: D - d >= w_F); elsewhere (a facet covered in part
    or not at all, or a gap larger than the search) F is searched against every master facet.
    The rule is the full search's, up to round-off where a master outside the ball cuts a piece
    of F without being chosen for it.

    Args:
        slave: The slave facets' vertices, shape (m_s, nv, gdim).
        slave_normals: Their outward unit normals.
        master: The master facets' vertices, shape (m_m, nv, gdim).
        master_normals: Their outward unit normals.
        degree: The polynomial degree integrated exactly on each piece.
        window: The penetration window w_F of each slave facet (or one for all), >= 0
            (:func:`~dwr_signorini.mortar.mortar_rule`).

    Returns:
        The :class:`~dwr_signorini.mortar.MortarRule`, its points in the order of the slave
        facets.
    """
    windows = np.broadcast_to(np.asarray(window, dtype=float), (len(slave),))
    if len(slave) == 0 or len(master) == 0:
        return mortar_rule(slave, slave_normals, master, master_normals, degree, windows)
    centres, slave_centres = master.mean(axis=1), slave.mean(axis=1)
    reach = np.linalg.norm(master - centres[:, None], axis=2).max(axis=1)
    slave_reach = np.linalg.norm(slave - slave_centres[:, None], axis=2).max(axis=1)
    diameter = 2.0 * slave_reach
    depth = np.maximum(SEARCH_DEPTH * diameter, windows + diameter)
    near = cKDTree(centres).query_ball_point(
        slave_centres, (1.0 + 1e-9) * (depth + slave_reach + reach.max())
    )
    parts, full = [], []
    for i, candidates in enumerate(near):
        c = np.asarray(candidates, dtype=np.int64)
        r = mortar_rule(slave[i:i + 1], slave_normals[i:i + 1], master[c], master_normals[c],
                        degree, windows[i]) if len(c) else None
        if r is None or not _kept(r, slave[i], depth[i] - diameter[i]):
            full.append(i)
            continue
        parts.append(MortarRule(np.full(len(r.facet), i, dtype=np.int64), r.points, r.weights,
                                c[r.master], r.gap))
    if full:
        f = np.asarray(full, dtype=np.int64)
        r = mortar_rule(slave[f], slave_normals[f], master, master_normals, degree, windows[f])
        parts.append(MortarRule(f[r.facet], r.points, r.weights, r.master, r.gap))
    rule = MortarRule(*(np.concatenate([getattr(p, k) for p in parts]) for k in (
        "facet", "points", "weights", "master", "gap")))
    order = np.argsort(rule.facet, kind="stable")
    return MortarRule(*(getattr(rule, k)[order] for k in (
        "facet", "points", "weights", "master", "gap")))


def _kept(rule: MortarRule, facet: np.ndarray, depth: float) -> bool:
    """Whether a one-facet rule from the candidates covers the facet within ``depth``."""
    if len(rule.weights) == 0 or np.max(np.abs(rule.gap)) > depth:
        return False
    if len(facet) == 2:
        measure = float(np.linalg.norm(facet[1] - facet[0]))
    else:
        measure = _polygon_fan_area(facet)
    return float(rule.weights.sum()) >= (1.0 - 1e-9) * measure


def _polygon_fan_area(facet: np.ndarray) -> float:
    """The area of a flat triangle or quadrilateral facet (vertices in dolfinx's order)."""
    ring = facet if len(facet) == 3 else facet[[0, 1, 3, 2]]
    return 0.5 * float(np.linalg.norm(sum(
        np.cross(ring[k] - ring[0], ring[k + 1] - ring[0]) for k in range(1, len(ring) - 1))))
