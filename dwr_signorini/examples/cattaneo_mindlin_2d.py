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

x measured from the first contact point (0, 0). The theory assumes that the normal and the
tangential problems decouple, which holds exactly for nu = 1/2 (rigid flat): Dundurs' constant
beta = (1 - 2 nu) / (2 (1 - nu)) vanishes (:func:`dundurs_beta`). With nu = 0.49 (the default;
nu = 1/2 itself is not admissible in the displacement formulation) beta = 0.0196, and the press
alone leaves an odd tangential traction (Poisson's ratio draws the contact surface inwards and
friction resists it; :attr:`CMMeasure.coupling`). Measured at the defaults (mu = 0.3, macro
facets of 0.02 to 0.0025 at the contact): the mean friction on either half of the contact is
within 3.5 % of its Coulomb limit, with a sign that changes with the mesh, while lambda_t
oscillates from facet to facet (rms 0.10-0.18 of mu p, up to 0.4 mu p0 at the ends of the
contact). The oscillation does not shrink under refinement: it is the P1 displacement's
response to nu = 0.49 (lambda / mu = 49, near-incompressible), seen in lambda_n too, and it
also rides on lambda_t in the shear steps (about +-0.08 mu p0 in the stick zone).

The measurements (:func:`measure_cattaneo_mindlin`) read a solution as a user would: P and Q
are the integrals of lambda_n and lambda_t over Gamma_C (Q with its sign: the goal
:func:`~dwr_signorini.examples.goal_friction_force` is Q), the computed stick half-width c_h
is half the extent along x of the sticking macro facets (their outer vertices), and the
relative L2 error of lambda_t against q(x) is integrated facet by facet (Gauss-Legendre on
every straight macro facet). All of them are collective: the facets are gathered on rank 0 and
the results broadcast.

The measurement and its record serve both dimensions: :func:`measure_cattaneo_mindlin` also
measures a solution of the 3D path of :mod:`~dwr_signorini.examples.cattaneo_mindlin_3d` (a
sphere), which imports the pieces the two share from here (the tags, the gmsh reader, the load
path, the gathering of the facets, :class:`CMMeasure`).

The mesh builder reads the gmsh script ``meshes/cattaneo_2d.py`` of the project's checkout (the
folder next to the package); pass ``mesh=(msh, cell_tags, facet_tags)`` with the script's tags
to use another mesh.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
from dolfinx import mesh as dmesh

from ..laws import Coulomb
from ..mesh_io import read_mesh
from ..obstacles import Plane
from ..problem import SignoriniProblem
from ..viz.gather import gather_contact_force, gather_friction

__all__ = [
    "CM_CONTACT",
    "CM_DEFAULTS",
    "CM_TOP",
    "CMMeasure",
    "ContactProfile",
    "cattaneo_mindlin_mesh",
    "cattaneo_mindlin_path",
    "cm_traction",
    "dundurs_beta",
    "gather_contact_profile",
    "hertz_half_width",
    "hertz_pressure",
    "measure_cattaneo_mindlin",
    "stick_half_width",
]

#: Facet tags of ``meshes/cattaneo_2d.py`` (and of ``meshes/hertz_3d.py``): the arc Gamma_C
#: and the top.
CM_CONTACT, CM_TOP = 1, 2

#: The data of :func:`cattaneo_mindlin_path`: geometry, material, friction, the top's
#: displacements, load steps and the gmsh mesh sizes. ``press`` gives a / R = 0.094 and
#: ``shear`` a final Q / (mu P) of 0.69 (c / a = 0.56), in four shear steps.
CM_DEFAULTS: dict[str, float] = {
    "radius": 1.0, "E": 1.0, "nu": 0.49, "mu": 0.3, "press": 0.012, "shear": 0.0055,
    "steps": 4, "h": 0.2, "h_contact": 0.01, "refine_radius": 0.15,
}

_MESHES = Path(__file__).resolve().parents[2] / "meshes"
_MESH_SCRIPT = _MESHES / "cattaneo_2d.py"


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
    """Hertz's pressure p(x) = p0 sqrt(1 - x^2 / a^2) on |x| <= a, 0 outside, eq. (H3).

    Also the sphere's p(r), eq. (H3') of :mod:`~dwr_signorini.examples.cattaneo_mindlin_3d`.

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
    """Cattaneo-Mindlin's stick half-width c = a sqrt(1 - |Q| / (mu P)), eq. (CM1).

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
        |x| < c), zero outside the contact |x| > a.
    """
    x = np.asarray(x, dtype=float)
    if a <= 0:
        return 0.0 * x
    outer = np.sqrt(np.clip(a**2 - x**2, 0.0, None))
    inner = np.sqrt(np.clip(c**2 - x**2, 0.0, None))
    return mu * p0 / a * (outer - inner)


# --------------------------------------------------------------------------------------------------
# The problem
# --------------------------------------------------------------------------------------------------


def _mesh_script(script: Path = _MESH_SCRIPT) -> Any:
    """The module ``meshes/cattaneo_2d.py`` (or ``script``) of the checkout."""
    if not script.is_file():
        raise FileNotFoundError(
            f"the Cattaneo-Mindlin mesh builders read the gmsh script {script}, which is missing "
            "(an installed package has no meshes/ folder): pass mesh=(msh, cell_tags, facet_tags)"
        )
    spec = importlib.util.spec_from_file_location(f"meshes_{script.stem}", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if (module.CONTACT, module.TOP) != (CM_CONTACT, CM_TOP):
        raise RuntimeError(f"{script}: tags differ from CM_CONTACT, CM_TOP")
    return module


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
        ``(mesh, cell_tags, facet_tags)`` with the facet tags :data:`CM_CONTACT`, :data:`CM_TOP`.
    """
    return _gmsh_mesh(comm, _MESH_SCRIPT, radius=radius, h=h, h_contact=h_contact,
                      refine_radius=refine_radius)


def _gmsh_mesh(
    comm: MPI.Comm, script_path: Path, **kwargs: Any
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """The mesh of a gmsh script's ``build(model, **kwargs)``, made on rank 0 and distributed."""
    import gmsh

    script = _mesh_script(script_path)
    started = not gmsh.isInitialized()
    if started:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.add(script_path.stem)
            script.build(gmsh.model, **kwargs)
        return read_mesh(gmsh.model, comm)
    finally:
        if started:
            gmsh.finalize()
        elif comm.rank == 0:
            gmsh.model.remove()


def _check_steps(steps: int) -> None:
    """Raise a ValueError unless ``steps`` is a positive integer."""
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps must be a positive integer, got {steps!r}")


def _shear_path(
    mesh: tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags],
    dim: int,
    *,
    mu: float,
    nu: float,
    steps: int,
    press: float,
    shear: float,
    E: float,
    radius: float,
    fixed: dict[int, tuple[float | None, ...]] | None = None,
) -> list[SignoriniProblem]:
    """The press step and the ``steps`` shear steps of a cylinder (2D) or sphere (3D).

    The body of radius ``radius`` centred at ``radius e_dim`` touches the rigid flat
    x_dim <= 0 at the origin (Coulomb friction ``mu``); its top :data:`CM_TOP` is displaced by
    ``-press e_dim + (k shear / steps) e_x`` in step k = 0, ..., ``steps``, and
    :data:`CM_CONTACT` is projected onto the circle (sphere) when the mesh is refined.

    Args:
        mesh: ``(msh, cell_tags, facet_tags)``.
        dim: 2 (plane strain) or 3.
        mu: Coulomb's friction coefficient.
        nu: Poisson's ratio.
        steps: The number of shear steps.
        press: The top's displacement towards the flat.
        shear: The top's final displacement along x.
        E: Young's modulus.
        radius: The radius R.
        fixed: Further Dirichlet conditions of every step, ``{tag: components}``.

    Returns:
        ``steps + 1`` problems on ``mesh``.
    """
    msh, cell_tags, facet_tags = mesh
    flat = Plane((0.0,) * dim, (0.0,) * (dim - 1) + (-1.0,))
    center = np.zeros(3)
    center[dim - 1] = radius
    center = center[:, None]

    def onto_surface(x: np.ndarray) -> np.ndarray:
        d = x - center
        d[dim:] = 0.0
        return center + radius * d / np.linalg.norm(d, axis=0)

    law = Coulomb(mu)
    model = "plane_strain" if dim == 2 else "3d"
    return [
        SignoriniProblem(
            msh, facet_tags, contact=CM_CONTACT,
            dirichlet={CM_TOP: (k * shear / steps, *(0.0,) * (dim - 2), -press), **(fixed or {})},
            E=E, nu=nu, model=model, gap=flat, friction=law, cell_tags=cell_tags,
            boundary_projection={CM_CONTACT: onto_surface},
        )
        for k in range(int(steps) + 1)
    ]


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
            :data:`CM_CONTACT`, :data:`CM_TOP`).

    Returns:
        ``steps + 1`` problems: the press ``(0, -press)``, then ``(k shear / steps, -press)``.

    Raises:
        ValueError: If ``steps`` is not a positive integer.
    """
    _check_steps(steps)
    if mesh is None:
        mesh = cattaneo_mindlin_mesh(
            comm, h_contact=h_contact, h=h, refine_radius=refine_radius, radius=radius)
    return _shear_path(mesh, 2, mu=mu, nu=nu, steps=steps, press=press, shear=shear, E=E,
                       radius=radius)


# --------------------------------------------------------------------------------------------------
# Measurements
# --------------------------------------------------------------------------------------------------


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
    """A solution of the Cattaneo-Mindlin path measured against the theory (module docstring).

    Attributes:
        P: int_GC lambda_n ds, the normal force per unit length.
        Q: int_GC lambda_t ds, the tangential force (with its sign).
        ratio: |Q| / (mu P).
        a: Hertz's half-width for P, eq. (H1).
        p0: Hertz's peak pressure for P, eq. (H2).
        c: Cattaneo-Mindlin's stick half-width for P and Q, eq. (CM1) (nan if |Q| > mu P).
        a_h: Half the extent along x of the macro facets in contact (outer vertices).
        c_h: Half the extent along x of the sticking macro facets (outer vertices; 0 if none).
        stick_center: The middle of the sticking facets' extent (0 in the theory).
        h_facet: The longest macro facet of the contact zone |x| <= a: the unit of "within
            one macro facet".
        c_error_facets: (c_h - c) / h_facet.
        a_error_facets: (a_h - a) / h_facet.
        num_stick, num_slip: The numbers of sticking and slipping macro facets.
        l2_lam_t: ||lambda_t - sign(Q) q||_L2(GC) / ||q||_L2(GC), eq. (CM2).
        l2_best: The relative L2 error of the best approximation of q by macro-facet constants
            (the facet means of q): what lambda_t's P0 space allows at best.
        l2_lam: ||lambda_n - p||_L2(GC) / ||p||_L2(GC), eq. (H3).
        max_lam_t: max |lambda_t| / (mu p0): a coupling measure of the press step.
        rms_lam_t: ||lambda_t||_L2(GC) / ||mu p||_L2(GC), eq. (H3): another one.
        coupling: int_{GC, x > 0} lambda_t ds / (mu int_{GC, x > 0} lambda_n ds): the mean
            friction on one half of the contact in units of its Coulomb limit, the coupling
            measure of the press step (the press alone gives an odd lambda_t, zero for
            beta = 0).
        dim: 2, or 3 for a solution of
            :func:`~dwr_signorini.examples.cattaneo_mindlin_3d.cattaneo_mindlin_path_3d`.
        l2_lam_ty: In 3D ||lambda_t . e_y||_L2(GC) / ||q||_L2(GC), the traction across the shear
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
        sol: A :class:`~dwr_signorini.Solution` of one step of :func:`cattaneo_mindlin_path`
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
