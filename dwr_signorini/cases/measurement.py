"""The measurement of a Cattaneo-Mindlin solution: its record and what both dimensions share.

:func:`~dwr_signorini.cases.cattaneo_mindlin_measure.measure_cattaneo_mindlin` measures a
solution of the 2D path (:mod:`~dwr_signorini.cases.cattaneo_mindlin_measure`, on the facets of
:func:`~dwr_signorini.cases.cattaneo_mindlin_measure.gather_contact_profile`) or of the 3D path
(:mod:`~dwr_signorini.cases.cattaneo_mindlin_3d`, on the facets of
:func:`~dwr_signorini.cases.cattaneo_mindlin_3d.gather_contact_patch`). Both gather the macro
contact facets on rank 0 (:func:`gather_facets`), give the theory's fields for the computed
forces (:func:`theory_fields`) and fill a :class:`CMMeasure` (:func:`cm_measure`) with relative
L2 errors (:func:`relative_l2`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..viz.gather import gather_contact_force, gather_friction

__all__ = ["CMMeasure", "cm_measure", "gather_facets", "relative_l2", "theory_fields"]


def gather_facets(sol: Any) -> tuple[np.ndarray, ...] | None:
    """The macro contact facets of a frictional solution on rank 0 (``None`` elsewhere).

    Collective (:func:`~dwr_signorini.viz.gather.gather_friction` and
    :func:`~dwr_signorini.viz.gather.gather_contact_force`, which gather in the same order).

    Args:
        sol: A :class:`~dwr_signorini.Solution` of a problem with friction.

    Returns:
        ``(x, lam, lam_t, active, stick, slip)``: the facets' vertices, lambda_n, lambda_t, and
        whether each is in contact, sticks, slips (booleans).
    """
    data = gather_friction(sol)
    normal = gather_contact_force(sol)
    if data is None:
        return None
    x, lam, lam_t, stick, slip = data
    return x, lam, lam_t, normal[2].astype(bool), stick.astype(bool), slip.astype(bool)


@dataclass(frozen=True)
class CMMeasure:
    """A solution of a Cattaneo-Mindlin path measured against the theory (module docstring).

    Attributes:
        P: int_GC lambda_n ds, the normal force per unit length.
        Q: int_GC lambda_t ds, the tangential force (with its sign).
        ratio: ``|Q| / (mu P)``.
        a: Hertz's half-width for P, eq. (H1).
        p0: Hertz's peak pressure for P, eq. (H2).
        c: Cattaneo-Mindlin's stick half-width for P and Q, eq. (CM1) (nan if ``|Q| > mu P``).
        a_h: Half the extent along x of the macro facets in contact (outer vertices).
        c_h: Half the extent along x of the sticking macro facets (outer vertices; 0 if none).
        stick_center: The middle of the sticking facets' extent (0 in the theory).
        h_facet: The longest macro facet of the contact zone ``|x| <= a``: the unit of "within
            one macro facet".
        c_error_facets: (c_h - c) / h_facet.
        a_error_facets: (a_h - a) / h_facet.
        num_stick, num_slip: The numbers of sticking and slipping macro facets.
        l2_lam_t: ``||lambda_t - sign(Q) q||_L2(GC) / ||q||_L2(GC)``, eq. (CM2).
        l2_best: The relative L2 error of the best approximation of q by macro-facet constants
            (the facet means of q): what lambda_t's P0 space allows at best.
        l2_lam: ``||lambda_n - p||_L2(GC) / ||p||_L2(GC)``, eq. (H3).
        max_lam_t: ``max |lambda_t| / (mu p0)``: a coupling measure of the press step.
        rms_lam_t: ``||lambda_t||_L2(GC) / ||mu p||_L2(GC)``, eq. (H3): another one.
        coupling: int_{GC, x > 0} lambda_t ds / (mu int_{GC, x > 0} lambda_n ds): the mean
            friction on one half of the contact in units of its Coulomb limit, the coupling
            measure of the press step (the press alone gives an odd lambda_t, zero for
            beta = 0).
        dim: 2, or 3 for a solution of
            :func:`~dwr_signorini.cases.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`.
        l2_lam_ty: In 3D ``||lambda_t . e_y||_L2(GC) / ||q||_L2(GC)``, the traction across the shear
            (zero in Mindlin's approximation); nan in 2D.

    In 3D (:func:`~dwr_signorini.cases.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`, the
    docstring of :mod:`~dwr_signorini.cases.cattaneo_mindlin_3d`) the fields are those of the
    whole sphere: P and Q are twice the half body's (Q = 2 J_h of
    :func:`~dwr_signorini.examples.goal_friction_force`), a, p0 and c are Hertz's and
    Mindlin's radii and peak pressure (eqs. H1', H2', CM1'), a_h and c_h the radii of discs of
    the areas in contact and sticking, stick_center the stick zone's centroid's x, h_facet the
    mean edge of the macro facets in the contact zone, lambda_t in ``l2_lam_t``,
    ``l2_best`` its x component (along Q) against eq. (CM2'), and ``coupling`` the mean radial
    friction int lambda_t . e_r ds / (mu P) (outward positive). The counts are the half body's.
    """

    P: float
    Q: float
    ratio: float
    a: float
    p0: float
    c: float
    a_h: float
    c_h: float
    stick_center: float
    h_facet: float
    c_error_facets: float
    a_error_facets: float
    num_stick: int
    num_slip: int
    l2_lam_t: float
    l2_best: float
    l2_lam: float
    max_lam_t: float
    rms_lam_t: float
    coupling: float
    dim: int = 2
    l2_lam_ty: float = math.nan

    def as_dict(self) -> dict[str, float]:
        """The fields as a dict (a table row).

        Returns:
            ``{field: value}`` in the order of the fields.
        """
        return asdict(self)


def theory_fields(
    P: float, Q: float, mu: float, hertz: tuple[float, float],
    stick: Callable[[float, float, float, float], float],
) -> dict[str, float]:
    """The fields P, Q, ratio, a, p0 and c of :class:`CMMeasure` for the computed P and Q.

    Args:
        P: The computed normal force.
        Q: The computed tangential force.
        mu: The friction coefficient.
        hertz: Hertz's ``(a, p0)`` for P.
        stick: The stick size ``stick(a, Q, mu, P)``, used where |Q| <= mu P (else c is nan).

    Returns:
        ``{"P": P, "Q": Q, "ratio": |Q| / (mu P), "a": a, "p0": p0, "c": c}``.
    """
    a, p0 = hertz
    ratio = abs(Q) / (mu * P) if P > 0 else math.nan
    c = stick(a, Q, mu, P) if ratio <= 1.0 else math.nan
    return {"P": P, "Q": Q, "ratio": ratio, "a": a, "p0": p0, "c": c}


def relative_l2(err: float, norm: float) -> float:
    """A relative L2 error from squared norms.

    Args:
        err: The squared norm of the error.
        norm: The squared norm of the reference.

    Returns:
        ``sqrt(err / norm)``; nan if ``norm`` is not > 0.
    """
    return math.sqrt(err / norm) if norm > 0 else math.nan


def cm_measure(
    theory: dict[str, float], a_h: float, c_h: float, stick_center: float, h_facet: float,
    stick: np.ndarray, slip: np.ndarray, **fields: Any,
) -> CMMeasure:
    """The :class:`CMMeasure` of the theory, the computed sizes and further fields.

    Args:
        theory: The fields of :func:`theory_fields`.
        a_h: The computed contact size.
        c_h: The computed stick size.
        stick_center: The stick zone's centre along x.
        h_facet: The macro facet size of the contact zone.
        stick: Whether each macro facet sticks.
        slip: Whether each macro facet slips.
        **fields: The other fields of :class:`CMMeasure` (the L2 errors, the coupling).

    Returns:
        The record.
    """
    return CMMeasure(
        **theory, a_h=a_h, c_h=c_h, stick_center=stick_center, h_facet=h_facet,
        c_error_facets=(c_h - theory["c"]) / h_facet,
        a_error_facets=(a_h - theory["a"]) / h_facet,
        num_stick=int(stick.sum()), num_slip=int(slip.sum()), **fields,
    )


