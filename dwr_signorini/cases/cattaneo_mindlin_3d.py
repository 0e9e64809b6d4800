"""Cattaneo-Mindlin in 3D: a sphere pressed onto a rigid flat, then sheared (Coulomb friction).

The body is the half y >= 0 of the hemisphere of ``meshes/hertz_3d.py`` (the ball of radius R
centred at (0, 0, R), cut at z = R; E, nu), its sphere Gamma_C in possible contact with the
rigid half-space z <= 0 (:class:`~dwr_signorini.obstacles.Plane`), Coulomb friction with
coefficient mu (:class:`~dwr_signorini.laws.Coulomb`). The plane y = 0 is a symmetry plane
(u_y = 0): a shear along x keeps the whole sphere's problem symmetric about it. The top z = R is
displaced by ``(0, 0, -press)`` in the first load step and by ``(k shear / steps, 0, -press)``
in steps k = 1, ..., ``steps``. :func:`cattaneo_mindlin_path_3d` builds these ``steps + 1``
problems on one mesh for :func:`~dwr_signorini.solve_path`, as
:func:`~dwr_signorini.cases.cattaneo_mindlin_2d.cattaneo_mindlin_path` does for the
cylinder; what the two share lives in :mod:`~dwr_signorini.cases.load_path` (the
facet tags, the gmsh reader, the load path) and :mod:`~dwr_signorini.cases.measurement` (the
gathering of the facets, the theory's fields, :class:`~dwr_signorini.cases.CMMeasure`);
:func:`~dwr_signorini.cases.measure_cattaneo_mindlin` measures solutions of either path.

Theory (a << R; Johnson, *Contact Mechanics*, 1985, eqs. (4.22)-(4.23) and (7.38)-(7.43)): for
a rigid flat, with E* = E / (1 - nu^2), P the normal force on the whole sphere and r the
distance from the first contact point (0, 0, 0) in the flat,

    (H1')  a = (3 P R / (4 E*))^(1/3),      (H2')  p0 = 3 P / (2 pi a^2),
    (H3')  p(r) = p0 sqrt(1 - r^2 / a^2),   r <= a,

and under a monotonically growing tangential force Q < mu P along x the contact sticks on the
disc r <= c and slips on the annulus c <= r <= a with (Mindlin's approximation: the traction
along Q)

    (CM1') c = a (1 - Q / (mu P))^(1/3),
    (CM2') q(r) = mu p0 (sqrt(1 - r^2 / a^2) - (c / a) sqrt(1 - r^2 / c^2)),  r <= c,
           q(r) = mu p(r),                                                  c <= r <= a.

As in 2D the theory assumes that the normal and the tangential problems decouple (Dundurs'
beta = 0, :func:`~dwr_signorini.cases.cattaneo_mindlin_2d.dundurs_beta`); nu = 0.49 is the
default here too.

The measurements (:func:`~dwr_signorini.cases.measure_cattaneo_mindlin` of a 3D solution,
:class:`~dwr_signorini.cases.CMMeasure`) are those of the whole sphere: on the half body P
and Q (from lambda_t . e_x) are twice the integrals over its Gamma_C, the computed radii a_h and
c_h are those of the discs whose areas are the (doubled) areas in the flat of the macro facets
in contact and sticking, and the relative L2 errors are integrated on every macro facet by a
collapsed Gauss-Legendre rule. The facets are gathered on rank 0
(:func:`gather_contact_patch`) and the results broadcast.

The mesh builder reads the gmsh script ``meshes/hertz_3d.py`` through the package
(:mod:`dwr_signorini.meshes`); pass ``mesh=(msh, cell_tags, facet_tags)`` with the script's tags
to use another mesh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import mesh as dmesh

from ..problem import SignoriniProblem
from .cattaneo_mindlin_2d import hertz_pressure
from .load_path import MESHES, check_steps, gmsh_mesh, mesh_script, shear_path
from .measurement import CMMeasure, cm_measure, gather_facets, relative_l2, theory_fields

__all__ = [
    "CM_DEFAULTS_3D",
    "CM_SYMMETRY_Y",
    "ContactPatch",
    "cattaneo_mindlin_mesh_3d",
    "cattaneo_mindlin_path_3d",
    "cm_traction_3d",
    "gather_contact_patch",
    "hertz_radius",
    "measure_contact_patch",
    "stick_radius",
]

#: Facet tag of the symmetry plane y = 0 of the 3D half sphere (``meshes/hertz_3d.py``).
CM_SYMMETRY_Y = 4

#: The data of :func:`cattaneo_mindlin_path_3d`, as
#: :data:`~dwr_signorini.cases.CM_DEFAULTS`: ``press`` gives a / R = 0.105 and ``shear`` a
#: final Q / (mu P) of about 0.8 (c / a = 0.57).
CM_DEFAULTS_3D: dict[str, float] = {
    "radius": 1.0, "E": 1.0, "nu": 0.49, "mu": 0.3, "press": 0.01, "shear": 0.004,
    "steps": 4, "h": 0.25, "h_contact": 0.03, "refine_radius": 0.15,
}

_MESH_SCRIPT_3D = MESHES / "hertz_3d.py"


# --------------------------------------------------------------------------------------------------
# Theory
# --------------------------------------------------------------------------------------------------


def hertz_radius(P: float, radius: float, E: float, nu: float) -> tuple[float, float]:
    """Hertz's point contact of a sphere on a rigid flat, eqs. (H1'), (H2') of the module.

    Args:
        P: The normal force on the whole sphere.
        radius: The sphere's radius R.
        E: Young's modulus of the sphere.
        nu: Its Poisson's ratio (E* = E / (1 - nu^2)).

    Returns:
        ``(a, p0)``: the contact radius and the peak pressure.
    """
    e_star = E / (1.0 - nu**2)
    a = (3.0 * abs(P) * radius / (4.0 * e_star)) ** (1.0 / 3.0)
    return a, (3.0 * abs(P) / (2.0 * math.pi * a**2) if a > 0 else 0.0)


def stick_radius(a: float, Q: float, mu: float, P: float) -> float:
    """Mindlin's stick radius ``c = a (1 - |Q| / (mu P))^(1/3)``, eq. (CM1').

    Args:
        a: The contact radius.
        Q: The tangential force on the whole sphere (its sign does not matter).
        mu: The friction coefficient.
        P: The normal force on the whole sphere.

    Returns:
        c, 0 <= c <= a.

    Raises:
        ValueError: If ``|Q| > mu P`` (the whole contact slides, no stick zone) or P <= 0.
    """
    if P <= 0 or mu <= 0:
        raise ValueError(f"stick_radius needs P > 0 and mu > 0, got P = {P}, mu = {mu}")
    ratio = abs(Q) / (mu * P)
    if ratio > 1.0:
        raise ValueError(f"|Q| / (mu P) = {ratio:.4g} > 1: the contact slides as a whole")
    return a * (1.0 - ratio) ** (1.0 / 3.0)


def cm_traction_3d(r: npt.ArrayLike, a: float, c: float, p0: float, mu: float) -> np.ndarray:
    """Mindlin's tangential traction q(r) of a sphere, eq. (CM2') (positive, the sign of Q).

    Args:
        r: Distances from the first contact point in the flat.
        a: The contact radius.
        c: The stick radius, 0 <= c <= a.
        p0: Hertz's peak pressure.
        mu: The friction coefficient.

    Returns:
        q at ``r``: mu p0 (sqrt(1 - r^2 / a^2) - (c / a) sqrt(1 - r^2 / c^2)) (the second root
        only where r < c), zero outside the contact r > a. Along the direction of Q.
    """
    r = np.asarray(r, dtype=float)
    if a <= 0:
        return 0.0 * r
    outer = np.sqrt(np.clip(1.0 - (r / a) ** 2, 0.0, None))
    inner = np.sqrt(np.clip(1.0 - (r / c) ** 2, 0.0, None)) if c > 0 else 0.0 * r
    return mu * p0 * (outer - c / a * inner)


# --------------------------------------------------------------------------------------------------
# The problem
# --------------------------------------------------------------------------------------------------


def cattaneo_mindlin_mesh_3d(
    comm: MPI.Comm,
    h_contact: float = CM_DEFAULTS_3D["h_contact"],
    h: float = CM_DEFAULTS_3D["h"],
    refine_radius: float = CM_DEFAULTS_3D["refine_radius"],
    radius: float = CM_DEFAULTS_3D["radius"],
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """The half hemisphere y >= 0 of ``meshes/hertz_3d.py``, built by gmsh on rank 0.

    Collective; gmsh as :func:`~dwr_signorini.cases.cattaneo_mindlin_2d.cattaneo_mindlin_mesh`.

    Args:
        comm: The communicator.
        h_contact: Macro facet size on the sphere within ``refine_radius`` R of (0, 0, 0).
        h: Mesh size away from the contact.
        refine_radius: Radius (relative to R) of the zone of size ``h_contact``.
        radius: The radius R.

    Returns:
        ``(mesh, cell_tags, facet_tags)`` with the facet tags
        :data:`~dwr_signorini.cases.CM_CONTACT` (the sphere),
        :data:`~dwr_signorini.cases.CM_TOP` (z = R) and :data:`CM_SYMMETRY_Y` (y = 0).

    Raises:
        RuntimeError: If the script's tag of the plane y = 0 is not :data:`CM_SYMMETRY_Y`.
    """
    if mesh_script(_MESH_SCRIPT_3D).SYMMETRY_Y != CM_SYMMETRY_Y:
        raise RuntimeError(f"{_MESH_SCRIPT_3D}: SYMMETRY_Y differs from CM_SYMMETRY_Y")
    return gmsh_mesh(comm, _MESH_SCRIPT_3D, radius=radius, h=h, h_contact=h_contact,
                      refine_radius=refine_radius, quarter=0, half=1)


def cattaneo_mindlin_path_3d(
    comm: MPI.Comm,
    h_contact: float = CM_DEFAULTS_3D["h_contact"],
    mu: float = CM_DEFAULTS_3D["mu"],
    nu: float = CM_DEFAULTS_3D["nu"],
    steps: int = int(CM_DEFAULTS_3D["steps"]),
    press: float = CM_DEFAULTS_3D["press"],
    shear: float = CM_DEFAULTS_3D["shear"],
    E: float = CM_DEFAULTS_3D["E"],
    radius: float = CM_DEFAULTS_3D["radius"],
    h: float = CM_DEFAULTS_3D["h"],
    refine_radius: float = CM_DEFAULTS_3D["refine_radius"],
    mesh: tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags] | None = None,
) -> list[SignoriniProblem]:
    """The 3D load path of the module docstring: the half sphere y >= 0, pressed, then sheared.

    Args:
        comm: The communicator (collective).
        h_contact: Macro facet size at the contact (:func:`cattaneo_mindlin_mesh_3d`).
        mu: Coulomb's friction coefficient.
        nu: Poisson's ratio.
        steps: The number of shear steps (at least 1).
        press: The top's downward displacement (a / R = 0.105 at the defaults).
        shear: The top's final displacement along x, reached in ``steps`` equal increments.
        E: Young's modulus.
        radius: The radius R.
        h: Mesh size away from the contact.
        refine_radius: Radius (relative to R) of the zone of size ``h_contact``.
        mesh: ``(msh, cell_tags, facet_tags)`` to use instead of building one (tags
            :data:`~dwr_signorini.cases.CM_CONTACT`, :data:`~dwr_signorini.cases.CM_TOP`,
            :data:`CM_SYMMETRY_Y`).

    Returns:
        ``steps + 1`` problems on the half body (its forces are half the whole sphere's).

    Raises:
        ValueError: If ``steps`` is not a positive integer.

    As :func:`~dwr_signorini.cases.cattaneo_mindlin_2d.cattaneo_mindlin_path` on
    :func:`cattaneo_mindlin_mesh_3d`: the top z = R is displaced by ``(0, 0, -press)``, then by
    ``(k shear / steps, 0, -press)``; the plane y = 0 is a symmetry plane (u_y = 0; a shear
    along x keeps the whole sphere's problem symmetric about it). The sphere is projected onto
    itself when the mesh is refined.
    """
    check_steps(steps)
    if mesh is None:
        mesh = cattaneo_mindlin_mesh_3d(
            comm, h_contact=h_contact, h=h, refine_radius=refine_radius, radius=radius)
    return shear_path(mesh, 3, mu=mu, nu=nu, steps=steps, press=press, shear=shear, E=E,
                       radius=radius, fixed={CM_SYMMETRY_Y: (None, 0.0, None)})


# --------------------------------------------------------------------------------------------------
# Measurements
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ContactPatch:
    """The macro contact facets (triangles) of a 3D solution, gathered on rank 0.

    Attributes:
        x: The vertices of each facet, shape (facets, 3, 3).
        area: Each facet's area as the solver integrates it (the lumped multiplier mass
            ``sol.system.M``; with ``boundary_projection`` the refined facets' area).
        lam: lambda_n on each facet.
        lam_t: The tangential traction vector on each facet, shape (facets, 3).
        active: Whether each facet is in contact (the normal active set).
        stick, slip: Whether each facet is in contact and sticks, slips.
    """

    x: np.ndarray
    area: np.ndarray
    lam: np.ndarray
    lam_t: np.ndarray
    active: np.ndarray
    stick: np.ndarray
    slip: np.ndarray

    @property
    def centroid(self) -> np.ndarray:
        """The facets' centroids, shape (facets, 3)."""
        return self.x.mean(axis=1)

    @property
    def r(self) -> np.ndarray:
        """The centroids' distances from the axis x = y = 0."""
        c = self.centroid
        return np.hypot(c[:, 0], c[:, 1])

    @property
    def flat_area(self) -> np.ndarray:
        """The (straight) facets' areas projected onto the flat z = 0."""
        e1, e2 = self.x[:, 1] - self.x[:, 0], self.x[:, 2] - self.x[:, 0]
        return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])

    @property
    def edge(self) -> np.ndarray:
        """Each facet's mean edge length."""
        return np.mean([np.linalg.norm(self.x[:, (k + 1) % 3] - self.x[:, k], axis=1)
                        for k in range(3)], axis=0)


def gather_contact_patch(sol: Any) -> ContactPatch | None:
    """The macro contact facets of a 3D frictional solution on rank 0 (``None`` elsewhere).

    Collective (:func:`~dwr_signorini.viz.gather.gather_friction`,
    :func:`~dwr_signorini.viz.gather.gather_contact_force` and the facet areas, gathered in the
    same order: each rank's owned contact cells).

    Args:
        sol: A :class:`~dwr_signorini.Solution` of a 3D problem with friction.

    Returns:
        The :class:`ContactPatch` on rank 0, ``None`` on the other ranks.

    Raises:
        ValueError: If the contact facets are not triangles (a 2D problem).
    """
    sub = sol.disc.contact_mesh
    if sub.topology.dim != 2:
        raise ValueError("gather_contact_patch: a 3D problem (triangular contact facets) only")
    n = sub.topology.index_map(2).size_local
    dofs = sol.lam.function_space.dofmap.list[:n, 0]
    n_q = sol.system.algebra.n_q
    owned = dofs < n_q
    area = np.full(n, np.nan)
    area[owned] = sol.system.M.array[:n_q][dofs[owned]]
    areas = sub.comm.gather(area, root=0)
    facets = gather_facets(sol)
    if facets is None:
        return None
    x, lam, lam_t, active, stick, slip = facets
    area = np.concatenate(areas)
    missing = np.isnan(area)  # a facet whose row another rank owns: its straight area
    if missing.any():
        e1, e2 = x[missing, 1] - x[missing, 0], x[missing, 2] - x[missing, 0]
        area[missing] = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    return ContactPatch(x, area, lam, np.asarray(lam_t).reshape(-1, 3), active, stick, slip)


def _triangle_rule(x: np.ndarray, points: int) -> tuple[np.ndarray, np.ndarray]:
    """The collapsed Gauss-Legendre rule with ``points**2`` points on each triangle of ``x``.

    Returns:
        The points, shape (facets, points**2, 3), and the weights relative to the facet's
        area (summing to 1 on every facet), shape (points**2,).
    """
    g, w = np.polynomial.legendre.leggauss(points)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    s, t = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    weights = 2.0 * np.outer(w, w).ravel() * s  # Duffy: x = x0 + s (x1 - x0) + s t (x2 - x1)
    pts = (x[:, None, 0] + s[None, :, None] * (x[:, None, 1] - x[:, None, 0])
           + (s * t)[None, :, None] * (x[:, None, 2] - x[:, None, 1]))
    return pts, weights


def measure_contact_patch(
    patch: ContactPatch, mu: float, E: float, nu: float, radius: float, points: int,
    half: bool | None,
) -> CMMeasure:
    """Measure the gathered facets of a 3D solution against Hertz and Mindlin (module docstring).

    Args:
        patch: The facets of :func:`gather_contact_patch` (rank 0).
        mu: Coulomb's friction coefficient of the path.
        E: Young's modulus.
        nu: Poisson's ratio.
        radius: The radius R.
        points: Gauss-Legendre points per direction of the collapsed rule on each triangle.
        half: The mesh is the half y >= 0 of a body symmetric about y = 0 (forces and areas
            doubled); None: if no contact facet reaches below y = 0.

    Returns:
        The :class:`~dwr_signorini.cases.measurement.CMMeasure` of
        :func:`~dwr_signorini.cases.measure_cattaneo_mindlin`.
    """
    if half is None:
        half = bool(patch.x[..., 1].min() > -1e-9 * radius)
    factor = 2.0 if half else 1.0
    P = factor * float(np.sum(patch.lam * patch.area))
    Q = factor * float(np.sum(patch.lam_t[:, 0] * patch.area))
    theory = theory_fields(P, Q, mu, hertz_radius(P, radius, E, nu), stick_radius)
    a, p0, c = theory["a"], theory["p0"], theory["c"]

    def disc_radius(mask: np.ndarray) -> float:
        return math.sqrt(factor * float(np.sum(patch.flat_area[mask])) / math.pi)

    a_h, c_h = disc_radius(patch.active), disc_radius(patch.stick)
    cx = patch.centroid[:, 0]
    center = (float(np.sum((cx * patch.flat_area)[patch.stick])
                    / np.sum(patch.flat_area[patch.stick])) if patch.stick.any() else math.nan)
    zone = patch.r <= max(a, a_h)
    h_facet = float(patch.edge[zone].mean()) if zone.any() else math.nan

    pts, w = _triangle_rule(patch.x, points)
    r = np.hypot(pts[..., 0], pts[..., 1])
    dA = patch.area[:, None] * w[None, :]
    q = cm_traction_3d(r, a, c if c == c else 0.0, p0, mu)
    p = hertz_pressure(r, a, p0)
    sign = 1.0 if Q >= 0 else -1.0
    norm_q = float(np.sum(dA * q**2))
    norm_p = float(np.sum(dA * p**2))
    err_t = float(np.sum(dA * (sign * patch.lam_t[:, 0, None] - q) ** 2))
    means = np.sum(w[None, :] * q, axis=1)
    err_b = float(np.sum(dA * (means[:, None] - q) ** 2))
    err_n = float(np.sum(dA * (patch.lam[:, None] - p) ** 2))
    ty = float(np.sum(patch.area * patch.lam_t[:, 1] ** 2))
    mag = np.linalg.norm(patch.lam_t, axis=1)
    rc = np.maximum(patch.r, 1e-300)
    radial = (cx * patch.lam_t[:, 0] + patch.centroid[:, 1] * patch.lam_t[:, 1]) / rc
    normal = mu * float(np.sum(patch.lam * patch.area))
    return cm_measure(
        theory, a_h, c_h, center, h_facet, patch.stick, patch.slip,
        l2_lam_t=relative_l2(err_t, norm_q), l2_best=relative_l2(err_b, norm_q),
        l2_lam=relative_l2(err_n, norm_p),
        max_lam_t=float(mag.max() / (mu * p0)) if p0 > 0 else math.nan,
        rms_lam_t=relative_l2(float(np.sum(patch.area * mag**2)), mu**2 * norm_p),
        coupling=float(np.sum(radial * patch.area)) / normal if normal > 0 else math.nan,
        dim=3, l2_lam_ty=relative_l2(ty, norm_q),
    )
