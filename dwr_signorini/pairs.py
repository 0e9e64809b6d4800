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
the master cells that v o Pi lives on. :meth:`MasterTrace.share` moves such a term, localised to
the slave cells, to the master cells in proportion to the measure of the slave facet that
Pi maps into each of them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import basix
import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh

from . import compat
from .mortar import MortarRule, facet_normals, mortar_rule
from .timing import timed

__all__ = [
    "ContactPair",
    "MasterTrace",
    "check_contact_pairs",
    "check_pair_bodies",
    "check_pair_gap",
]


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


def check_contact_pairs(contact: Any) -> tuple[list[Any], tuple[ContactPair, ...]]:
    """``contact`` split into its tags (pairs by their slave tag) and its pairs.

    Args:
        contact: A tag, a :class:`ContactPair`, or a sequence of them.

    Returns:
        The contact entries with each pair replaced by its slave tag (in the order given), and
        the pairs.

    Raises:
        ValueError: A master tag that is also a contact tag or a slave tag of another pair.
    """
    entries = [contact] if isinstance(contact, ContactPair) else contact
    if isinstance(entries, (str, bytes)) or not isinstance(entries, Iterable):
        return contact, ()
    entries = list(entries)
    pairs = tuple(e for e in entries if isinstance(e, ContactPair))
    tags = [e.slave if isinstance(e, ContactPair) else e for e in entries]
    slaves = {p.slave for p in pairs}
    for p in pairs:
        if p.master in tags or p.master in slaves:
            raise ValueError(
                f"ContactPair(slave={p.slave}, master={p.master}): the master tag {p.master} "
                "is also a contact (slave) tag; a facet is on one side of the contact only"
            )
    return tags, pairs


def check_pair_gap(gap: Any, pairs: tuple[ContactPair, ...], rigid_tags: tuple[int, ...]) -> Any:
    """The ``gap`` of a problem with pairs: it is the rigid contact tags' gap only.

    Raises:
        ValueError: A gap given for a pair's slave tag, or a gap other than the default 0
            without rigid contact tags.
    """
    slaves = sorted(p.slave for p in pairs)
    if isinstance(gap, Mapping):
        named = sorted(set(gap) & set(slaves))
        if named:
            raise ValueError(
                f"gap is given for the ContactPair slave tag(s) {named}: the gap of a pair is "
                "the distance to the master surface along the slave normal, measured from the "
                "meshes; give gap for the rigid-obstacle contact tags only"
            )
        return gap
    if not rigid_tags:
        if isinstance(gap, (int, float)) and not isinstance(gap, bool) and gap == 0.0:
            return gap
        raise ValueError(
            "gap applies to rigid-obstacle contact tags, and every contact tag here is the "
            f"slave side of a ContactPair ({slaves}): the gap of a pair is measured from the "
            "meshes; leave gap at its default"
        )
    return gap


def check_pair_bodies(
    mesh: dmesh.Mesh, facet_tags: dmesh.MeshTags, pairs: tuple[ContactPair, ...]
) -> None:
    """The slave and master facets of each pair share no vertex (two bodies, collective).

    Raises:
        ValueError: A pair whose sides touch in the mesh (one body, or glued bodies).
    """
    if not pairs:
        return
    fdim = mesh.topology.dim - 1
    mesh.topology.create_connectivity(fdim, 0)
    f2v = mesh.topology.connectivity(fdim, 0)

    def vertices(tag: int) -> set[int]:
        return {int(v) for f in facet_tags.find(tag) for v in f2v.links(f)}

    comm = mesh.comm
    for p in pairs:
        shared = comm.allreduce(len(vertices(p.slave) & vertices(p.master)), op=MPI.SUM)
        if shared:
            raise ValueError(
                f"ContactPair(slave={p.slave}, master={p.master}): {shared} vertices lie on "
                "both sides; the two sides must belong to two bodies that share no vertex "
                "(mesh them as separate volumes, e.g. gmsh surfaces without a common curve)"
            )


@dataclass
class _Master:
    """The master facets of a pair, gathered on every rank."""

    vertices: np.ndarray  # (m, nv, gdim)
    normals: np.ndarray  # (m, gdim)
    geometry: np.ndarray  # (m, nodes, gdim): the adjacent cell's geometry
    dofs: np.ndarray  # (m, ndofs): its global block dofs of V
    cell: np.ndarray  # (m,): its global cell index


class MasterTrace:
    """The projection P of the master trace onto W, the gap, and the master share (module).

    Collective: every rank gathers the master facets of its pairs.

    Args:
        disc: The discretisation (its slave facet mesh ``disc.slave_mesh``).
        V: A vector Lagrange space on T_h (P1 of the solves, P2 of the weights).

    Attributes:
        W: Vector DG of V's degree on Sigma_h; ``Ws`` the scalar one.
        P: The projection (PETSc Mat, W x V, the prescribed Dirichlet columns included).
        gap: The projected gap (a function of ``Ws``; the problem's ``miss_gap`` where no
            master facet is met).
        rule: The mortar rule of this rank's slave facets.
        frame: The normal of the contact frame on the fine slave facets (vector DG0,
            :meth:`_frame`), in which the tangential slip is measured.
    """

    def __init__(self, disc: Any, V: fem.FunctionSpace) -> None:
        self.disc, self.V = disc, V
        sub = disc.slave_mesh
        gdim = sub.geometry.dim
        degree = V.ufl_element().embedded_superdegree
        self.W = fem.functionspace(sub, ("DG", degree, (gdim,)))
        self.Ws = fem.functionspace(sub, ("DG", degree))
        self._images: dict[int, tuple[fem.Function, fem.Function]] = {}
        with timed("master trace"):
            self._build(disc, V, degree)

    # -- geometry ----------------------------------------------------------------------------
    def _slave_facets(self, disc: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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

    def _master_facets(self, disc: Any, V: fem.FunctionSpace, tag: int) -> _Master:
        """The owned master facets of ``tag`` with their cells, gathered on every rank."""
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
        index_map = V.dofmap.index_map
        local = np.array([V.dofmap.cell_dofs(c) for c in cells], dtype=np.int32)
        dofs = index_map.local_to_global(local.ravel()).reshape(local.shape) if len(cells) else (
            np.zeros((0, V.dofmap.dof_layout.num_dofs), dtype=np.int64))
        cell = fine.topology.index_map(tdim).local_to_global(cells)
        parts = disc.comm.allgather((vertices, normals, geometry, dofs, cell))
        return _Master(*(np.concatenate([p[k] for p in parts]) for k in range(5)))

    # -- assembly ----------------------------------------------------------------------------
    def _build(self, disc: Any, V: fem.FunctionSpace, degree: int) -> None:
        """The rule, P, the gap and the share weights (one pass over the slave facets)."""
        vertices, normals, slave_cells, slave_tag = self._slave_facets(disc)
        rules, masters = [], []
        offset = 0
        for pair in disc.problem.pairs:
            master = self._master_facets(disc, V, pair.master)
            on = np.flatnonzero(slave_tag == pair.slave)
            r = mortar_rule(vertices[on], normals[on], master.vertices, master.normals,
                            2 * degree)
            rules.append(MortarRule(on[r.facet], r.points, r.weights, r.master + offset, r.gap))
            masters.append(master)
            offset += len(master.cell)
        self.rule = MortarRule(*(np.concatenate([getattr(r, f) for r in rules]) for f in (
            "facet", "points", "weights", "master", "gap")))
        master = _Master(*(np.concatenate([getattr(m, f) for m in masters]) for f in (
            "vertices", "normals", "geometry", "dofs", "cell")))
        basis = _FacetBasis(self.Ws, vertices, self.rule)
        projected = self.rule.points + self.rule.gap[:, None] * normals[self.rule.facet]
        phi = _master_basis(disc.mesh, V, master, self.rule.master, projected)
        self.P = self._projection(basis, phi, master)
        self.gap = self._gap(basis)
        self.frame = self._frame(normals, master.normals[self.rule.master])
        self._share = self._share_matrix(slave_cells, master)

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

    def _frame(self, slave: np.ndarray, master: np.ndarray) -> fem.Function:
        """The normal of the contact frame per fine slave facet (vector DG0 on Sigma_h).

        n_c = (n_s - <n_m>) / |n_s - <n_m>|, <n_m> the mean of the master normals over the
        part of the facet the master covers (weights of the rule): the bisector of the two
        surfaces, which does not change when the bodies swap sides (up to its sign). Where
        no master facet is met, or the surfaces do not face each other (n_s . <n_m> >= 0), the
        slave normal n_s.

        Args:
            slave: The outward normals of this rank's slave facets.
            master: The outward normal of the master facet of each point of the rule.
        """
        rule = self.rule
        mean = np.zeros_like(slave)
        np.add.at(mean, rule.facet, master * rule.weights[:, None])
        covered = np.zeros(len(slave))
        np.add.at(covered, rule.facet, rule.weights)
        mean /= np.where(covered > 0.0, covered, 1.0)[:, None]
        bisector = slave - mean
        length = np.linalg.norm(bisector, axis=1)
        facing = (covered > 0.0) & (np.einsum("fi,fi->f", slave, mean) < 0.0)
        frame = np.where(facing[:, None], bisector / np.where(facing, length, 1.0)[:, None],
                         slave)
        gdim = slave.shape[1]
        V0 = fem.functionspace(self.W.mesh, ("DG", 0, (gdim,)))
        out = fem.Function(V0, name="contact_frame")
        cells = np.array([V0.dofmap.cell_dofs(f)[0] for f in range(len(slave))], dtype=np.int64)
        out.x.array[(cells[:, None] * gdim + np.arange(gdim)).ravel()] = frame.ravel()
        out.x.scatter_forward()
        return out

    def _share_matrix(self, slave_cells: np.ndarray, master: _Master) -> PETSc.Mat:
        """S[K, c]: the part of slave cell c's facets that Pi maps into master cell K."""
        rule, fine = self.rule, self.disc.mesh
        cells = fine.topology.index_map(fine.topology.dim)
        hit = np.zeros(len(slave_cells))
        np.add.at(hit, rule.facet, rule.weights)
        frac = rule.weights / np.where(hit > 0.0, hit, 1.0)[rule.facet]
        # a slave cell with several slave facets shares each facet's part equally
        count = np.zeros(len(slave_cells))
        _, inverse, counts = np.unique(slave_cells, return_inverse=True, return_counts=True)
        count[:] = counts[inverse]
        S = PETSc.Mat().createAIJ(
            size=((cells.size_local, cells.size_global), (cells.size_local, cells.size_global)),
            nnz=(8, 8), comm=self.disc.comm,
        )
        S.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        rows = master.cell[rule.master].astype(PETSc.IntType)
        cols = slave_cells[rule.facet].astype(PETSc.IntType)
        for r, c, v in zip(rows, cols, frac / count[rule.facet], strict=True):
            S.setValue(r, c, v, addv=PETSc.InsertMode.ADD_VALUES)
        S.assemble()
        return S

    # -- use -----------------------------------------------------------------------------------
    def apply(self, f: fem.Function) -> fem.Function:
        """P f: the projected master trace of ``f`` on the slave facets (a function of W).

        The image is remembered for :meth:`image` (the estimator moves the terms of a weight's
        trace to the master cells).

        Args:
            f: A function of this trace's space V.

        Returns:
            A new function of W holding P f.
        """
        out = fem.Function(self.W, name=f"P_{f.name}")
        vec = f.x.petsc_vec
        self.P.mult(vec, out.x.petsc_vec)
        out.x.scatter_forward()
        self._images[id(f)] = (f, out)
        return out

    def image(self, f: fem.Function) -> fem.Function | None:
        """The last :meth:`apply` of ``f``.

        Args:
            f: A function of V.

        Returns:
            The function of W that :meth:`apply` returned for ``f`` last, or None.
        """
        found = self._images.get(id(f))
        return found[1] if found is not None and found[0] is f else None

    def share(self, slave_part: np.ndarray, DG0: fem.FunctionSpace) -> np.ndarray:
        """A term localised to the slave cells, moved to the master cells (module docstring).

        Args:
            slave_part: The term's cell indicators (DG0 on T_h, owned and ghost entries).
            DG0: The DG0 space of the indicators.

        Returns:
            The indicators of the same term on the master cells (DG0 entries; ghosts zero).
        """
        fine = self.disc.mesh
        cells = fine.topology.index_map(fine.topology.dim)
        n = cells.size_local
        dof = DG0.dofmap.list[:n, 0]
        p = self._share.createVecRight()
        p.array_w[:] = slave_part[dof]
        out = self._share.createVecLeft()
        self._share.mult(p, out)
        moved = np.zeros_like(slave_part)
        moved[dof] = out.array
        for v in (p, out):
            v.destroy()
        return moved

    def destroy(self) -> None:
        """Release the PETSc matrices (collective)."""
        for name in ("P", "_share"):
            mat = getattr(self, name, None)
            if mat is not None:
                mat.destroy()
                setattr(self, name, None)
        self._images.clear()


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
    for g in np.unique(which):
        at = np.flatnonzero(which == g)
        X = cmap.pull_back(np.ascontiguousarray(y[at, :gdim]), master.geometry[g])
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

