"""Quantities of interest J(u, lambda) written in UFL, and their derivatives J', J''.

A goal is a function ``goal(u, lam, m) -> ufl.Form`` of the displacement ``u``, the normal contact
force ``lam`` (on Gamma_C) and the measures ``m`` (:class:`~dwr_signorini.measures.Measures`) of the
fine mesh; with friction it may take the tangential traction too, ``goal(u, lam, m, lam_t)``.
Everything the estimators need (J'_u, J'_lambda for the dual problem (11)-(12), directional
derivatives for the dual residual rho*) comes from ``ufl.derivative``.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from ufl.algorithms import expand_derivatives

from .agreement import check_form_on_ranks
from .collective import call_collectively, shadow
from .laws import tangent_basis
from .pairs import images_of
from .quadrature import with_quadrature_degrees
from .spaces import Discretization
from .timing import timed

__all__ = ["Goal", "GoalForms", "localize"]

Goal = Callable[..., ufl.Form]


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


def _takes_four(goal: Goal) -> bool:
    """Whether ``goal`` takes a fourth positional argument (lam_t)."""
    try:
        params = inspect.signature(goal).parameters.values()
    except (TypeError, ValueError):  # a builtin or C callable: assume three
        return False
    positional = [
        p for p in params
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
    ]
    required = [p for p in positional if p.default is p.empty]
    if len(required) >= 4:
        return True
    return len(positional) >= 4 or any(p.kind == p.VAR_POSITIONAL for p in params)


class GoalForms:
    """J and its derivatives for one discrete solution w_h = (u_h, lambda_H).

    A goal takes ``(u, lam, m)``; with friction it may take ``(u, lam, m, lam_t)``, the
    tangential traction (:attr:`~dwr_signorini.Solution.lam_t`): in 2D its value along
    t = (-n_2, n_1), in 3D the traction vector lambda_t1 t_1 + lambda_t2 t_2 (UFL).

    Args:
        goal: The user's ``goal(u, lam, m)`` or ``goal(u, lam, m, lam_t)``.
        u: u_h (a Function on V_h).
        lam: lambda_H (a Function on Lambda_H).
        disc: The discretisation.
        lam_t: lambda_t,H with friction, else None: a function (2D), or the tangential
            multipliers (:attr:`~dwr_signorini.Solution.tangential`, 3D: two).

    Raises:
        CollectiveError: ``goal`` raised, on any rank (then on every rank, naming ``goal``).
        TypeError: ``goal`` is not callable or does not return a UFL form.
        ValueError: The form is not scalar, lives on another mesh, or integrates lambda or
            lambda_t outside Gamma_C; a goal that needs lam_t on a frictionless problem.
    """

    def __init__(
        self, goal: Goal, u: fem.Function, lam: fem.Function, disc: Discretization,
        lam_t: fem.Function | tuple[fem.Function, ...] | None = None,
    ):
        if not callable(goal):
            raise TypeError(f"goal must be a callable goal(u, lam, m) -> ufl.Form, got {goal!r}")
        four = _takes_four(goal)
        if lam_t is None and four and _requires_four(goal):
            raise ValueError(
                "goal takes four arguments goal(u, lam, m, lam_t), but the problem is "
                "frictionless (no tangential traction lam_t): give the goal three arguments, "
                "or a friction law (SignoriniProblem(..., friction=ds.Tresca(s)))"
            )
        tangential = (() if lam_t is None else
                      tuple(lam_t) if isinstance(lam_t, (tuple, list)) else (lam_t,))
        if not tangential:
            lam_t = None
        elif len(tangential) == 1:
            lam_t = tangential[0]
        else:  # 3D: the traction vector from its coordinates in the tangent basis
            basis = tangent_basis(disc.contact_frame())
            lam_t = sum(f * t for f, t in zip(tangential, basis, strict=True))
        args = (u, lam, disc.m, lam_t) if lam_t is not None and four else (u, lam, disc.m)
        J = call_collectively(disc.comm, "goal", goal, *args)
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
        check_form_on_ranks(disc.comm, "estimate", "goal", J)
        multipliers = (lam, *tangential)
        for itg in J.integrals():
            _check_integral(itg, disc, multipliers)
        self.goal = goal
        self.J = J
        self.u = u
        self.lam = lam
        self.lam_t = lam_t
        self.disc = disc
        v = ufl.TestFunction(u.function_space)
        self.dJ_u = ufl.derivative(J, u, v)
        #: The master traces P u_h in J (contact pairs), and J' in their direction (a test
        #: function of the trace's space W), or () and None: J'_u(v) = dJ_u(v) + dJ_trace(P v).
        self.u_trace, self.dJ_trace = _master_trace_part(J, u, disc)
        derivatives = [
            ufl.derivative(J, f, ufl.TestFunction(f.function_space)) for f in multipliers
        ]
        #: J' in the direction of each multiplier of the contact law (None where J has none).
        self.dJ_multipliers = [None if _is_empty(d) else d for d in derivatives]
        self.dJ_lam = derivatives[0]
        self.has_lam = self.dJ_multipliers[0] is not None
        self._has_u_direct = not _is_empty(self.dJ_u)
        self.has_u = self._has_u_direct or self.dJ_trace is not None
        second = [ufl.derivative(self.dJ_u, f) for f in (u, *multipliers)]
        if self.dJ_trace is not None:
            unknowns = (u, *self.u_trace, *multipliers)
            second += [ufl.derivative(self.dJ_u, g) for g in self.u_trace]
            second += [ufl.derivative(self.dJ_trace, f) for f in unknowns]
        for d in self.dJ_multipliers:
            if d is not None:
                second += [ufl.derivative(d, f) for f in (u, *multipliers)]
        self.is_linear = all(_is_empty(f) for f in second)

    def value(self) -> float:
        """J(w_h), reduced over all ranks.

        Non-polynomial integrands take the problem's ``quadrature_degree``, the rule of J' in
        the dual problem (:func:`~dwr_signorini.dual.dual_rhs`); polynomial ones are exact.
        """
        degree = self.disc.problem.quadrature_degree
        with timed("goal"):
            local = fem.assemble_scalar(self.disc.form(with_quadrature_degrees(self.J, degree)))
        return self.disc.comm.allreduce(local, op=MPI.SUM)

    def rate(self, constant: fem.Constant) -> float:
        """dJ/dc at w_h for a scalar Constant c of J, reduced over all ranks.

        c is the displacement of a force-controlled obstacle, ``m.obstacle_displacement``.

        By UFL's differentiation: c is replaced in J by ``ufl.variable(c)`` and every integrand
        differentiated with ``ufl.diff`` (exact for any goal; 0 for a goal without c). The
        quadrature degree is that of :meth:`value`.

        Args:
            constant: The scalar Constant.

        Returns:
            The derivative.
        """
        variable = ufl.variable(constant)
        J = ufl.replace(self.J, {constant: variable})
        dJ = ufl.Form([itg.reconstruct(integrand=ufl.diff(itg.integrand(), variable))
                       for itg in J.integrals()])
        if _is_empty(dJ):
            return 0.0
        degree = self.disc.problem.quadrature_degree
        with timed("goal"):
            local = fem.assemble_scalar(self.disc.form(with_quadrature_degrees(dJ, degree)))
        return self.disc.comm.allreduce(local, op=MPI.SUM)

    def directional(self, du: Any, *dlams: Any) -> ufl.Form:
        """J'(w_h)(du, dlam[, dlam_t]) as a scalar form (any UFL functions on T_h)."""
        form = (ufl.replace(self.dJ_u, {self.dJ_u.arguments()[0]: du})
                if self._has_u_direct else None)
        if self.dJ_trace is not None:  # the master trace's part, J'_{Pu}(P du)
            part = ufl.replace(self.dJ_trace, {self.dJ_trace.arguments()[0]: self._trace(du)})
            form = part if form is None else form + part
        for dJ, d in zip(self.dJ_multipliers, dlams, strict=False):
            if dJ is not None:
                part = ufl.replace(dJ, {dJ.arguments()[0]: d})
                form = part if form is None else form + part
        return form

    def _trace(self, du: Any) -> Any:
        """P du (UFL) for a Function or a sum of Functions: new images that name ``du``.

        The estimator finds them in the residual by their ``trace_of``
        (:func:`~dwr_signorini.pairs.images_of`) and moves that part to the master cells.
        """
        if not isinstance(du, (fem.Function, ufl.algebra.Sum)):
            raise TypeError(
                "GoalForms.directional: a goal with the master trace of u takes a direction "
                f"that is a Function (or a sum of them), got {type(du).__name__}"
            )
        return self.disc.trace_image(du)


def _master_trace_part(
    J: ufl.Form, u: fem.Function, disc: Discretization
) -> tuple[tuple[fem.Function, ...], ufl.Form | None]:
    """The master traces P u of u in J, and J' in their direction (``(), None`` without).

    With contact pairs, a goal written with the relative displacement u - P u
    (:meth:`~dwr_signorini.spaces.Discretization.relative`, as the history goal of a load path)
    holds P u as a function of its own, which names u (:func:`~dwr_signorini.pairs.images_of`);
    ``ufl.derivative(J, u)`` does not see it.
    """
    if getattr(disc, "slave_mesh", None) is None:
        return (), None
    images = tuple(images_of(J, u))
    if not images:
        return (), None
    test = ufl.TestFunction(images[0].function_space)
    dJ = sum(ufl.derivative(J, g, test) for g in images)
    return ((), None) if _is_empty(dJ) else (images, dJ)


def _check_integral(
    itg: ufl.Integral, disc: Discretization, multipliers: tuple[fem.Function, ...]
) -> None:
    """One integral of a goal: on T_h, with the tags of T_h, the tractions on Gamma_C only.

    Raises:
        ValueError: Naming the mistake (see :class:`GoalForms`).
    """
    if itg.ufl_domain() != disc.mesh.ufl_domain():
        raise ValueError(
            "goal uses a measure of another mesh: build it from the measures in `m` "
            "(m.dx, m.ds_contact, m.ds(tag)) of the current mesh"
        )
    _check_measure(itg)
    _check_domains(itg, disc, multipliers)
    _check_tags_exist(itg, disc)
    used = ufl.algorithms.extract_coefficients(itg.integrand())
    for name, f in zip(("lam", "lam_t", "lam_t"), multipliers, strict=False):
        if f in used:
            contact = disc.problem.contact_tags
            ids = itg.subdomain_id()
            ids = ids if isinstance(ids, tuple) else (ids,)
            if itg.integral_type() != "exterior_facet" or any(i not in contact for i in ids):
                raise ValueError(
                    f"goal integrates {name} outside Gamma_C: the contact tractions "
                    "live on the contact boundary only, use them in integrals over "
                    "m.ds_contact"
                )


def _requires_four(goal: Goal) -> bool:
    """Whether ``goal`` cannot be called with three positional arguments."""
    try:
        params = inspect.signature(goal).parameters.values()
    except (TypeError, ValueError):
        return False
    required = [
        p for p in params
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty
    ]
    return len(required) >= 4


#: The measures of ``m`` that replace a bare UFL measure, by integral type.
_REPLACEMENTS = {
    "cell": "m.dx (or m.dx(tag) with cell tags)",
    "exterior_facet": "m.ds_contact or m.ds(tag)",
    "interior_facet": "m.dS",
}


def _check_measure(itg: ufl.Integral) -> None:
    """A subdomain id needs the tags of the current mesh: a bare ``ufl.ds(3)`` has none.

    The form is the same on every rank, so the decision is too (no reduction needed).
    """
    ids = itg.subdomain_id()
    ids = ids if isinstance(ids, tuple) else (ids,)
    tagged = [i for i in ids if i not in ("everywhere", "otherwise")]
    if tagged and itg.subdomain_data() is None:
        kind = itg.integral_type()
        short = {"cell": "dx", "exterior_facet": "ds", "interior_facet": "dS"}.get(kind, kind)
        raise ValueError(
            f"goal integrates over ufl.{short}({', '.join(map(str, tagged))}), a measure "
            "without the facet or cell tags of the current mesh: use "
            f"{_REPLACEMENTS.get(kind, 'the measures of m')} from the measures `m` passed to "
            "the goal"
        )


def _check_domains(
    itg: ufl.Integral, disc: Discretization, multipliers: tuple[fem.Function, ...]
) -> None:
    """Every coefficient and coordinate of the integrand lives on T_h or Gamma_C's submesh.

    A ``ufl.SpatialCoordinate`` of the user's macro mesh T_H in a goal on T_h cannot be
    compiled. The form is the same on every rank, so the decision is too.
    """
    allowed = [disc.mesh.ufl_domain()]
    allowed += [f.function_space.mesh.ufl_domain() for f in multipliers]
    if getattr(disc, "slave_mesh", None) is not None:  # the master trace of contact pairs
        allowed.append(disc.slave_mesh.ufl_domain())
    for domain in ufl.domain.extract_domains(itg.integrand()):
        if domain not in allowed:
            what = "the macro mesh T_H (problem.mesh)" if domain == disc.problem.mesh.ufl_domain() \
                else "another mesh"
            raise ValueError(
                f"goal uses a coordinate or function of {what}, but the goal is integrated on "
                "the fine mesh T_h of the solution: use m.x (the spatial coordinate of the "
                "current mesh) and functions on the spaces of u and lam"
            )


def _check_tags_exist(itg: ufl.Integral, disc: Discretization) -> None:
    """A tag of ``m.ds(tag)`` marks facets of the mesh on some rank (else J is silently 0).

    Collective (one ``allgather`` on the mesh's processes, for every integral with a tag).
    """
    data = itg.subdomain_data()
    ids = itg.subdomain_id()
    ids = ids if isinstance(ids, tuple) else (ids,)
    tagged = [i for i in ids if i not in ("everywhere", "otherwise")]
    if not tagged or not hasattr(data, "values") or itg.integral_type() != "exterior_facet":
        return
    present = {int(v) for v in np.unique(data.values)}
    present = set().union(*shadow(disc.comm).allgather(present))
    missing = sorted(int(i) for i in tagged if i not in present)
    if missing:
        raise ValueError(
            f"goal integrates over m.ds({', '.join(map(str, missing))}), but no facet carries "
            f"that tag (facet tags present: {sorted(present)}): J would be 0; pass a tag of "
            "facet_tags, or m.ds_contact for Gamma_C"
        )
