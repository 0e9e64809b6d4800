"""Frictionless contact: Signorini's condition and the law of the normal force alone.

:class:`Normal` is the normal component of every law (the frictional laws of
:mod:`dwr_signorini.laws.friction` add tangential ones); :class:`Frictionless` is the law of
``friction=None`` (:func:`check_law`, the validation of a problem's law).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import ufl

from .base import Component, ContactLaw, set_test_argument

__all__ = ["Frictionless", "Normal", "check_law"]


class Normal(Component):
    """Signorini's condition: P_n(x) = max(0, x); constrained = active (eq. 21)."""

    name = "normal"

    def direction(self, n: Any) -> Any:
        """See the base class."""
        return n

    def direction_in(self, n: Any, frame: Any) -> Any:
        """The normal of the contact frame (n itself without one)."""
        return frame

    def offset_in(self, gap: Any, n: Any, frame: Any) -> Any:
        """The gap along the frame's normal: g n . n_c (g is measured along n), g if n_c is n."""
        return gap if frame is n else gap * ufl.dot(n, frame)

    def offset(self, gap: Any) -> Any:
        """See the base class."""
        return gap

    def projection(self, x: Any, bound: Any) -> Any:
        """See the base class."""
        return ufl.max_value(0.0, x)

    def derivative(self, x: Any, bound: Any) -> Any:
        """See the base class."""
        return ufl.conditional(ufl.gt(x, 0.0), 1.0, 0.0)

    def ncp(self, Mlam, x, bound):  # noqa: D102  (see Component)
        return Mlam - np.maximum(0.0, x)

    def newton_set(self, Mlam, residual, c, M, g, u_max, force_size, bound):  # noqa: D102  (see Component)
        clean, test, size = set_test_argument(Mlam, residual, c, M, g, u_max, force_size)
        return clean > 0.0, np.zeros_like(Mlam), np.abs(self.ncp(Mlam, test, bound)), size


class Frictionless(ContactLaw):
    """Frictionless contact (Signorini): the normal contact force alone, lambda_t = 0."""

    name = "frictionless"

    def components(self, tdim: int) -> tuple[Component, ...]:
        """See the base class."""
        return (Normal(),)

    def __repr__(self) -> str:
        """The law as it is constructed."""
        return "Frictionless()"


def check_law(law: Any, problem: Any) -> ContactLaw:
    """``friction`` of :class:`~dwr_signorini.SignoriniProblem` validated (None: frictionless).

    Args:
        law: The problem's ``friction``: None or a :class:`~dwr_signorini.laws.ContactLaw`.
        problem: The problem whose data the law's data are checked against.

    Returns:
        The law (:class:`Frictionless` for None).

    Raises:
        TypeError: ``law`` is not a contact law.
        ValueError: The law's data do not fit the problem (:meth:`ContactLaw.check`).
    """
    if law is None:
        return Frictionless()
    if not isinstance(law, ContactLaw):
        raise TypeError(
            "friction must be None, ds.Frictionless(), ds.Tresca(s) or ds.Coulomb(mu), got "
            f"{type(law).__name__}"
        )
    return law.check(problem)
