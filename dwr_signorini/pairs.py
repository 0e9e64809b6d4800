r"""Two deformable bodies in contact: the contact pair and the master trace of one mesh.

A :class:`ContactPair` names facets of one body (the *slave* side, where the multiplier lives)
that may touch facets of another body of the same mesh (the *master* side). Small sliding in the
reference configuration: a slave point x of a facet with outward normal n meets the master
surface at Pi(x) = x + g(x) n (:mod:`~dwr_signorini.mortar`), g(x) is the gap, and the contact
conditions (2) hold for the normal relative displacement

    [u]_n(x) = (u(x) - u(Pi(x))) . n <= g(x),

with the friction laws acting on the tangential part of the same relative displacement.

**The master trace.** For a displacement space V on T_h, :class:`MasterTrace` assembles once per
mesh the matrix P of the L2 projection, per fine slave facet, onto the discontinuous polynomials
W of V's degree on the fine slave facets Sigma_h of what the slave side is compared with: v o Pi
where the master covers F (chi = 1, the mortar rule's pieces) and v itself where it does not,

    (P v)|_F = argmin_{w in P_k(F)} ||w - (chi v o Pi + (1 - chi) v)||_{L2(F)},

from the exact integrals of the mortar rule (onto constants on a facet covered in part). So the
relative displacement v - P v vanishes where the master is not there, and the conditions of a
macro facet hold on its covered part. Every form of the package writes the relative
displacement as ``v - P v`` (:meth:`~dwr_signorini.spaces.Discretization.relative`), P v a
function of W. For a multiplier piecewise constant on the macro facets and a normal constant on
each flat facet, (mu, (P v) . n)_GC = (mu, (v o Pi) . n)_GC exactly: the coupling matrix
N (I - P) of the algebra is the mortar matrix, and the residuals of the estimators use the same
coupling as the discrete problem (Galerkin orthogonality holds in both bodies). The gap is the
same projection of chi g(x); a macro facet that no master facet covers gets ``miss_gap``.

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

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh

from . import compat
from .mortar import (
    FacetBasis,
    FacetMap,
    MortarRule,
    check_planar,
    facet_normals,
    mortar_rule,
    tabulate,
    warp,
)
from .timing import timed

#: The covered fraction of a macro facet below which it counts as uncovered (``miss_gap``).
MIN_MACRO_COVER = 1e-3

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
        window: The penetration window, a length > 0; None (default): the diameter of each
            slave macro facet (twice that of its fine facets).

    A slave point's partner is the first crossing of its normal ray with a master facet that
    faces it, in front of the point or behind it by at most ``window``
    (:mod:`~dwr_signorini.mortar`): master facets on the far side of the master body, or farther
    behind, are no partners, so the tags may be whole boundaries.
    """

    slave: int
    master: int
    window: float | None = None

    def __post_init__(self) -> None:
        for name in ("slave", "master"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"ContactPair: {name} must be an integer facet tag, got {value!r}")
            object.__setattr__(self, name, int(value))
        w = self.window
        if w is not None:
            if isinstance(w, bool) or not isinstance(w, (int, float, np.floating, np.integer)):
                raise TypeError(f"ContactPair: window must be a number or None, got {w!r}")
            if not (0.0 < float(w) < np.inf):
                raise ValueError(f"ContactPair: window must be a finite length > 0, got {w!r}")
            object.__setattr__(self, "window", float(w))
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
class _Side:
    """Facets of one side of a pair with their cells (the master's gathered on every rank)."""

    vertices: np.ndarray  # (m, nv, gdim)
    normals: np.ndarray  # (m, gdim)
    geometry: np.ndarray  # (m, nodes, gdim): the adjacent cell's geometry
    dofs: np.ndarray  # (m, ndofs): its global block dofs of V
    cell: np.ndarray  # (m,): its global cell index

    @staticmethod
    def fields() -> tuple[str, ...]:
        """The attributes in order."""
        return ("vertices", "normals", "geometry", "dofs", "cell")


class MasterTrace:
    """The projection P of the master trace onto W, the gap, and the master share (module).

    Collective: every rank gathers the master facets of its pairs.

    Args:
        disc: The discretisation (its slave facet mesh ``disc.slave_mesh``).
        V: A vector Lagrange space on T_h (P1 of the solves, P2 of the weights).

    Attributes:
        W: Vector DG of V's degree on Sigma_h; ``Ws`` the scalar one.
        P: The projection (PETSc Mat, W x V, the prescribed Dirichlet columns included).
        gap: The projected gap (a function of ``Ws``; the problem's ``miss_gap`` on the
            macro facets that no master facet covers).
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
    def _slave_facets(self, disc: Any) -> tuple[np.ndarray, np.ndarray, _Side, np.ndarray]:
        """This rank's slave facets: vertices, normals, their cells and the slave tag."""
        sub, fine = disc.slave_mesh, disc.mesh
        tdim = fine.topology.dim
        num = sub.topology.index_map(sub.topology.dim).size_local
        facets = disc.slave_to_fine[:num]
        x = sub.geometry.x[:, :sub.geometry.dim]
        vertices = x[compat.geometry_dofmap(sub)[:num]]
        f2c = fine.topology.connectivity(tdim - 1, tdim)
        cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
        cell = _cells(fine, self.V, cells, vertices)
        tag = _facet_tag(disc.facet_tags, facets)
        return vertices, cell.normals, cell, tag

    def _master_facets(self, disc: Any, V: fem.FunctionSpace, tag: int) -> _Side:
        """The owned master facets of ``tag`` with their cells, gathered on every rank."""
        fine = disc.mesh
        tdim = fine.topology.dim
        n_own = fine.topology.index_map(tdim - 1).size_local
        facets = disc.facet_tags.find(tag)
        facets = facets[facets < n_own].astype(np.int32)
        f2c = fine.topology.connectivity(tdim - 1, tdim)
        cells = np.array([f2c.links(f)[0] for f in facets], dtype=np.int32)
        mine = _cells(fine, V, cells, _entity_points(fine, tdim - 1, facets))
        parts = disc.comm.allgather(tuple(getattr(mine, f) for f in _Side.fields()))
        return _Side(*(np.concatenate([p[k] for p in parts]) for k in range(5)))

    @staticmethod
    def _check_planar(disc: Any) -> None:
        """Refuse warped quadrilateral facets of the pairs' macro facets, on every rank.

        (The macro ones: the children of a warped facet would not even be tagged on T_h.)
        """
        macro, tags = disc.macro_mesh, disc.problem.facet_tags
        fdim = macro.topology.dim - 1
        n_own = macro.topology.index_map(fdim).size_local
        found = [tags.find(t) for p in disc.problem.pairs for t in (p.slave, p.master)]
        facets = np.unique(np.concatenate(found)) if found else np.zeros(0, np.int32)
        facets = facets[facets < n_own].astype(np.int32)
        check_planar(disc.comm.allreduce(warp(_entity_points(macro, fdim, facets)), op=MPI.MAX))

    @staticmethod
    def _windows(pair: ContactPair, vertices: np.ndarray) -> np.ndarray | float:
        """The pair's penetration window (default: each slave macro facet's diameter)."""
        if pair.window is not None:
            return pair.window
        d = np.linalg.norm(vertices[:, :, None] - vertices[:, None], axis=3)
        return 2.0 * d.max(axis=(1, 2)) if len(vertices) else np.zeros(0)

    # -- assembly ----------------------------------------------------------------------------
    def _build(self, disc: Any, V: fem.FunctionSpace, degree: int) -> None:
        """The rule, P, the gap and the share weights (one pass over the slave facets)."""
        self._check_planar(disc)
        vertices, normals, slave, slave_tag = self._slave_facets(disc)
        rules, masters = [], []
        offset = 0
        for pair in disc.problem.pairs:
            master = self._master_facets(disc, V, pair.master)
            on = np.flatnonzero(slave_tag == pair.slave)
            r = mortar_rule(vertices[on], normals[on], master.vertices, master.normals,
                            2 * degree, self._windows(pair, vertices[on]))
            rules.append(MortarRule(on[r.facet], r.points, r.weights, r.master + offset, r.gap))
            masters.append(master)
            offset += len(master.cell)
        self.rule = MortarRule(*(np.concatenate([getattr(r, f) for r in rules]) for f in (
            "facet", "points", "weights", "master", "gap")))
        master = _Side(*(np.concatenate([getattr(m, f) for m in masters])
                           for f in _Side.fields()))
        basis = FacetBasis(self.Ws.ufl_element().basix_element, FacetMap(vertices), self.rule)
        projected = self.rule.points + self.rule.gap[:, None] * normals[self.rule.facet]
        phi = _cell_basis(disc.mesh, V, master.geometry, self.rule.master, projected)
        terms = [(self.rule.facet, self.rule.weights, basis.theta, phi,
                  master.dofs[self.rule.master])]
        terms += self._uncovered(basis, slave)
        self.P = self._projection(basis, terms)
        self.gap = self._gap(basis)
        self.frame = self._frame(normals, master.normals[self.rule.master])
        self._share = self._share_matrix(slave.cell, master, basis)

    def _uncovered(self, basis: FacetBasis, slave: _Side) -> list[tuple[np.ndarray, ...]]:
        """The slave's own trace on the uncovered part of each facet: + int_F, - int_covered.

        P v = v o Pi where a master facet is met and v itself where none is, so that the
        relative displacement v - P v vanishes where the master is not there.
        """
        part = np.flatnonzero(~basis.full)
        if len(part) == 0:
            return []
        on = np.isin(basis.full_facet, part)
        f_full = basis.full_facet[on]
        at = np.isin(self.rule.facet, part)
        f_rule = self.rule.facet[at]
        facet = np.concatenate([f_full, f_rule])
        x = np.concatenate([basis.full_points[on], self.rule.points[at]])
        phi = _cell_basis(self.disc.mesh, self.V, slave.geometry, facet, x)
        theta = np.concatenate([basis.full_theta[on], basis.theta[at]])
        weights = np.concatenate([basis.full_weights[on], -self.rule.weights[at]])
        return [(facet, weights, theta, phi, slave.dofs[facet])]

    def _projection(self, basis: FacetBasis, terms: list[tuple[np.ndarray, ...]]) -> PETSc.Mat:
        """P = M_F^{-1} sum_q w_q theta(x_q) phi(y_q)^T per facet and component.

        Args:
            basis: W's basis on the slave facets.
            terms: (facet, weight, theta(x_q), phi(y_q), global dofs of phi's cell) per point:
                the master points y_q = Pi(x_q) of the rule, and the slave's own points on the
                uncovered parts (:meth:`_uncovered`).
        """
        W, V = self.W, self.V
        bs = W.dofmap.index_map_bs
        wmap, vmap = W.dofmap.index_map, V.dofmap.index_map
        inv = np.linalg.inv(basis.mass) if len(basis.mass) else basis.mass
        w_dofs = wmap.local_to_global(
            np.array([W.dofmap.cell_dofs(int(f)) for f in range(len(basis.mass))],
                     dtype=np.int32).ravel()
        ).reshape(len(basis.mass), -1) if len(basis.mass) else np.zeros((0, 1), np.int64)
        rows, cols, vals = [], [], []
        for facet, weights, theta, phi, dofs in terms:
            # per point: the facet's rows (a) times the cell's columns (j)
            local = np.einsum("qab,qb->qa", inv[facet], theta) * weights[:, None]
            # a facet the master covers in part: the mean (no polynomial through the jump at
            # the master's end); its integral against a constant is the same
            part = basis.partial[facet]
            local[part] = (weights[part] / basis.measure[facet[part]])[:, None]
            r_q = w_dofs[facet]
            v_q = np.einsum("qa,qj->qaj", local, phi)
            shape = v_q.shape
            for c in range(bs):
                rows.append(np.broadcast_to((r_q * bs + c)[:, :, None], shape).ravel())
                cols.append(np.broadcast_to((dofs * bs + c)[:, None, :], shape).ravel())
                vals.append(v_q.ravel())
        return _csr(self.disc.comm, rows, cols, vals, wmap.local_range[0] * bs,
                    (wmap.size_local * bs, wmap.size_global * bs),
                    (vmap.size_local * V.dofmap.index_map_bs,
                     vmap.size_global * V.dofmap.index_map_bs))

    def _gap(self, basis: FacetBasis) -> fem.Function:
        """The gap g projected per facet from its covered part (zero elsewhere).

        The uncovered part of a facet carries no gap (and no relative displacement,
        :meth:`_uncovered`): the integrated gap of a macro facet is that of its covered part.
        On a facet covered in part, the projection onto constants (a polynomial through the
        jump at the master's end would dip below the gaps met: a false contact). A macro facet
        that no master facet covers at all gets the problem's ``miss_gap``, which
        keeps its multiplier zero; so does one covered by less than :data:`MIN_MACRO_COVER` of
        its measure (its row of N would be that small: a near-null pivot).
        """
        rule, Ws = self.rule, self.Ws
        gap = fem.Function(Ws, name="gap")
        rhs = np.zeros_like(basis.integrals)
        np.add.at(rhs, rule.facet, basis.theta * (rule.weights * rule.gap)[:, None])
        value = np.linalg.solve(basis.mass, rhs[..., None])[..., 0] if len(rhs) else rhs
        part = basis.partial
        value[part] = (rhs[part].sum(axis=1) / basis.measure[part])[:, None]
        macro = self.disc.fine_to_macro_facet[self.disc.slave_to_fine[:len(rhs)]]
        hit, size = np.zeros((2, int(macro.max(initial=-1)) + 1))
        np.add.at(hit, macro, basis.covered)
        np.add.at(size, macro, basis.measure)
        value[hit[macro] <= MIN_MACRO_COVER * size[macro]] = self.disc.problem.miss_gap
        dofs = np.array([Ws.dofmap.cell_dofs(f) for f in range(len(rhs))], dtype=np.int32)
        gap.x.array[dofs.ravel()] = value.ravel()
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

    def _share_matrix(self, slave_cells: np.ndarray, master: _Side,
                      basis: FacetBasis) -> PETSc.Mat:
        """S[K, c]: the part of slave cell c's facets that Pi maps into master cell K.

        The uncovered part of a facet stays with its slave cell (S[c, c]; P v is v there).
        """
        rule, fine = self.rule, self.disc.mesh
        cells = fine.topology.index_map(fine.topology.dim)
        measure = np.where(basis.measure > 0.0, basis.measure, 1.0)
        frac = rule.weights / measure[rule.facet]
        own = np.clip(1.0 - basis.covered / measure, 0.0, 1.0)
        # a slave cell with several slave facets shares each facet's part equally
        count = np.zeros(len(slave_cells))
        _, inverse, counts = np.unique(slave_cells, return_inverse=True, return_counts=True)
        count[:] = counts[inverse]
        S = PETSc.Mat().createAIJ(
            size=((cells.size_local, cells.size_global), (cells.size_local, cells.size_global)),
            nnz=(8, 8), comm=self.disc.comm,
        )
        S.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        rows = np.concatenate([master.cell[rule.master], slave_cells]).astype(PETSc.IntType)
        cols = np.concatenate([slave_cells[rule.facet], slave_cells]).astype(PETSc.IntType)
        vals = np.concatenate([frac / count[rule.facet], own / count])
        for r, c, v in zip(rows, cols, vals, strict=True):
            if v != 0.0:
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


def _cells(
    msh: dmesh.Mesh, V: fem.FunctionSpace, cells: np.ndarray, vertices: np.ndarray
) -> _Side:
    """The facets' cells: their geometry, V's global dofs, global index; the facets' normals."""
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    geometry = msh.geometry.x[compat.geometry_dofmap(msh)[cells]][:, :, :gdim]
    normals = facet_normals(vertices, geometry.mean(axis=1)) if len(cells) else (
        np.zeros((0, gdim)))
    local = np.array([V.dofmap.cell_dofs(c) for c in cells], dtype=np.int32)
    dofs = V.dofmap.index_map.local_to_global(local.ravel()).reshape(local.shape) if len(
        cells) else np.zeros((0, V.dofmap.dof_layout.num_dofs), dtype=np.int64)
    cell = msh.topology.index_map(tdim).local_to_global(cells)
    return _Side(vertices, normals, geometry, dofs, cell)


def _cell_basis(
    mesh: dmesh.Mesh, V: fem.FunctionSpace, geometry: np.ndarray, which: np.ndarray,
    y: np.ndarray,
) -> np.ndarray:
    """phi_j(y_q) of V's scalar element in the cell ``which[q]`` (geometry nodes ``geometry``)."""
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
        X = cmap.pull_back(np.ascontiguousarray(y[at, :gdim]), geometry[g])
        out[at] = tabulate(element, X)
    return out


def _entity_points(msh: dmesh.Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """The geometry nodes of ``entities`` of dimension ``dim``, shape (m, nodes, gdim)."""
    gdim = msh.geometry.dim
    if len(entities) == 0:  # (entities_to_geometry divides by the count)
        simplex = msh.topology.cell_type in (
            dmesh.CellType.interval, dmesh.CellType.triangle, dmesh.CellType.tetrahedron)
        nodes = dim + 1 if simplex else 2**dim
        if dim == msh.topology.dim:
            nodes = compat.geometry_dofmap(msh).shape[1]
        return np.zeros((0, nodes, gdim))
    return msh.geometry.x[dmesh.entities_to_geometry(msh, dim, entities)][:, :, :gdim]


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

