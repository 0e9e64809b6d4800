"""What the three examples share besides mesh tagging: material record, goal interface, problem.

Hooke's law itself is :func:`dwr_signorini.problem.lame_parameters` and
:func:`dwr_signorini.problem.stress`; :class:`Material` only holds an example's ``E``, ``nu`` and
model and hands them to those functions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import ufl
from dolfinx.mesh import Mesh, MeshTags

from ..problem import SignoriniProblem, lame_parameters, stress
from ._mesh import CONTACT, DIRICHLET

__all__ = ["Goal", "GoalContext", "Material", "example_problem"]


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material of one example (Section 5).

    Attributes:
        E: Young's modulus.
        nu: Poisson's ratio.
        model: ``"plane_strain"`` or ``"plane_stress"`` (2D) or ``"3d"``, as in
            :class:`dwr_signorini.SignoriniProblem`.
    """

    E: float
    nu: float
    model: str = "plane_strain"

    def lame(self) -> tuple[float, float]:
        """The Lame parameters of the material.

        Returns:
            ``(mu, lambda)``, see :func:`dwr_signorini.problem.lame_parameters`.
        """
        return lame_parameters(self.E, self.nu, self.model)

    def sigma(self, u: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The stress of Hooke's law of the material.

        Args:
            u: The displacement (UFL).

        Returns:
            The stress tensor ``sigma(u)``, see :func:`dwr_signorini.problem.stress`.
        """
        return stress(u, self.E, self.nu, self.model)


class GoalContext(Protocol):
    """What a goal builder needs from the solver.

    Attributes:
        x: ``ufl.SpatialCoordinate`` of the mesh.
        dx: Cell measure of the mesh.
        ds_contact: Measure of the contact boundary, e.g. ``ds(CONTACT)``.
        sigma: Callable returning the stress tensor ``sigma(u)`` of the example's material.
    """

    x: ufl.core.expr.Expr
    dx: ufl.Measure
    ds_contact: ufl.Measure
    sigma: Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]


#: A quantity of interest ``J(u, lambda_n)`` as a function returning a UFL form.
Goal = Callable[[ufl.core.expr.Expr, ufl.core.expr.Expr, GoalContext], ufl.Form]


def example_problem(mesh_and_tags: tuple[Mesh, MeshTags], **data: Any) -> SignoriniProblem:
    """The problem on an example mesh: clamped on DIRICHLET, possible contact on CONTACT.

    Args:
        mesh_and_tags: An example's macro mesh and its facet tags.
        **data: Material, loads and gap, the keyword arguments of
            :class:`~dwr_signorini.SignoriniProblem`.

    Returns:
        The problem.
    """
    msh, tags = mesh_and_tags
    return SignoriniProblem(msh, tags, contact=CONTACT, dirichlet=(DIRICHLET,), **data)
