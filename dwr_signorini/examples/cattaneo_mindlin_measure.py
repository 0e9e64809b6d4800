"""Cattaneo-Mindlin: a solution of the load paths measured against Hertz and Cattaneo-Mindlin.

The paths of :mod:`~dwr_signorini.examples.cattaneo_mindlin_2d` (a cylinder) and
:mod:`~dwr_signorini.examples.cattaneo_mindlin_3d` (a sphere) press an elastic body onto a rigid
flat and then shear it with Coulomb friction; their docstrings give the theory: Hertz's contact
half-width (radius) a, peak pressure p0 and pressure p(x) (eqs. H1-H3), and Cattaneo-Mindlin's
stick half-width (radius) c and tangential traction q(x) under a tangential force Q < mu P
(eqs. CM1, CM2). :func:`measure_cattaneo_mindlin` compares a solution of one step of either
path with them (:class:`CMMeasure`): the computed forces P and Q and the a, p0 and c they give,
the computed contact and stick sizes a_h, c_h against a and c in units of one macro facet, the
relative L2 errors of lambda_n against p and of lambda_t against q (beside the best that a
facet-wise constant lambda_t allows), and the coupling of the normal and the tangential
problems that nu < 1/2 leaves in the press step.

The measurements read a solution as a user would: P and Q are the integrals of lambda_n and
lambda_t over Gamma_C (Q with its sign: the goal
:func:`~dwr_signorini.examples.goal_friction_force` is Q), the computed stick half-width c_h
is half the extent along x of the sticking macro facets (their outer vertices), and the
relative L2 error of lambda_t against q(x) is integrated facet by facet (Gauss-Legendre on
every straight macro facet). All of them are collective: the facets are gathered on rank 0
(:func:`gather_contact_profile`) and the results broadcast. A 3D solution is measured on the
facets of :func:`~dwr_signorini.examples.cattaneo_mindlin_3d.gather_contact_patch` (its
docstring), by :mod:`~dwr_signorini.examples.cattaneo_mindlin_3d`, which imports the pieces the
two dimensions share from here (the gathering of the facets, the theory's fields,
:class:`CMMeasure`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import partial
from typing import Any

import numpy as np

from ..viz.gather import gather_contact_force, gather_friction
from .cattaneo_mindlin_2d import (
    CM_DEFAULTS,
    cm_traction,
    hertz_half_width,
    hertz_pressure,
    stick_half_width,
)

__all__ = [
    "CMMeasure",
    "ContactProfile",
    "gather_contact_profile",
    "measure_cattaneo_mindlin",
]


@dataclass(frozen=True)
class ContactProfile:
    """The macro contact facets of a 2D solution, gathered on rank 0 and sorted along x.

    Attributes:
        x0, x1: The x of each facet's left and right vertex (straight facets).
        length: Each facet's length.
        lam: lambda_n on each facet.
        lam_t: lambda_t on each facet.
        active: Whether each facet is in contact (the normal active set).
        stick, slip: Whether each facet is in contact and sticks, slips.
    """

    x0: np.ndarray
    x1: np.ndarray
    length: np.ndarray
    lam: np.ndarray
    lam_t: np.ndarray
    active: np.ndarray
    stick: np.ndarray
    slip: np.ndarray

    @property
    def mid(self) -> np.ndarray:
        """The facets' midpoints' x."""
        return 0.5 * (self.x0 + self.x1)


def _gather_facets(sol: Any) -> tuple[np.ndarray, ...] | None:
    """The macro contact facets of a frictional solution on rank 0 (``None`` elsewhere).

    Collective (:func:`~dwr_signorini.viz.gather.gather_friction` and
    :func:`~dwr_signorini.viz.gather.gather_contact_force`, which gather in the same order).

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


def gather_contact_profile(sol: Any) -> ContactProfile | None:
    """The macro contact facets of a 2D frictional solution on rank 0 (``None`` elsewhere).

    Collective (:func:`~dwr_signorini.viz.gather.gather_friction` and
    :func:`~dwr_signorini.viz.gather.gather_contact_force`, which gather in the same order).

    Args:
        sol: A :class:`~dwr_signorini.Solution` of a 2D problem with friction.

    Returns:
        The :class:`ContactProfile` on rank 0, ``None`` on the other ranks.

    Raises:
        ValueError: On rank 0, if the contact facets are not segments (a 3D problem).
    """
    facets = _gather_facets(sol)
    if facets is None:
        return None
    x, lam, lam_t, active, stick, slip = facets
    if x.shape[1:] != (2, 3):
        raise ValueError("gather_contact_profile: a 2D problem (facets with two vertices) only")
    x0, x1 = np.minimum(x[:, 0, 0], x[:, 1, 0]), np.maximum(x[:, 0, 0], x[:, 1, 0])
    length = np.linalg.norm(x[:, 1, :] - x[:, 0, :], axis=1)
    order = np.argsort(x0 + x1, kind="stable")
    return ContactProfile(x0[order], x1[order], length[order],
                          *(v[order] for v in (lam, lam_t, active, stick, slip)))


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
            :func:`~dwr_signorini.examples.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`.
        l2_lam_ty: In 3D ``||lambda_t . e_y||_L2(GC) / ||q||_L2(GC)``, the traction across the shear
            (zero in Mindlin's approximation); nan in 2D.

    In 3D (:func:`~dwr_signorini.examples.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`, the
    docstring of :mod:`~dwr_signorini.examples.cattaneo_mindlin_3d`) the fields are those of the
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


def _theory(
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


def _rel(err: float, norm: float) -> float:
    """sqrt(err / norm), a relative L2 error from squared norms; nan if ``norm`` is not > 0."""
    return math.sqrt(err / norm) if norm > 0 else math.nan


def _cm_measure(
    theory: dict[str, float], a_h: float, c_h: float, stick_center: float, h_facet: float,
    stick: np.ndarray, slip: np.ndarray, **fields: Any,
) -> CMMeasure:
    """The :class:`CMMeasure` of the theory (:func:`_theory`), the computed sizes and ``fields``."""
    return CMMeasure(
        **theory, a_h=a_h, c_h=c_h, stick_center=stick_center, h_facet=h_facet,
        c_error_facets=(c_h - theory["c"]) / h_facet,
        a_error_facets=(a_h - theory["a"]) / h_facet,
        num_stick=int(stick.sum()), num_slip=int(slip.sum()), **fields,
    )


def _facet_l2(profile: ContactProfile, values: np.ndarray, exact: Any, points: int) -> tuple:
    """(||values - exact||^2, ||exact||^2) over the facets, Gauss-Legendre per facet.

    ``values`` are constant per facet; ``exact`` is a function of x. The facets are straight,
    so ds = (length / (x1 - x0)) dx along each.
    """
    s, w = np.polynomial.legendre.leggauss(points)
    dx = profile.x1 - profile.x0
    x = 0.5 * (profile.x0 + profile.x1)[:, None] + 0.5 * dx[:, None] * s[None, :]
    f = exact(x)
    weights = 0.5 * profile.length[:, None] * w[None, :]
    return (float(np.sum(weights * (values[:, None] - f) ** 2)),
            float(np.sum(weights * f**2)))


def _facet_means(profile: ContactProfile, exact: Any, points: int) -> np.ndarray:
    """The mean of ``exact`` (a function of x) on every facet, Gauss-Legendre."""
    s, w = np.polynomial.legendre.leggauss(points)
    x = (0.5 * (profile.x0 + profile.x1)[:, None]
         + 0.5 * (profile.x1 - profile.x0)[:, None] * s[None, :])
    return 0.5 * np.sum(exact(x) * w[None, :], axis=1)


def _measure_on_root(
    profile: ContactProfile, mu: float, E: float, nu: float, radius: float, points: int
) -> CMMeasure:
    """:func:`measure_cattaneo_mindlin` on the gathered facets."""
    P = float(np.sum(profile.lam * profile.length))
    Q = float(np.sum(profile.lam_t * profile.length))
    theory = _theory(P, Q, mu, hertz_half_width(P, radius, E, nu), stick_half_width)
    a, p0, c = theory["a"], theory["p0"], theory["c"]
    active = profile.active
    a_h = 0.5 * (profile.x1[active].max() - profile.x0[active].min()) if active.any() else 0.0
    if profile.stick.any():
        left, right = profile.x0[profile.stick].min(), profile.x1[profile.stick].max()
        c_h, center = 0.5 * (right - left), 0.5 * (right + left)
    else:
        c_h, center = 0.0, math.nan
    zone = np.abs(profile.mid) <= max(a, a_h)
    h_facet = float(profile.length[zone].max()) if zone.any() else math.nan

    def q(x: np.ndarray) -> np.ndarray:
        return cm_traction(x, a, c, p0, mu)

    sign = 1.0 if Q >= 0 else -1.0
    err_t, norm_t = _facet_l2(profile, sign * profile.lam_t, lambda x: sign * q(x), points)
    err_b, _ = _facet_l2(profile, _facet_means(profile, q, points), q, points)
    err_n, norm_n = _facet_l2(profile, profile.lam, lambda x: hertz_pressure(x, a, p0), points)
    right = profile.mid > 0
    normal_right = mu * float(np.sum((profile.lam * profile.length)[right]))
    return _cm_measure(
        theory, a_h, c_h, center, h_facet, profile.stick, profile.slip,
        l2_lam_t=_rel(err_t, norm_t), l2_best=_rel(err_b, norm_t), l2_lam=_rel(err_n, norm_n),
        max_lam_t=float(np.abs(profile.lam_t).max() / (mu * p0)) if p0 > 0 else math.nan,
        rms_lam_t=_rel(float(np.sum(profile.lam_t**2 * profile.length)), norm_n) / mu,
        coupling=(float(np.sum((profile.lam_t * profile.length)[right])) / normal_right
                  if normal_right > 0 else math.nan),
    )


def measure_cattaneo_mindlin(
    sol: Any,
    mu: float = CM_DEFAULTS["mu"],
    E: float = CM_DEFAULTS["E"],
    nu: float = CM_DEFAULTS["nu"],
    radius: float = CM_DEFAULTS["radius"],
    points: int = 16,
    half: bool | None = None,
) -> CMMeasure:
    """Measure a solution of the path against Hertz and Cattaneo-Mindlin (module docstrings).

    Collective: the facets are gathered on rank 0, measured there, the result broadcast.

    Args:
        sol: A :class:`~dwr_signorini.Solution` of one step of
            :func:`~dwr_signorini.examples.cattaneo_mindlin_2d.cattaneo_mindlin_path`
            or :func:`~dwr_signorini.examples.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`
            (e.g. in the ``callback`` of :func:`~dwr_signorini.solve_path`).
        mu: Coulomb's friction coefficient of the path.
        E: Young's modulus.
        nu: Poisson's ratio.
        radius: The radius R.
        points: Gauss-Legendre points per macro facet of the L2 errors (in 3D per direction
            of the collapsed rule on each triangle, ``points**2`` in all).
        half: 3D only: the mesh is the half y >= 0 of a body symmetric about y = 0, and its
            forces and areas are doubled; None: if no contact facet reaches below y = 0.

    Returns:
        The :class:`CMMeasure`, the same on every rank.

    Raises:
        Exception: What the measurement raised on rank 0, raised on every rank.
    """
    comm = sol.disc.comm
    on_root: Callable[[], CMMeasure]
    if sol.disc.contact_mesh.topology.dim == 2:  # imported here: the 3D module imports this one
        from .cattaneo_mindlin_3d import _measure_on_root_3d, gather_contact_patch

        on_root = partial(_measure_on_root_3d, gather_contact_patch(sol), mu, E, nu, radius,
                          points, half)
    else:
        on_root = partial(_measure_on_root, gather_contact_profile(sol), mu, E, nu, radius, points)
    result: CMMeasure | Exception | None = None
    if comm.rank == 0:
        try:
            result = on_root()
        except Exception as error:  # raised on every rank below
            result = error
    result = comm.bcast(result, root=0)
    if isinstance(result, Exception):
        raise result
    return result
