"""Higher-order reconstructions for the weights of the estimators (Section 4).

* i_2h^(2): patch-wise quadratic reconstruction of a fine P1 (Q1) function. The fine mesh is one
  uniform refinement of the macro mesh, so the vertices of the children of a macro cell are exactly
  the P2 (Q2) nodes of that macro cell: reading the fine nodal values as macro P2 values *is* the
  reconstruction. It is returned as a function of the fine P2 space (exact: a macro P2 function is
  P2 on every child).
* i_2H^(1): a linear reconstruction of a P0 function on the macro contact facets. Choice: the
  vertex-averaged recovery, i.e. the lumped L2 projection onto continuous P1 on Gamma_C of T_H,
  ``r(p) = int_GC lam phi_p / int_GC phi_p`` (the facet-size weighted mean of the values of the
  macro facets around vertex p). It is linear on each macro facet and second-order accurate at
  interior vertices for smooth lambda. It is returned as a scalar P1 function on T_h whose trace on
  Gamma_C is the reconstruction.
"""

from __future__ import annotations

from petsc4py import PETSc

import basix
import numpy as np
import scipy.sparse
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc

from .spaces import Discretization

__all__ = ["Reconstructor"]


def _all_cells(V: fem.FunctionSpace) -> np.ndarray:
    imap = V.mesh.topology.index_map(V.mesh.topology.dim)
    return np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)


class _Transfer:
    """Interpolation between two spaces on different meshes, data built once."""

    def __init__(
        self, V_to: fem.FunctionSpace, V_from: fem.FunctionSpace, cells: np.ndarray | None = None
    ) -> None:
        self.cells = _all_cells(V_to) if cells is None else cells
        self.data = fem.create_interpolation_data(V_to, V_from, self.cells, padding=1e-10)

    def __call__(self, target: fem.Function, source: fem.Function) -> fem.Function:
        target.interpolate_nonmatching(source, self.cells, self.data)
        target.x.scatter_forward()
        return target


_SIMPLEX = {
    dmesh.CellType.triangle: basix.CellType.triangle,
    dmesh.CellType.tetrahedron: basix.CellType.tetrahedron,
}


def patch_p2_matrix(
    disc: Discretization, V2h: fem.FunctionSpace
) -> tuple[scipy.sparse.csr_matrix, np.ndarray]:
    """The map fine P1 nodal values -> fine P2 nodal values of i_2h^(2), on simplices.

    Built from the refinement's parent map alone (no point location): in the reference
    coordinates of its parent, every vertex of a child sits on the lattice of the parent's P2
    nodes, and every P2 node of a child is a point where the parent's P2 basis is tabulated.

    Returns:
        A sparse matrix from the local (scalar) nodes of V_h to the local nodes of ``V2h``, and
        for each local macro cell the fine P1 node at each of its P2 nodes (reference order).
    """
    fine, macro = disc.mesh, disc.macro_mesh
    tdim = fine.topology.dim
    element = basix.create_element(
        basix.ElementFamily.P,
        _SIMPLEX[fine.topology.cell_type],
        2,
        basix.LagrangeVariant.equispaced,
    )
    lattice = np.rint(2 * element.points).astype(np.int64) @ (3 ** np.arange(tdim))
    node_of_key = np.full(3**tdim, -1, dtype=np.int64)
    node_of_key[lattice] = np.arange(len(lattice))

    num_cells = len(disc.parent_cell)
    parents = disc.parent_cell
    gx = macro.geometry.x[:, :tdim]
    pv = gx[macro.geometry.dofmap[parents]]  # (n, tdim+1, tdim): parent vertices
    J = np.transpose(pv[:, 1:, :] - pv[:, :1, :], (0, 2, 1))  # columns: edges from vertex 0
    Jinv = np.linalg.inv(J)

    def reference(points: np.ndarray) -> np.ndarray:
        """Parent reference coordinates of (n, k, tdim) points of each child."""
        return np.einsum("nij,nkj->nki", Jinv, points - pv[:, :1, :])

    # Which fine P1 node is the parent's P2 node k.
    dofs1 = disc.V.dofmap.list[:num_cells]
    x1 = disc.V.tabulate_dof_coordinates()[:, :tdim]
    keys = np.rint(2 * reference(x1[dofs1])).astype(np.int64) @ (3 ** np.arange(tdim))
    node = node_of_key[keys]
    if np.any(node < 0):
        raise RuntimeError(
            "a child vertex is not a P2 node of its parent: not a uniform refinement"
        )
    num_nodes = len(lattice)
    parent_node_dof = np.full((macro.topology.index_map(tdim).size_local, num_nodes), -1, np.int64)
    parent_node_dof[np.repeat(parents, dofs1.shape[1]), node.ravel()] = dofs1.ravel()
    if np.any(parent_node_dof[np.unique(parents)] < 0):
        raise RuntimeError("a P2 node of a macro cell is not a vertex of its children")

    # Tabulate the parent's P2 basis at the children's P2 nodes; each fine P2 node once.
    dofs2 = V2h.dofmap.list[:num_cells]
    x2 = V2h.tabulate_dof_coordinates()[:, :tdim]
    rows, first = np.unique(dofs2.ravel(), return_index=True)
    cell_of = first // dofs2.shape[1]
    xi = np.einsum("nij,nj->ni", Jinv[cell_of], x2[rows] - pv[cell_of, 0, :])
    phi = element.tabulate(0, xi)[0, :, :, 0]  # (rows, num_nodes)
    cols = parent_node_dof[parents[cell_of]]
    # CSR directly: the rows are sorted and each has one entry per parent P2 node.
    indptr = np.zeros(len(x2) + 1, dtype=np.int64)
    indptr[rows + 1] = num_nodes
    matrix = scipy.sparse.csr_matrix(
        (phi.ravel(), cols.ravel(), np.cumsum(indptr)), shape=(len(x2), len(x1))
    )
    return matrix, parent_node_dof


class Reconstructor:
    """Patch-wise reconstructions on one discretisation (interpolation data built once)."""

    def __init__(self, disc: Discretization) -> None:
        self.disc = disc
        gdim = disc.mesh.geometry.dim
        macro = disc.macro_mesh
        self.V2H = fem.functionspace(macro, ("Lagrange", 2, (gdim,)))
        self.V2h = fem.functionspace(disc.mesh, ("Lagrange", 2, (gdim,)))
        self.P1H = fem.functionspace(macro, ("Lagrange", 1))
        self.P1h = fem.functionspace(disc.mesh, ("Lagrange", 1))
        self.simplex = disc.mesh.topology.cell_type in _SIMPLEX
        if self.simplex:
            self._p2_matrix, self._parent_node_dof = patch_p2_matrix(disc, self.V2h)
            self.P2H = fem.functionspace(macro, ("Lagrange", 2))
        else:
            # Quadrilaterals/hexahedra (uniform runs only): through the macro Q2 space.
            self._p2_matrix = None
            self._parent_node_dof = None
            self._fine_to_macro = _Transfer(self.V2H, disc.V)
            self._macro_to_fine = _Transfer(self.V2h, self.V2H)
        if self._parent_node_dof is None:
            self._scalar_to_fine = _Transfer(self.P1h, self.P1H)

        # Lumped mass of Gamma_C on the macro mesh: int_GC phi_p.
        phi = ufl.TestFunction(self.P1H)
        ds_macro = ufl.Measure("ds", domain=macro, subdomain_data=disc.problem.facet_tags)
        self._ds_c = ds_macro(disc.problem.contact)
        self._phi = phi
        mass = fem_petsc.assemble_vector(fem.form(phi * self._ds_c))
        mass.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        mass.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        self._mass = mass

    def __del__(self) -> None:
        mass = getattr(self, "_mass", None)
        if mass is not None:
            mass.destroy()

    def as_fine_p2(self, v: fem.Function) -> fem.Function:
        """A fine P1 function written in the fine P2 space (exact)."""
        out = fem.Function(self.V2h)
        out.interpolate(v)
        return out

    def patch_quadratic(self, v: fem.Function) -> fem.Function:
        """i_2h^(2) v: fine P1 values read as macro P2 values, as a fine P2 function."""
        if self._p2_matrix is not None:
            out = fem.Function(self.V2h, name=f"i2h({v.name})")
            bs = self.V2h.dofmap.index_map_bs
            values = self._p2_matrix @ v.x.array.reshape(-1, bs)
            out.x.array[:] = values.ravel()
            out.x.scatter_forward()
            return out
        macro = fem.Function(self.V2H)
        self._fine_to_macro(macro, v)
        return self._macro_to_fine(fem.Function(self.V2h, name=f"i2h({v.name})"), macro)

    def macro_quadratic(self, v: fem.Function) -> fem.Function:
        """i_2h^(2) v as a function of the macro P2 space (simplices).

        The fine nodal values are read as macro P2 nodal values; set on every local macro cell
        whose children are on this process.
        """
        if self._parent_node_dof is None:
            raise NotImplementedError("macro_quadratic needs a simplex mesh")
        out = fem.Function(self.V2H, name=f"i2h({v.name})")
        bs = self.V2H.dofmap.index_map_bs
        parents = np.flatnonzero(self._parent_node_dof[:, 0] >= 0)
        macro_dofs = self.V2H.dofmap.list[parents].ravel()
        fine_dofs = self._parent_node_dof[parents].ravel()
        out.x.array.reshape(-1, bs)[macro_dofs] = v.x.array.reshape(-1, bs)[fine_dofs]
        return out

    def macro_linear_multiplier(self, lam: fem.Function) -> fem.Function:
        """i_2H^(1) lam: vertex-averaged P1 recovery on Gamma_C, a scalar P1 function on T_H."""
        form = self.disc.macro_form(lam * self._phi * self._ds_c)
        num = fem_petsc.assemble_vector(form)
        num.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        num.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        rec = fem.Function(self.P1H, name=f"i2H({lam.name})")
        with num.localForm() as n_loc, self._mass.localForm() as m_loc:
            mass = m_loc.array_r
            rec.x.array[:] = np.divide(n_loc.array_r, mass, out=np.zeros_like(mass), where=mass > 0)
        num.destroy()
        return rec

    def patch_linear_multiplier(self, lam: fem.Function) -> fem.Function:
        """i_2H^(1) lam: vertex-averaged P1 recovery on Gamma_C, as a scalar P1 function on T_h."""
        rec = self.macro_linear_multiplier(lam)
        out = fem.Function(self.P1h, name=f"i2H({lam.name})")
        if self._parent_node_dof is None:
            return self._scalar_to_fine(out, rec)
        # Simplices: the macro P1 function as macro P2 (exact), whose nodes are fine vertices.
        rec2 = fem.Function(self.P2H)
        rec2.interpolate(rec)
        parents = np.flatnonzero(self._parent_node_dof[:, 0] >= 0)
        macro_dofs = self.P2H.dofmap.list[parents]
        out.x.array[self._parent_node_dof[parents].ravel()] = rec2.x.array[macro_dofs.ravel()]
        out.x.scatter_forward()
        return out
