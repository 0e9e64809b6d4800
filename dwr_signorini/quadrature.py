"""Quadrature degrees: exact for polynomial integrands, a fixed degree for data.

Loads, gaps and goal weights may be non-polynomial expressions of x (``sin``, ``exp``, ``sqrt``,
divisions, conditionals). UFL's degree estimate for them is a guess, often very high; they are
integrated with :data:`DATA_QUADRATURE_DEGREE` everywhere (the Newton system and the residuals
of the estimators), so that the discrete residual vanishes on discrete test functions (Galerkin
orthogonality) up to round-off. Polynomial integrands, such as a(u_h, v) with the weights of the
estimators, are integrated exactly with UFL's estimate, which costs far fewer points: on
triangles degree 1 or 2 takes 1 or 3 points where degree 8 takes 16.

Data are evaluated at many points (16 per triangle at degree 8), so their kernels matter. UFL
writes ``x**4`` and the derivatives of such powers (a body force ``-div sigma(u)`` of a polynomial
``u``) as calls of C's ``pow``, which compilers expand only under unsafe math flags;
:func:`expand_integer_powers` rewrites them as products before compilation (the same values up to
round-off, several times faster on example 5.1's body force).
"""

from __future__ import annotations

import ufl
import ufl.algebra
import ufl.mathfunctions
from ufl.algorithms import estimate_total_polynomial_degree, expand_derivatives
from ufl.algorithms.map_integrands import map_integrand_dags
from ufl.conditional import Conditional, MaxValue, MinValue
from ufl.constant import Constant
from ufl.constantvalue import ConstantValue, IntValue, RealValue
from ufl.core.terminal import Terminal
from ufl.corealg.map_dag import map_expr_dag
from ufl.corealg.multifunction import MultiFunction
from ufl.corealg.traversal import unique_pre_traversal

from . import compat

__all__ = [
    "DATA_QUADRATURE_DEGREE",
    "expand_integer_powers",
    "is_polynomial",
    "with_quadrature_degrees",
]

DATA_QUADRATURE_DEGREE = 8

_NON_POLYNOMIAL = (
    ufl.mathfunctions.MathFunction,
    ufl.mathfunctions.BesselFunction,
    ufl.mathfunctions.Atan2,
    ufl.algebra.Abs,
    Conditional,
    MinValue,
    MaxValue,
)


#: Largest exponent written out as products by :func:`expand_integer_powers`.
MAX_EXPANDED_POWER = 64


def _integer_exponent(exponent: ufl.core.expr.Expr) -> int | None:
    """The exponent as an int in [2, MAX_EXPANDED_POWER] if it is such a literal, else None."""
    if isinstance(exponent, (IntValue, RealValue)):
        value = float(exponent)
        if value.is_integer() and 2 <= value <= MAX_EXPANDED_POWER:
            return int(value)
    return None


def _power_by_squaring(base: ufl.core.expr.Expr, n: int) -> ufl.core.expr.Expr:
    """``base**n`` as a product of ``base`` and its repeated squares (n >= 1)."""
    result = None
    while n:
        if n & 1:
            result = base if result is None else result * base
        n >>= 1
        if n:
            base = base * base
    return result


class _IntegerPowers(MultiFunction):
    """Rewrites powers with small integer literal exponents as products."""

    expr = MultiFunction.reuse_if_untouched

    def power(
        self, o: ufl.core.expr.Expr, base: ufl.core.expr.Expr, exponent: ufl.core.expr.Expr
    ) -> ufl.core.expr.Expr:
        """``base**n`` by squaring if ``n`` is a small integer literal, else unchanged."""
        n = _integer_exponent(exponent)
        if n is None:
            return self.reuse_if_untouched(o, base, exponent)
        return _power_by_squaring(base, n)


def expand_integer_powers(expr: ufl.core.expr.Expr | ufl.Form) -> ufl.core.expr.Expr | ufl.Form:
    """``expr`` with derivatives applied and ``f**n`` (n = 2 ... 64, literal) as products.

    Derivatives are applied first, since they turn ``f**n`` into ``n f**(n-1) f'``. Powers with
    other exponents (negative, fractional, non-literal) are left to ``pow``.
    """
    expanded = expand_derivatives(expr)
    if isinstance(expanded, ufl.Form):
        return map_integrand_dags(_IntegerPowers(), expanded)
    return map_expr_dag(_IntegerPowers(), expanded)


def _constant(expr: ufl.core.expr.Expr) -> bool:
    """Whether ``expr`` is built from literals and dolfinx Constants only."""
    return all(
        not isinstance(node, Terminal) or isinstance(node, (ConstantValue, Constant))
        for node in unique_pre_traversal(expr)
    )


def _affine_simplex(domain: ufl.AbstractDomain) -> bool:
    element = domain.ufl_coordinate_element()
    return compat.is_simplex(domain.ufl_cell()) and element.embedded_superdegree == 1


def is_polynomial(expr: ufl.core.expr.Expr) -> bool:
    """Whether ``expr`` is a polynomial in x, coefficients and arguments on each cell.

    False for math functions, absolute values, conditionals, min/max, divisions by anything
    but constants and powers other than non-negative integer literals.
    """
    for node in unique_pre_traversal(expr):
        if isinstance(node, _NON_POLYNOMIAL):
            return False
        if isinstance(node, ufl.algebra.Division) and not _constant(node.ufl_operands[1]):
            return False
        if isinstance(node, ufl.algebra.Power):
            exponent = node.ufl_operands[1]
            if not (isinstance(exponent, IntValue) and int(exponent) >= 0) and not (
                isinstance(exponent, RealValue)
                and float(exponent).is_integer()
                and float(exponent) >= 0
            ):
                return False
    return True


def with_quadrature_degrees(
    form: ufl.Form, data_degree: int | None = DATA_QUADRATURE_DEGREE
) -> ufl.Form:
    """``form`` with a quadrature degree on every integral that does not set one.

    On affine simplex cells, polynomial integrands get UFL's estimate (exact), capped at
    ``data_degree``; all other integrals get ``data_degree``. With ``data_degree=None`` the form
    is returned unchanged (UFL estimates every degree).
    """
    if data_degree is None:
        return form
    integrals = []
    for itg in expand_integer_powers(form).integrals():
        metadata = dict(itg.metadata())
        if "quadrature_degree" not in metadata:
            integrand = itg.integrand()
            if _affine_simplex(itg.ufl_domain()) and is_polynomial(integrand):
                degree = estimate_total_polynomial_degree(integrand)
                metadata["quadrature_degree"] = min(int(degree), data_degree)
            else:
                metadata["quadrature_degree"] = data_degree
        integrals.append(itg.reconstruct(metadata=metadata))
    return ufl.Form(integrals)
