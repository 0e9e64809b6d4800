r"""Bodies held only by contact: their free rigid motions, and an active set that holds them.

A body whose Dirichlet conditions leave a rigid motion free (a disc pressed by a traction onto a
flat, a face whose pressing component is given as a traction) has a singular stiffness matrix K:
only the contact holds it. The Newton matrix of an active set A,

    [ K      N_A^T ]
    [ N_A    0     ],

is nonsingular iff N_A has full row rank and no free rigid motion z (K z = 0) leaves every active
row unmoved, i.e. iff N_A Z has full column rank for a basis Z of the free rigid motions. From a
zero initial iterate the rule (21) takes only the facets that penetrate already, so the first
step of such a problem has a singular matrix.

:class:`RigidHold` completes a set that does not hold the bodies with the facets that the
bodies' free rigid motion under the load reaches: with the free motions Z (orthonormal), the
load's push b = Z^T f (K Z = 0) projected onto the motions the set leaves free (the load, not
the out-of-balance force: a warm start's multipliers off the set may balance it already), and
the approach rate s = N Z b of each facet, facet i is
reached after the rigid motion alpha_i = (g - N u)_i / s_i (s_i > 0). The facets join that are
reached by the motion alpha* at which springs of the NCP function's stiffness c_n on the
reached facets carry the push, sum_i c_n,i s_i (alpha* s_i - (g - N u)_i)_+ / M_i = b . b
(one penalty step; at least the first facet reached, all facets of a flat); again until the
set holds. The set of the next steps is the rule's (21) again, completed only where it would
leave a motion free, so the Newton matrix of the last step, the solution and the dual problem
are those of the discrete problem: nothing is added to K, no regularisation is left to vanish.

**Why springs.** The window decides how many Newton steps follow. Measured from zero (Newton
steps; the problems of ``tests/test_held_by_contact.py``: the mixed face, the quarter disc of
``meshes/hertz_2d.py`` with contact facets of 0.02 and 0.005, the quarter hemisphere of
``meshes/hertz_3d.py``, the disc pressed on a disc of ``meshes/hertz_cylinders_2d.py``):

==========================================  =====  ======  =======  ====  ====
start                                       mixed  2D .02  2D .005   3D   pair
==========================================  =====  ======  =======  ====  ====
the first facets only (smallest alpha)        1      4        6      13     4
every approaching facet (s_i > 0)             1     12       13      28     7
all facets, ``lam0 = 1`` (the workaround)     1      5        6       7     3
springs c_n (chosen)                          1      3        4       5     4
==========================================  =====  ======  =======  ====  ====

From the first facets alone the set grows by a ring of facets per step (a point load's
penetration is local), from every approaching facet it shrinks by a ring per step; the
workaround's window, the facets with g_i < M_i lam0 / c_n,i, depends on the units of lam0.
The springs c_n = E / H are the NCP function's own scale: a window in the problem's units. A
regularisation of K (a vanishing eps K_0 in the first steps) was not taken: its first step
moves the body by O(1 / eps), so every approaching facet penetrates (it would start as the
second row of the table; not measured), and it would leave a modified matrix to remove
before the dual problem.

A body that no load pushes (held between a rigid flat and another body pressed onto it, loaded
only through the contact) has no direction of approach: the facets it already touches (no room,
a free motion moves them) join the set, on both sides, and the rule (21) decides from there.

The free motions are found per body (connected component of the mesh, over all ranks): the
translations and rotations (about the body's centroid) whose values on the Dirichlet dofs
vanish. A motion that no contact row can move (a translation along a frictionless flat) or that
the load moves away from every contact facet raises a ValueError naming the motion, the body and
its tags.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.csgraph
from dolfinx import fem, la

from .collective import log_on_root
from .spaces import Discretization

__all__ = ["FreeMotions", "RigidHold", "free_motions", "held_method"]

logger = logging.getLogger("dwr_signorini.newton")

#: A motion is free when at most this fraction of its squared norm lies on Dirichlet dofs.
FREE_FRACTION = 1e-10
#: A set holds a motion when N_A moves it by at least this fraction of what all rows move it.
HOLD_FRACTION = 1e-10


@dataclass
class FreeMotions:
    """The rigid motions of the bodies that the Dirichlet conditions leave free.

    Attributes:
        Z: The motions on the owned displacement dofs, orthonormal columns (n_u x m).
        labels: One description per body of each column's standard coordinates:
            ``(body, coefficients)``, coefficients on the body's translations and rotations.
        bodies: Per body: centroid, size and the facet tags on it.
    """

    Z: np.ndarray
    labels: list[tuple[int, np.ndarray]]
    bodies: list[tuple[np.ndarray, float, list[int]]]

    @property
    def count(self) -> int:
        """The number of free motions (global)."""
        return self.Z.shape[1]

    def describe(self, coefficients: np.ndarray) -> str:
        """A motion given in the columns' coordinates, in words (its body, translation, axis)."""
        parts = []
        for j, (body, std) in enumerate(self.labels):
            if abs(coefficients[j]) > 1e-8 * np.max(np.abs(coefficients)):
                parts.append((body, coefficients[j] * std))
        by_body: dict[int, np.ndarray] = {}
        for body, std in parts:
            by_body[body] = by_body.get(body, 0.0) + std
        return "; ".join(self._words(body, std) for body, std in sorted(by_body.items()))

    def _words(self, body: int, std: np.ndarray) -> str:
        centroid, size, tags = self.bodies[body]
        gdim = len(centroid)
        t, w = std[:gdim], std[gdim:] / size
        where = (
            f"the body around ({_fmt(centroid)}) with facet tags {tags or 'none'}"
        )
        if np.linalg.norm(w) <= 1e-8 * max(np.linalg.norm(t), 1e-300):
            return f"translation along ({_fmt(t / np.linalg.norm(t))}) of {where}"
        if gdim == 2:
            point = centroid + np.array([-t[1], t[0]]) / w[0]
            return f"rotation about ({_fmt(point)}) of {where}"
        point = centroid + np.cross(w, t) / (w @ w)
        axis = w / np.linalg.norm(w)
        return f"rotation about the axis ({_fmt(axis)}) through ({_fmt(point)}) of {where}"


def _fmt(v: np.ndarray) -> str:
    return ", ".join(f"{c:.4g}" for c in np.where(np.abs(v) < 1e-12, 0.0, v))


def _local_bodies(V: fem.FunctionSpace) -> tuple[np.ndarray, int]:
    """The connected component of each local node (owned and ghost) on this rank."""
    cells = V.dofmap.list
    num_nodes = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    rows = np.repeat(np.arange(cells.shape[0]), cells.shape[1])
    incidence = scipy.sparse.csr_matrix(
        (np.ones(rows.size), (rows, cells.ravel())), shape=(cells.shape[0], num_nodes)
    )
    count, labels = scipy.sparse.csgraph.connected_components(incidence.T @ incidence)
    return labels, count


def body_labels(V: fem.FunctionSpace, comm: MPI.Comm) -> tuple[np.ndarray, int]:
    """The body (connected component over all ranks) of each local node, numbered 0, 1, ...

    The components of each rank are merged through the nodes shared between ranks (a ghost node
    joins its component on this rank to its owner's): union-find on the gathered links.

    Returns:
        The body of each local node (owned and ghost) and the number of bodies.
    """
    labels, count = _local_bodies(V)
    offset = comm.exscan(count) or 0
    total = comm.allreduce(count)
    im = V.dofmap.index_map
    vec = la.vector(im)
    vec.array[:] = labels + offset
    vec.scatter_forward()
    ghosts = slice(im.size_local, None)
    links = np.unique(
        np.stack([labels[ghosts] + offset, vec.array[ghosts].astype(np.int64)], axis=1), axis=0
    )
    parent = np.arange(total)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in (link for part in comm.allgather(links) for link in part):
        ra, rb = root(int(a)), root(int(b))
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(i) for i in range(total)])
    unique, compact = np.unique(roots, return_inverse=True)
    return compact[labels + offset], len(unique)


def _standard_motions(x: np.ndarray, centroid: np.ndarray, size: float) -> np.ndarray:
    """Translations and rotations about ``centroid`` (scaled by 1 / size) at nodes ``x``.

    Returns:
        An array (nodes, gdim, gdim + rotations).
    """
    gdim = len(centroid)
    d = (x - centroid) / size
    if gdim == 2:
        rot = np.stack([-d[:, 1], d[:, 0]], axis=1)[:, :, None]
    else:
        rot = np.stack([np.cross(np.eye(3)[k], d) for k in range(3)], axis=2)
    trans = np.broadcast_to(np.eye(gdim), (len(x), gdim, gdim))
    return np.concatenate([trans, rot], axis=2)


def free_motions(disc: Discretization) -> FreeMotions:
    """The rigid motions of the bodies of ``disc`` that its Dirichlet conditions leave free.

    Collective. Per body, the standard motions Z_b (translations, rotations about the centroid)
    and the generalised eigenproblem Z_b,D^T Z_b,D v = mu Z_b^T Z_b v (D the Dirichlet dofs):
    the motions with mu <= :data:`FREE_FRACTION` are free.

    Args:
        disc: The discretisation (its V on T_h and Dirichlet conditions).

    Returns:
        The free motions (none where the supports hold every body).
    """
    V, comm = disc.V, disc.comm
    gdim = disc.mesh.geometry.dim
    n_nodes = V.dofmap.index_map.size_local
    body, num_bodies = body_labels(V, comm)
    x = V.tabulate_dof_coordinates()[:n_nodes, :gdim]
    owned = body[:n_nodes]
    sums = np.zeros((num_bodies, gdim + 1))
    np.add.at(sums, owned, np.hstack([x, np.ones((n_nodes, 1))]))
    sums = comm.allreduce(sums)
    centroids = sums[:, :gdim] / sums[:, gdim:]
    radius = np.zeros(num_bodies)
    np.maximum.at(radius, owned, np.linalg.norm(x - centroids[owned], axis=1))
    comm.Allreduce(MPI.IN_PLACE, radius, op=MPI.MAX)
    radius = np.maximum(radius, 1e-300)
    constrained = _dirichlet_mask(disc)
    tags = _body_tags(disc, body, num_bodies)
    columns, labels = [], []
    for b in range(num_bodies):
        on = owned == b
        Z_b = np.zeros((n_nodes, gdim, gdim + (1 if gdim == 2 else 3)))
        Z_b[on] = _standard_motions(x[on], centroids[b], radius[b])
        Z_b = Z_b.reshape(n_nodes * gdim, -1)
        full = comm.allreduce(Z_b.T @ Z_b)
        fixed = comm.allreduce(Z_b[constrained].T @ Z_b[constrained])
        mu, vecs = scipy.linalg.eigh(fixed, full)
        for k in np.flatnonzero(mu <= FREE_FRACTION):
            columns.append(Z_b @ vecs[:, k])
            labels.append((b, vecs[:, k]))
    Z = np.stack(columns, axis=1) if columns else np.zeros((n_nodes * gdim, 0))
    bodies = [(centroids[b], float(radius[b]), tags[b]) for b in range(num_bodies)]
    return FreeMotions(Z, labels, bodies)


def _dirichlet_mask(disc: Discretization) -> np.ndarray:
    """Whether each owned displacement dof is a Dirichlet dof."""
    mask = fem.Function(disc.V)
    mask.x.array[:] = 1.0
    for bc in disc.bcs:
        bc.set(mask.x.array)
    n_u = disc.V.dofmap.index_map.size_local * disc.V.dofmap.index_map_bs
    return mask.x.array[:n_u] == 0.0


def _body_tags(disc: Discretization, body: np.ndarray, num_bodies: int) -> list[list[int]]:
    """The facet tags on each body (gathered from every rank)."""
    tdim = disc.mesh.topology.dim
    disc.mesh.topology.create_connectivity(tdim - 1, tdim)
    f2c = disc.mesh.topology.connectivity(tdim - 1, tdim)
    first_cell = f2c.array[f2c.offsets[disc.facet_tags.indices]]
    on = body[disc.V.dofmap.list[first_cell, 0]]
    local = [set(np.unique(disc.facet_tags.values[on == b]).tolist()) for b in range(num_bodies)]
    return [sorted(set().union(*(r[b] for r in disc.comm.allgather(local))))
            for b in range(num_bodies)]


def held_method(method: str | None, count: int) -> str:
    """The method where only contact holds a body or an obstacle: the block path.

    Args:
        method: The method asked for (None: automatic).
        count: The number of free rigid motions.

    Returns:
        ``"block"``.

    Raises:
        ValueError: ``method`` is ``"schur"`` or ``"krylov"``: they solve with K alone, which
            is singular where a body is held only by contact, and know no force-controlled
            obstacle.
    """
    if method in (None, "block"):
        return "block"
    raise ValueError(
        f"method={method!r} solves with the stiffness matrix K alone, which is singular where "
        f"only contact holds a body ({count} rigid motion(s) left free by dirichlet), and "
        "knows no obstacle under a given force: use method='block' (the default there)"
    )


class RigidHold:
    """Completes an active set that leaves a free rigid motion unheld (module docstring).

    Args:
        motions: The free motions (:func:`free_motions`), at least one.
        N: The coupling matrix (rows of all the law's components).
        n_q: Owned rows of one component (the normal rows come first).
        c_n, M: c_n,i of the NCP function (20) and the facet sizes M_i, owned rows.
        obstacle: With a force-controlled obstacle, the rate of its rows' gap residual per unit
            approach (-m, owned normal rows) and its force F: one motion more.
        problem: The problem (its tags, for the messages).

    Raises:
        ValueError: A free motion that no contact row moves (collective).
    """

    def __init__(
        self, motions: FreeMotions, N: PETSc.Mat, n_q: int, c_n: np.ndarray, M: np.ndarray,
        problem: object, obstacle: tuple[np.ndarray, float] | None = None,
    ) -> None:
        self.motions, self.n_q, self.problem = motions, n_q, problem
        self.c_n, self.M = c_n, M
        self.comm = N.getComm().tompi4py()
        u, lam = N.createVecRight(), N.createVecLeft()
        H = []
        for z in motions.Z.T:
            u.array_w[:] = z
            N.mult(u, lam)
            H.append(lam.array_r.copy())
        num_rows = lam.getLocalSize()
        u.destroy()
        lam.destroy()
        self.load = np.zeros(motions.count)
        if obstacle is not None:  # a force-controlled obstacle: one motion more, no K
            rate = np.zeros(num_rows)
            rate[:n_q] = obstacle[0]
            H.append(rate)
            self.load = np.append(self.load, obstacle[1])
        self.H = np.stack(H, axis=1)
        full = self._gram(np.ones(len(self.H), dtype=bool))
        mu, vecs = np.linalg.eigh(full)
        scale = max(float(np.max(mu)), 1e-300)
        unseen = vecs[:, mu <= HOLD_FRACTION * scale]
        if unseen.shape[1] or np.max(mu) <= 0.0:
            raise ValueError(self._message(
                unseen if unseen.shape[1] else vecs,
                "no contact facet can hold it (a frictionless contact does not hold a motion "
                "along its surface)",
            ))
        self.full_inv_sqrt = vecs @ np.diag(mu**-0.5) @ vecs.T

    def apply(self, loop: Any, system: Any, u: fem.Function, new: np.ndarray) -> np.ndarray:
        """The step's set ``new`` completed where it leaves a free motion unheld (collective).

        Args:
            loop: The Newton loop (:class:`~dwr_signorini.semismooth.NewtonLoop`; its history
                records the rows added as ``held``).
            system: The Newton system (its load and gap).
            u: The displacement iterate.
            new: The step's constrained rows.

        Returns:
            The completed set.
        """
        u_vec = u.x.petsc_vec
        new, added = self.complete(new, system.f, system.algebra.gap_residual(u_vec))
        if added:
            loop.history[-1]["held"] = added
            log_on_root(self.comm, logger, logging.INFO,
                        "%d facet(s) added to the active set to hold the free motions", added)
        return new

    def _gram(self, rows: np.ndarray) -> np.ndarray:
        H = self.H[rows]
        return self.comm.allreduce(H.T @ H)

    def unheld(self, active: np.ndarray) -> np.ndarray:
        """The motions the rows ``active`` leave free: orthonormal columns, motion coordinates."""
        W = self.full_inv_sqrt @ self._gram(active) @ self.full_inv_sqrt
        mu, vecs = np.linalg.eigh(W)
        free = vecs[:, mu <= HOLD_FRACTION]
        if not free.shape[1]:
            return free
        basis, _ = np.linalg.qr(self.full_inv_sqrt @ free)
        return basis

    def complete(
        self, active: np.ndarray, f: PETSc.Vec, gap_residual: np.ndarray
    ) -> tuple[np.ndarray, int]:
        """``active`` with the facets the unheld motions reach first, until it holds (collective).

        Args:
            active: The step's constrained rows (all components).
            f: The load vector.
            gap_residual: (N u - g) on the owned rows.

        Returns:
            The completed set and the number of rows added (global).

        Raises:
            ValueError: The load moves an unheld motion away from every contact facet (or does
                not push it at all), naming the motion and its body.
        """
        out = active.copy()
        added = 0
        load = self.comm.allreduce(self.motions.Z.T @ f.array_r[: len(self.motions.Z)])
        push = np.append(load, self.load[len(load):])
        while True:
            free = self.unheld(out)
            if not free.shape[1]:
                return out, added
            drift = free @ (free.T @ push)
            rate = self.H[: self.n_q] @ drift
            size = self.comm.allreduce(float(np.max(np.abs(rate), initial=0.0)), op=MPI.MAX)
            candidates = (rate > 1e-10 * size) & ~out[: self.n_q]
            room = -gap_residual[: self.n_q]
            alpha = np.full(self.n_q, np.inf)
            alpha[candidates] = np.maximum(room[candidates], 0.0) / rate[candidates]
            first = self.comm.allreduce(float(np.min(alpha, initial=np.inf)), op=MPI.MIN)
            if size == 0.0 and not np.any(push):
                touching = self._touching(free, out, room)
                if self.comm.allreduce(int(touching.sum())):
                    out[: self.n_q] |= touching
                    added += self.comm.allreduce(int(touching.sum()))
                    continue
            if size == 0.0 or not np.isfinite(first):
                reason = (
                    "the load does not push it onto any contact facet (it moves it away from "
                    "every one, or not at all)" if size > 0.0 or np.any(push)
                    else "no load acts on it"
                )
                shown = free if not np.any(drift) else (drift / np.linalg.norm(drift))[:, None]
                raise ValueError(self._message(shown, reason))
            weight = np.where(candidates, rate**2 * self.c_n[: self.n_q] / self.M[: self.n_q], 0.0)
            reach = self._winkler(alpha, weight, float(push @ drift), first)
            chosen = candidates & (alpha <= reach)
            out[: self.n_q] |= chosen
            added += self.comm.allreduce(int(chosen.sum()))

    def _touching(self, free: np.ndarray, active: np.ndarray, room: np.ndarray) -> np.ndarray:
        """The inactive facets in contact (no room) that a free motion moves (collective).

        A body that no load pushes (held between others, loaded only through them: a body
        between a rigid flat and another body pressed onto it) has no direction to reach
        facets along; the facets it touches already hold it where they constrain its motions.
        """
        n_q = self.n_q
        moves = np.abs(self.H[:n_q] @ free)
        scale = self.comm.allreduce(float(np.max(moves, initial=0.0)), op=MPI.MAX)
        gap = self.comm.allreduce(float(np.max(np.abs(room), initial=0.0)), op=MPI.MAX)
        moved = np.any(moves > 1e-10 * scale, axis=1) if scale > 0.0 else np.zeros(n_q, bool)
        return moved & ~active[:n_q] & (room <= 1e-10 * gap)

    def _winkler(
        self, alpha: np.ndarray, weight: np.ndarray, load: float, first: float
    ) -> float:
        """The rigid motion at which springs c_n on the facets carry the load (collective).

        The force of the springs along the drift, sum_i w_i (a - alpha_i)_+ with
        w_i = c_n,i s_i^2 / M_i, grows piecewise linearly from 0 at a = ``first``; the root of
        force(a) = ``load`` by bisection (to round-off of the range).
        """
        finite = np.isfinite(alpha)

        def force(a: float) -> float:
            local = float(np.sum(weight[finite] * np.maximum(a - alpha[finite], 0.0)))
            return self.comm.allreduce(local)

        last = self.comm.allreduce(float(np.max(alpha[finite], initial=first)), op=MPI.MAX)
        lo, hi = first, first + max(last - first, abs(first), 1e-300)
        while force(hi) < load:
            hi = first + 2.0 * (hi - first)
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if force(mid) < load else (lo, mid)
        return hi

    def _message(self, free: np.ndarray, reason: str) -> str:
        problem = self.problem
        count = self.motions.count
        motions = "; ".join(
            self.motions.describe(free[:count, k]) if np.any(free[:count, k]) else
            f"the approach of the obstacle {self.problem.force_obstacle!r}"
            for k in range(free.shape[1])
        )
        return (
            f"only contact can hold a rigid motion that the Dirichlet conditions leave free "
            f"(dirichlet tags {list(problem.dirichlet)}), but {reason}: {motions}; contact "
            f"tags {list(problem.contact_tags)}. Prescribe that motion (dirichlet), or load "
            "the body (or direct the obstacle's force) towards the contact"
        )
