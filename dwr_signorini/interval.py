r"""An interval for J(w) on every level: the error identity with each unknown term bounded.

Proposition 4 of the paper splits the error of J (with eta as in (15))

    J(w) - J(w_h) = eta[z - z_h, w - w_h] + (quadratic remainders, R_J) + R_A,

where eta[z - z_h, w - w_h] is the estimator with the exact weights. The computed estimate eta
replaces the exact weights by reconstructed or P2 ones and leaves out R_A and the quadratic
remainders. The interval bounds each left-out part by a computed quantity:

1. **the weights' error** by a saturation assumption in the sense of Endtmayer, Langer and Wick
   (SIAM J. Sci. Comput. 42 (2020) A371): ``|eta[z - z_h, w - w_h] - eta| <= b |eta[z - z_h,
   w - w_h]|``, which places the exactly weighted part in ``[eta / (1 + b), eta / (1 - b)]``
   (the effectivity of eta in [1/(1 + b), 1/(1 - b)] when the other parts vanish). b =
   :data:`SATURATION` = 0.4 (effectivity in [0.71, 1.67]) on a level whose contact set is
   resolved, and :data:`SATURATION_UNRESOLVED` = 1/2 ([2/3, 2]) on one whose contact set is
   not;
2. **the remainder of the nonlinearity** (R_J of a nonlinear goal, and the difference between
   the primal and the primal-dual identities (13) and (15)) by ``|eta - eta_p|``: both estimate
   the same error, and their difference is that second-order part;
3. **the active-set remainder R_A** by the magnitude of its value with reconstructed w and xi
   (:func:`~dwr_signorini.residuals.active_set_remainder`).

So, with ``r = |eta - eta_p| + |R_A|``,

    J(w) in [J_h + min(eta / (1 + b), eta / (1 - b)) - r,
             J_h + max(eta / (1 + b), eta / (1 - b)) + r].                             (*)

With the primal estimator alone (``estimator="eta_p"``) eta_p takes the place of eta and r is
``|R_A|``. The centre of (*) is J_h + eta / (1 - b^2) (1.19 eta resolved, 1.33 eta unresolved): an
estimate that satisfies the assumption can underestimate more than it can overestimate.

**When it is a bound.** (*) contains J(w) whenever the three assumptions hold: the weights
satisfy the saturation assumption, the computed R_A is not smaller in magnitude than the true
one, and the quadratic remainders are not larger than ``|eta - eta_p|``. None of them is checked on
a level: they are assumptions, as the saturation assumption is, not theorems. Where an error is
small by cancellation (J_h passing through J between two levels) the interval stays as wide as
the neighbouring levels' errors. The package makes the first assumption hold where it fails
most (``weights="auto"``, the default): on a level whose contact set is *not resolved* the
patch-wise recovery of z_h misses the contact (wrong sign or a factor 50 on the first 3D
contact levels, ``benchmarks/README.md``), and the estimate is computed again with P2 weights
(``weights="hierarchical"``: the P2 dual and primal of the final active set, iterated on the
Newton factors, no new factorisation). The patch weights are checked with P2 ones as well
(factored, ``weights="higher_order"``, exact to round-off) where J_h vanishes to round-off and
their estimate does not: there J(w) vanishes by symmetry
far more often than J_h crosses J by chance, the error is then zero, and a nonzero estimate is
the patch weights' own error, which the assumption bounds only relative to the exactly weighted
estimate, zero here (the friction force of a block pressed without shear, on level 0 of a mesh
that is not mirror-symmetric: patch weights -2.6e-5, P2 weights 4e-18, J_h 7e-16).
``benchmarks/interval_coverage.py`` measures coverage,
width and the centre's effectivity against reference values obtained from J_h alone.

**Resolved contact set** (decided from computed quantities only, :func:`contact_set_resolved`):
with the patch weights, the active-set remainder and the contact-violation term are small beside
the estimate, ``|R_A| + |C(w_h)(xi_H)| <= theta |estimate|`` with theta =
:data:`RESOLVED_RATIO` = 1/4. R_A measures where the reconstructed solution would switch facets
between contact and no contact, C where the discrete solution violates the contact conditions
pointwise (it is the whole estimate on a level whose mesh misses the contact): both are of the
size of the error on the levels where contact first appears.

**Round-off.** J_h comes from a linear solve and a sum over cells, so it carries round-off of
about the machine precision times the condition number of the stiffness matrix (which grows like
N^(2/d)) times the size of J's integrand, ``int |j|``. Where J(w) = 0 by symmetry (the friction
force of a block pressed without shear on a mirror-symmetric mesh) J_h and every indicator are
round-off, and an interval ``J_h + O(estimate)`` would shrink round J_h = 1e-16 and miss 0.
:func:`roundoff_bound` gives ``q = ROUNDOFF_FACTOR eps N^(2/d) int |j|`` (10 eps N^(2/d), at
least a hundred times the round-off measured on the symmetric block); it widens (*) on both
sides, and estimates and remainders below it count as zero in :func:`contact_set_resolved`.

**The centre.** The number to use is the centre of (*), :func:`best_estimate`,
``J_best = J_h + eta / (1 - b^2)`` (``Estimate.J_best``, ``LevelRecord.J_best``): J_h corrected by
the estimate. J_h itself is often outside (*): (*) lies on the side of J_h that eta points to
and starts ``eta / (1 + b) - r`` away from it, so J_h is inside only where r exceeds that.

The constants b and theta were chosen on the measurements of ``benchmarks/README.md`` (the 2D
and 3D problems there), not derived: they state how far the weights are trusted.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "RESOLVED_RATIO",
    "ROUNDOFF_FACTOR",
    "SATURATION",
    "SATURATION_UNRESOLVED",
    "best_estimate",
    "contact_set_resolved",
    "error_interval",
    "remainder_bound",
    "roundoff_bound",
]

#: b of the saturation assumption on the weights where the contact set is resolved (item 1).
SATURATION = 0.4

#: b where the contact set is not resolved (then the weights are P2 with ``weights="auto"``).
SATURATION_UNRESOLVED = 0.5

#: theta: a level's contact set counts as resolved when |R_A| <= theta |estimate|.
RESOLVED_RATIO = 0.25

#: The round-off of J_h in units of eps N^(2/d) int |j| (:func:`roundoff_bound`).
ROUNDOFF_FACTOR = 10.0


def roundoff_bound(magnitude: float, num_dofs: int, tdim: int) -> float:
    """q: the round-off that J_h, the estimates and the remainders may carry.

    Args:
        magnitude: ``int |j|``, the integral of the magnitude of J's integrand at w_h.
        num_dofs: The displacement DoFs N (global).
        tdim: The dimension d of the mesh.

    Returns:
        ``ROUNDOFF_FACTOR eps N^(2/d) int |j|``.
    """
    eps = float(np.finfo(float).eps)
    return ROUNDOFF_FACTOR * eps * max(num_dofs, 1) ** (2.0 / tdim) * abs(magnitude)


def contact_set_resolved(
    estimate: float, remainder: float, contact_term: float, roundoff: float = 0.0
) -> bool:
    """Whether the discrete contact set is resolved: ``|R_A| + |C| <= theta |estimate| + q``.

    Args:
        estimate: The level's estimate (eta or eta_p) with the patch weights.
        remainder: Its active-set remainder R_A (Proposition 4, with reconstructions).
        contact_term: The contact-violation term C(w_h)(xi_H).
        roundoff: q of :func:`roundoff_bound`: values below it are round-off, not evidence.

    Returns:
        True when R_A and C together are at most :data:`RESOLVED_RATIO` times the estimate in
        magnitude, or at most round-off.
    """
    return abs(remainder) + abs(contact_term) <= RESOLVED_RATIO * abs(estimate) + roundoff


def remainder_bound(eta: float | None, eta_p: float, remainder: float) -> float:
    """The bound ``r = |eta - eta_p| + |R_A|`` (items 2 and 3 of the module docstring).

    Args:
        eta: The primal-dual estimate (15), or ``None`` when only eta_p was computed (then
            the first term is left out).
        eta_p: The primal estimate (13).
        remainder: The active-set remainder R_A.

    Returns:
        The bound r of the parts of the error that the estimate leaves out.
    """
    nonlinear = 0.0 if eta is None else abs(eta - eta_p)
    return nonlinear + abs(remainder)


def _saturation(resolved: bool) -> float:
    """The b of the saturation assumption (item 1)."""
    return SATURATION if resolved else SATURATION_UNRESOLVED


def best_estimate(J_h: float, estimate: float, resolved: bool = True) -> float:
    """J_best, the centre of (*): ``J_h + estimate / (1 - b^2)``.

    Args:
        J_h: J(w_h).
        estimate: eta (or eta_p with the primal estimator alone).
        resolved: Whether the contact set is resolved (picks b).

    Returns:
        The best estimate of J(w) the level has: J_h corrected by the estimate.
    """
    b = _saturation(resolved)
    return J_h + estimate / (1.0 - b * b)


def error_interval(
    J_h: float,
    eta: float | None,
    eta_p: float,
    remainder: float,
    resolved: bool = True,
    roundoff: float = 0.0,
) -> tuple[float, float]:
    """The interval (*) of the module docstring that J(w) lies in under its assumptions.

    Args:
        J_h: J(w_h).
        eta: The primal-dual estimate (15), or ``None``: then eta_p takes its place.
        eta_p: The primal estimate (13).
        remainder: The active-set remainder R_A.
        resolved: Whether the contact set is resolved (:func:`contact_set_resolved`), which
            picks b: :data:`SATURATION` or :data:`SATURATION_UNRESOLVED`.
        roundoff: q of :func:`roundoff_bound`, added to r.

    Returns:
        ``(J_low, J_high)``.

    Raises:
        ValueError: If any of the numbers is not finite.
    """
    values = {
        "J_h": J_h, "eta": eta, "eta_p": eta_p, "remainder": remainder, "roundoff": roundoff
    }
    for name, value in values.items():
        if value is not None and not math.isfinite(value):
            raise ValueError(f"error_interval: {name} must be finite, got {value!r}")
    estimate = eta_p if eta is None else eta
    b = _saturation(resolved)
    ends = (estimate / (1 + b), estimate / (1 - b))
    r = remainder_bound(eta, eta_p, remainder) + abs(roundoff)
    return J_h + min(ends) - r, J_h + max(ends) + r
