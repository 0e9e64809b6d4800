"""Finite strain: a rubber (Neo-Hookean) cylinder pressed onto a rigid flat, then slid along it.

The body is the half-disc of ``meshes/cattaneo_2d.py`` (radius R centred at (0, R), cut at
y = R; plane strain), its lower arc Gamma_C in possible frictionless contact with the rigid
half-plane y <= 0, its top y = R bonded to a rigid plate. :func:`rubber_cylinder_problems` gives
the two phases of the load path: the press (the plate displaced by ``(0, -approach)``, applied in
load steps from the undeformed state) and the slide (the plate moved on to
``(slide, -approach)``, from the pressed state: ``ds.solve_path(..., initial_guess=pressed)``).
The flat is frictionless and translation invariant, so the slid state is the pressed state
translated by ``(slide, 0)``: the contact force and width stay those of the press.

:func:`measure_contact` takes a finite-strain solution's contact data from its forms (collective):
the total force per unit thickness, the deformed length of the active facets (the contact width)
and the profile of the facets.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc

from ..materials import NeoHookean
from ..obstacles import Plane
from ..problem import SignoriniProblem
from .cattaneo_mindlin_2d import cattaneo_mindlin_mesh
from .load_path import CM_CONTACT, CM_TOP, MESHES, mesh_script

__all__ = ["RC_DEFAULTS", "ContactMeasure", "measure_contact", "rubber_cylinder_mesh",
           "rubber_cylinder_problems"]

#: Geometry, material (a soft rubber in plane strain), the plate's approach (20 % of R) and
#: slide (one radius) and the gmsh mesh sizes of :func:`rubber_cylinder_problems`.
RC_DEFAULTS: dict[str, float] = {
    "radius": 1.0, "E": 1.0, "nu": 0.4, "approach": 0.2, "slide": 1.0,
    "h": 0.2, "h_contact": 0.05, "refine_radius": 0.6,
}


def rubber_cylinder_mesh(
    comm: MPI.Comm, h_contact: float = RC_DEFAULTS["h_contact"], h: float = RC_DEFAULTS["h"],
    refine_radius: float = RC_DEFAULTS["refine_radius"],
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """The half-disc (R = 1), facets of ``h_contact`` within ``refine_radius`` of (0, 0).

    Collective (gmsh on rank 0).

    Args:
        comm: The communicator.
        h_contact: Macro facet length on the arc near the first contact point.
        h: Mesh size away from the contact.
        refine_radius: Radius of the zone of size ``h_contact``.

    Returns:
        ``(mesh, cell_tags, facet_tags)`` with the facet tags
        :data:`~dwr_signorini.cases.CM_CONTACT` (the arc) and
        :data:`~dwr_signorini.cases.CM_TOP`.
    """
    return cattaneo_mindlin_mesh(comm, h_contact=h_contact, h=h, refine_radius=refine_radius)


def rubber_cylinder_problems(
    mesh: tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags],
    approach: float = RC_DEFAULTS["approach"], slide: float = RC_DEFAULTS["slide"],
    E: float = RC_DEFAULTS["E"], nu: float = RC_DEFAULTS["nu"],
) -> tuple[SignoriniProblem, SignoriniProblem]:
    """The press and the slide of the module docstring on ``mesh`` (Neo-Hookean, plane strain).

    Args:
        mesh: ``(msh, cell_tags, facet_tags)`` of :func:`rubber_cylinder_mesh`.
        approach: The plate's downward displacement.
        slide: The plate's horizontal displacement in the slide.
        E: Young's modulus.
        nu: Poisson's ratio.

    Returns:
        ``(press, slide)``, both on the macro mesh ``mesh[0]``.
    """
    msh, cells, facets = mesh
    projection = mesh_script(MESHES / "cattaneo_2d.py").projections(1.0)

    def problem(top: tuple[float, float]) -> SignoriniProblem:
        return SignoriniProblem(
            msh, facets, contact=CM_CONTACT, dirichlet={CM_TOP: top}, E=E, nu=nu,
            cell_tags=cells, material=NeoHookean(), gap=Plane((0.0, 0.0), (0.0, -1.0)),
            boundary_projection=projection,
        )

    return problem((0.0, -approach)), problem((slide, -approach))


@dataclass(frozen=True)
class ContactMeasure:
    """The contact of a 2D finite-strain solution (:func:`measure_contact`).

    Attributes:
        force: int_{Gamma_C} lambda dS, the total normal force per unit thickness.
        width: The deformed length of the active macro facets.
        x: Per macro facet (rank 0, sorted by x): the deformed midpoint's abscissa.
        lam: lambda_H, the force per reference length.
        pressure: The Cauchy contact pressure, force per deformed length, ``lambda |E| / |e|``.
        active: Whether the facet is in contact.
    """

    force: float
    width: float
    x: np.ndarray
    lam: np.ndarray
    pressure: np.ndarray
    active: np.ndarray


def measure_contact(sol: Any) -> ContactMeasure:
    """The contact data of a 2D finite-strain solution (collective; the arrays on rank 0).

    Per macro facet E (reference) with deformed image e: ``|E| = int_E dS``,
    ``|e| = int_E |F t| dS`` (t the unit tangent), the deformed midpoint
    ``int_E (x + u) dS / |E|``.

    Args:
        sol: A :class:`~dwr_signorini.finite_strain.FiniteStrainSolution` of a 2D problem.

    Returns:
        The :class:`ContactMeasure` (the facet arrays empty off rank 0).
    """
    disc, u = sol.disc, sol.u
    m, q = disc.m, ufl.TestFunction(disc.Q)
    t = ufl.as_vector([-m.n[1], m.n[0]])
    Ft = m.F(u) * t
    rows = [_owned(disc, f * q * m.ds_contact)
            for f in (1.0, ufl.sqrt(ufl.dot(Ft, Ft)), m.x[0] + u[0])]
    n = disc.Q.dofmap.index_map.size_local
    lam = sol.lam.x.array[:n].copy()
    active = lam > 0.0
    comm = disc.comm
    force = comm.allreduce(float(lam @ rows[0]), op=MPI.SUM)
    width = comm.allreduce(float(rows[1][active].sum()), op=MPI.SUM)
    gathered = comm.gather((rows[0], rows[1], rows[2], lam), root=0)
    if comm.rank != 0:
        empty = np.zeros(0)
        return ContactMeasure(force, width, empty, empty, empty, empty.astype(bool))
    ref, deformed, xm, lam = (np.concatenate(v) for v in zip(*gathered, strict=True))
    x = xm / ref
    order = np.argsort(x)
    pressure = lam * ref / deformed
    return ContactMeasure(force, width, x[order], lam[order], pressure[order],
                          lam[order] > 0.0)


def _owned(disc: Any, form: Any) -> np.ndarray:
    """The owned entries of a vector form on Lambda_H."""
    vec = fem_petsc.assemble_vector(disc.form(form))
    vec.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    out = vec.array_r.copy()
    vec.destroy()
    return out
