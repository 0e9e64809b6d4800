"""The collective phase of the field plots: mesh and solution data gathered on rank 0 (MPI).

Every field plot is two phases. The gather phase (collective, this module) turns dolfinx objects
into numpy arrays on rank 0: every rank sends the data of its local cells (``comm.gather``). The
draw phase (rank 0 only: :mod:`.meshes`, :mod:`.fields2d`, :mod:`.fields3d`) sees only those
arrays: the public functions drop their references to meshes and solutions before drawing. This
matters in parallel: matplotlib and the import system leave reference cycles (caught exceptions
with their tracebacks) that keep the frames on the stack alive until the garbage collector runs.
Had those frames held a solution, rank 0 would destroy its PETSc objects (MUMPS factorisations, a
collective operation) in a garbage collection of its own, at a moment the other ranks do not, and
the program would hang. For the same reason a plot of an intermediate mesh inside a callback
should gather with :func:`snapshot_mesh` and draw later.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from mpi4py import MPI

import numpy as np
import numpy.typing as npt
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.cpp import mesh as _cpp_mesh

from .. import compat
from ..collective import collective
from ..fields import gap_value

__all__ = [
    "MeshSnapshot",
    "SolutionData",
    "gather_contact_force",
    "gather_solution",
    "snapshot_mesh",
    "von_mises_2d",
]


def _gather_arrays(comm: MPI.Comm, *arrays: npt.NDArray[Any]) -> list[npt.NDArray[Any]] | None:
    """Concatenate each array over the ranks on rank 0 (``None`` elsewhere)."""
    gathered = comm.gather(arrays, root=0)
    if comm.rank != 0:
        return None
    return [np.concatenate([g[k] for g in gathered]) for k in range(len(arrays))]


def _num_local_cells(msh: dmesh.Mesh) -> int:
    """Number of cells owned by this process."""
    return msh.topology.index_map(msh.topology.dim).size_local


def _cell_vertices(msh: dmesh.Mesh, dim: int, entities: npt.NDArray[np.int32]) -> np.ndarray:
    """Coordinates of the vertices of ``entities``: shape (num, vertices per entity, 3).

    Empty input gives an empty array of the right shape without calling into dolfinx (some of
    its functions fail on empty entity lists, e.g. a rank without contact facets).
    """
    entities = np.asarray(entities, dtype=np.int32)
    if len(entities) == 0:
        ct = _cpp_mesh.cell_entity_type(msh.topology.cell_type, dim, 0)
        return np.zeros((0, _cpp_mesh.cell_num_vertices(ct), 3))
    nodes = dmesh.entities_to_geometry(msh, dim, entities, False)
    return msh.geometry.x[nodes]


def _exterior_facets(msh: dmesh.Mesh) -> npt.NDArray[np.int32]:
    """Local indices of the facets on the boundary of the mesh."""
    fdim = msh.topology.dim - 1
    msh.topology.create_entities(fdim)
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    return dmesh.exterior_facet_indices(msh.topology)


def _outward_normals(msh: dmesh.Mesh, facets: npt.NDArray[np.int32]) -> np.ndarray:
    """Outer unit normals of exterior facets (2D or 3D, straight facets), shape (num, 3)."""
    tdim = msh.topology.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    if len(facets) == 0:
        return np.zeros((0, 3))
    f2c = msh.topology.connectivity(fdim, tdim)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    x = _cell_vertices(msh, fdim, facets)
    if tdim == 2:
        t = x[:, 1] - x[:, 0]
        n = np.stack([t[:, 1], -t[:, 0], np.zeros(len(t))], axis=1)
    else:
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    inward = dmesh.compute_midpoints(msh, tdim, cells).reshape(-1, 3) - x.mean(axis=1)
    n[np.sum(n * inward, axis=1) > 0] *= -1.0
    return n


def _gap_at(
    problem: Any, gdim: int, tags: np.ndarray, x: np.ndarray, n: np.ndarray
) -> np.ndarray:
    """The problem's gap g at the vertices ``x`` (facets, vertices, 3) of contact facets.

    By UFL evaluation (a few hundred points), with the facets' tags ``tags`` and outward normals
    ``n`` (facets, 3): an obstacle's gap depends on the normal, a gap per contact tag on the
    facet's tag.
    """
    out = np.empty(x.shape[:2])
    for f in range(x.shape[0]):
        spec = problem.gap[int(tags[f])] if isinstance(problem.gap, Mapping) else problem.gap
        normal = ufl.as_vector([float(c) for c in n[f, :gdim]])
        for k in range(x.shape[1]):
            point = ufl.as_vector([float(c) for c in x[f, k, :gdim]])
            out[f, k] = float(gap_value(spec, point, normal, problem.miss_gap))
    return out


def _contact_obstacle(sol: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local fine contact facets: vertex coordinates, outer normals, gap at the vertices."""
    disc = sol.disc
    msh = disc.mesh
    tags = disc.facet_tags
    # the rigid obstacle's facets (a contact pair's master is a body of the mesh, drawn as such)
    facets = np.concatenate([tags.find(t) for t in disc.problem.rigid_tags] + [np.zeros(0, int)])
    facets = np.intersect1d(facets, _exterior_facets(msh)).astype(np.int32)
    facet_tag = tags.values[np.searchsorted(tags.indices, facets)]
    x = _cell_vertices(msh, msh.topology.dim - 1, facets)
    n = _outward_normals(msh, facets)
    with collective(msh.comm, "gap"):  # the user's gap at this rank's points
        g = _gap_at(disc.problem, msh.geometry.dim, facet_tag, x, n)
    return x, n, g


def _p1_cells(u: fem.Function) -> tuple[np.ndarray, np.ndarray]:
    """Per local cell: dof coordinates and values of a (vector) P1/Q1 function.

    Returns:
        Arrays of shape (cells, dofs per cell, 3) and (cells, dofs per cell, value size).
    """
    V = u.function_space
    n = _num_local_cells(V.mesh)
    dofs = V.dofmap.list[:n]
    coords = V.tabulate_dof_coordinates()[dofs]
    bs = V.dofmap.index_map_bs
    values = u.x.array.reshape(-1, bs)[dofs]
    return coords, values


def _cellwise(msh: dmesh.Mesh, expr: ufl.core.expr.Expr) -> np.ndarray:
    """A scalar UFL expression interpolated into DG0, per local cell."""
    W = fem.functionspace(msh, ("DG", 0))
    f = fem.Function(W)
    f.interpolate(fem.Expression(expr, compat.interpolation_points(W.element)))
    return f.x.array[W.dofmap.list[: _num_local_cells(msh), 0]].copy()


def von_mises_2d(sigma: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
    """Von Mises equivalent stress of a 2x2 stress tensor (plane stress, sigma_e = 1).

    Args:
        sigma: The stress tensor, a 2x2 UFL expression.

    Returns:
        ``sqrt(s11^2 + s22^2 - s11 s22 + 3 s12^2)``, the paper's sigma_{M,2} of Figure 5.
    """
    s11, s22, s12 = sigma[0, 0], sigma[1, 1], sigma[0, 1]
    return ufl.sqrt(s11**2 + s22**2 - s11 * s22 + 3.0 * s12**2)


@dataclass(frozen=True)
class MeshSnapshot:
    """A mesh gathered on rank 0 for drawing (see :func:`snapshot_mesh`).

    Attributes:
        cells: Vertex coordinates of every cell, shape (cells, vertices per cell, 3).
        ranks: The owning process of each cell.
        cell_type: The dolfinx cell type.
        tdim: Topological dimension.
    """

    cells: np.ndarray
    ranks: np.ndarray
    cell_type: dmesh.CellType
    tdim: int

    @property
    def num_cells(self) -> int:
        """Number of cells."""
        return len(self.cells)


def snapshot_mesh(msh: dmesh.Mesh) -> MeshSnapshot | None:
    """Gather the cells of a mesh on rank 0, to draw now or later. Collective.

    Args:
        msh: A 2D or 3D mesh.

    Returns:
        The snapshot on rank 0, ``None`` on the other ranks.
    """
    cells = np.arange(_num_local_cells(msh), dtype=np.int32)
    data = _gather_arrays(
        msh.comm, _cell_vertices(msh, msh.topology.dim, cells), np.full(len(cells), msh.comm.rank)
    )
    if data is None:
        return None
    return MeshSnapshot(data[0], data[1], msh.topology.cell_type, msh.topology.dim)


@dataclass(frozen=True)
class SolutionData:
    """A displacement and the obstacle on Gamma_C, gathered on rank 0."""

    coords: np.ndarray  # (cells, dofs per cell, 3): dof coordinates per cell
    values: np.ndarray  # (cells, dofs per cell, gdim): u_h at those dofs
    cellvalue: np.ndarray  # (cells,): a cell-wise colour (von Mises) or zeros
    obs_x: np.ndarray  # (facets, vertices, 3): fine contact facets
    obs_n: np.ndarray  # (facets, 3): their outer normals
    obs_g: np.ndarray  # (facets, vertices): the gap at their vertices
    outline: np.ndarray  # (facets, 2, 3): exterior facets (2D only)


def gather_solution(
    sol: Any, obstacle: bool, von_mises: bool, outline: bool
) -> SolutionData | None:
    """Gather the displacement of a solution, and optionally more, on rank 0. Collective.

    Args:
        sol: A :class:`~dwr_signorini.Solution`.
        obstacle: Include the fine contact facets with their normals and gaps.
        von_mises: Include the cell-wise von Mises stress (2D); else the cell values are zeros.
        outline: Include the exterior facets (the reference configuration, 2D).

    Returns:
        The gathered data on rank 0 (the parts not asked for are empty), ``None`` elsewhere.
    """
    disc = sol.disc
    msh = disc.mesh
    coords, values = _p1_cells(sol.u)
    cellvalue = (
        _cellwise(msh, von_mises_2d(disc.fields.sigma(sol.u)))
        if von_mises
        else np.zeros(len(coords))
    )
    if obstacle:
        obs = _contact_obstacle(sol)
    else:
        nv = _cell_vertices(msh, msh.topology.dim - 1, np.zeros(0, np.int32)).shape[1]
        obs = (np.zeros((0, nv, 3)), np.zeros((0, 3)), np.zeros((0, nv)))
    edges = _cell_vertices(msh, 1, _exterior_facets(msh)) if outline else np.zeros((0, 2, 3))
    data = _gather_arrays(msh.comm, coords, values, cellvalue, *obs, edges)
    return None if data is None else SolutionData(*data)


def gather_friction(sol: Any) -> list[np.ndarray] | None:
    """Gather lambda_n, lambda_t and the stick and slip sets on rank 0. Collective.

    Args:
        sol: A :class:`~dwr_signorini.Solution` of a frictional problem.

    Returns:
        On rank 0 the vertex coordinates of the macro facets, shape (facets, vertices, 3),
        lambda_n and lambda_t on each (in 3D the traction vector, shape (facets, 3)), and
        whether it sticks and whether it slips (in contact); ``None`` elsewhere.
    """
    sub = sol.disc.contact_mesh
    sdim = sub.topology.dim
    n = sub.topology.index_map(sdim).size_local
    x = _cell_vertices(sub, sdim, np.arange(n, dtype=np.int32))
    dofs = sol.lam.function_space.dofmap.list[:n, 0]
    owned = dofs < len(sol.stick)
    sets = []
    for rows in (sol.stick, sol.slip):
        out = np.zeros(n, dtype=bool)
        out[owned] = np.asarray(rows, dtype=bool)[dofs[owned]]
        sets.append(out)
    space = sol.lam_t.function_space
    bs = space.dofmap.index_map_bs
    lam_t = sol.lam_t.x.array.reshape(-1, bs)[space.dofmap.list[:n, 0]]
    return _gather_arrays(
        sub.comm, x, sol.lam.x.array[dofs].copy(), lam_t[:, 0].copy() if bs == 1 else lam_t,
        *sets,
    )


def gather_contact_force(sol: Any) -> list[np.ndarray] | None:
    """Gather the contact force lambda_H on the macro contact facets on rank 0. Collective.

    Args:
        sol: A :class:`~dwr_signorini.Solution`.

    Returns:
        On rank 0 the vertex coordinates of the macro facets, shape (facets, vertices, 3), the
        value of lambda_H on each and whether it is in the active set; ``None`` elsewhere.
    """
    sub = sol.disc.contact_mesh
    sdim = sub.topology.dim
    n = sub.topology.index_map(sdim).size_local
    x = _cell_vertices(sub, sdim, np.arange(n, dtype=np.int32))
    dofs = sol.lam.function_space.dofmap.list[:n, 0]
    lam = sol.lam.x.array[dofs].copy()
    active = np.zeros(n, dtype=bool)
    owned = dofs < len(sol.active)
    active[owned] = np.asarray(sol.active, dtype=bool)[dofs[owned]]
    return _gather_arrays(sub.comm, x, lam, active)
