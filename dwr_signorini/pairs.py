r"""Two deformable bodies in contact: the contact pair and the master trace of one mesh.

A :class:`ContactPair` names facets of one body (the *slave* side, where the multiplier lives)
that may touch facets of another body of the same mesh (the *master* side). Small sliding in the
reference configuration: a slave point x of a facet with outward normal n meets the master
surface at Pi(x) = x + g(x) n (:mod:`~dwr_signorini.mortar`), g(x) is the gap, and the contact
conditions (2) hold for the normal relative displacement

    [u]_n(x) = (u(x) - u(Pi(x))) . n <= g(x),

with the friction laws acting on the tangential part of the same relative displacement.

**The master trace.** For a displacement space V on T_h, :class:`MasterTrace` assembles once per
mesh the matrix P of the L2 projection of v o Pi, per fine slave facet, onto the discontinuous
polynomials W of V's degree on the fine slave facets Sigma_h:

    (P v)|_F = argmin_{w in P_k(F)} ||w - v o Pi||_{L2(F)},

from the exact integrals of the mortar rule. Every form of the package writes the relative
displacement as ``v - P v`` (:meth:`~dwr_signorini.spaces.Discretization.relative`), P v a
function of W. For a multiplier piecewise constant on the macro facets and a normal constant on
each flat facet, (mu, (P v) . n)_GC = (mu, (v o Pi) . n)_GC exactly: the coupling matrix
N (I - P) of the algebra is the mortar matrix, and the residuals of the estimators use the same
coupling as the discrete problem (Galerkin orthogonality holds in both bodies). The gap is the
same projection of g(x).

**The master share.** A residual term (r, (P v) . e)_GC with a displacement weight v belongs to
the master cells that v o Pi lives on. :meth:`TraceGeometry.share` moves such a term, localised
to the fine slave facets, from the slave cell beside each facet to the master cells, in
proportion to the measure of the facet's covered part that Pi maps into each of them (each
covered facet's shares sum to 1, so the moved indicators sum to the term).

**One geometry per mesh.** The slave and master facets (the master facets gathered once), the
mortar rule of each degree and the share do not depend on the displacement space:
:class:`TraceGeometry` holds them once per mesh, and the :class:`MasterTrace` of each space (P1 of
the solves, P2 of the weights) adds its projection. The discretisation owns both and releases
them in its ``destroy()``.

**Images name what they project.** :meth:`MasterTrace.apply` returns P f as a function of W
whose attribute ``trace_of`` is f; :func:`images_of` finds the images of f among a form's
coefficients, so the part of a form linear in the trace of a weight is read off the form itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from . import compat
from .mortar import MortarRule, facet_normals
from .search import candidate_rule
from .timing import timed

__all__ = [
    "MAX_DEGREE",
    "ContactPair",
    "MasterTrace",
    "TraceGeometry",
    "images_of",
]

#: The highest degree of a displacement space that a master trace takes (Lagrange, no dof
#: transformations).
MAX_DEGREE = 2


@dataclass(frozen=True)
class ContactPair:
    """Facets tagged ``slave`` of one body may touch facets tagged ``master`` of another.

    Both bodies are elastic and live in the problem's mesh, disjoint (no shared vertex); the
    multiplier lives on the slave side's macro facets (P0) and the gap of a slave point is its
    distance to the master surface along the slave normal (:mod:`~dwr_signorini.pairs`).

    Args:
        slave: The facet tag of the slave side.
        master: The facet tag of the master side.
    """

    slave: int
    master: int

    def __post_init__(self) -> None:
        for name in ("slave", "master"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"ContactPair: {name} must be an integer facet tag, got {value!r}")
            object.__setattr__(self, name, int(value))
        if self.slave == self.master:
            raise ValueError(
                f"ContactPair: slave and master must be different facet tags, got {self.slave} "
                "for both"
            )


@dataclass
class _Master:
    """The master facets of a pair, gathered on every rank."""

    vertices: np.ndarray  # (m, nv, gdim)
    normals: np.ndarray  # (m, gdim)
    geometry: np.ndarray  # (m, nodes, gdim): the adjacent cell's geometry
    dofs: np.ndarray  # (m, ndofs): its global block dofs of V
    cell: np.ndarray  # (m,): its global cell index


class TraceGeometry:
    """The geometry of a mesh's pairs: facets, mortar rules, share (module).

    Built once per mesh by the discretisation (collective: every rank gathers the master
    facets of its pairs) and shared by the :class:`MasterTrace` of each displacement space.

    Args:
        disc: The discretisation (its slave facet mesh ``disc.slave_mesh``).

    Attributes:
        vertices, normals: This rank's slave facets (owned cells of ``disc.slave_mesh``).
        slave_cells: The fine cell beside each slave facet (global index).
        master: The master facets of all pairs, gathered (without dofs).
        Fs: DG0 on the slave facets: the space of indicators localised per facet.
        share_weights: S^T (PETSc Mat, slave facets x fine cells): row F holds the part of
            facet F's covered measure that Pi maps into each master cell; it sums to 1 on a
            facet the master covers (at all), and is empty on one it misses.
    """

    #: How many geometries are alive (built and not destroyed), on this rank.
    live = 0

    def __init__(self, disc: Any) -> None:
        self.disc = disc
        self.Fs = fem.functionspace(disc.slave_mesh, ("DG", 0))
        with timed("master trace"):
            self._build(disc)
        TraceGeometry.live += 1

    def _build(self, disc: Any) -> None:
        """The facets, the masters of every pair, the rule of the solves and the share."""
        vertices, normals, slave_cells, self._slave_tag = _slave_facets(disc)
        self.vertices, self.normals, self.slave_cells = vertices, normals, slave_cells
        masters, self.master_cells = [], []
        for pair in disc.problem.pairs:
            master, local = _master_facets(disc, pair.master)
            masters.append(master)
            self.master_cells.append(local)
        self._masters = masters
        self.master = _Master(*(np.concatenate([getattr(m, f) for m in masters]) for f in (
            "vertices", "normals", "geometry", "dofs", "cell")))
        self._rules: dict[int, MortarRule] = {}
        self.share_weights, self._home = self._share_matrices(self.rule(1))

    def rule(self, degree: int) -> MortarRule:
        """The mortar rule for a space of ``degree`` (exact to degree 2 ``degree``), kept.

        The pieces do not depend on the degree (the share is the same from any rule); the
        Gauss points on them do. Each degree asked for runs the mortar search once per mesh.

        Args:
            degree: The degree of the displacement space.

        Returns:
            The :class:`~dwr_signorini.mortar.MortarRule` of this rank's slave facets.
        """
        if degree not in self._rules:
            rules, offset = [], 0
            vertices, normals = self.vertices, self.normals
            for pair, master in zip(self.disc.problem.pairs, self._masters, strict=True):
                on = np.flatnonzero(self._slave_tag == pair.slave)
                r = candidate_rule(vertices[on], normals[on], master.vertices, master.normals,
                                   2 * degree)
                rules.append(MortarRule(on[r.facet], r.points, r.weights, r.master + offset,
                                        r.gap))
                offset += len(master.cell)
            self._rules[degree] = MortarRule(*(np.concatenate([getattr(r, f) for r in rules])
                                               for f in ("facet", "points", "weights",
                                                         "master", "gap")))
        return self._rules[degree]

    def _share_matrices(self, rule: MortarRule) -> tuple[PETSc.Mat, PETSc.Mat]:
        """S^T (facet -> master cells, rows summing to 1 where covered) and H^T (its cell)."""
        fine, Fs = self.disc.mesh, self.Fs
        cells = fine.topology.index_map(fine.topology.dim)
        fmap = Fs.dofmap.index_map
        num = len(self.vertices)
        hit = np.zeros(num)
        np.add.at(hit, rule.facet, rule.weights)
        rows = fmap.local_to_global(Fs.dofmap.list[:num, 0].astype(np.int32))
        frac = rule.weights / np.where(hit > 0.0, hit, 1.0)[rule.facet]
        covered = np.flatnonzero(hit > 0.0)
        first = fmap.local_range[0]
        row_sizes = (fmap.size_local, fmap.size_global)
        col_sizes = (cells.size_local, cells.size_global)
        comm = self.disc.comm
        S = _csr(comm, [rows[rule.facet]], [self.master.cell[rule.master]], [frac], first,
                 row_sizes, col_sizes)
        H = _csr(comm, [rows[covered]], [self.slave_cells[covered]], [np.ones(len(covered))],
                 first, row_sizes, col_sizes)
        return S, H

    def share(self, facet_part: np.ndarray, DG0: fem.FunctionSpace) -> np.ndarray:
        """A term localised per slave facet, moved from the slave to the master cells.

        Args:
            facet_part: The term's indicators per owned slave facet (owned entries of ``Fs``).
            DG0: The DG0 space of the cell indicators on T_h.

        Returns:
            S p - H p as DG0 entries (owned and ghost, ghosts zero): added to the indicators
            of the term localised to the slave cells, it moves each covered facet's part
            from the cell beside the facet to the master cells; it sums to zero.
        """
        fine = self.disc.mesh
        n = fine.topology.index_map(fine.topology.dim).size_local
        p = self.share_weights.createVecLeft()
        p.array_w[:] = facet_part
        out, home = self.share_weights.createVecRight(), self._home.createVecRight()
        self.share_weights.multTranspose(p, out)
        self._home.multTranspose(p, home)
        moved = np.zeros(DG0.dofmap.index_map.size_local + DG0.dofmap.index_map.num_ghosts)
        moved[DG0.dofmap.list[:n, 0]] = out.array - home.array
        for v in (p, out, home):
            v.destroy()
        return moved

    def destroy(self) -> None:
        """Release the PETSc matrices (collective; idempotent)."""
        if getattr(self, "share_weights", None) is not None:
            TraceGeometry.live -= 1
        for name in ("share_weights", "_home"):
            mat = getattr(self, name, None)
            if mat is not None:
                mat.destroy()
                setattr(self, name, None)


class MasterTrace:
    """The projection P of the master trace onto W and the gap, for one space (module).

    Collective (every rank gathers the master dofs of its pairs).

    Args:
        disc: The discretisation (its slave facet mesh ``disc.slave_mesh``).
        V: A vector Lagrange space on T_h of degree <= :data:`MAX_DEGREE` (P1 of the solves,
            P2 of the weights).
        geometry: The mesh's :class:`TraceGeometry`.

    Raises:
        NotImplementedError: V of a degree above :data:`MAX_DEGREE`.

    Attributes:
        W: Vector DG of V's degree on Sigma_h; ``Ws`` the scalar one.
        P: The projection (PETSc Mat, W x V, the prescribed Dirichlet columns included).
        gap: The projected gap (a function of ``Ws``; the problem's ``miss_gap`` where no
            master facet is met).
        rule: The mortar rule of this rank's slave facets (the geometry's of V's degree).
    """

    #: How many traces are alive (built and not destroyed), on this rank.
    live = 0

    def __init__(self, disc: Any, V: fem.FunctionSpace, geometry: TraceGeometry) -> None:
        self.disc, self.V, self.geometry = disc, V, geometry
        sub = disc.slave_mesh
        gdim = sub.geometry.dim
        degree = V.ufl_element().embedded_superdegree
        if degree > MAX_DEGREE:
            raise NotImplementedError(
                f"contact pairs take displacement spaces of degree <= {MAX_DEGREE}, got {degree}"
            )
        self.W = fem.functionspace(sub, ("DG", degree, (gdim,)))
        self.Ws = fem.functionspace(sub, ("DG", degree))
        with timed("master trace"):
            self._build(disc, V, degree)
        MasterTrace.live += 1

    # -- assembly ----------------------------------------------------------------------------
    def _build(self, disc: Any, V: fem.FunctionSpace, degree: int) -> None:
        """P and the gap from the geometry's rule (one pass over the rule's points)."""
        geometry = self.geometry
        vertices, normals = geometry.vertices, geometry.normals
        self.rule = geometry.rule(degree)
        master = geometry.master
        master = _Master(master.vertices, master.normals, master.geometry,
                         _master_dofs(disc, V, geometry.master_cells), master.cell)
        basis = _FacetBasis(self.Ws, vertices, self.rule)
        projected = self.rule.points + self.rule.gap[:, None] * normals[self.rule.facet]
        phi = _master_basis(disc.mesh, V, master, self.rule.master, projected)
        self.P = self._projection(basis, phi, master)
        self.gap = self._gap(basis)

    def _projection(self, basis: _FacetBasis, phi: np.ndarray, master: _Master) -> PETSc.Mat:
        """P = M_F^{-1} sum_q w_q theta(x_q) phi(Pi(x_q))^T per facet and component.

        On a facet the master covers in part, the projection onto constants instead (as the
        gap, :meth:`_gap`).
        """
        rule, W, V = self.rule, self.W, self.V
        bs = W.dofmap.index_map_bs
        wmap, vmap = W.dofmap.index_map, V.dofmap.index_map
        inv = np.linalg.inv(basis.mass) if len(basis.mass) else basis.mass
        # per point: the facet's rows (a) times the master cell's columns (j)
        local = np.einsum("qab,qb->qa", inv[rule.facet], basis.theta) * rule.weights[:, None]
        # a facet the master covers in part: the mean of the trace (no polynomial through the
        # master's end); its integral against a constant is the same
        part = basis.partial[rule.facet]
        local[part] = (rule.weights[part] / basis.measure[rule.facet[part]])[:, None]
        w_dofs = wmap.local_to_global(
            np.array([W.dofmap.cell_dofs(int(f)) for f in range(len(basis.mass))],
                     dtype=np.int32).ravel()
        ).reshape(len(basis.mass), -1) if len(basis.mass) else np.zeros((0, 1), np.int64)
        rows, cols, vals = [], [], []
        r_q, c_q = w_dofs[rule.facet], master.dofs[rule.master]  # (q, a), (q, j)
        v_q = np.einsum("qa,qj->qaj", local, phi)
        shape = v_q.shape
        for c in range(bs):
            rows.append(np.broadcast_to((r_q * bs + c)[:, :, None], shape).ravel())
            cols.append(np.broadcast_to((c_q * bs + c)[:, None, :], shape).ravel())
            vals.append(v_q.ravel())
        return _csr(self.disc.comm, rows, cols, vals, wmap.local_range[0] * bs,
                    (wmap.size_local * bs, wmap.size_global * bs),
                    (vmap.size_local * V.dofmap.index_map_bs,
                     vmap.size_global * V.dofmap.index_map_bs))

    def _gap(self, basis: _FacetBasis) -> fem.Function:
        """The gap g projected per facet, the problem's miss_gap where no master facet is met.

        On a facet that the master covers in part, the projection onto constants: a polynomial
        through the jump from the gaps met to miss_gap would dip below them (a false contact).
        """
        miss = self.disc.problem.miss_gap
        rule, Ws = self.rule, self.Ws
        gap = fem.Function(Ws, name="gap")
        rhs = miss * basis.integrals.copy()
        np.add.at(rhs, rule.facet, basis.theta * (rule.weights * (rule.gap - miss))[:, None])
        for f in range(len(basis.mass)):
            if basis.partial[f]:  # the mean, between the gaps met and miss_gap
                value = rhs[f].sum() / basis.measure[f]
            else:
                value = np.linalg.solve(basis.mass[f], rhs[f])
            gap.x.array[Ws.dofmap.cell_dofs(f)] = value
        gap.x.scatter_forward()
        return gap

    # -- use -----------------------------------------------------------------------------------
    def apply(self, f: fem.Function) -> fem.Function:
        """P f: the projected master trace of ``f`` on the slave facets (a function of W).

        Each call returns a new function; its attribute ``trace_of`` is ``f`` (the estimator
        finds the images of a weight in a form by it, :func:`images_of`).

        Args:
            f: A function of this trace's space V.

        Returns:
            A new function of W holding P f.

        Raises:
            ValueError: ``f`` is not a function of V.
        """
        if f.function_space != self.V:
            raise ValueError(
                f"MasterTrace.apply: {f.name} is not a function of this trace's space"
            )
        # temporary PETSc vectors, destroyed here: a Function's own (x.petsc_vec) is destroyed
        # by dolfinx's __del__, at a time of the garbage collector's on each rank
        x, y = self.P.createVecRight(), self.P.createVecLeft()
        x.array_w[:] = f.x.array[: len(x.array_r)]
        self.P.mult(x, y)
        out = fem.Function(self.W, name=f"P_{f.name}")
        out.x.array[: len(y.array_r)] = y.array_r
        for vec in (x, y):
            vec.destroy()
        out.x.scatter_forward()
        out.trace_of = f
        return out

    def destroy(self) -> None:
        """Release the projection (collective; idempotent; the geometry is the disc's)."""
        if getattr(self, "P", None) is not None:
            MasterTrace.live -= 1
            self.P.destroy()
            self.P = None


def images_of(form: Any, f: fem.Function) -> list[fem.Function]:
    """The master-trace images of ``f`` (:meth:`MasterTrace.apply`) among a form's coefficients.

    Args:
        form: A UFL form or expression.
        f: A function of a displacement space.

    Returns:
        The functions P f in ``form`` whose ``trace_of`` is ``f`` (in UFL's order).
    """
    return [c for c in ufl.algorithms.extract_coefficients(form)
            if getattr(c, "trace_of", None) is f]


class _FacetBasis:
    """W's scalar basis on this rank's slave facets: theta_a(x_q), mass matrices, int theta_a."""

    def __init__(self, Ws: fem.FunctionSpace, vertices: np.ndarray, rule: MortarRule) -> None:
        element = Ws.ufl_element().basix_element
        fdim = Ws.mesh.topology.dim
        num = len(vertices)
        # affine facets: x = v0 + sum_k X_k (v_{k+1} - v0) (a quadrilateral's vertices 1 and 2)
        axes = np.stack([vertices[:, k + 1] - vertices[:, 0] for k in range(fdim)], axis=1) \
            if num else np.zeros((0, fdim, vertices.shape[-1]))
        gram = np.einsum("fkd,fld->fkl", axes, axes)
        if len(rule.facet):
            A = gram[rule.facet]
            b = np.einsum("qkd,qd->qk", axes[rule.facet], rule.points - vertices[rule.facet, 0])
            X = np.linalg.solve(A, b[..., None])[..., 0]
            self.theta = _tabulate(element, X)
        else:
            self.theta = np.zeros((0, element.dim))
        points, weights = basix.make_quadrature(element.cell_type, 2 * max(element.degree, 1))
        ref = _tabulate(element, points)
        jac = np.sqrt(np.abs(np.linalg.det(gram))) if num else np.zeros(0)
        self.mass = np.einsum("q,qa,qb->ab", weights, ref, ref)[None] * jac[:, None, None]
        self.integrals = (weights @ ref)[None] * jac[:, None]
        #: |F|, and whether the master covers F in part only (not at all, or not all of it)
        self.measure = self.integrals.sum(axis=1)
        covered = np.zeros(num)
        np.add.at(covered, rule.facet, rule.weights)
        self.partial = covered < (1.0 - 1e-9) * self.measure


def _slave_facets(disc: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """This rank's slave facets: vertices, normals, slave cells (global), slave tag."""
    sub, fine = disc.slave_mesh, disc.mesh
    tdim = fine.topology.dim
    num = sub.topology.index_map(sub.topology.dim).size_local
    facets = disc.slave_to_fine[:num]
    x = sub.geometry.x[:, :sub.geometry.dim]
    vertices = x[compat.geometry_dofmap(sub)[:num]]
    f2c = fine.topology.connectivity(tdim - 1, tdim)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    inside = _entity_points(fine, tdim, cells).mean(axis=1)
    normals = facet_normals(vertices, inside)
    glob = fine.topology.index_map(tdim).local_to_global(cells)
    tag = _facet_tag(disc.facet_tags, facets)
    return vertices, normals, glob, tag


def _master_facets(disc: Any, tag: int) -> tuple[_Master, np.ndarray]:
    """The owned master facets of ``tag`` gathered on every rank, and this rank's cells.

    Returns:
        The gathered facets (``dofs`` empty: :func:`_master_dofs` adds a space's), and the
        local index of the cell beside each of this rank's owned facets of ``tag``.
    """
    fine = disc.mesh
    tdim, gdim = fine.topology.dim, fine.geometry.dim
    n_own = fine.topology.index_map(tdim - 1).size_local
    facets = disc.facet_tags.find(tag)
    facets = facets[facets < n_own].astype(np.int32)
    f2c = fine.topology.connectivity(tdim - 1, tdim)
    cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
    vertices = _entity_points(fine, tdim - 1, facets)
    geometry = fine.geometry.x[compat.geometry_dofmap(fine)[cells]][:, :, :gdim]
    normals = facet_normals(vertices, geometry.mean(axis=1))
    cell = fine.topology.index_map(tdim).local_to_global(cells)
    parts = disc.comm.allgather((vertices, normals, geometry, cell))
    vertices, normals, geometry, cell = (np.concatenate([p[k] for p in parts]) for k in range(4))
    return _Master(vertices, normals, geometry, np.zeros((len(cell), 0), np.int64), cell), cells


def _master_dofs(disc: Any, V: fem.FunctionSpace, cells: list[np.ndarray]) -> np.ndarray:
    """V's global block dofs of the master cells, gathered in :class:`TraceGeometry`'s order.

    Args:
        disc: The discretisation.
        V: The displacement space.
        cells: Per pair, the local cells of this rank's owned master facets.
    """
    index_map = V.dofmap.index_map
    width = V.dofmap.dof_layout.num_dofs
    out = []
    for local in cells:
        dofs = np.array([V.dofmap.cell_dofs(c) for c in local], dtype=np.int32).reshape(-1, width)
        dofs = index_map.local_to_global(dofs.ravel()).reshape(dofs.shape)
        out.extend(disc.comm.allgather(dofs))
    return np.concatenate(out) if out else np.zeros((0, width), np.int64)


def _master_basis(
    mesh: dmesh.Mesh, V: fem.FunctionSpace, master: _Master, which: np.ndarray, y: np.ndarray
) -> np.ndarray:
    """phi_j(y_q) of V's scalar element in the master cell ``which[q]`` of each point."""
    element = V.ufl_element().sub_elements[0].basix_element
    if V.element.needs_dof_transformations:
        raise NotImplementedError(
            "contact pairs need an element without dof transformations (Lagrange of degree <= 2)"
        )
    cmap = compat.geometry_cmap(mesh)
    gdim = mesh.geometry.dim
    out = np.zeros((len(y), element.dim))
    order = np.argsort(which, kind="stable")  # the points of each master facet, in one pass
    cuts = np.flatnonzero(np.diff(which[order])) + 1
    for at in np.split(order, cuts) if len(order) else []:
        X = cmap.pull_back(np.ascontiguousarray(y[at, :gdim]), master.geometry[which[at[0]]])
        out[at] = _tabulate(element, X)
    return out


def _entity_points(msh: dmesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The geometry nodes of ``entities`` of dimension ``dim``, shape (m, nodes, gdim)."""
    gdim = msh.geometry.dim
    if len(entities) == 0:  # (entities_to_geometry divides by the count)
        nodes = msh.topology.dim + 1 if dim == msh.topology.dim else dim + 1
        return np.zeros((0, nodes, gdim))
    return msh.geometry.x[dmesh.entities_to_geometry(msh, dim, entities)][:, :, :gdim]


def _tabulate(element: Any, X: np.ndarray) -> np.ndarray:
    """A scalar basix element's basis values at the reference points X, shape (points, dofs)."""
    values = element.tabulate(0, np.ascontiguousarray(X, dtype=np.float64))
    return values.reshape(values.shape[1], values.shape[2])


def _facet_tag(tags: dmesh.MeshTags, facets: np.ndarray) -> np.ndarray:
    """The tag of each of ``facets`` (-1 where untagged)."""
    lookup = dict(zip(tags.indices.tolist(), tags.values.tolist(), strict=True))
    return np.array([lookup.get(int(f), -1) for f in facets], dtype=np.int64)


def _csr(
    comm: MPI.Comm, rows: list, cols: list, vals: list, first: int, row_sizes: tuple,
    col_sizes: tuple,
) -> PETSc.Mat:
    """An AIJ matrix from owned global rows, columns and values (duplicates summed)."""
    n = row_sizes[0]
    r = np.concatenate(rows).astype(np.int64) - first if rows else np.zeros(0, np.int64)
    c = np.concatenate(cols).astype(np.int64) if cols else np.zeros(0, np.int64)
    v = np.concatenate(vals) if vals else np.zeros(0)
    keep = v != 0.0
    r, c, v = r[keep], c[keep], v[keep]
    key = r * col_sizes[1] + c
    uniq, inverse = np.unique(key, return_inverse=True)
    summed = np.zeros(len(uniq))
    np.add.at(summed, inverse, v)
    ur, uc = uniq // col_sizes[1], uniq % col_sizes[1]
    indptr = np.zeros(n + 1, dtype=PETSc.IntType)
    np.add.at(indptr, ur + 1, 1)
    indptr = np.cumsum(indptr).astype(PETSc.IntType)
    return PETSc.Mat().createAIJ(
        size=(row_sizes, col_sizes),
        csr=(indptr, uc.astype(PETSc.IntType), summed),
        comm=comm,
    )


