"""The stack works: a P1 elasticity solve with MUMPS, serial against parallel, and a
codimension-1 submesh form assembled with ``entity_maps``."""

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh

from dwr_signorini import compat
from dwr_signorini.compat import create_submesh

from .fem_compat import linear_problem


def _elasticity_energy(comm: MPI.Comm) -> float:
    """Strain energy of a clamped, gravity-loaded unit square, P1, solved with MUMPS."""
    msh = mesh.create_unit_square(comm, 16, 16, mesh.CellType.triangle)
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    left = mesh.locate_entities_boundary(msh, 1, lambda x: np.isclose(x[0], 0.0))
    bc = fem.dirichletbc(np.zeros(2), fem.locate_dofs_topological(V, 1, left), V)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    mu_, lmbda = 1.0, 1.5

    def sigma(w):
        eps = ufl.sym(ufl.grad(w))
        return 2 * mu_ * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)

    a = ufl.inner(sigma(u), ufl.sym(ufl.grad(v))) * ufl.dx
    L = ufl.inner(fem.Constant(msh, (0.0, -1.0)), v) * ufl.dx
    problem = linear_problem(
        a, L, bcs=[bc],
        petsc_options={"ksp_type": "preonly", "pc_type": "lu",
                       "pc_factor_mat_solver_type": "mumps"},
    )
    uh = problem.solve()
    energy = fem.assemble_scalar(fem.form(ufl.inner(sigma(uh), ufl.sym(ufl.grad(uh))) * ufl.dx))
    return msh.comm.allreduce(energy, op=MPI.SUM)


def test_mumps_available():
    assert PETSc.Sys.hasExternalPackage("mumps")


@pytest.mark.mpi
def test_elasticity_serial_equals_parallel():
    comm = MPI.COMM_WORLD
    e_world = _elasticity_energy(comm)
    e_self = _elasticity_energy(MPI.COMM_SELF)
    assert e_world > 0
    assert abs(e_world - e_self) <= 1e-10 * abs(e_self)


@pytest.mark.mpi
def test_facet_submesh_form_with_entity_maps():
    """Mixed-dimensional assembly: int_{x=1} mu * (v . n) ds with mu on the facet submesh.

    With mu = 1 and v = (1, 0) the total is the length of the right edge, 1.
    """
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 8, 8, mesh.CellType.triangle)
    fdim = msh.topology.dim - 1
    right = mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[0], 1.0))
    sub, sub_to_parent, _, _ = create_submesh(msh, fdim, right)
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    num_facets = msh.topology.index_map(fdim).size_local + msh.topology.index_map(fdim).num_ghosts
    parent_to_sub = np.full(num_facets, -1, dtype=np.int32)
    parent_to_sub[sub_to_parent] = np.arange(len(sub_to_parent), dtype=np.int32)

    Q = fem.functionspace(sub, ("DG", 0))
    V = fem.functionspace(msh, ("Lagrange", 1, (2,)))
    tags = mesh.meshtags(msh, fdim, right, np.full(len(right), 1, dtype=np.int32))
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    mu, v = ufl.TrialFunction(Q), ufl.TestFunction(V)
    n = ufl.FacetNormal(msh)
    form = compat.form(ufl.inner(mu, ufl.dot(v, n)) * ds(1), entity_maps={sub: parent_to_sub})
    from dolfinx.fem.petsc import assemble_matrix

    A = assemble_matrix(form)
    A.assemble()
    ones_q = A.createVecRight()
    ones_q.set(1.0)
    vx = fem.Function(V)
    vx.interpolate(lambda x: np.vstack([np.ones(x.shape[1]), np.zeros(x.shape[1])]))
    out = A.createVecLeft()
    A.mult(ones_q, out)
    total = out.dot(vx.x.petsc_vec)
    assert np.isclose(total, 1.0, rtol=1e-12)
    A.destroy()
