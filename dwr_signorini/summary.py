"""What users read off a contact: force, contact area and radius, pressures, friction, stick/slip.

:func:`contact_summary` reduces a :class:`~dwr_signorini.Solution` to the numbers a contact is
usually described by, each an integral of the multipliers over Gamma_C (the slave side of a
pair) and the same on every rank:

* the resultant the contact exerts on the body, ``F = -int_GC (lambda_n n + lambda_t) ds``
  (``lambda_n >= 0`` a pressure, n the normal of the contact frame, ``Discretization.
  contact_frame``: the body's outward normal where the gap is a number or a function, the
  obstacle's or the pair's shared normal otherwise; ``lambda_t`` the tangential
  multiplier as a vector: the traction of the body on the obstacle, as ``lambda_n n`` is; the
  signs of the primal equation ``a(u, v) + (lambda_n, v_n) + (lambda_t, v_t) = l(v)``), the
  total pressure ``P = int_GC lambda_n ds`` and the friction part ``-int_GC lambda_t ds``;
* the measure of the contact set ``{lambda_H > 0}`` (a length per unit thickness in 2D, an area
  in 3D), its mean pressure ``P / area`` and the peak ``max lambda_H``;
* the centre of pressure ``c = int lambda x ds / P`` and the second moment
  ``M_2 = int lambda r^2 ds`` about it, ``r`` the distance from ``c`` in the tangent plane (the
  plane normal to the resultant normal direction). The radius of the contact is read from the
  moments as that of Hertz's profile ``p(r) = p_0 sqrt(1 - r^2 / a^2)`` with the same ``P`` and
  ``M_2``: ``M_2 / P = a^2 / 4`` for the strip of half-width ``a`` (2D), ``2 a^2 / 5`` for the
  disc of radius ``a`` (3D). It is exact for Hertz's profile and integrates over the whole
  contact, so it converges with the pressure's mean, not with the resolution of the contact
  set's edge (a facet partly in contact is inactive); for another profile it is the radius of
  the Hertzian pressure with the same moments (a uniform pressure on ``|r| < b`` gives
  ``a = 2 b / sqrt(3)`` in 2D, ``sqrt(5 / 4) b`` in 3D);
* with friction, the measures of the sticking and slipping facets in contact
  (:attr:`~dwr_signorini.Solution.stick`, :attr:`~dwr_signorini.Solution.slip`).

Everything is assembled from one compiled form, ``int_GC f (k . phi) ds`` with ``f`` a function
on Lambda_H (the multiplier, or the indicator of a set of facets), ``phi`` the monomials of x, the
normal and the tangents, and ``k`` a constant picking one of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from ufl.domain import extract_unique_domain

from .laws import tangent_basis
from .newton import Solution

__all__ = ["ContactSummary", "contact_summary"]


@dataclass(frozen=True)
class ContactSummary:
    """The numbers of a contact (:func:`contact_summary`), the same on every rank.

    In 2D forces are per unit thickness and areas are lengths (per unit thickness). Of a
    symmetric part of a body (a half or quarter model) the forces and areas are those of the
    part; pass the symmetry point as ``centre`` for the radius of the whole contact.

    Attributes:
        force: The resultant the contact exerts on the body,
            ``-int (lambda_n n + lambda_t) ds`` (gdim components).
        normal_force: ``P = int lambda_n ds``, the total pressure (>= 0).
        friction_force: The friction part ``-int lambda_t ds`` of :attr:`force` (gdim
            components; it opposes the body's slip), None without friction.
        area: The measure of the contact set ``{lambda_H > 0}`` (the macro facets in contact):
            the contact width in 2D, its area in 3D.
        mean_pressure: ``P / area`` (0 without contact).
        peak_pressure: ``max lambda_H``. A P0 multiplier's maximum does not converge where the
            surface is a polygon (a curved face meshed by facets): at the kinks lambda_H
            overshoots the pressure (Hertz's cylinder without ``boundary_projection``: +16 %,
            then +33 % on a finer mesh; Hertz's ball on gmsh meshes without it: +22 %, +50 %,
            +43 % at contact facets of 0.03, 0.02, 0.015 of R), and on locally refined curved
            faces in 3D by 9-32 %. Read the pressure through its means
            (:attr:`mean_pressure`, :attr:`radius`, a goal over a patch), not its maximum.
        centre: The point the moments are taken about: the centre of pressure
            ``int lambda x ds / P`` or the ``centre`` given (gdim components; NaN without
            contact).
        second_moment: ``M_2 = int lambda_n r^2 ds``, r the distance from :attr:`centre` in
            the tangent plane.
        radius: The contact's half-width (2D) or radius (3D) from the moments, that of Hertz's
            profile with the same ``P`` and ``M_2``: ``2 sqrt(M_2 / P)`` (2D),
            ``sqrt(5 M_2 / (2 P))`` (3D); 0 without contact.
        stick_area: With friction, the measure of the facets in contact that stick; else None.
        slip_area: With friction, the measure of the facets in contact that slip; else None.
    """

    force: np.ndarray
    normal_force: float
    friction_force: np.ndarray | None
    area: float
    mean_pressure: float
    peak_pressure: float
    centre: np.ndarray
    second_moment: float
    radius: float
    stick_area: float | None = None
    slip_area: float | None = None


class _Moments:
    """``int_GC f phi_j ds`` for a function f on Lambda_H and the monomials phi (one form)."""

    def __init__(self, sol: Solution) -> None:
        disc = sol.disc
        m = disc.m
        self.gdim = gdim = disc.mesh.geometry.dim
        domain = extract_unique_domain(m.x)
        self.x0 = fem.Constant(domain, np.zeros(gdim))
        d = m.x - self.x0
        n = disc.contact_frame()  # the normal the multipliers act along
        tangents = list(tangent_basis(n)) if gdim == 3 else []
        entries = [ufl.as_ufl(1.0)] + [d[i] for i in range(gdim)] + [n[i] for i in range(gdim)]
        entries += [t[i] for t in tangents for i in range(gdim)]
        self.pairs = [(i, j) for i in range(gdim) for j in range(i, gdim)]
        entries += [d[i] * d[j] for i, j in self.pairs]
        #: Where each group of monomials starts in phi.
        self.first = {"x": 1, "n": 1 + gdim, "t": 1 + 2 * gdim,
                      "xx": 1 + (2 + len(tangents)) * gdim}
        self.k = fem.Constant(domain, np.zeros(len(entries)))
        self.f = fem.Function(disc.Q)
        self.owned = disc.Q.dofmap.index_map.size_local
        self.comm = disc.comm
        self.form = disc.form(self.f * ufl.dot(self.k, ufl.as_vector(entries)) * m.ds_contact)

    def integrals(self, values: np.ndarray, start: int, count: int) -> np.ndarray:
        """``int f phi_j ds`` for j in [start, start + count), f's owned ``values`` (collective)."""
        self.f.x.array[: self.owned] = values[: self.owned]
        self.f.x.scatter_forward()
        out = np.zeros(count)
        for j in range(count):
            self.k.value[:] = 0.0
            self.k.value[start + j] = 1.0
            out[j] = fem.assemble_scalar(self.form)
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return out

    def measure(self, indicator: np.ndarray) -> float:
        """The measure of the facets where ``indicator`` (owned rows) is true."""
        return float(self.integrals(indicator.astype(float), 0, 1)[0])

    def tensor(self, values: np.ndarray) -> np.ndarray:
        """``int f (x - x0)(x - x0)^T ds`` (gdim x gdim)."""
        flat = self.integrals(values, self.first["xx"], len(self.pairs))
        out = np.zeros((self.gdim, self.gdim))
        for (i, j), v in zip(self.pairs, flat, strict=True):
            out[i, j] = out[j, i] = v
        return out


def _friction_force(sol: Solution, moments: _Moments) -> np.ndarray:
    """``-int lambda_t ds`` (2D: lambda_t t, t = (-n_2, n_1); 3D: sum_k lambda_tk t_k; n_c's)."""
    gdim = moments.gdim
    if gdim == 2:
        n = moments.integrals(sol.lam_t.x.array, moments.first["n"], 2)
        return np.array([n[1], -n[0]])
    force = np.zeros(gdim)
    for k, lam_tk in enumerate(sol.tangential):
        force -= moments.integrals(lam_tk.x.array, moments.first["t"] + k * gdim, gdim)
    return force


def _second_moment(
    lam: np.ndarray, moments: _Moments, centre: np.ndarray, normal: np.ndarray
) -> float:
    """``int lambda r^2 ds`` about ``centre``, r in the plane normal to ``normal``."""
    moments.x0.value[:] = centre
    S = moments.tensor(lam)
    moments.x0.value[:] = 0.0
    return float(np.trace(S) - normal @ S @ normal)


def _radius(P: float, M2: float, gdim: int) -> float:
    """Hertz's half-width (2D) or radius (3D) with the force P and second moment M_2."""
    if P <= 0.0:
        return 0.0
    return 2.0 * math.sqrt(max(M2, 0.0) / P) if gdim == 2 else math.sqrt(2.5 * max(M2, 0.0) / P)


def _check(sol: Any, centre: Any) -> np.ndarray | None:
    if not isinstance(sol, Solution):
        raise TypeError(f"sol must be a ds.Solution (of ds.solve), got {type(sol).__name__}")
    if centre is None:
        return None
    gdim = sol.disc.mesh.geometry.dim
    c = np.asarray(centre, dtype=float)
    if c.shape != (gdim,) or not np.all(np.isfinite(c)):
        raise ValueError(f"centre must be {gdim} finite numbers (a point), got {centre!r}")
    return c


def contact_summary(sol: Solution, centre: Any = None) -> ContactSummary:
    """The force, contact area and radius, pressures and friction of a solution (collective).

    Definitions in the module docstring; Hertz's half-width compares with ``radius``.

    Args:
        sol: A solution of :func:`~dwr_signorini.solve` (or of a run's level or step).
        centre: The point to take the moments about (gdim numbers), e.g. the symmetry point of
            a half or quarter model; default the centre of pressure.

    Returns:
        The :class:`ContactSummary`, the same on every rank.

    Raises:
        TypeError: ``sol`` is not a Solution.
        ValueError: ``centre`` is not a point of the mesh's dimension.
    """
    given = _check(sol, centre)
    moments = _Moments(sol)
    gdim, comm = moments.gdim, moments.comm
    lam = sol.lam.x.array
    first = moments.integrals(lam, 0, 1 + 2 * gdim)  # int lambda (1, x, n)
    P, lam_x, lam_n = float(first[0]), first[1 : 1 + gdim], first[1 + gdim :]
    force = -lam_n
    friction = None if sol.lam_t is None else _friction_force(sol, moments)
    if friction is not None:
        force = force + friction
    normal = -lam_n / np.linalg.norm(lam_n) if np.linalg.norm(lam_n) > 0.0 else np.zeros(gdim)
    if given is not None:
        c = given
    else:
        c = lam_x / P if P > 0.0 else np.full(gdim, np.nan)
    M2 = _second_moment(lam, moments, c, normal) if P > 0.0 else 0.0
    area = moments.measure(lam[: moments.owned] > 0.0)
    peak = comm.allreduce(float(np.max(lam[: moments.owned], initial=0.0)), op=MPI.MAX)
    stick = slip = None
    if sol.stick is not None and sol.slip is not None:
        stick, slip = moments.measure(sol.stick), moments.measure(sol.slip)
    return ContactSummary(
        force=force, normal_force=P, friction_force=friction, area=area,
        mean_pressure=P / area if area > 0.0 else 0.0, peak_pressure=peak, centre=c,
        second_moment=M2, radius=_radius(P, M2, gdim), stick_area=stick, slip_area=slip,
    )
