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
the master cells that v o Pi lives on. :meth:`TraceGeometry.share` moves such a term, localised
to the fine slave facets, from the slave cell beside each facet to the master cells, in
proportion to the measure of the facet that Pi maps into each of them; the uncovered part of a
facet stays on its slave cell (P v is v there). Each facet's shares sum to its covered
fraction, and what leaves the slave cell is that fraction, so the moved indicators sum to the
term.

**One geometry per mesh.** The slave and master facets (each rank holding the master facets its
slave facets need, :mod:`~dwr_signorini.exchange`), the mortar rule of each degree, the
contact frame and the share do not depend on the displacement space: :class:`TraceGeometry`
holds them once per mesh, and the :class:`MasterTrace` of each space (P1 of the solves, P2 of
the weights) adds its projection. The discretisation owns both and
releases them in its ``destroy()``.

**Images name what they project.** :meth:`MasterTrace.apply` returns P f as a function of W
whose attribute ``trace_of`` is f; :func:`images_of` finds the images of f among a form's
coefficients, so the part of a form linear in the trace of a weight is read off the form itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem

from .clipping import place
from .exchange import MasterExchange
from .mortar import (
    FacetBasis,
    FacetMap,
    MortarRule,
    bilinear,
    facet_reach,
    mortar_rule,
)
from .pair_facets import (
    Side,
    cell_basis,
    cell_dofs,
    check_pair_facets,
    csr_matrix,
    facet_cell_blocks,
    facet_rows_matrix,
    master_facets,
    slave_facets,
    windows,
)
from .search import merge_rules, search_radius
from .timing import timed
from .trace_balance import search_parts

__all__ = [
    "MAX_DEGREE",
    "MIN_MACRO_COVER",
    "ContactPair",
    "MasterTrace",
    "TraceGeometry",
    "images_of",
]

#: The highest degree of a displacement space that a master trace takes (Lagrange, no dof
#: transformations).
MAX_DEGREE = 2

#: The covered fraction of a macro facet below which it counts as uncovered (``miss_gap``).
MIN_MACRO_COVER = 1e-3


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


class TraceGeometry:
    """The geometry of a mesh's pairs: facets, mortar rules, contact frame, share (module).

    Built once per mesh by the discretisation (collective: each rank receives the master
    facets its slave facets need, :mod:`~dwr_signorini.exchange`) and shared by the
    :class:`MasterTrace` of each displacement space.

    Args:
        disc: The discretisation (its slave facet mesh ``disc.slave_mesh``).
        balance: Whether the ranks share the contact search of the slave facets, whoever
            owns them (:mod:`~dwr_signorini.trace_balance`; the same rule either way).

    Raises:
        ValueError: Warped quadrilateral facets on a pair (on every rank).

    Attributes:
        vertices, normals: This rank's slave facets (owned cells of ``disc.slave_mesh``).
        slave: Those facets with their cells (``dofs`` empty: each trace adds its space's).
        slave_cells: The fine cell beside each slave facet (global index).
        master: The master facets of all pairs that this rank holds (``dofs`` empty likewise).
        exchanges: Per pair, the :class:`~dwr_signorini.exchange.MasterExchange` of its master
            facets (this rank's own, and those it holds).
        facets: The slave facets' coordinate map (:class:`~dwr_signorini.mortar.FacetMap`).
        pieces: The pieces of the mortar rule, found once (:meth:`_search`); the rule of each
            degree is placed on them (:meth:`rule`).
        measure, covered: The measure of each slave facet and of its covered part.
        frame: The normal of the contact frame on the fine slave facets (vector DG0,
            :meth:`_frame`), in which the tangential slip is measured.
        Fs: DG0 on the slave facets: the space of indicators localised per facet.
        share_weights: S^T (PETSc Mat, slave facets x fine cells): row F holds the fraction of
            F's measure that Pi maps into each master cell; it sums to F's covered fraction (1 on a
            facet the master covers, 0 on one it misses).
    """

    #: How many geometries are alive (built and not destroyed), on this rank.
    live = 0

    def __init__(self, disc: Any, balance: bool = True) -> None:
        self.disc, self.balance = disc, balance
        self.Fs = fem.functionspace(disc.slave_mesh, ("DG", 0))
        with timed("master trace"):
            self._build(disc)
        TraceGeometry.live += 1

    def _build(self, disc: Any) -> None:
        """The facets, the masters of every pair, the rule of the solves, frame and share."""
        check_pair_facets(disc)
        self.slave, self.slave_local, self._slave_tag = slave_facets(disc)
        self.vertices, self.normals = self.slave.vertices, self.slave.normals
        self.slave_cells = self.slave.cell
        self.facets = FacetMap(self.vertices)
        self.exchanges = []
        for pair in disc.problem.pairs:
            exchange = MasterExchange(disc.comm, *master_facets(disc, pair.master))
            slave, _, w = self._pair_slaves(pair)
            exchange.boxes(facet_reach(slave)[0], search_radius(slave, w, exchange.reach))
            self.exchanges.append(exchange)
        self.pieces = self._search()
        self._rules: dict[int, MortarRule] = {}
        rule = self.rule(1)
        f, _, _, w = self.facets.quadrature(1)
        num = len(self.vertices)
        self.measure = np.bincount(f, weights=w, minlength=num)[:num]
        self.covered = np.bincount(rule.facet, weights=rule.weights, minlength=num)[:num]
        self.frame = self._frame(rule)
        self.share_weights, self._home = self._share_matrices(rule)

    @property
    def master(self) -> Side:
        """The master facets of every pair held by this rank (:mod:`~dwr_signorini.exchange`)."""
        sides = [x.side for x in self.exchanges]
        return Side(*(np.concatenate([getattr(m, f) for m in sides]) for f in Side.fields()))

    def master_dofs(self, V: fem.FunctionSpace) -> np.ndarray:
        """V's global block dofs of the cells of :attr:`master` (collective)."""
        return np.concatenate([x.dofs(V) for x in self.exchanges])

    def _search(self) -> MortarRule:
        """The pieces of the mortar rule of every pair (the search; collective).

        Returns:
            The rule of degree None (:func:`~dwr_signorini.mortar.piece_rule`) of this
            rank's slave facets, its ``master`` an index into :attr:`master`.
        """
        rules = [self._pair_rule(pair, x) for pair, x in zip(
            self.disc.problem.pairs, self.exchanges, strict=True)]
        offsets = np.cumsum([0] + [len(x.number) for x in self.exchanges])
        rules = [MortarRule(r.facet, r.points, r.weights, r.master + offset, r.gap)
                 for r, offset in zip(rules, offsets, strict=False)]
        return merge_rules(rules, self.vertices.shape[2])

    def rule(self, degree: int) -> MortarRule:
        """The mortar rule for a space of ``degree`` (exact to degree 2 ``degree``), kept.

        The pieces do not depend on the degree (nor does the share): the mortar search runs
        once per mesh, with each pair's penetration window (:func:`windows`), and each degree
        asked for puts its Gauss points on the pieces (:func:`~dwr_signorini.clipping.place`).

        Args:
            degree: The degree of the displacement space.

        Returns:
            The :class:`~dwr_signorini.mortar.MortarRule` of this rank's slave facets, its
            ``master`` an index into :attr:`master`.
        """
        if degree not in self._rules:
            master = self.master
            self._rules[degree] = place(
                self.pieces, 2 * degree, bilinear(self.vertices, master.vertices),
                self.normals, master.vertices, master.normals)
        return self._rules[degree]

    def _pair_slaves(self, pair: ContactPair) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This rank's slave facets of ``pair``: vertices, indices, penetration windows."""
        on = np.flatnonzero(self._slave_tag == pair.slave)
        slave = self.vertices[on]
        w = np.broadcast_to(np.asarray(windows(pair, slave), dtype=float), (len(on),))
        return slave, on, w

    def _pair_rule(self, pair: ContactPair, exchange: MasterExchange) -> MortarRule:
        """One pair's pieces: the candidate search, then the facets it leaves against their shadow.

        Collective (the facets left over ask every rank for the master facets in their
        shadow, :meth:`~dwr_signorini.exchange.MasterExchange.shadows`).
        """
        slave, on, w = self._pair_slaves(pair)
        normals = self.normals[on]
        held = exchange.side
        parts, full = search_parts(self.disc.comm, slave, normals, w,
                                   (held.vertices, held.normals, exchange.number),
                                   exchange.reach, self.balance)
        exchange.shadows(slave[full], normals[full], w[full])
        held, order = exchange.side, np.argsort(exchange.number, kind="stable")
        r = mortar_rule(slave[full], normals[full], held.vertices[order], held.normals[order],
                        None, w[full])
        parts.append(MortarRule(full[r.facet], r.points, r.weights, order[r.master], r.gap))
        r = merge_rules(parts, slave.shape[2])
        return MortarRule(on[r.facet], r.points, r.weights, r.master, r.gap)

    @property
    def on_pairs(self) -> np.ndarray:
        """Whether each of this rank's slave facets is on a pair's slave side (not rigid)."""
        return np.isin(self._slave_tag, [pair.slave for pair in self.disc.problem.pairs])

    def _frame(self, rule: MortarRule) -> fem.Function:
        """The normal of the contact frame per fine slave facet (vector DG0 on Sigma_h).

        n_c = (n_s - <n_m>) / |n_s - <n_m>|, <n_m> the mean of the master normals over the
        part of the facet the master covers (weights of the rule): the bisector of the two
        surfaces, which does not change when the bodies swap sides (up to its sign). Where
        no master facet is met, or the surfaces do not face each other (n_s . <n_m> >= 0), the
        slave normal n_s.

        Args:
            rule: The mortar rule of this rank's slave facets.
        """
        slave, master = self.normals, self.master.normals[rule.master]
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
        V0 = fem.functionspace(self.disc.slave_mesh, ("DG", 0, (gdim,)))
        out = fem.Function(V0, name="contact_frame")
        cells = V0.dofmap.list[:len(slave), 0].astype(np.int64)
        out.x.array[(cells[:, None] * gdim + np.arange(gdim)).ravel()] = frame.ravel()
        out.x.scatter_forward()
        return out

    def _share_matrices(self, rule: MortarRule) -> tuple[PETSc.Mat, PETSc.Mat]:
        """S^T (facet -> master cells) and H^T (facet -> its cell), rows: the covered fraction.

        The uncovered part of a facet stays with its slave cell (P v is v there): neither
        matrix moves it.
        """
        fine, Fs = self.disc.mesh, self.Fs
        cells = fine.topology.index_map(fine.topology.dim)
        fmap = Fs.dofmap.index_map
        num = len(self.vertices)
        measure = np.where(self.measure > 0.0, self.measure, 1.0)
        rows = fmap.local_to_global(Fs.dofmap.list[:num, 0].astype(np.int32))
        frac = rule.weights / measure[rule.facet]
        covered = np.flatnonzero(self.covered > 0.0)
        first = fmap.local_range[0]
        row_sizes = (fmap.size_local, fmap.size_global)
        col_sizes = (cells.size_local, cells.size_global)
        comm = self.disc.comm
        S = csr_matrix(comm, [rows[rule.facet]], [self.master.cell[rule.master]], [frac], first,
                 row_sizes, col_sizes)
        H = csr_matrix(comm, [rows[covered]], [self.slave_cells[covered]],
                 [self.covered[covered] / measure[covered]], first, row_sizes, col_sizes)
        return S, H

    def share(self, facet_part: np.ndarray, DG0: fem.FunctionSpace) -> np.ndarray:
        """A term localised per slave facet, moved from the slave to the master cells.

        Args:
            facet_part: The term's indicators per owned slave facet (owned entries of ``Fs``).
            DG0: The DG0 space of the cell indicators on T_h.

        Returns:
            S p - H p as DG0 entries (owned and ghost, ghosts zero): added to the indicators
            of the term localised to the slave cells, it moves the covered part of each
            facet's indicator from the cell beside the facet to the master cells (the
            uncovered part stays); it sums to zero.
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

    Collective (each rank receives the master dofs of the master facets it holds).

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
        gap: The projected gap (a function of ``Ws``; the problem's ``miss_gap`` on the
            macro facets that no master facet covers).
        rule: The mortar rule of this rank's slave facets (the geometry's of V's degree).
        frame: The normal of the contact frame on the fine slave facets (the geometry's,
            :meth:`TraceGeometry._frame`), in which the tangential slip is measured.
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
        self.frame = geometry.frame
        with timed("master trace"):
            self._build(disc, V, degree)
        MasterTrace.live += 1

    # -- assembly ----------------------------------------------------------------------------
    def _build(self, disc: Any, V: fem.FunctionSpace, degree: int) -> None:
        """P and the gap from the geometry's rule (one pass over the rule's points)."""
        geometry = self.geometry
        self.rule = rule = geometry.rule(degree)
        master = geometry.master
        master = Side(master.vertices, master.normals, master.geometry,
                      geometry.master_dofs(V), master.cell)
        basis = FacetBasis(self.Ws.ufl_element().basix_element, geometry.facets, rule)
        projected = rule.points + rule.gap[:, None] * geometry.normals[rule.facet]
        phi = cell_basis(disc.mesh, V, master.geometry, rule.master, projected)
        terms = [(rule.facet, rule.weights, basis.theta, phi, master.dofs[rule.master],
                  rule.master)]
        terms += self._uncovered(basis, cell_dofs(V, geometry.slave_local))
        self.P = self._projection(basis, terms)
        self.gap = self._gap(basis)

    def _uncovered(self, basis: FacetBasis, slave_dofs: np.ndarray) -> list[tuple[np.ndarray, ...]]:
        """The slave's own trace on the uncovered part of each facet: + int_F, - int_covered.

        P v = v o Pi where a master facet is met and v itself where none is, so that the
        relative displacement v - P v vanishes where the master is not there. Not on the
        facets of a rigid contact tag (beside the pairs): P v = 0 there, v - P v = v.

        Args:
            basis: W's basis on the slave facets.
            slave_dofs: V's global block dofs of the cell beside each slave facet.
        """
        part = np.flatnonzero(~basis.full & self.geometry.on_pairs)
        if len(part) == 0:
            return []
        on = np.isin(basis.full_facet, part)
        f_full = basis.full_facet[on]
        at = np.isin(self.rule.facet, part)
        f_rule = self.rule.facet[at]
        facet = np.concatenate([f_full, f_rule])
        x = np.concatenate([basis.full_points[on], self.rule.points[at]])
        phi = cell_basis(self.disc.mesh, self.V, self.geometry.slave.geometry, facet, x)
        theta = np.concatenate([basis.full_theta[on], basis.theta[at]])
        weights = np.concatenate([basis.full_weights[on], -self.rule.weights[at]])
        return [(facet, weights, theta, phi, slave_dofs[facet], facet)]

    def _projection(self, basis: FacetBasis, terms: list[tuple[np.ndarray, ...]]) -> PETSc.Mat:
        """P = M_F^{-1} sum_q w_q theta(x_q) phi(y_q)^T per facet and component.

        The points of one facet and one cell are summed into one block (rows of the facet,
        columns of the cell), which M_F^{-1} then scales, before the blocks are expanded per
        component: the work and the matrix entries grow with the facet-cell pairs, not with
        the rule's points.

        Args:
            basis: W's basis on the slave facets.
            terms: (facet, weight, theta(x_q), phi(y_q), global dofs of phi's cell, cell key) per
                point: the master points y_q = Pi(x_q) of the rule, and the slave's own points
                on the uncovered parts (:meth:`_uncovered`).
        """
        W, V = self.W, self.V
        bs = W.dofmap.index_map_bs
        wmap, vmap = W.dofmap.index_map, V.dofmap.index_map
        num = len(basis.mass)
        # per facet: M_F^{-1}; on a facet the master covers in part, the mean (no polynomial
        # through the jump at the master's end; its integral against a constant is the same):
        # every row the integral over the covered part, over |F|
        scale = np.linalg.inv(basis.mass) if num else basis.mass
        part = basis.partial
        scale[part] = np.eye(scale.shape[1])[None] / basis.measure[part, None, None]
        w_dofs = wmap.local_to_global(W.dofmap.list[:num].ravel()).reshape(
            num, W.dofmap.list.shape[1])
        facets, cols, vals = [], [], []
        for facet, weights, theta, phi, dofs, key in terms:
            # per point: the facet's rows (a) times the cell's columns (j), summed per facet
            # and cell, then scaled per facet
            local = np.where(part[facet][:, None], 1.0, theta) * weights[:, None]
            at, blocks = facet_cell_blocks(facet, key, local, phi)
            facets.append(facet[at])
            cols.append(dofs[at])
            vals.append(scale[facet[at]] @ blocks)
        a, j = scale.shape[1], V.dofmap.dof_layout.num_dofs
        return facet_rows_matrix(
            self.disc.comm, w_dofs, np.concatenate(facets) if facets else np.zeros(0, np.int64),
            np.concatenate(cols) if cols else np.zeros((0, j), np.int64),
            np.concatenate(vals) if vals else np.zeros((0, a, j)), wmap.local_range[0],
            (wmap.size_local * bs, wmap.size_global * bs),
            (vmap.size_local * V.dofmap.index_map_bs, vmap.size_global * V.dofmap.index_map_bs),
            bs)

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
        gap.x.array[Ws.dofmap.list[:len(rhs)].ravel()] = value.ravel()
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
