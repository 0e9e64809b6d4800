"""Cattaneo-Mindlin: a solution of the load paths measured against Hertz and Cattaneo-Mindlin.

The paths of :mod:`~dwr_signorini.cases.cattaneo_mindlin_2d` (a cylinder) and
:mod:`~dwr_signorini.cases.cattaneo_mindlin_3d` (a sphere) press an elastic body onto a rigid
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
facets of :func:`~dwr_signorini.cases.cattaneo_mindlin_3d.gather_contact_patch` (its
docstring), by :func:`~dwr_signorini.cases.cattaneo_mindlin_3d.measure_contact_patch`; what the
two dimensions share (the gathering of the facets, the theory's fields,
:class:`~dwr_signorini.cases.CMMeasure`) is :mod:`~dwr_signorini.cases.measurement`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from .cattaneo_mindlin_2d import (
    CM_DEFAULTS,
    cm_traction,
    hertz_half_width,
    hertz_pressure,
    stick_half_width,
)
from .cattaneo_mindlin_3d import gather_contact_patch, measure_contact_patch
from .measurement import CMMeasure, cm_measure, gather_facets, relative_l2, theory_fields

__all__ = [
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
    facets = gather_facets(sol)
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
    theory = theory_fields(P, Q, mu, hertz_half_width(P, radius, E, nu), stick_half_width)
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
    return cm_measure(
        theory, a_h, c_h, center, h_facet, profile.stick, profile.slip,
        l2_lam_t=relative_l2(err_t, norm_t), l2_best=relative_l2(err_b, norm_t),
        l2_lam=relative_l2(err_n, norm_n),
        max_lam_t=float(np.abs(profile.lam_t).max() / (mu * p0)) if p0 > 0 else math.nan,
        rms_lam_t=relative_l2(float(np.sum(profile.lam_t**2 * profile.length)), norm_n) / mu,
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
            :func:`~dwr_signorini.cases.cattaneo_mindlin_2d.cattaneo_mindlin_path`
            or :func:`~dwr_signorini.cases.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`
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
    if sol.disc.contact_mesh.topology.dim == 2:
        on_root = partial(measure_contact_patch, gather_contact_patch(sol), mu, E, nu, radius,
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
