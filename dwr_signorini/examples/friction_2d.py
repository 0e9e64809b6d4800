"""A frictional example: a block pressed onto a rigid cylinder and sheared (Tresca's law).

The block (0, 1) x (0, 1/2) in plane strain (E = 10, nu = 0.3) lies with its bottom Gamma_C on a
rigid cylinder of radius R, whose top touches the block at x = 1/2 (the paraboloid gap of
:func:`friction_gap`). The top is displaced by ``(shear, -press)``: the cylinder indents the
bottom over a contact zone about the middle, and the shear makes the contact zone stick in its
centre and slip towards its ends, where the pressure falls and friction cannot hold it (the
zones of Cattaneo and Mindlin's problem, with Tresca's threshold s instead of Coulomb's
mu lambda_n). The quantity of interest is the total friction force,
``J(u, lambda, lambda_t) = int_GC lambda_t ds`` (:func:`goal_friction_force`).
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import mesh as dmesh

from ..laws import Tresca
from ..problem import SignoriniProblem
from ._mesh import CONTACT, DIRICHLET, NEUMANN, tag_exterior_facets

__all__ = [
    "FRICTION_DEFAULTS",
    "friction_gap",
    "friction_problem",
    "goal_friction_force",
]

#: The data of :func:`friction_problem`: cylinder radius, top displacement, Tresca threshold.
FRICTION_DEFAULTS = {"radius": 1.0, "press": 0.02, "shear": 0.01, "s": 0.2}


def friction_gap(radius: float) -> Any:
    """The gap to a cylinder of ``radius`` touching the bottom at x = 1/2 (a parabola)."""

    def gap(x: Any) -> Any:
        return (x[0] - 0.5) ** 2 / (2.0 * radius)

    return gap


def friction_problem(
    comm: MPI.Comm,
    nx: int = 17,
    ny: int = 7,
    radius: float = FRICTION_DEFAULTS["radius"],
    press: float = FRICTION_DEFAULTS["press"],
    shear: float = FRICTION_DEFAULTS["shear"],
    s: float = FRICTION_DEFAULTS["s"],
) -> SignoriniProblem:
    """The sheared block on a cylinder (module docstring), on an nx x ny triangle macro mesh.

    The default nx, ny give macro triangles without two edges of the same length (dolfinx's
    refinement orders edges by length, and ties broken by round-off would refine serial and
    parallel runs differently).
    """
    msh = dmesh.create_rectangle(
        comm, [np.array([0.0, 0.0]), np.array([1.0, 0.5])], [nx, ny],
        dmesh.CellType.triangle, ghost_mode=dmesh.GhostMode.none,
    )

    def classify(x: np.ndarray) -> np.ndarray:
        tags = np.full(x.shape[1], NEUMANN, dtype=np.int32)
        tags[np.isclose(x[1], 0.5)] = DIRICHLET
        tags[np.isclose(x[1], 0.0)] = CONTACT
        return tags

    return SignoriniProblem(
        msh, tag_exterior_facets(msh, classify), contact=CONTACT,
        dirichlet={DIRICHLET: (shear, -press)}, E=10.0, nu=0.3,
        gap=friction_gap(radius), friction=Tresca(s),
    )


def goal_friction_force() -> Any:
    """``goal(u, lam, m, lam_t) = int_GC lambda_t ds``, the total friction force on the body."""

    def goal(u: Any, lam: Any, m: Any, lam_t: Any) -> ufl.Form:
        return lam_t * m.ds_contact

    return goal
