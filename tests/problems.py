"""Test problems shared by several test files."""

import numpy as np
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex

TRI = mesh.CellType.triangle
E, NU = ex.ANALYTIC_MATERIAL.E, ex.ANALYTIC_MATERIAL.nu


def strip_problem(comm, nx=32, ny=8, cell_type=TRI):
    """A 4 x 1 strip clamped on top, pushed down onto an obstacle under its long bottom side.

    Its long contact boundary is cut by the mesh partitioner, so with 2 ranks both own contact
    rows (on the examples' meshes Gamma_C ends up on one rank).
    """
    msh = mesh.create_rectangle(
        comm,
        [np.array([0.0, 0.0]), np.array([4.0, 1.0])],
        [nx, ny],
        cell_type,
        ghost_mode=mesh.GhostMode.none,
    )

    def classify(x):
        values = np.full(x.shape[1], ex.NEUMANN, dtype=np.int32)
        values[np.isclose(x[1], 1.0)] = ex.DIRICHLET
        values[np.isclose(x[1], 0.0)] = ex.CONTACT
        return values

    return ds.SignoriniProblem(
        msh,
        ex.tag_exterior_facets(msh, classify),
        contact=ex.CONTACT,
        dirichlet=(ex.DIRICHLET,),
        E=E,
        nu=NU,
        body_force=(0.0, -1.0),
        gap=lambda x: 0.02 * (x[0] - 2.0) ** 2 - 0.01,
    )
