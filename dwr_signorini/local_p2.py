"""P2 weights near Gamma_C: the P2 system solved on a band of cells, the patch weights elsewhere.

``weights="local"`` of :func:`~dwr_signorini.estimator.estimate`. Where the contact set is not
resolved, the patch reconstruction i_2h^(2) of z_h and w_h misses the error near Gamma_C (the
contact-violation and active-set terms weigh the multipliers' and the displacements' traces
there); away from Gamma_C, where the discrete solutions are smooth, it serves. So the P2
dual and primal of the final active set (the systems of ``weights="higher_order"``) are
solved only on a band B of cells around the contact zone (:func:`band_cells`: every cell with a
vertex on Gamma_C, and :data:`BAND_LAYERS` layers of cells around the facets where lambda_h does
not vanish), with the patch reconstructions i_2h^(2) z_h and i_2h^(2) w_h as Dirichlet data on
the P2 nodes that a cell outside B touches:

    z^(2) = i_2h^(2) z_h off the free nodes of B,   A^T z^(2) = J'(w_h) on them,

and the same for w^(2) with the Newton step's right-hand side. Every multiplier row lies in B,
so the constrained nodes carry no contact row. Outside B the weights are then the patch
weights; on B those of a P2 solve with data from the patch reconstruction. The stiffness
matrix is assembled over B only (with the diagonal of the other rows), so the factorisation is
that of the band, not of the P2 system of the whole mesh.
"""

from __future__ import annotations

from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import cpp as _cpp
from dolfinx import fem, la
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc

__all__ = ["BAND_LAYERS", "BAND_ORDERING", "ContactBand", "band_cells", "band_options"]

#: Layers of cells around the contact zone on which ``weights="local"`` solves the P2 systems,
#: per dimension (:func:`band_cells`). Measured with ``benchmarks/interval_coverage.py``: on the
#: 2D indented block's unresolved levels 16 layers give intervals 3.3-8.2 times the error, about
#: as the P2 weights of the whole mesh did (2.9-5.8, 19 on one level), 4 layers 7.6-46 times. In
#: 3D the band's factorisation grows with its volume (the indentation's level of 98k cells, a
#: probe: 4 layers 4.9 s, 8 layers 13.7 s, 12 layers 71 s); with 4 layers the estimate is within
#: 10 % of the whole mesh's (``benchmarks/band_weights_cost.py``: 9.7 % there, 9.1 % on 5.3's
#: level of 49k cells), the intervals holding the references.
BAND_LAYERS = {2: 16, 3: 4}


def _marked(imap: Any, nodes: np.ndarray) -> np.ndarray:
    """Local nodes of ``imap`` (owned and ghost) that any rank lists in ``nodes`` (collective)."""
    marks = la.vector(imap, 1)
    marks.array[:] = 0.0
    marks.array[nodes] = 1.0
    marks.scatter_reverse(la.InsertMode.add)
    marks.scatter_forward()
    return marks.array > 0


def _touching(vertex: np.ndarray, dofs: np.ndarray) -> np.ndarray:
    """The cells (rows of ``dofs``, their P1 nodes) with a marked vertex."""
    return np.flatnonzero(vertex[dofs].any(axis=1)).astype(np.int32)


def _zone_vertices(disc: Any, zone: fem.Function, P1: fem.FunctionSpace) -> np.ndarray:
    """The vertices of the Gamma_C facets where ``zone`` (a function on Lambda_H) is not 0."""
    form = disc.form(abs(zone) * ufl.TestFunction(P1) * disc.m.ds_contact)
    vec = fem.assemble_vector(form)
    vec.scatter_reverse(la.InsertMode.add)
    vec.scatter_forward()
    return vec.array > 0


def band_cells(disc: Any, layers: int, zone: fem.Function | None = None) -> np.ndarray:
    """The owned cells of T_h near Gamma_C and its contact zone (collective).

    Args:
        disc: The discretisation (its fine facet tags mark Gamma_C).
        layers: At least 1: the vertex layers of cells around the contact zone (the first:
            every cell with a vertex on it, the next every cell with a vertex on one of these).
        zone: The normal multiplier lambda_h: the contact zone is the Gamma_C facets where it
            is not 0. None: all of Gamma_C.

    Returns:
        Sorted local indices of owned cells: every cell with a vertex on Gamma_C, and the
        ``layers`` layers around the contact zone; the same band whatever the partition.

    Raises:
        ValueError: ``layers`` below 1.
    """
    if layers < 1:
        raise ValueError(f"the band needs at least one layer of cells, got {layers}")
    msh = disc.mesh
    tdim = msh.topology.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    P1 = fem.functionspace(msh, ("Lagrange", 1))
    tags = disc.problem.contact_tags
    facets = np.flatnonzero(np.isin(disc.facet_tags.values, tags))
    facets = disc.facet_tags.indices[facets].astype(np.int32)
    vertex = _marked(P1.dofmap.index_map, fem.locate_dofs_topological(P1, fdim, facets))
    dofs = P1.dofmap.list[: msh.topology.index_map(tdim).size_local]
    first = _touching(vertex, dofs)
    cells = first if zone is None else _touching(_zone_vertices(disc, zone, P1), dofs)
    for _ in range(layers - 1):
        cells = _touching(_marked(P1.dofmap.index_map, dofs[cells].ravel()), dofs)
    return np.union1d(first, cells).astype(np.int32)


class ContactBand:
    """The band B of cells around Gamma_C and the P2 nodes a cell outside it touches.

    Args:
        disc: The discretisation.
        V2: The vector P2 space on T_h.
        layers: The band's layers of cells (:func:`band_cells`; None: :data:`BAND_LAYERS`
            of the mesh's dimension).
        zone: lambda_h, whose nonzero facets are the contact zone (:func:`band_cells`).

    Attributes:
        cells: Owned cells of B (local indices).
        dx: The cell measure of B.
        frozen: Local node indices (owned and ghost) of V2 that a cell outside B touches: the
            constrained nodes of the band's systems.
        free_dofs: Global number of the unconstrained displacement dofs (all ranks).
        total_dofs: Global number of displacement dofs of V2.
    """

    def __init__(self, disc: Any, V2: fem.FunctionSpace, layers: int | None = None,
                 zone: fem.Function | None = None) -> None:
        msh = disc.mesh
        tdim = msh.topology.dim
        self.V2 = V2
        self._zero: fem.DirichletBC | None = None
        self.cells = band_cells(disc, BAND_LAYERS[tdim] if layers is None else layers, zone)
        tags = dmesh.meshtags(msh, tdim, self.cells, np.ones(self.cells.size, dtype=np.int32))
        self.dx = ufl.Measure("dx", domain=msh, subdomain_data=tags)(1)
        num_cells = msh.topology.index_map(tdim).size_local
        outside = np.setdiff1d(np.arange(num_cells, dtype=np.int32), self.cells)
        imap, bs = V2.dofmap.index_map, V2.dofmap.index_map_bs
        touched = _marked(imap, V2.dofmap.list[outside].ravel())
        self.frozen = np.flatnonzero(touched).astype(np.int32)
        owned_frozen = int(np.count_nonzero(self.frozen < imap.size_local))
        comm = msh.comm
        self.total_dofs = imap.size_global * bs
        self.free_dofs = self.total_dofs - bs * comm.allreduce(owned_frozen, op=MPI.SUM)

    def conditions(
        self, bcs: list[fem.DirichletBC], prescribed: list[fem.DirichletBC], values: fem.Function
    ) -> tuple[list[fem.DirichletBC], list[fem.DirichletBC]]:
        """The band's conditions before the physical ones (which so win where both hold).

        Args:
            bcs: The homogeneous conditions on Gamma_D.
            prescribed: The same with their values u_D.
            values: The data on the constrained nodes (i_2h^(2) w_h, a function of V2).

        Returns:
            The homogeneous and the prescribed conditions of the band's system.
        """
        self._zero = fem.dirichletbc(np.zeros(self.V2.mesh.geometry.dim), self.frozen, self.V2)
        return [self._zero, *bcs], [fem.dirichletbc(values, self.frozen), *prescribed]

    def stiffness(self, form: fem.Form, bcs: list[fem.DirichletBC]) -> PETSc.Mat:
        """K of the band (``form`` integrated over B), 1 on the diagonal of the constrained rows.

        Args:
            form: The compiled stiffness form over :attr:`dx`.
            bcs: The band's homogeneous conditions (:meth:`conditions`).

        Returns:
            The assembled matrix (the caller owns it). Its sparsity pattern is B's and the
            diagonal: the rows of nodes outside B hold nothing else, so the factorisation sees
            the band alone.
        """
        pattern = fem.create_sparsity_pattern(form)
        imap = self.V2.dofmap.index_map
        pattern.insert_diagonal(np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32))
        pattern.finalize()
        K = _cpp.la.petsc.create_matrix(self.V2.mesh.comm, pattern)
        fem_petsc.assemble_matrix(K, form, bcs=bcs)
        K.assemble()
        return K

    def lift(self, b: PETSc.Vec, values: fem.Function, form: fem.Form,
             bcs: list[fem.DirichletBC]) -> None:
        """Give the dual's right-hand side ``b`` the data ``values`` on the constrained nodes.

        On the free rows b - K_(free, frozen) values, on the constrained rows the values, on
        Gamma_D 0 (``bcs``, the homogeneous physical conditions, set last).

        Args:
            b: The assembled (ghost-updated) displacement part of the right-hand side.
            values: i_2h^(2) z_h, a function of V2.
            form: The band's stiffness form (K is symmetric: its own transpose).
            bcs: The homogeneous conditions of the band's system (:meth:`conditions`).
        """
        bc = fem.dirichletbc(values, self.frozen)
        physical = [c for c in bcs if c is not self._zero]
        lifting = b.duplicate()
        with lifting.localForm() as local:
            local.set(0.0)
        fem_petsc.apply_lifting(lifting, [form], bcs=[[bc]])
        lifting.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        b.axpy(1.0, lifting)
        lifting.destroy()
        fem_petsc.set_bc(b, [bc, *physical])


#: MUMPS's ordering of the band's systems: approximate minimum fill (ICNTL(7) = 2). The
#: ordering MUMPS picks itself (PORD in this build, which lacks METIS) spends minutes on the
#: constrained rows, isolated nodes of the matrix's graph: the 3D indentation of 98k cells,
#: 2 layers, 419k P2 unknowns of which 51k free, analysis 210.8 s and factorisation 1.0 s;
#: with AMF 0.14 s and 1.1 s.
BAND_ORDERING = {"mat_mumps_icntl_7": 2}


def band_options(petsc_options: dict[str, Any] | None) -> dict[str, Any] | None:
    """The band's solver options: ``petsc_options``, with :data:`BAND_ORDERING` under MUMPS.

    Args:
        petsc_options: The estimate's options for the P2 system, or None (the package's
            direct solver, :func:`~dwr_signorini.linalg.options.default_petsc_options`).

    Returns:
        The options for the band's system (a new dict where :data:`BAND_ORDERING` is added).
    """
    options = petsc_options or {}
    direct = options.get("pc_type", "cholesky") in ("lu", "cholesky")
    mumps = options.get("pc_factor_mat_solver_type", "mumps") == "mumps"
    if not (direct and mumps and PETSc.Sys.hasExternalPackage("mumps")):
        return petsc_options
    return {**BAND_ORDERING, **options}
