"""Material laws: linear elasticity (the default) and hyperelastic laws at finite strain.

:class:`LinearElastic` is the small-strain model of the paper (Hooke's law on eps(u) =
sym(grad u)); a problem with it is solved exactly as without a ``material`` argument. The
hyperelastic laws give a strain energy psi(F) per reference volume of the deformation gradient
F = I + grad u, with the Lame parameters mu, lambda from ``E`` and ``nu`` (plane strain or 3D):

* :class:`NeoHookean` (compressible): psi = mu/2 (I_1 - d - 2 ln J) + lambda/2 (ln J)^2,
  I_1 = tr(F^T F), J = det F, d the space dimension;
* :class:`SaintVenantKirchhoff`: psi = mu tr(E^2) + lambda/2 (tr E)^2, E = (F^T F - I)/2;
* :class:`Hyperelastic` (``psi``): a user's ``psi(F, mu, lmbda)`` as UFL.

Each linearises at F = I to Hooke's law. The first Piola-Kirchhoff stress P = dpsi/dF and its
tangent are UFL derivatives (:meth:`Hyperelastic.first_piola`); the finite-strain problem is
solved by :mod:`dwr_signorini.finite_strain`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import ufl

__all__ = [
    "Hyperelastic",
    "LinearElastic",
    "Material",
    "NeoHookean",
    "SaintVenantKirchhoff",
    "check_material_law",
]


class Material:
    """A material law of a :class:`~dwr_signorini.SignoriniProblem` (``material=``).

    Attributes:
        finite_strain: Whether the law is a finite-strain (hyperelastic) law.
    """

    finite_strain: bool = False

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and vars(self) == vars(other)

    def __hash__(self) -> int:
        return hash(type(self).__name__)

    def __repr__(self) -> str:
        return f"ds.{type(self).__name__}()"


class LinearElastic(Material):
    """Linear elasticity at small strain: sigma = 2 mu eps(u) + lambda tr(eps(u)) I (default)."""


class Hyperelastic(Material):
    """A hyperelastic law given by its strain energy per reference volume.

    Args:
        psi: ``psi(F, mu, lmbda)`` returning the strain energy density (a UFL scalar) of the
            deformation gradient ``F`` (a UFL tensor, d x d), with the Lame parameters ``mu`` and
            ``lmbda`` (from ``E``, ``nu`` as given: numbers, UFL expressions or DG0 functions).

    Raises:
        TypeError: If ``psi`` is not callable.
    """

    finite_strain = True

    def __init__(self, psi: Callable[[Any, Any, Any], Any]) -> None:
        if not callable(psi):
            raise TypeError(
                "Hyperelastic(psi): psi must be a callable psi(F, mu, lmbda) returning the UFL "
                f"strain energy per reference volume, got {type(psi).__name__}"
            )
        self.psi = psi

    def __repr__(self) -> str:
        name = getattr(self.psi, "__name__", "psi")
        return f"ds.Hyperelastic({name})"

    def energy(self, F: Any, mu: Any, lmbda: Any) -> Any:
        """The strain energy density psi(F) per reference volume.

        Args:
            F: The deformation gradient (UFL tensor).
            mu: The shear modulus.
            lmbda: The first Lame parameter.

        Returns:
            psi as a UFL scalar.
        """
        return self.psi(F, mu, lmbda)

    def first_piola(self, F: Any, mu: Any, lmbda: Any) -> Any:
        """The first Piola-Kirchhoff stress P = dpsi/dF (a UFL derivative).

        Args:
            F: The deformation gradient as a ``ufl.variable``.
            mu: The shear modulus.
            lmbda: The first Lame parameter.

        Returns:
            P as a UFL tensor.
        """
        return ufl.diff(self.energy(F, mu, lmbda), F)


class NeoHookean(Hyperelastic):
    """Compressible Neo-Hookean law: psi = mu/2 (I_1 - d - 2 ln J) + lambda/2 (ln J)^2.

    I_1 = tr(F^T F), J = det F, d the space dimension (2 in plane strain, 3 in 3D).
    """

    def __init__(self) -> None:
        super().__init__(_neo_hookean)

    def __repr__(self) -> str:
        return "ds.NeoHookean()"


class SaintVenantKirchhoff(Hyperelastic):
    """Saint Venant-Kirchhoff law: psi = mu tr(E^2) + lambda/2 (tr E)^2, E = (F^T F - I)/2."""

    def __init__(self) -> None:
        super().__init__(_saint_venant_kirchhoff)

    def __repr__(self) -> str:
        return "ds.SaintVenantKirchhoff()"


def _neo_hookean(F: Any, mu: Any, lmbda: Any) -> Any:
    d = F.ufl_shape[0]
    J = ufl.det(F)
    return mu / 2 * (ufl.tr(F.T * F) - d - 2 * ufl.ln(J)) + lmbda / 2 * ufl.ln(J) ** 2


def _saint_venant_kirchhoff(F: Any, mu: Any, lmbda: Any) -> Any:
    E = (F.T * F - ufl.Identity(F.ufl_shape[0])) / 2
    return mu * ufl.tr(E * E) + lmbda / 2 * ufl.tr(E) ** 2


def check_material_law(material: Any, problem: Any) -> Material:
    """``material`` validated for a problem's model and contact (the constructor's data).

    Args:
        material: ``None`` (linear elasticity) or a :class:`Material`.
        problem: The problem under construction (its ``model``, ``pairs``, ``friction``,
            ``gap`` already checked).

    Returns:
        The material law.

    Raises:
        TypeError: ``material`` is not a material law.
        ValueError: A finite-strain law with plane stress, friction, contact pairs or an
            obstacle under a given force (not covered at finite strain).
    """
    if material is None:
        return LinearElastic()
    if not isinstance(material, Material):
        raise TypeError(
            "material must be ds.LinearElastic(), ds.NeoHookean(), ds.SaintVenantKirchhoff() "
            f"or ds.Hyperelastic(psi), got {type(material).__name__}"
        )
    if not material.finite_strain:
        return material
    refused = []
    if problem.model == "plane_stress":
        refused.append("model='plane_stress' (use plane strain or 3D)")
    if problem.pairs:
        refused.append("ContactPair (two deformable bodies)")
    if problem.law.frictional:
        refused.append(f"friction={problem.law!r} (only frictionless contact)")
    if problem.force_obstacle is not None:
        refused.append("an obstacle with force= (force control)")
    if not refused:
        from .finite_strain import check_obstacle

        check_obstacle(problem.gap)
    if refused:
        raise ValueError(
            f"material={material!r} (finite strain) does not support " + "; ".join(refused)
            + " yet: these combinations are covered by the linear small-strain model only"
        )
    return material
