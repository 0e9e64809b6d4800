"""Cattaneo-Mindlin in 2D: a cylinder pressed onto a rigid flat, then sheared (Coulomb friction).

The body is the half-disc of ``meshes/cattaneo_2d.py`` (radius R centred at (0, R), cut at
y = R; plane strain, E, nu), its lower arc Gamma_C in possible contact with the rigid half-plane
y <= 0 (:class:`~dwr_signorini.obstacles.Plane`), Coulomb friction with coefficient mu
(:class:`~dwr_signorini.laws.Coulomb`). The top y = R is displaced by ``(0, -press)`` in the
first load step (the press: a Hertz line contact of half-width a and total normal force P) and
by ``(k shear / steps, -press)`` in steps k = 1, ..., ``steps`` (the shear: a tangential force
Q < mu P). :func:`cattaneo_mindlin_path` builds these ``steps + 1`` problems on one mesh for
:func:`~dwr_signorini.solve_path`.

Theory (a half-plane, a << R; Johnson, *Contact Mechanics*, 1985, eqs. (4.43)-(4.45) and
(7.7)-(7.11)): for a rigid flat, with E* = E / (1 - nu^2) and the force per unit length P,

    (H1)  a = sqrt(4 P R / (pi E*)),        (H2)  p0 = 2 P / (pi a),
    (H3)  p(x) = p0 sqrt(1 - x^2 / a^2),    |x| <= a,

and under a monotonically growing tangential force Q < mu P the contact sticks on |x| <= c and
slips on c <= |x| <= a with

    (CM1) c = a sqrt(1 - Q / (mu P)),
    (CM2) q(x) = mu p0 / a (sqrt(a^2 - x^2) - sqrt(c^2 - x^2)),  |x| <= c,
          q(x) = mu p(x),                                        c <= |x| <= a,

x measured from the first contact point (0, 0). When the tangential force turns back from Q*
(stick half-width c*) towards Q, the contact slips backwards on c' <= |x| <= a while the centre
keeps its traction (Mindlin and Deresiewicz 1953; Johnson 1985, Sect. 7.4, whose superposition
argument for the sphere carries over to the cylinder; Hills and Nowell, *Mechanics of Fretting
Fatigue*, 1994, Sect. 2.4): the change from Q* is a Cattaneo distribution with 2 mu in place of
mu, so that

    (MD1) Q* - Q = 2 mu P (1 - c'^2 / a^2),  i.e.  c' = a sqrt(1 - |Q* - Q| / (2 mu P)),
    (MD2) q(x) = q*(x) - 2 mu p0 / a (sqrt(a^2 - x^2) - sqrt(c'^2 - x^2))   (Q* > 0),

q* the traction (CM2) at Q* (the second root only where |x| < c'), for Q between Q* and -Q*.
At Q = -Q* the reverse slip covers c* <= |x| <= a (c' = c*, q = -q*).

The theory assumes that the normal and the tangential problems decouple, which holds exactly
for nu = 1/2 (rigid flat): Dundurs' constant beta = (1 - 2 nu) / (2 (1 - nu)) vanishes
(:func:`dundurs_beta`). With nu = 0.49 (the default; nu = 1/2 itself is not admissible in the
displacement formulation) beta = 0.0196, and the press alone leaves an odd tangential traction
(Poisson's ratio draws the contact surface inwards and friction resists it;
:attr:`~dwr_signorini.cases.CMMeasure.coupling`). The half-disc is no half-plane, though: its
compression bulges it sideways, which moves the contact points outwards by a strain of order
P / (E* R) whatever nu, while the half-plane's inward strain is of order (1 - 2 nu) P / (E* a);
at a / R = 0.094 and nu = 0.49 the two are of one size, at nu -> 1/2 the bulge dominates.
Measured at the defaults (mu = 0.3, macro facets of 0.02 to 0.0025 at the contact): the friction
force on either half of the contact on the press step is 0.17-0.21 of its Coulomb limit, and
lambda_t oscillates from facet to facet (rms 0.25-0.33 of mu p, up to 0.4 mu p0 at the ends of
the contact). Neither falls under refinement nor with a / R (0.17, 0.06, 0.15 at a / R = 0.094,
0.042, 0.019 on about 9 facets per a; at nu = 0.4999 0.60 and 0.21): the oscillation is the P1
displacement's response to nu = 0.49 (lambda / mu = 49, near-incompressible), seen in lambda_n
too, and it also rides on lambda_t in the shear steps (about +-0.08 mu p0 in the stick zone).

The measurements against this theory (and that of the sphere) are in
:mod:`~dwr_signorini.cases.cattaneo_mindlin_measure`. The 3D path of
:mod:`~dwr_signorini.cases.cattaneo_mindlin_3d` (a sphere) shares the tags, the gmsh reader
and the load path with it (:mod:`~dwr_signorini.cases.load_path`).

The mesh builder reads the gmsh script ``meshes/cattaneo_2d.py``, found through the package
(:mod:`dwr_signorini.meshes`, the checkout's ``meshes/`` installed with it), so it works from the
checkout and after ``pip install .``; pass ``mesh=(msh, cell_tags, facet_tags)`` with the
script's tags to use another mesh.
"""

from __future__ import annotations

import math

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import mesh as dmesh

from ..problem import SignoriniProblem
from .load_path import MESHES, check_steps, gmsh_mesh, shear_path

__all__ = [
    "CM_DEFAULTS",
    "cattaneo_mindlin_mesh",
    "cattaneo_mindlin_path",
    "cm_traction",
    "dundurs_beta",
    "hertz_half_width",
    "hertz_pressure",
    "reversal_stick_half_width",
    "reversal_traction",
    "stick_half_width",
]

#: The data of :func:`cattaneo_mindlin_path`: geometry, material, friction, the top's
#: displacements, load steps and the gmsh mesh sizes. ``press`` gives a / R = 0.094 and
#: ``shear`` a final Q / (mu P) of 0.69 (c / a = 0.56), in four shear steps.
CM_DEFAULTS: dict[str, float] = {
    "radius": 1.0, "E": 1.0, "nu": 0.49, "mu": 0.3, "press": 0.012, "shear": 0.0055,
    "steps": 4, "h": 0.2, "h_contact": 0.01, "refine_radius": 0.15,
}

#: The gmsh script of the half-disc (:data:`~dwr_signorini.cases.load_path.MESHES`).
_MESH_SCRIPT = MESHES / "cattaneo_2d.py"


# --------------------------------------------------------------------------------------------------
# Theory
# --------------------------------------------------------------------------------------------------


def dundurs_beta(nu: float) -> float:
    """Dundurs' second constant for an elastic body on a rigid flat: (1 - 2 nu) / (2 (1 - nu)).

    beta = 0 decouples the normal and the tangential contact problems (Johnson 1985, eq. 5.4).

    Args:
        nu: The body's Poisson's ratio.

    Returns:
        beta (0 for nu = 1/2).
    """
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


def hertz_half_width(P: float, radius: float, E: float, nu: float) -> tuple[float, float]:
    """Hertz's line contact of a cylinder on a rigid flat, eqs. (H1), (H2) of the module.

    Args:
        P: The normal force per unit length.
        radius: The cylinder's radius R.
        E: Young's modulus of the cylinder.
        nu: Its Poisson's ratio (plane strain: E* = E / (1 - nu^2)).

    Returns:
        ``(a, p0)``: the half-width and the peak pressure.
    """
    e_star = E / (1.0 - nu**2)
    a = math.sqrt(4.0 * abs(P) * radius / (math.pi * e_star))
    return a, (2.0 * abs(P) / (math.pi * a) if a > 0 else 0.0)


def hertz_pressure(x: npt.ArrayLike, a: float, p0: float) -> np.ndarray:
    """Hertz's pressure p(x) = p0 sqrt(1 - x^2 / a^2) on ``|x| <= a``, 0 outside, eq. (H3).

    Also the sphere's p(r), eq. (H3') of :mod:`~dwr_signorini.cases.cattaneo_mindlin_3d`.

    Args:
        x: Positions along the flat (distances r in 3D), from the first contact point.
        a: The contact half-width (radius).
        p0: Hertz's peak pressure.

    Returns:
        p at ``x`` (zero everywhere if a = 0).
    """
    x = np.asarray(x, dtype=float)
    return p0 * np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None)) if a > 0 else 0.0 * x


def stick_half_width(a: float, Q: float, mu: float, P: float) -> float:
    """Cattaneo-Mindlin's stick half-width ``c = a sqrt(1 - |Q| / (mu P))``, eq. (CM1).

    Args:
        a: The contact half-width.
        Q: The tangential force per unit length (its sign does not matter).
        mu: The friction coefficient.
        P: The normal force per unit length.

    Returns:
        c, 0 <= c <= a.

    Raises:
        ValueError: If ``|Q| > mu P`` (the whole contact slides, no stick zone) or P <= 0.
    """
    if P <= 0 or mu <= 0:
        raise ValueError(f"stick_half_width needs P > 0 and mu > 0, got P = {P}, mu = {mu}")
    ratio = abs(Q) / (mu * P)
    if ratio > 1.0:
        raise ValueError(f"|Q| / (mu P) = {ratio:.4g} > 1: the contact slides as a whole")
    return a * math.sqrt(1.0 - ratio)


def cm_traction(x: npt.ArrayLike, a: float, c: float, p0: float, mu: float) -> np.ndarray:
    """Cattaneo-Mindlin's tangential traction q(x), eq. (CM2) (positive, the sign of Q).

    Args:
        x: Positions along the flat, measured from the first contact point.
        a: The contact half-width.
        c: The stick half-width, 0 <= c <= a.
        p0: Hertz's peak pressure.
        mu: The friction coefficient.

    Returns:
        q at ``x``: mu p0 / a (sqrt(a^2 - x^2) - sqrt(c^2 - x^2)) (the second root only where
        ``|x| < c``), zero outside the contact ``|x| > a``.
    """
    x = np.asarray(x, dtype=float)
    if a <= 0:
        return 0.0 * x
    outer = np.sqrt(np.clip(a**2 - x**2, 0.0, None))
    inner = np.sqrt(np.clip(c**2 - x**2, 0.0, None))
    return mu * p0 / a * (outer - inner)


def reversal_stick_half_width(a: float, Q_turn: float, Q: float, mu: float, P: float) -> float:
    """Mindlin-Deresiewicz's stick half-width after a reversal, eq. (MD1) of the module.

    ``c' = a sqrt(1 - |Q_turn - Q| / (2 mu P))``: the tangential force turned back at
    ``Q_turn`` (monotone before) and has since moved to ``Q``.

    Args:
        a: The contact half-width.
        Q_turn: The tangential force per unit length at the reversal (Q* of the module).
        Q: The tangential force per unit length now.
        mu: The friction coefficient.
        P: The normal force per unit length.

    Returns:
        c', 0 <= c' <= a.

    Raises:
        ValueError: If Q is not between ``Q_turn`` and ``-Q_turn`` (no reversal, or more than
            a full one), ``|Q_turn| > mu P``, or P, mu <= 0.
    """
    if P <= 0 or mu <= 0 or abs(Q_turn) > mu * P:
        raise ValueError("reversal_stick_half_width needs P > 0, mu > 0 and |Q_turn| <= mu P, "
                         f"got P = {P}, mu = {mu}, Q_turn = {Q_turn}")
    back = (Q_turn - Q) / Q_turn if Q_turn != 0 else math.nan
    if not 0.0 <= back <= 2.0:
        raise ValueError(f"Q = {Q} is no reversal from Q_turn = {Q_turn}: eq. (MD1) holds for Q "
                         "between Q_turn and -Q_turn (beyond -Q_turn Cattaneo's c of |Q| holds)")
    return a * math.sqrt(1.0 - abs(Q_turn - Q) / (2.0 * mu * P))


def reversal_traction(
    x: npt.ArrayLike, a: float, c_turn: float, c_rev: float, p0: float, mu: float, sign: float
) -> np.ndarray:
    """Mindlin-Deresiewicz's tangential traction after a reversal, eq. (MD2) of the module.

    Args:
        x: Positions along the flat, measured from the first contact point.
        a: The contact half-width.
        c_turn: The stick half-width c* at the reversal (eq. CM1 with Q*).
        c_rev: The stick half-width c' after it (:func:`reversal_stick_half_width`).
        p0: Hertz's peak pressure.
        mu: The friction coefficient.
        sign: The sign of Q* (the traction turns back from it).

    Returns:
        q at ``x``, with the sign of the force: ``sign (q*(x) - 2 q'(x))`` with q* and q' the
        Cattaneo tractions (:func:`cm_traction`) of half-widths ``c_turn`` and ``c_rev``.
    """
    return sign * (cm_traction(x, a, c_turn, p0, mu) - 2.0 * cm_traction(x, a, c_rev, p0, mu))


# --------------------------------------------------------------------------------------------------
# The problem
# --------------------------------------------------------------------------------------------------


def cattaneo_mindlin_mesh(
    comm: MPI.Comm,
    h_contact: float = CM_DEFAULTS["h_contact"],
    h: float = CM_DEFAULTS["h"],
    refine_radius: float = CM_DEFAULTS["refine_radius"],
    radius: float = CM_DEFAULTS["radius"],
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """The half-disc of ``meshes/cattaneo_2d.py``, built by gmsh on rank 0 and distributed.

    Collective. Uses the running gmsh session if there is one (in a model of its own, removed
    afterwards), else starts and ends one.

    Args:
        comm: The communicator.
        h_contact: Macro facet length on the arc within ``refine_radius`` R of (0, 0).
        h: Mesh size away from the contact.
        refine_radius: Radius (relative to R) of the zone of size ``h_contact``.
        radius: The radius R.

    Returns:
        ``(mesh, cell_tags, facet_tags)`` with the facet tags
        :data:`~dwr_signorini.cases.CM_CONTACT`,
        :data:`~dwr_signorini.cases.CM_TOP`.
    """
    return gmsh_mesh(comm, _MESH_SCRIPT, radius=radius, h=h, h_contact=h_contact,
                     refine_radius=refine_radius)


def cattaneo_mindlin_path(
    comm: MPI.Comm,
    h_contact: float = CM_DEFAULTS["h_contact"],
    mu: float = CM_DEFAULTS["mu"],
    nu: float = CM_DEFAULTS["nu"],
    steps: int = int(CM_DEFAULTS["steps"]),
    press: float = CM_DEFAULTS["press"],
    shear: float = CM_DEFAULTS["shear"],
    E: float = CM_DEFAULTS["E"],
    radius: float = CM_DEFAULTS["radius"],
    h: float = CM_DEFAULTS["h"],
    refine_radius: float = CM_DEFAULTS["refine_radius"],
    mesh: tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags] | None = None,
) -> list[SignoriniProblem]:
    """The load path of the module docstring: a press step, then ``steps`` shear steps.

    All problems live on one macro mesh (for :func:`~dwr_signorini.solve_path`); the arc is
    projected onto the circle when the mesh is refined (``boundary_projection``).

    Args:
        comm: The communicator (collective).
        h_contact: Macro facet length at the contact (:func:`cattaneo_mindlin_mesh`).
        mu: Coulomb's friction coefficient.
        nu: Poisson's ratio (0.49: Dundurs' beta = 0.0196, module docstring).
        steps: The number of shear steps (at least 1).
        press: The top's downward displacement (a / R = 0.10 at the defaults).
        shear: The top's final horizontal displacement, reached in ``steps`` equal increments.
        E: Young's modulus.
        radius: The radius R.
        h: Mesh size away from the contact.
        refine_radius: Radius (relative to R) of the zone of size ``h_contact``.
        mesh: ``(msh, cell_tags, facet_tags)`` to use instead of building one (tags
            :data:`~dwr_signorini.cases.CM_CONTACT`,
            :data:`~dwr_signorini.cases.CM_TOP`).

    Returns:
        ``steps + 1`` problems: the press ``(0, -press)``, then ``(k shear / steps, -press)``.

    Raises:
        ValueError: If ``steps`` is not a positive integer.
    """
    check_steps(steps)
    if mesh is None:
        mesh = cattaneo_mindlin_mesh(
            comm, h_contact=h_contact, h=h, refine_radius=refine_radius, radius=radius)
    return shear_path(mesh, 2, mu=mu, nu=nu, steps=steps, press=press, shear=shear, E=E,
                      radius=radius)
