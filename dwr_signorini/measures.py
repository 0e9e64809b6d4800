"""What a goal functional may use: the measures, the coordinate and the stresses on T_h.

``goal(u, lam, m)`` receives a :class:`Measures` ``m`` of the fine mesh T_h
(:mod:`~dwr_signorini.spaces`): its measures (``m.dx``, ``m.ds_contact``, ``m.ds(tag)``), the
coordinate and normal, the problem and its data on the mesh, and the stresses of the material
law (``m.sigma(u)``, ``m.F(u)``, ``m.P(u)``, ``m.cauchy(u)``, ``m.epsilon(u)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import ufl
from dolfinx import mesh as dmesh

from .fields import MeshFields, deformation_gradient
from .problem import SignoriniProblem

__all__ = ["Measures"]


@dataclass(frozen=True)
class Measures:
    """What a goal functional may use, all on the fine mesh T_h.

    Attributes:
        x: Spatial coordinate.
        dx: Cell measure.
        ds_contact: Measure of the possible contact boundary Gamma_C.
        ds: Boundary measure with the facet tags (``m.ds(tag)``).
        n: Outer unit normal.
        mesh: The fine mesh.
        problem: The problem (for material data).
        fields: The problem's data on the fine mesh (the discretisation's
            :class:`~dwr_signorini.fields.MeshFields`).
        obstacle_displacement: The displacement delta of an obstacle under a given force along
            its direction (a dolfinx Constant, for goals: its dual entry takes dJ/ddelta), or
            None.
    """

    x: Any
    dx: ufl.Measure
    ds_contact: ufl.Measure
    ds: ufl.Measure
    n: Any
    mesh: dmesh.Mesh
    problem: SignoriniProblem
    fields: MeshFields
    obstacle_displacement: Any = None

    def sigma(self, u: Any) -> Any:
        """Stress sigma(u) of the problem's material law.

        Args:
            u: A displacement (UFL vector).

        Returns:
            The stress tensor (UFL), with the problem's E, nu and model.
        """
        return self.fields.sigma(u)

    def F(self, u: Any) -> Any:
        """The deformation gradient F = I + grad u (for any material law).

        Args:
            u: A displacement (UFL vector).

        Returns:
            F (UFL tensor).
        """
        return deformation_gradient(u)

    def P(self, u: Any) -> Any:
        """The first Piola-Kirchhoff stress dpsi/dF(I + grad u) of the material law.

        With E, nu per cell tag as given; Hooke's sigma(u) for the linear material.

        Args:
            u: A displacement (UFL vector).

        Returns:
            P (UFL tensor), :meth:`~dwr_signorini.fields.MeshFields.first_piola`.
        """
        return self.fields.first_piola(u)

    def cauchy(self, u: Any) -> Any:
        """The Cauchy stress P F^T / det F; Hooke's sigma(u) for the linear material.

        Args:
            u: A displacement (UFL vector).

        Returns:
            sigma (UFL tensor) at the reference points, :meth:`~.MeshFields.cauchy`.
        """
        return self.fields.cauchy(u)

    def epsilon(self, u: Any) -> Any:
        """Strain eps(u) = sym(grad u).

        Args:
            u: A displacement (UFL vector).

        Returns:
            The strain tensor (UFL).
        """
        return self.problem.epsilon(u)
