"""The stress of a solution as fields to look at: Cauchy stress and von Mises stress (DG0).

With P1 displacements on T_h the strain is constant on every fine cell, so the Cauchy stress
``sigma(u_h) = 2 mu eps(u_h) + lambda tr(eps(u_h)) I`` (Hooke's law, Section 2 of the paper) is
too for constant material data: its DG0 interpolant, at each cell's midpoint, is exact (for E, nu
varying in x, and for Q1 on quadrilaterals or hexahedra, it is the midpoint value). The von
Mises stress is that of the full 3D stress tensor, ``sigma_vM = sqrt(3/2 s : s)``,
``s = sigma - tr(sigma) / 3 I``: in plane strain with the out-of-plane stress
``sigma_zz = nu (sigma_xx + sigma_yy)``, in plane stress with ``sigma_zz = 0``.
The output of :func:`~dwr_signorini.solve_adaptive` and :func:`~dwr_signorini.solve_path`
writes both beside u and lambda (:mod:`dwr_signorini.io`).
"""

from __future__ import annotations

from typing import Any

import ufl
from dolfinx import fem

from . import compat

__all__ = ["stress_fields", "von_mises"]


def von_mises(sigma: Any, nu: Any, model: str) -> Any:
    """The von Mises stress of the in-plane (2D) or full (3D) stress tensor ``sigma`` (UFL).

    Args:
        sigma: The Cauchy stress, gdim x gdim.
        nu: Poisson's ratio (for the plane-strain out-of-plane stress).
        model: ``"plane_strain"``, ``"plane_stress"`` or ``"3d"``.

    Returns:
        ``sqrt(3/2 s : s)`` with s the deviator of the 3D stress tensor (UFL scalar).
    """
    if model == "3d":
        full = sigma
    else:
        szz = nu * (sigma[0, 0] + sigma[1, 1]) if model == "plane_strain" else 0.0
        full = ufl.as_matrix([[sigma[0, 0], sigma[0, 1], 0.0],
                              [sigma[1, 0], sigma[1, 1], 0.0],
                              [0.0, 0.0, szz]])
    s = ufl.dev(full)
    return ufl.sqrt(1.5 * ufl.inner(s, s))


def stress_fields(sol: Any) -> tuple[fem.Function, fem.Function]:
    """The Cauchy stress and the von Mises stress of ``sol`` as DG0 functions on T_h.

    Collective (an interpolation; the expressions are compiled once per form signature).

    Args:
        sol: A :class:`~dwr_signorini.Solution`.

    Returns:
        ``(sigma, von_mises)``, named ``"sigma"`` (gdim x gdim) and ``"von_mises"``.
    """
    disc = sol.disc
    msh = disc.mesh
    gdim = msh.geometry.dim
    fields = disc.fields
    sigma = fields.sigma(sol.u)
    _, nu = fields.material(ufl.SpatialCoordinate(msh))
    out = []
    for name, expr, shape in (
        ("sigma", sigma, (gdim, gdim)),
        ("von_mises", von_mises(sigma, nu, disc.problem.model), ()),
    ):
        space = fem.functionspace(msh, ("DG", 0, shape))
        f = fem.Function(space, name=name)
        f.interpolate(fem.Expression(expr, compat.interpolation_points(space.element)))
        out.append(f)
    return out[0], out[1]
