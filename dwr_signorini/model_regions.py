r"""Friction on part of Gamma_C: the law of a per-region model and its facets from level to level.

A per-region model (Rademacher, Numer. Math. 2019: model adaptivity for frictional contact) runs
the richer law, Coulomb with coefficient mu, on a set R of macro contact facets and the simpler
frictionless law elsewhere. No new law is needed: frictionless is Coulomb with mu = 0, so the
mixed model is

    Coulomb(mu chi_R),  chi_R = 1 on the facets of R, 0 elsewhere (a function of Lambda_H),  (M4)

(:class:`RegionMu`); its model error against Coulomb(mu) is (M1) as for frictionless, with the
tangential rows of the facets outside R filled as there (:func:`new_rows`). Which facets join R
is decided in :mod:`dwr_signorini.model_choice`; this module holds R as data: the macro contact
facets of a level, gathered on every rank with their flags (:class:`RegionMap`), which gives
chi_R on the next level's facets (each new facet takes the flag of the old facet nearest to its
midpoint: its parent, which contains it) and the model map of the run
(:func:`dwr_signorini.viz.plot_model_map`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import fem

from . import compat
from .laws import Coulomb

__all__ = ["RegionMap", "RegionMu", "law_label", "model_label", "new_rows", "regional"]

#: The name of a per-region model in records and lines.
MIXED = "frictionless/coulomb"

#: The name of the model of a finite-strain (hyperelastic) problem in records: it is
#: frictionless, so its material names it.
FINITE_STRAIN = "finite_strain"

#: New facets whose midpoints are matched to old facets at once (memory of the distances).
CHUNK = 256


class RegionMu:
    """mu chi_R of (M4): the friction coefficient of a per-region model, a callable of x.

    Args:
        mu: The rich law's coefficient: a number or a callable x -> UFL scalar.
        chi: chi_R, a function of Lambda_H (``disc.Q``) that is 1 on R and 0 elsewhere.
    """

    def __init__(self, mu: Any, chi: fem.Function) -> None:
        self.mu = mu
        # private: the checks that data agree on all ranks compare the public attributes, and
        # a discrete function's values need its mesh
        self._chi = chi

    @property
    def chi(self) -> fem.Function:
        """chi_R."""
        return self._chi

    def __call__(self, x: Any) -> Any:
        """mu(x) chi_R as UFL."""
        return (self.mu(x) if callable(self.mu) else self.mu) * self.chi

    def __repr__(self) -> str:
        """The coefficient and the region's name."""
        return f"RegionMu({self.mu!r}, chi_R)"


def regional(law: Any) -> bool:
    """Whether ``law`` is a per-region model (Coulomb with a :class:`RegionMu`)."""
    return isinstance(law, Coulomb) and isinstance(law.data, RegionMu)


def law_label(law: Any) -> str:
    """The model's name in records: the law's name, ``"frictionless/coulomb"`` per region."""
    return MIXED if regional(law) else law.name


def model_label(problem: Any) -> str:
    """The model's name in records: ``"finite_strain"`` (hyperelastic), else :func:`law_label`."""
    return FINITE_STRAIN if problem.finite_strain else law_label(problem.law)


def new_rows(law: Any, algebra: Any, known: int) -> np.ndarray:
    """The owned multiplier rows the simpler model leaves out, as a mask of the rich law's rows.

    Args:
        law: The simpler model's law.
        algebra: The richer law's :class:`~dwr_signorini.algebra.ContactAlgebra`.
        known: The multiplier components of the simpler law.

    Returns:
        The components past ``known`` (frictionless, Tresca), or for a per-region model the
        tangential rows of the facets outside R.
    """
    n_q = algebra.n_q
    mask = np.zeros(algebra.n_lam, dtype=bool)
    if not regional(law):
        mask[known * n_q :] = True
        return mask
    outside = law.data.chi.x.array[:n_q] == 0.0
    mask[n_q:] = np.tile(outside, len(algebra.components) - 1)
    return mask


def _owned_facets(disc: Any) -> np.ndarray:
    """The vertices of the owned macro contact facets in the order of Q's owned dofs."""
    sub = disc.contact_mesh
    n_q = disc.Q.dofmap.index_map.size_local
    num_cells = sub.topology.index_map(sub.topology.dim).size_local
    dofs = disc.Q.dofmap.list[:num_cells, 0]
    nodes = compat.geometry_dofmap(sub)[:num_cells]
    gdim = disc.mesh.geometry.dim
    out = np.empty((n_q, nodes.shape[1], gdim))
    owned = dofs < n_q
    out[dofs[owned]] = sub.geometry.x[nodes[owned]][:, :, :gdim]
    return out


def _distances(points: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    """Distances (k, n) of k points to n segments or triangles (their nearest point, clamped)."""
    origin = simplices[:, 0]
    edges = simplices[:, 1:] - origin[:, None, :]  # (n, d, gdim)
    gram = np.einsum("nig,njg->nij", edges, edges)
    rel = points[:, None, :] - origin[None]  # (k, n, gdim)
    rhs = np.einsum("nig,kng->kni", edges, rel)
    coef = np.linalg.solve(gram[None], rhs[..., None])[..., 0]  # (k, n, d)
    coef = np.clip(coef, 0.0, 1.0)
    total = coef.sum(axis=-1, keepdims=True)
    coef = np.where(total > 1.0, coef / np.maximum(total, 1.0), coef)
    nearest = origin[None] + np.einsum("kni,nig->kng", coef, edges)
    return np.linalg.norm(points[:, None, :] - nearest, axis=-1)


@dataclass
class RegionMap:
    """R on one level: every macro contact facet (on every rank) and whether it is in R.

    Attributes:
        facets: The facets' vertices, shape (n, tdim, gdim), the same on every rank.
        rich: Whether each facet runs the rich law, shape (n,).
    """

    facets: np.ndarray
    rich: np.ndarray

    @classmethod
    def gather(cls, disc: Any, rich: np.ndarray) -> RegionMap:
        """The map of a level from the flags of its owned macro contact facets (collective).

        Args:
            disc: The level's discretisation.
            rich: One flag per owned dof of ``disc.Q``.

        Returns:
            The map, the same on every rank.
        """
        parts = disc.comm.allgather((_owned_facets(disc), np.asarray(rich, dtype=bool)))
        return cls(
            np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        )

    @property
    def share(self) -> float:
        """The share of Gamma_C (by measure) that R covers."""
        edges = self.facets[:, 1:] - self.facets[:, :1]
        size = np.sqrt(np.abs(np.linalg.det(np.einsum("nig,njg->nij", edges, edges))))
        total = float(size.sum())
        return float(size[self.rich].sum()) / total if total > 0 else 0.0

    def indicator(self, disc: Any) -> fem.Function:
        """chi_R on the macro contact facets of ``disc`` (a later level), from their parents.

        Each facet takes the flag of the facet of this map nearest to its midpoint (its parent,
        which contains it).

        Args:
            disc: A discretisation whose macro mesh refines this map's.

        Returns:
            chi_R as a function of ``disc.Q``.
        """
        midpoints = _owned_facets(disc).mean(axis=1)
        flags = np.zeros(len(midpoints))
        for start in range(0, len(midpoints), CHUNK):
            d = _distances(midpoints[start : start + CHUNK], self.facets)
            flags[start : start + CHUNK] = self.rich[np.argmin(d, axis=1)]
        return flag_function(disc, flags)

    def as_dict(self, level: int) -> dict[str, Any]:
        """The map as plain data (for JSON and :func:`~dwr_signorini.viz.plot_model_map`).

        Args:
            level: The level it ran on.

        Returns:
            ``{"level", "facets" (vertex lists), "rich" (flags), "share"}``.
        """
        return {"level": level, "facets": self.facets.tolist(),
                "rich": self.rich.astype(int).tolist(), "share": self.share}


def flag_function(disc: Any, flags: np.ndarray) -> fem.Function:
    """A function of ``disc.Q`` from the values of its owned dofs (ghosts updated)."""
    chi = fem.Function(disc.Q, name="chi_R")
    chi.x.array[: len(flags)] = flags
    chi.x.scatter_forward()
    return chi


def num_rich(chi: fem.Function, comm: MPI.Comm) -> tuple[int, int]:
    """(facets in R, all facets) over the ranks."""
    n_q = chi.function_space.dofmap.index_map.size_local
    return (comm.allreduce(int(np.count_nonzero(chi.x.array[:n_q])), op=MPI.SUM),
            comm.allreduce(n_q, op=MPI.SUM))
