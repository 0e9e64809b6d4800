"""Quantities of interest J(u, lambda) written in UFL, and their derivatives J', J''.

A goal is a function ``goal(u, lam, m) -> ufl.Form`` of the displacement ``u``, the normal contact
force ``lam`` (on Gamma_C) and the measures ``m`` (:class:`~dwr_signorini.spaces.Measures`) of the
fine mesh. Everything the estimators need (J'_u, J'_lambda for the dual problem (11)-(12),
directional derivatives for the dual residual rho*) comes from ``ufl.derivative``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mpi4py import MPI

import ufl
from dolfinx import fem
from ufl.algorithms import expand_derivatives

from .collective import call_collectively
from .spaces import Discretization
from .timing import timed

__all__ = ["Goal", "GoalForms", "localize"]

Goal = Callable[[Any, Any, Any], ufl.Form]


def _is_empty(form: ufl.Form) -> bool:
    return expand_derivatives(form).empty()


def localize(form: ufl.Form, q: ufl.Argument) -> ufl.Form:
    """Multiply every integrand of a scalar form by a DG0 test function ``q`` (cell indicators).

    Facet integrals attach to the adjacent cell. Summing the assembled vector gives back the form:
    this is the localisation by filtering of Section 4 (no integration by parts). The integrals
    keep their metadata (quadrature degrees).
    """
    integrals = [
        itg.reconstruct(integrand=q * itg.integrand())
        for itg in expand_derivatives(form).integrals()
    ]
    return ufl.Form(integrals)


class GoalForms:
    """J and its derivatives for one discrete solution w_h = (u_h, lambda_H).

    Args:
        goal: The user's ``goal(u, lam, m)``.
        u: u_h (a Function on V_h).
        lam: lambda_H (a Function on Lambda_H).
        disc: The discretisation.

    Raises:
        CollectiveError: ``goal`` raised, on any rank (then on every rank, naming ``goal``).
        TypeError: ``goal`` is not callable or does not return a UFL form.
        ValueError: The form is not scalar, lives on another mesh, or integrates lambda
            outside Gamma_C.
    """

    def __init__(self, goal: Goal, u: fem.Function, lam: fem.Function, disc: Discretization):
        if not callable(goal):
            raise TypeError(f"goal must be a callable goal(u, lam, m) -> ufl.Form, got {goal!r}")
        J = call_collectively(disc.comm, "goal", goal, u, lam, disc.m)
        if not isinstance(J, ufl.Form):
            raise TypeError(
                "goal(u, lam, m) must return a UFL form such as `ufl.inner(u, u) * m.dx`, got "
                f"{type(J).__name__}"
            )
        if len(J.arguments()) != 0:
            raise ValueError(
                "goal(u, lam, m) must return a scalar functional (a form without test or trial "
                f"functions); it has {len(J.arguments())} argument(s)"
            )
        for itg in J.integrals():
            if itg.ufl_domain() != disc.mesh.ufl_domain():
                raise ValueError(
                    "goal uses a measure of another mesh: build it from the measures in `m` "
                    "(m.dx, m.ds_contact, m.ds(tag)) of the current mesh"
                )
            if lam in ufl.algorithms.extract_coefficients(itg.integrand()):
                contact = disc.problem.contact_tags
                ids = itg.subdomain_id()
                ids = ids if isinstance(ids, tuple) else (ids,)
                if itg.integral_type() != "exterior_facet" or any(i not in contact for i in ids):
                    raise ValueError(
                        "goal integrates lam outside Gamma_C: lambda lives on the contact "
                        "boundary only, use it in integrals over m.ds_contact"
                    )
        self.goal = goal
        self.J = J
        self.u = u
        self.lam = lam
        self.disc = disc
        v = ufl.TestFunction(u.function_space)
        mu = ufl.TestFunction(lam.function_space)
        self.dJ_u = ufl.derivative(J, u, v)
        self.dJ_lam = ufl.derivative(J, lam, mu)
        self.has_lam = not _is_empty(self.dJ_lam)
        self.has_u = not _is_empty(self.dJ_u)
        second = [ufl.derivative(self.dJ_u, u), ufl.derivative(self.dJ_u, lam)]
        if self.has_lam:
            second += [ufl.derivative(self.dJ_lam, lam), ufl.derivative(self.dJ_lam, u)]
        self.is_linear = all(_is_empty(f) for f in second)

    def value(self) -> float:
        """J(w_h), reduced over all ranks."""
        with timed("goal"):
            local = fem.assemble_scalar(self.disc.form(self.J))
        return self.disc.comm.allreduce(local, op=MPI.SUM)

    def directional(self, du: Any, dlam: Any) -> ufl.Form:
        """J'(w_h)(du, dlam) as a scalar form (``du``, ``dlam`` any UFL functions on T_h)."""
        form = ufl.replace(self.dJ_u, {self.dJ_u.arguments()[0]: du}) if self.has_u else None
        if self.has_lam:
            lam_form = ufl.replace(self.dJ_lam, {self.dJ_lam.arguments()[0]: dlam})
            form = lam_form if form is None else form + lam_form
        return form
