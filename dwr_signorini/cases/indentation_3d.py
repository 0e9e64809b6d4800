"""The 3D indentation: a sphere pressed into a block, the goal the total contact force.

The block [-1, 1]^2 x [-1, 0] on n x n x n/2 boxes (six tetrahedra each) is clamped at its bottom
z = -1 and touches at its top z = 0 (Gamma_C) a rigid sphere of radius R pressed in by a depth
delta: the gap g(x, y) = (x^2 + y^2) / (2 R) - delta (the sphere's paraboloid), E = 1e3,
nu = 0.3, no loads. Its contact zone, of radius about sqrt(2 R delta) (0.14 by default), is
small against the macro cells of the coarse meshes, which first miss it: the problem the
benchmarks of the interval, the adaptive payoff and the large 3D levels use.
"""

from __future__ import annotations

from mpi4py import MPI

import ufl
from dolfinx import mesh as _mesh

from ..examples import CONTACT, DIRICHLET, GoalContext, Material, tag_block_facets
from ..problem import SignoriniProblem

__all__ = ["INDENTATION_MATERIAL", "goal_total_force", "indentation_problem"]

#: The indentation's block: E = 1e3, nu = 0.3 (3D).
INDENTATION_MATERIAL = Material(E=1.0e3, nu=0.3, model="3d")


def indentation_problem(
    comm: MPI.Comm, n: int, depth: float = 0.005, radius: float = 2.0
) -> SignoriniProblem:
    """The indentation on a macro mesh of n x n x n/2 boxes.

    Args:
        comm: The communicator.
        n: Boxes along x and y (an even number; n/2 along z).
        depth: How far the sphere is pressed in, delta.
        radius: The sphere's radius R.

    Returns:
        The problem (contact tag :data:`CONTACT` at z = 0, clamped at z = -1).
    """
    msh = _mesh.create_box(comm, [(-1, -1, -1), (1, 1, 0)], [n, n, n // 2],
                           _mesh.CellType.tetrahedron, ghost_mode=_mesh.GhostMode.none)


    mat = INDENTATION_MATERIAL
    return SignoriniProblem(
        msh, tag_block_facets(msh, -1.0), contact=CONTACT, dirichlet=(DIRICHLET,),
        E=mat.E, nu=mat.nu, model=mat.model,
        gap=lambda x: (x[0] ** 2 + x[1] ** 2) / (2 * radius) - depth,
    )


def goal_total_force(u: ufl.Coefficient, lam: ufl.Coefficient, m: GoalContext) -> ufl.Form:
    """J = the total contact force, the integral of lambda over Gamma_C.

    Args:
        u: The displacement.
        lam: The contact pressure.
        m: The measures (``m.ds_contact``).

    Returns:
        The form.
    """
    return lam * m.ds_contact
