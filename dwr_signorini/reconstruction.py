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

import functools

from petsc4py import PETSc

import basix
import numpy as np
import scipy.sparse
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc

from . import compat
from .spaces import Discretization

__all__ = ["Reconstructor"]


def _all_cells(V: fem.FunctionSpace) -> np.ndarray:
    imap = V.mesh.topology.index_map(V.mesh.topology.dim)
    return np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)


def node_occurrences(dofs: np.ndarray, num_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Each node that the cells' dofs touch once, with one of its places in ``dofs``.

    Found by a scatter rather than a sort (any occurrence serves the callers: the functions they
    read there are continuous).

    Args:
        dofs: (cells, dofs per cell) node indices, below ``num_nodes``.
        num_nodes: The number of nodes.

    Returns:
        The touched nodes (sorted), and for each its flat index in ``dofs``: the cell is that
        index divided by the dofs per cell, the local dof the remainder.
    """
    occurrence = np.full(num_nodes, -1, dtype=np.int32)
    occurrence[dofs.ravel()] = np.arange(dofs.size, dtype=np.int32)
    nodes = np.flatnonzero(occurrence >= 0)
    return nodes, occurrence[nodes]


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


def _lattice_key(points: np.ndarray, radix: int) -> np.ndarray:
    """Integer lattice points (last axis: coordinates) numbered in base ``radix``."""
    key = np.zeros(points.shape[:-1], dtype=np.int64)
    for i in range(points.shape[-1] - 1, -1, -1):
        key = key * radix + points[..., i]
    return key


def _p2_nodes_doubled(vertex_values: np.ndarray, cell: basix.CellType) -> np.ndarray:
    """Twice a linear function at the P2 nodes of each simplex, from its values at the vertices.

    Args:
        vertex_values: (n, vertices, ...) values (or coordinates) at the vertices.
        cell: The reference cell.

    Returns:
        (n, P2 nodes, ...): the vertices, then the midpoints of the reference edges (basix's
        order). Doubled, so that integer lattice coordinates stay integers.
    """
    ends = np.array(basix.topology(cell)[1])
    midpoints = vertex_values[:, ends[:, 0]] + vertex_values[:, ends[:, 1]]
    return np.concatenate([2 * vertex_values, midpoints], axis=1)


def _reference_coordinates(edges: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Reference coordinates of points in n simplices, by the dual basis of the edges (Cramer).

    Args:
        edges: (n, d, d); row j is vertex j+1 minus vertex 0 of the simplex.
        points: (n, k, d), relative to vertex 0.

    Returns:
        (n, k, d) coordinates in the basis of the edges.
    """
    if edges.shape[1] == 2:
        e1, e2 = edges[:, 0], edges[:, 1]
        dual = [np.stack([e2[:, 1], -e2[:, 0]], axis=1), np.stack([-e1[:, 1], e1[:, 0]], axis=1)]
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    else:
        e1, e2, e3 = edges[:, 0], edges[:, 1], edges[:, 2]
        dual = [np.cross(e2, e3), np.cross(e3, e1), np.cross(e1, e2)]
        det = np.einsum("ij,ij->i", e1, dual[0])
    out = np.empty(points.shape)
    for i, d in enumerate(dual):
        out[..., i] = sum(points[..., j] * d[:, None, j] for j in range(points.shape[-1]))
        out[..., i] /= det[:, None]
    return out


def _child_vertex_nodes(
    disc: Discretization, node_of_key: np.ndarray, chunk: int = 1 << 14
) -> np.ndarray:
    """For each local fine cell, which of its parent's P2 nodes each of its vertices is.

    The reference coordinates of the vertices in the parent (in units of 1/2: integers) are
    computed for ``chunk`` cells at a time, so that the temporaries stay small.
    Returns (cells, tdim + 1) indices into the parent's P2 nodes (-1: not a P2 node).
    """
    fine, macro = disc.mesh, disc.macro_mesh
    tdim = fine.topology.dim
    parents = disc.parent_cell
    gx = macro.geometry.x[:, :tdim]
    macro_cells = compat.geometry_dofmap(macro)
    fine_cells = compat.geometry_dofmap(fine)
    node = np.empty((len(parents), tdim + 1), dtype=np.int8)
    for start in range(0, len(parents), chunk):
        block = slice(start, min(start + chunk, len(parents)))
        parent_vertices = macro_cells[parents[block]]
        origin = gx[parent_vertices[:, 0]]
        edges = gx[parent_vertices[:, 1:]] - origin[:, None, :]
        vertices = fine.geometry.x[fine_cells[block], :tdim] - origin[:, None, :]
        reference = _reference_coordinates(edges, vertices)  # P1 dof order
        node[block] = node_of_key[_lattice_key(np.rint(2 * reference).astype(np.int8), 3)]
    return node


def patch_surplus_matrix(
    disc: Discretization, V2h: fem.FunctionSpace
) -> tuple[scipy.sparse.csr_matrix, np.ndarray]:
    """The map fine P1 nodal values -> fine P2 nodal values of i_2h^(2) - I, on simplices.

    This is the patch weight ``i_2h^(2) v - v`` of the estimators (Section 4) in one product.
    Built from the refinement's parent map alone (no point location). In the reference
    coordinates of its parent, every vertex of a child is one of the parent's P2 nodes (a point
    of the lattice of step 1/2), found once from the vertex coordinates; every P2 node of a child
    is a vertex or an edge midpoint of the child, a point of the lattice of step 1/4, where the
    parent's P2 basis is tabulated once on the reference cell. A fine P1 function is, at the
    midpoint of a child's edge, the mean of its values at the edge's ends, which are parent P2
    nodes too. At the fine vertices i_2h^(2) interpolates: their rows are empty.

    Returns:
        A sparse matrix from the local (scalar) nodes of V_h to the local nodes of ``V2h``, and
        for each local macro cell the fine P1 node at each of its P2 nodes (reference order).
    """
    fine, macro = disc.mesh, disc.macro_mesh
    tdim = fine.topology.dim
    cell = _SIMPLEX[fine.topology.cell_type]
    element = basix.create_element(
        basix.ElementFamily.P, cell, 2, basix.LagrangeVariant.equispaced
    )
    half = np.rint(2 * element.points).astype(np.int8)  # parent P2 nodes, in units of 1/2
    node_of_key = np.full(3**tdim, -1, dtype=np.int8)
    node_of_key[_lattice_key(half, 3)] = np.arange(len(half))

    # Which of its parent's P2 nodes each child vertex is (geometry of the P1 cells).
    parents = disc.parent_cell
    node = _child_vertex_nodes(disc, node_of_key)  # (n, tdim+1), P1 dof order
    if np.any(node < 0):
        raise RuntimeError(
            "a child vertex is not a P2 node of its parent: not a uniform refinement"
        )
    num_cells = len(parents)
    dofs1 = disc.V.dofmap.list[:num_cells]
    num_nodes = len(half)
    parent_node_dof = np.full((macro.topology.index_map(tdim).size_local, num_nodes), -1, np.int32)
    parent_node_dof[np.repeat(parents, dofs1.shape[1]), node.ravel()] = dofs1.ravel()
    has_children = np.zeros(len(parent_node_dof), dtype=bool)
    has_children[parents] = True
    if np.any(parent_node_dof[has_children] < 0):
        raise RuntimeError("a P2 node of a macro cell is not a vertex of its children")

    surplus_of, quarter = _surplus_table(element, half, cell)
    combination = _lattice_key(node, num_nodes)  # (n,): the row of each child in the table

    # Each fine P2 node once (any of its cells: on a macro facet the parents' P2 interpolants
    # agree); only the midpoints of the fine edges have entries.
    dofs2 = V2h.dofmap.list[:num_cells]
    if dofs2.shape[1] != quarter.shape[1]:
        raise RuntimeError("unexpected P2 cell layout (vertices, then edges)")
    num_rows = V2h.dofmap.index_map.size_local + V2h.dofmap.index_map.num_ghosts
    rows, first = node_occurrences(dofs2, num_rows)
    cell_of, local = np.divmod(first, dofs2.shape[1])
    midpoint = local > tdim
    rows, cell_of, local = rows[midpoint], cell_of[midpoint], local[midpoint]
    data = surplus_of.reshape(-1, num_nodes)[combination[cell_of] * dofs2.shape[1] + local]
    cols = parent_node_dof[parents[cell_of]]

    # CSR directly (32-bit indices, no copies): the rows are sorted and each midpoint row has
    # one entry per parent P2 node.
    indptr = np.zeros(num_rows + 1, dtype=np.int32)
    indptr[rows + 1] = num_nodes
    num_cols = disc.V.dofmap.index_map.size_local + disc.V.dofmap.index_map.num_ghosts
    matrix = scipy.sparse.csr_matrix(
        (data.ravel(), cols.ravel(), np.cumsum(indptr, dtype=np.int32)),
        shape=(num_rows, num_cols),
    )
    return matrix, parent_node_dof


def _surplus_table(
    element: basix.finite_element.FiniteElement, half: np.ndarray, cell: basix.CellType
) -> tuple[np.ndarray, np.ndarray]:
    """i_2h^(2) - I at the P2 nodes of a child, for every combination of its vertex nodes.

    Args:
        element: The parent's P2 element.
        half: The parent's P2 nodes in units of 1/2 of its reference cell.
        cell: The simplex.

    Returns:
        ``(surplus_of, quarter)``: ``surplus_of[combination, node, parent node]`` and the
        child's P2 nodes in units of 1/4 (``quarter[combination, node]``).
    """
    num_nodes, tdim = half.shape
    # The P2 nodes of each child (vertices, then the midpoints of the reference edges), in
    # units of 1/4 of the parent's reference cell, and i_2h^(2) - I there: the parent's P2
    # basis minus half at the parent nodes of the ends of the child's edge. They depend on the
    # child's vertex nodes alone: tabulated once for every combination of them.
    grid = np.array([q for q in np.ndindex(*(5,) * tdim) if sum(q) <= 4])
    row_of_key = np.full(5**tdim, -1, dtype=np.int64)
    row_of_key[_lattice_key(grid, 5)] = np.arange(len(grid))
    table = element.tabulate(0, grid / 4.0)[0, :, :, 0]  # (grid points, num_nodes)
    combinations = np.array(list(np.ndindex(*(num_nodes,) * (tdim + 1))), dtype=np.int64)
    combinations = combinations[np.argsort(_lattice_key(combinations, num_nodes))]  # row = key
    quarter = _p2_nodes_doubled(half[combinations], cell)  # (combinations, P2 nodes, tdim)
    surplus_of = table[row_of_key[_lattice_key(quarter, 5)]]  # (combinations, nodes, nodes)
    ends = _child_edge_ends(cell)
    at_row, at_node = np.indices(combinations.shape[:1] + ends.shape[:1])
    for k in range(2):
        np.subtract.at(surplus_of, (at_row, at_node, combinations[:, ends[:, k]]), 0.5)
    return surplus_of, quarter


def _child_edge_ends(cell: basix.CellType) -> np.ndarray:
    """For each local P2 node of a simplex (vertices, then edges), the two vertices of its edge.

    A vertex is given twice: a P1 function's value at any P2 node is the mean at these two.
    """
    vertices = np.arange(len(basix.topology(cell)[0]))
    ends = np.array(basix.topology(cell)[1])
    return np.concatenate([np.stack([vertices, vertices], axis=1), ends])


def p1_in_p2_matrix(V: fem.FunctionSpace, V2: fem.FunctionSpace) -> scipy.sparse.csr_matrix:
    """The map P1 nodal values -> P2 nodal values of the same function, on simplices.

    A P2 node is a vertex (the P1 value there) or an edge midpoint (the mean of the two end
    values); every local P2 node is read in one of its local cells. Rows hold two entries, a
    vertex twice with 1/2.

    Args:
        V: P1 on a simplex mesh (scalar or blocked).
        V2: P2 on the same mesh, with the same block size.

    Returns:
        A sparse matrix from the local (scalar) nodes of ``V`` to the local nodes of ``V2``.
    """
    msh = V.mesh
    num_cells = msh.topology.index_map(msh.topology.dim).size_local
    num_cells += msh.topology.index_map(msh.topology.dim).num_ghosts
    dofs1, dofs2 = V.dofmap.list[:num_cells], V2.dofmap.list[:num_cells]
    pairs = _child_edge_ends(_SIMPLEX[msh.topology.cell_type])  # per P2 local node
    if dofs2.shape[1] != len(pairs):
        raise RuntimeError("unexpected P2 cell layout (vertices, then edges)")
    num_rows = V2.dofmap.index_map.size_local + V2.dofmap.index_map.num_ghosts
    nodes, first = node_occurrences(dofs2, num_rows)
    if len(nodes) != num_rows:
        raise RuntimeError("a local P2 node lies in no local cell")
    cell, local = np.divmod(first, dofs2.shape[1])
    cols = dofs1[cell[:, None], pairs[local]]
    num_cols = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    return scipy.sparse.csr_matrix(
        (np.full(cols.size, 0.5), cols.ravel(), np.arange(0, cols.size + 1, 2, dtype=np.int32)),
        shape=(num_rows, num_cols),
    )


class Reconstructor:
    """Patch-wise reconstructions on one discretisation (interpolation data built once)."""

    def __init__(self, disc: Discretization) -> None:
        self.disc = disc
        macro = disc.macro_mesh
        self.V2h = disc.vector_space(2)  # one per mesh: the master trace of P2 is kept
        self.P1H = fem.functionspace(macro, ("Lagrange", 1))
        self.P1h = fem.functionspace(disc.mesh, ("Lagrange", 1))
        self.simplex = disc.mesh.topology.cell_type in _SIMPLEX
        if self.simplex:
            self._surplus_matrix, self._parent_node_dof = patch_surplus_matrix(disc, self.V2h)
        else:
            # Quadrilaterals/hexahedra (uniform runs only): through the macro Q2 space.
            self._surplus_matrix = None
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

    @functools.cached_property
    def V2H(self) -> fem.FunctionSpace:
        """The macro P2 vector space (built when first needed: the next level's warm start)."""
        gdim = self.disc.mesh.geometry.dim
        return fem.functionspace(self.disc.macro_mesh, ("Lagrange", 2, (gdim,)))

    def destroy(self) -> None:
        """Destroy the PETSc vector this reconstructor owns (collective; idempotent)."""
        if self._mass is not None:
            self._mass.destroy()
            self._mass = None

    @functools.cached_property
    def _p1_in_p2(self) -> scipy.sparse.csr_matrix | None:
        """P1 -> P2 nodal values on T_h (simplices; built when first needed)."""
        return p1_in_p2_matrix(self.disc.V, self.V2h) if self.simplex else None

    def _apply(self, matrix: scipy.sparse.csr_matrix, v: fem.Function, name: str) -> fem.Function:
        """The fine P2 function of nodal values ``matrix`` times those of the fine P1 ``v``."""
        out = fem.Function(self.V2h, name=name)
        bs = self.V2h.dofmap.index_map_bs
        out.x.array[:] = (matrix @ v.x.array.reshape(-1, bs)).ravel()
        out.x.scatter_forward()
        return out

    def as_fine_p2(self, v: fem.Function) -> fem.Function:
        """A fine P1 function written in the fine P2 space (exact)."""
        if self._p1_in_p2 is None:
            out = fem.Function(self.V2h)
            out.interpolate(v)
            return out
        return self._apply(self._p1_in_p2, v, v.name)

    def weight(self, v_plus: fem.Function, v: fem.Function) -> fem.Function:
        """The weight ``v_plus - v`` of the estimators (``A z_h - z_h``, Section 4) in fine P2.

        Args:
            v_plus: The reconstruction, a function of :attr:`V2h`.
            v: The fine P1 function.

        Returns:
            One function of :attr:`V2h` (rather than a UFL difference of two, which the
            indicator kernels would pack and evaluate twice).
        """
        if v_plus.function_space != self.V2h:
            raise ValueError("the reconstruction must be a function of the fine P2 space V2h")
        out = self.as_fine_p2(v)
        out.x.array[:] = v_plus.x.array - out.x.array
        out.name = f"{v_plus.name}-{v.name}"
        return out

    def patch_weight(self, v: fem.Function) -> fem.Function:
        """The patch weight ``i_2h^(2) v - v`` of the estimators (Section 4) in fine P2.

        Equal to ``weight(patch_quadratic(v), v)``; on simplices one product with the map
        of :func:`patch_surplus_matrix`, zero at the fine vertices.
        """
        if self._surplus_matrix is None:
            return self.weight(self.patch_quadratic(v), v)
        return self._apply(self._surplus_matrix, v, f"i2h({v.name})-{v.name}")

    def patch_quadratic(self, v: fem.Function) -> fem.Function:
        """i_2h^(2) v: fine P1 values read as macro P2 values, as a fine P2 function."""
        if self._surplus_matrix is not None:
            out = self.as_fine_p2(v)
            out.x.array[:] += self.patch_weight(v).x.array
            out.name = f"i2h({v.name})"
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
        # Simplices: the macro P1 function at the macro P2 nodes (the vertices, then the
        # midpoints of the reference edges), which are fine vertices.
        parents = np.flatnonzero(self._parent_node_dof[:, 0] >= 0)
        cell = _SIMPLEX[self.disc.mesh.topology.cell_type]
        values = 0.5 * _p2_nodes_doubled(rec.x.array[self.P1H.dofmap.list[parents]], cell)
        out.x.array[self._parent_node_dof[parents].ravel()] = values.ravel()
        out.x.scatter_forward()
        return out
