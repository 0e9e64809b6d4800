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
friction resists it;
:attr:`~dwr_signorini.examples.cattaneo_mindlin_measure.CMMeasure.coupling`). Measured at the
defaults (mu = 0.3, macro facets of 0.02 to 0.0025 at the contact): the mean friction on either
half of the contact is within 3.5 % of its Coulomb limit, with a sign that changes with the
mesh, while lambda_t oscillates from facet to facet (rms 0.10-0.18 of mu p, up to 0.4 mu p0 at
the ends of the contact). The oscillation does not shrink under refinement: it is the P1
displacement's response to nu = 0.49 (lambda / mu = 49, near-incompressible), seen in lambda_n
too, and it also rides on lambda_t in the shear steps (about +-0.08 mu p0 in the stick zone).

The measurements against this theory (and that of the sphere) are in
:mod:`~dwr_signorini.examples.cattaneo_mindlin_measure`. The 3D path of
:mod:`~dwr_signorini.examples.cattaneo_mindlin_3d` (a sphere) imports the pieces the two
dimensions share from here (the tags, the gmsh reader, the load path).

The mesh builder reads the gmsh script ``meshes/cattaneo_2d.py``, found through the package
(:mod:`dwr_signorini.meshes`, the checkout's ``meshes/`` installed with it), so it works from the
checkout and after ``pip install .``; pass ``mesh=(msh, cell_tags, facet_tags)`` with the
script's tags to use another mesh.
"""

from __future__ import annotations

import importlib.resources
import importlib.util
import math
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

__all__ = [
    "CM_CONTACT",
    "CM_DEFAULTS",
    "CM_TOP",
    "cattaneo_mindlin_mesh",
    "cattaneo_mindlin_path",
    "cm_traction",
    "dundurs_beta",
    "hertz_half_width",
    "hertz_pressure",
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

# The gmsh scripts: the checkout's meshes/, installed with the package as dwr_signorini.meshes
# (found through the package, wherever it is imported from).
_MESHES = Path(str(importlib.resources.files("dwr_signorini.meshes")))
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
    """Hertz's pressure p(x) = p0 sqrt(1 - x^2 / a^2) on ``|x| <= a``, 0 outside, eq. (H3).

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


# --------------------------------------------------------------------------------------------------
# The problem
# --------------------------------------------------------------------------------------------------


def _mesh_script(script: Path = _MESH_SCRIPT) -> Any:
    """The module ``dwr_signorini/meshes/cattaneo_2d.py`` (or ``script``) of the package."""
    if not script.is_file():
        raise FileNotFoundError(
            f"the Cattaneo-Mindlin mesh builders read the gmsh script {script}, which is missing "
            "(a package installed without its meshes/): pass mesh=(msh, cell_tags, facet_tags)"
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
