"""The solution of a contact problem: w_h = (u_h, lambda_H), its sets and its Newton system.

:func:`~dwr_signorini.solve` returns a :class:`Solution`; the dual problem, the estimator and
the drivers read it. It owns the Newton system whose last factorisations serve the dual problem.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem, la

from .laws import multiplier_names, tangent_basis
from .lifetime import Releasable
from .linalg import NewtonLinearSystem
from .spaces import Discretization

__all__ = ["Solution", "traction_vector"]


@dataclass
class Solution(Releasable):
    """The discrete solution w_h = (u_h, lambda_H) and what the dual problem needs.

    Owns the Newton system (its factorisations serve the dual problem): release it with
    :meth:`destroy` (collective), or use the solution as a context manager,
    ``with ds.solve(problem) as sol: ...``.

    Attributes:
        u: Displacement u_h on T_h.
        lam: Normal contact force lambda_H (DG0 on the macro contact facets).
        active: Active set of the last Newton step (owned multiplier rows).
        newton_iterations: Number of linear solves.
        history: Per-iteration record (active-set size, changes, residuals).
        disc: The discretisation.
        system: The Newton system; its last factorisations serve the dual problem
            (:meth:`~dwr_signorini.linalg.base.NewtonLinearSystem.solve_transpose`).
        num_active: Global number of active macro contact facets (computed once, in
            :func:`solve`: reading it needs no communication).
        ncp_scale: The c of the NCP function (20) the solution was computed with; the
            estimator uses the same (:attr:`system`'s ``c_n``).
        method: The linear solver of the Newton steps that was used (``"block"``,
            ``"schur"`` with K factored, ``"krylov"``:
            :class:`~dwr_signorini.linalg.KrylovNewtonSystem` or the Schur path with a Krylov solver
            of K; :func:`method_name`).
        lam_t: With friction, the tangential traction lambda_t (DG0 on the macro contact
            facets): in 2D its value along t = (-n_2, n_1), in 3D the traction vector
            (gdim components, the facet means of lambda_t1 t_1 + lambda_t2 t_2); None without.
        tangential: With friction, the tangential multipliers of the law: (lam_t,) in 2D,
            (lam_t1, lam_t2) in 3D, the coordinates in the tangent basis
            (:func:`~dwr_signorini.laws.tangent_basis`); () without.
        stick, slip: With friction, the macro contact facets in contact that stick
            (``|lambda_t| < s``) and that slip (owned rows); None without.
        obstacle_displacement: With an obstacle under a given force
            (``ds.obstacles.Plane(..., force=F)``), its rigid displacement delta along its
            direction of approach, an unknown of the discrete problem
            (:mod:`dwr_signorini.force`); None without.
    """

    u: fem.Function
    lam: fem.Function
    active: np.ndarray
    newton_iterations: int
    history: list[dict[str, Any]]
    disc: Discretization
    system: NewtonLinearSystem = field(repr=False)
    num_active: int = 0
    ncp_scale: str | float = "physical"
    method: str = "block"
    lam_t: fem.Function | None = None
    stick: np.ndarray | None = None
    slip: np.ndarray | None = None
    tangential: tuple[fem.Function, ...] = ()
    obstacle_displacement: float | None = None
    #: Whether :meth:`destroy` releases the discretisation too (its master traces): set where
    #: :func:`solve` discretised the problem itself, and by the drivers for each level.
    owns_disc: bool = False
    #: What estimates of several goals at this solution share (the reconstructor, the P2
    #: solvers and primal weights, :class:`~dwr_signorini.estimate_parts.EstimateParts`), or
    #: None: kept by a load path for its history's estimates, released by :meth:`destroy`.
    estimate_parts: Any = field(default=None, repr=False)
    #: The earlier steps of a load path, the first step first, where
    #: :func:`~dwr_signorini.solve_path` keeps them (``keep_steps=True``; the model error along
    #: the path, :mod:`~dwr_signorini.path_model_error`), else ().
    earlier: tuple[Solution, ...] = field(default=(), repr=False)
    #: Whether :meth:`destroy` releases :attr:`earlier` too (the path's last step's do).
    owns_earlier: bool = field(default=False, repr=False)

    @property
    def multipliers(self) -> tuple[fem.Function, ...]:
        """The contact law's multipliers: (lam,), (lam, lam_t) or (lam, lam_t1, lam_t2)."""
        return (self.lam, *self.tangential)

    @property
    def num_stick(self) -> int | None:
        """Global number of sticking macro contact facets (None without friction)."""
        return None if self.stick is None else self._count(self.stick)

    @property
    def num_slip(self) -> int | None:
        """Global number of slipping macro contact facets (None without friction)."""
        return None if self.slip is None else self._count(self.slip)

    def _count(self, rows: np.ndarray) -> int:
        return self.disc.comm.allreduce(int(rows.sum()), op=MPI.SUM)

    def destroy(self) -> None:
        """Release the Newton system, its force control, the estimate parts, an owned disc.

        And the earlier steps of a path where it owns them (:attr:`owns_earlier`).

        Collective; idempotent.
        """
        if self.owns_earlier:
            for step in self.earlier:
                step.destroy()
        if self.estimate_parts is not None:
            self.estimate_parts.destroy()
            self.estimate_parts = None
        force = getattr(self.system, "force_control", None)
        if force is not None:
            force.destroy()
        self.system.destroy()
        if self.owns_disc:
            self.disc.destroy()

    def stacked(self, functions: tuple[fem.Function, ...] | None = None) -> np.ndarray:
        """The owned values of one function per component of the law, stacked.

        Args:
            functions: One function on Lambda_H per component (default: the multipliers).

        Returns:
            The owned values laid out as the Newton system's multiplier rows.
        """
        functions = self.multipliers if functions is None else functions
        n_q = self.system.algebra.n_q
        return np.concatenate([f.x.array[:n_q] for f in functions])

    def multiplier_functions(self, values: np.ndarray, name: str) -> tuple[fem.Function, ...]:
        """One function on Lambda_H per component from the stacked owned rows ``values``.

        Args:
            values: The owned multiplier rows, laid out as the Newton system's.
            name: The name of the first function; the next are ``name`` and the tangential
                suffixes (``_t``; ``_t1``, ``_t2`` in 3D).

        Returns:
            The functions, normal first.
        """
        parts = self.system.algebra.components_of(values)
        names = multiplier_names(self.system.algebra.components, name)
        return tuple(self.multiplier_function(p, names[k]) for k, p in enumerate(parts))

    def multiplier_function(self, values: Any, name: str) -> fem.Function:
        """A function on Lambda_H from values on the owned multipliers (ghosts updated).

        Args:
            values: One value per owned macro contact facet (``system.algebra.n_q``).
            name: The function's name.

        Returns:
            A new DG0 function on Lambda_H.
        """
        out = fem.Function(self.disc.Q, name=name)
        out.x.array[: self.system.algebra.n_q] = values
        out.x.scatter_forward()
        return out


def traction_vector(disc: Discretization, tangential: list[fem.Function]) -> fem.Function:
    """The tangential traction lambda_t1 t_1 + lambda_t2 t_2 (3D) as facet means, vector DG0.

    Args:
        disc: The discretisation.
        tangential: (lambda_t1, lambda_t2) on Lambda_H.

    Returns:
        A DG0 function with gdim components on Sigma_H, named ``lambda_t``.
    """
    m = disc.m
    Qv = fem.functionspace(disc.Q.mesh, ("DG", 0, (disc.mesh.geometry.dim,)))
    mu = ufl.TestFunction(Qv)
    t = tangent_basis(disc.contact_frame())
    traction = sum(f * t_k for f, t_k in zip(tangential, t, strict=True))
    b = fem.assemble_vector(disc.form(ufl.inner(traction, mu) * m.ds_contact))
    M = fem.assemble_vector(disc.form(ufl.inner(ufl.as_vector([1.0] * Qv.num_sub_spaces), mu)
                                      * m.ds_contact))
    for vec in (b, M):
        vec.scatter_reverse(la.InsertMode.add)
    out = fem.Function(Qv, name="lambda_t")
    n = Qv.dofmap.index_map.size_local * Qv.dofmap.index_map_bs
    out.x.array[:n] = b.array[:n] / M.array[:n]
    out.x.scatter_forward()
    return out
