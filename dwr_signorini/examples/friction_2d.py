"""A frictional example: a block pressed onto a rigid cylinder (sphere) and sheared (Tresca).

The block (0, 1) x (0, 1/2) in plane strain (E = 10, nu = 0.3) lies with its bottom Gamma_C on a
rigid cylinder of radius R, whose top touches the block at x = 1/2 (the paraboloid gap of
:func:`friction_gap`). The top is displaced by ``(shear, -press)``: the cylinder indents the
bottom over a contact zone about the middle, and the shear makes the contact zone stick in its
centre and slip towards its ends, where the pressure falls and friction cannot hold it (the
zones of Cattaneo and Mindlin's problem, with Tresca's threshold s instead of Coulomb's
mu lambda_n). The quantity of interest is the total friction force,
``J(u, lambda, lambda_t) = int_GC lambda_t ds`` (:func:`goal_friction_force`).

With ``dim=3`` the block is (0, 1) x (0, 1) x (0, 1/2) on a rigid sphere of radius R touching
its bottom at (1/2, 1/2), the top displaced by ``(shear, 0, -press)``: a stick disc in a slip
annulus, with the slip direction turning round the annulus; the goal is the friction force
along x, ``int_GC lambda_t . e_x ds``.
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import mesh as dmesh

from ..laws import Tresca
from ..problem import SignoriniProblem
from ._mesh import CONTACT, DIRICHLET, tag_block_facets

__all__ = [
    "FRICTION_DEFAULTS",
    "FRICTION_DEFAULTS_3D",
    "friction_gap",
    "friction_problem",
    "goal_friction_force",
]

#: The data of :func:`friction_problem`: cylinder radius, top displacement, Tresca threshold.
FRICTION_DEFAULTS = {"radius": 1.0, "press": 0.02, "shear": 0.01, "s": 0.2}

#: The 3D demo's sphere radius, macro mesh (nx x nx x ny) and threshold, the displacements as
#: in 2D: the contact disc spans a few macro facets (a sphere of radius 1 would touch about one)
#: and, with s = 0.1, a stick disc lies in a slip annulus (with s = 0.2 the disc sticks).
FRICTION_DEFAULTS_3D = {"radius": 4.0, "nx": 6, "ny": 3, "s": 0.1}


def friction_gap(radius: float, dim: int = 2) -> Any:
    """The gap to a cylinder (2D) or sphere (3D) of ``radius`` touching the bottom's centre.

    Args:
        radius: The radius R of the cylinder or sphere.
        dim: 2 or 3.

    Returns:
        ``gap(x) -> UFL scalar``, the paraboloid ``|x' - x'_0|^2 / (2 R)`` in the bottom's
        coordinates x' = x (2D), (x, y) (3D), x'_0 the bottom's centre.
    """

    def gap(x: Any) -> Any:
        out = (x[0] - 0.5) ** 2
        if dim == 3:
            out = out + (x[1] - 0.5) ** 2
        return out / (2.0 * radius)

    return gap


def friction_problem(
    comm: MPI.Comm,
    nx: int = 17,
    ny: int = 7,
    radius: float = FRICTION_DEFAULTS["radius"],
    press: float = FRICTION_DEFAULTS["press"],
    shear: float = FRICTION_DEFAULTS["shear"],
    s: float = FRICTION_DEFAULTS["s"],
    dim: int = 2,
) -> SignoriniProblem:
    """The sheared block on a cylinder or sphere (module docstring).

    Args:
        comm: The communicator (collective).
        nx: Macro cells along x (and y in 3D).
        ny: Macro cells across the block's height.
        radius: The radius R of the cylinder (sphere).
        press: The top's displacement into the obstacle.
        shear: The top's displacement along x.
        s: Tresca's slip threshold.
        dim: 2 or 3.

    Returns:
        The :class:`~dwr_signorini.SignoriniProblem` with ``friction=Tresca(s)``, tags
        :data:`DIRICHLET` (the top), :data:`CONTACT` (the bottom) and :data:`NEUMANN`.

    Raises:
        ValueError: If ``dim`` is neither 2 nor 3.

    In 2D an nx x ny triangle macro mesh; the default nx, ny give macro triangles without two
    edges of the same length (dolfinx's refinement orders edges by length, and ties broken by
    round-off would refine serial and parallel runs differently). In 3D an nx x nx x ny
    tetrahedral macro mesh.
    """
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    top = 0.5
    if dim == 2:
        msh = dmesh.create_rectangle(
            comm, [np.array([0.0, 0.0]), np.array([1.0, top])], [nx, ny],
            dmesh.CellType.triangle, ghost_mode=dmesh.GhostMode.none,
        )
    else:
        msh = dmesh.create_box(
            comm, [np.array([0.0, 0.0, 0.0]), np.array([1.0, 1.0, top])], [nx, nx, ny],
            dmesh.CellType.tetrahedron, ghost_mode=dmesh.GhostMode.none,
        )


    moved = (shear, -press) if dim == 2 else (shear, 0.0, -press)
    return SignoriniProblem(
        msh, tag_block_facets(msh, top), contact=CONTACT,
        dirichlet={DIRICHLET: moved}, E=10.0, nu=0.3,
        gap=friction_gap(radius, dim), friction=Tresca(s),
    )


def goal_friction_force() -> Any:
    """``goal(u, lam, m, lam_t) = int_GC lambda_t ds``, the total friction force on the body.

    Returns:
        The goal; in 3D (lam_t the traction vector) the force's x component,
        ``int_GC lambda_t . e_x ds``.
    """

    def goal(u: Any, lam: Any, m: Any, lam_t: Any) -> ufl.Form:
        return (lam_t if lam_t.ufl_shape == () else lam_t[0]) * m.ds_contact

    return goal
