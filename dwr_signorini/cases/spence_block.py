"""Spence's problem: a rigid cylinder pressed into an elastic half-plane with Coulomb friction.

Theory (Spence 1975, *J. Elasticity* 5, 297-319; Johnson, *Contact Mechanics*, 1985, Sect.
5.4; Hills, Nowell and Sackfield, *Mechanics of Elastic Contacts*, 1993): a rigid cylinder of
radius R pressed monotonically into an elastic half-plane (E, nu, plane strain) touches it on
|x| <= a with Hertz's pressure (eqs. H1-H3 of :mod:`~dwr_signorini.cases.cattaneo_mindlin_2d`,
E* = E / (1 - nu^2)). The pressure draws the half-plane's surface towards the centre, by a
tangential strain of order beta p / E* with Dundurs' constant

    (S1)  beta = (1 - 2 nu) / (2 (1 - nu))
          (rigid indenter, :func:`~dwr_signorini.cases.dundurs_beta`),

and friction resists it: the contact sticks on |x| <= c and slips outwards of it, with a
tangential traction q of either sign on the two halves (odd in x, no net force). Hertz's
profile makes the problem self-similar: a point that the growing stick zone has taken keeps
its relative displacement, and

    (S2)  c / a depends on beta / mu only (constant under a monotone press),

1 at beta = 0 (nu = 1/2: no tangential traction at all, q = 0) and falling as beta / mu
grows. (S2) is exact when the shear's share of the normal displacement is neglected
(Goodman's approximation); the full half-plane theory couples the normal problem through
beta mu, and its c / a, computed by the boundary elements of ``tests/halfplane_contact.py``,
is 0.685 at nu = 0.3, mu = 0.3 and 0.720 at nu = 0.4, mu = 0.175 (both beta / mu = 0.95).

The half-plane is approximated by the block of ``meshes/spence_block.py``: width and depth
hundreds of contact widths (the default 40 x 20 against a <= 0.12), its bottom clamped, facets
of ``h_contact`` on the part ``|x| <= contact_half`` of its top that the cylinder may touch, the
mesh growing linearly away from it. The cylinder (:class:`~dwr_signorini.obstacles.Sphere` of
radius R in 2D, centred at (0, R)) touches the top at the origin and stays where it is; the
press is the bottom's upward displacement, growing from step to step so that a grows by a
fixed factor per step (:func:`spence_presses`). The slip of a step is the body's displacement
increment relative to the cylinder along its tangent (the contact frame of a rigid obstacle,
``docs/theory.md``); the cylinder moved down instead, one translated obstacle per step, gives
the same tractions (:mod:`~dwr_signorini.obstacle_motion`).

The steps grow geometrically because a step adds its new contact in slip: with a uniform step
in a that contact is a shrinking fraction of a, and so is the slip zone it leaves; a fixed
factor per step adds the same fraction of a at every step, so the discrete path is
self-similar as the theory is.

The measurements of :func:`~dwr_signorini.cases.measure_cattaneo_mindlin` apply as they are
(the contact is centred at x = 0, P and a from the computed lambda_n, c_h from the sticking
facets, ``rms_lam_t`` and ``coupling`` the size of lambda_t against mu lambda_n).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

from mpi4py import MPI

from dolfinx import mesh as dmesh

from ..laws import Coulomb
from ..obstacles import Sphere
from ..problem import SignoriniProblem
from .load_path import CM_CONTACT, CM_TOP, MESHES, gmsh_mesh

__all__ = ["SPENCE_DEFAULTS", "spence_block_mesh", "spence_block_path", "spence_presses"]

#: The data of :func:`spence_block_path`: the cylinder (a / R = 0.012 at the last press, so
#: that the tilt of its surface, a / R against beta, is negligible), material and friction
#: (beta / mu = 0.95), the presses (a from 0.03 to 0.12 in steps of 1.07 a) and the mesh.
SPENCE_DEFAULTS: dict[str, float] = {
    "radius": 10.0, "E": 1.0, "nu": 0.3, "mu": 0.3, "press": 0.004, "first": 0.0625,
    "ratio": 1.07, "width": 40.0, "depth": 20.0, "contact_half": 0.2, "h_contact": 0.005,
    "h": 2.0, "growth": 0.25,
}

_MESH_SCRIPT = MESHES / "spence_block.py"
_MESH_KEYS = ("width", "depth", "contact_half", "h_contact", "h", "growth")


def spence_block_mesh(
    comm: MPI.Comm, **sizes: float
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """The block of ``meshes/spence_block.py``, built by gmsh on rank 0 and distributed.

    Collective.

    Args:
        comm: The communicator.
        **sizes: Any of ``width``, ``depth``, ``contact_half``, ``h_contact``, ``h``, ``growth``
            (:data:`SPENCE_DEFAULTS`; the script's docstring).

    Returns:
        ``(mesh, cell_tags, facet_tags)``, the contact boundary tagged
        :data:`~dwr_signorini.cases.CM_CONTACT` and the clamped bottom
        :data:`~dwr_signorini.cases.CM_TOP` (the face the path drives).

    Raises:
        TypeError: If a keyword is not one of the mesh's sizes.
    """
    unknown = set(sizes) - set(_MESH_KEYS)
    if unknown:
        raise TypeError(f"spence_block_mesh: unknown sizes {sorted(unknown)}; "
                        f"it takes {', '.join(_MESH_KEYS)}")
    kwargs = {key: float(sizes.get(key, SPENCE_DEFAULTS[key])) for key in _MESH_KEYS}
    return gmsh_mesh(comm, _MESH_SCRIPT, **kwargs)


def spence_presses(
    press: float = SPENCE_DEFAULTS["press"],
    first: float = SPENCE_DEFAULTS["first"],
    ratio: float = SPENCE_DEFAULTS["ratio"],
) -> list[float]:
    """Geometric presses: ``press ratio^(-2 j)``, j = n, ..., 0, from about ``first press`` up.

    a grows about as the square root of the press, by ``ratio`` per step: each step adds the
    same fraction of a, which keeps the discrete path self-similar (module docstring).

    Args:
        press: The last (largest) press.
        first: The first press relative to the last (0 < first < 1).
        ratio: The growth of a per step (> 1).

    Returns:
        The increasing presses, the last ``press``.

    Raises:
        ValueError: If the arguments are out of range.
    """
    if not (press > 0 and 0 < first < 1 and ratio > 1):
        raise ValueError("spence_presses needs press > 0, 0 < first < 1 and ratio > 1, got "
                         f"{press}, {first}, {ratio}")
    n = math.ceil(-math.log(first) / (2.0 * math.log(ratio)))
    return [press * ratio ** (-2.0 * j) for j in range(n, -1, -1)]


def spence_block_path(
    comm: MPI.Comm,
    presses: Sequence[float] | None = None,
    mu: float = SPENCE_DEFAULTS["mu"],
    nu: float = SPENCE_DEFAULTS["nu"],
    E: float = SPENCE_DEFAULTS["E"],
    radius: float = SPENCE_DEFAULTS["radius"],
    mesh: tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags] | None = None,
    loads: Sequence[float] | None = None,
    **sizes: float,
) -> list[SignoriniProblem]:
    """The monotone press of the module docstring, one problem per press, for ``solve_path``.

    Each step displaces the block's bottom by ``(0, press)`` towards the rigid cylinder of
    radius ``radius`` centred at (0, radius), with Coulomb friction ``mu``; Dundurs' beta is
    ``cases.dundurs_beta(nu)``, eq. (S1); or, with ``loads``, the cylinder pressed by a force.

    Args:
        comm: The communicator (collective).
        presses: The bottom's upward displacements, increasing and positive (default
            :func:`spence_presses`).
        mu: Coulomb's friction coefficient.
        nu: Poisson's ratio.
        E: Young's modulus.
        radius: The cylinder's radius R.
        mesh: ``(msh, cell_tags, facet_tags)`` with the tags of :func:`spence_block_mesh`, or
            None to build it.
        **sizes: The sizes of :func:`spence_block_mesh` (without ``mesh``).
        loads: The cylinder's forces P per unit length, increasing and positive (Hertz: a =
            sqrt(4 P R / (pi E*))), in place of ``presses``: the press stated as the
            half-plane theory states it, the bottom clamped and the cylinder pressed down
            (:mod:`~dwr_signorini.force`; its motion is part of the slip).

    Returns:
        One problem per press, on one mesh.

    Raises:
        ValueError: If the presses (or loads) are not positive and increasing.
        TypeError: If both ``mesh`` and sizes, or both ``presses`` and ``loads``, are given.
    """
    if loads is not None and presses is not None:
        raise TypeError("spence_block_path: give presses= or loads=, not both")
    values = loads if loads is not None else spence_presses() if presses is None else presses
    values = [float(d) for d in values]
    if not values or values[0] <= 0 or any(b <= a for a, b in itertools.pairwise(values)):
        raise ValueError(f"spence_block_path: {'loads' if loads is not None else 'presses'} "
                         f"must be positive and increasing, got {values}")
    if mesh is None:
        mesh = spence_block_mesh(comm, **sizes)
    elif sizes:
        raise TypeError("spence_block_path: give mesh= or the mesh's sizes, not both")
    msh, cell_tags, facet_tags = mesh
    law = Coulomb(mu)

    def step(value: float) -> SignoriniProblem:
        if loads is None:
            gap, bottom = Sphere((0.0, radius), radius), (0.0, value)
        else:
            gap = Sphere((0.0, radius), radius, force=value, direction=(0.0, -1.0))
            bottom = (0.0, 0.0)
        return SignoriniProblem(
            msh, facet_tags, contact=CM_CONTACT, dirichlet={CM_TOP: bottom},
            E=E, nu=nu, model="plane_strain", gap=gap, friction=law, cell_tags=cell_tags)

    return [step(value) for value in values]
