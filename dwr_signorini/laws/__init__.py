"""Contact laws: the NCP functions of the contact conditions and their generalised derivatives.

A law is a list of *components*, one per multiplier on the macro contact facets: the normal
contact force lambda_n for every law, and the tangential traction lambda_t of a frictional law
(a scalar in 2D, along the tangent t = (-n_2, n_1); in 3D its two coordinates in the tangent
basis (t_1, t_2) of :func:`tangent_basis`). Component k has a direction e_k (n or t),
an offset g_k (the gap g for the normal, 0 for the tangential) and a projection P_k onto the
set of admissible forces, and its condition is the NCP (paper eq. 8, with the scale c of
:mod:`~dwr_signorini.residuals`)

    C_k(w)(mu) = (mu, lambda_k - P_k(lambda_k + c (u . e_k - g_k)))_GC = 0,

    normal (Signorini):   P_n(x) = max(0, x),         P_n'(x) = [x > 0]       (active / inactive)
    tangential (Tresca):  P_t(x) = max(-s, min(s, x)), P_t'(x) = [abs(x) < s]  (stick / slip)

Both projections are piecewise linear with slopes 0 and 1, so each component splits its facets
into *constrained* ones (slope 1: the contact condition fixes the displacement, (u . e_k)_i = g_k,i;
active, stick) and *free* ones (slope 0: it fixes the force, lambda_k,i = P_k(x_i), which is 0 on
inactive facets and s sign(x_i) on slipping ones). The semi-smooth Newton step, the dual problem
(the transposed Newton matrix), the residuals and the estimator only see that split and the
value on the free facets (:meth:`Component.newton_set`), and the UFL forms of P_k and P_k'
(:meth:`Component.projection`, :meth:`Component.derivative`): they do not branch on the law.

Tresca's law is the classical given-threshold friction law (Duvaut and Lions): ``|lambda_t| <= s``
on all of Gamma_C, u_t = 0 where ``|lambda_t| < s`` and ``lambda_t = s u_t / |u_t|`` where the
body slips.
The threshold does not depend on the normal force, so a facet that separates still carries
lambda_t = +-s where it moves tangentially: the law is a model of friction with a known normal
pressure, and Coulomb's law (threshold mu lambda_n) is the one for friction that follows contact.
What makes Tresca's law the first frictional law to build on is that the discrete problem is
convex: it minimises the energy plus ``sum_i s_i |(T u)_i|`` under (N u)_i <= g_i, with a unique
solution, whose dual is a bound-constrained quadratic programme in (lambda_n, lambda_t) (the
tests solve it by another method for an independent check). A threshold s chi on the contact
set alone would couple the tangential condition to the normal one through the set, a
quasi-variational inequality whose discrete problem need not have a unique solution (tried: the
semi-smooth Newton method cycled on facets at the edge of the contact zone). The normal and
tangential conditions do not couple in the Newton matrix, which stays symmetric, and every
linear solver of the frictionless problem serves (:mod:`dwr_signorini.linalg`).

**3D.** The tangential traction is a vector of the tangent plane and Tresca's law projects it
onto the disc of radius s: P(x) = x min(1, s / |x|) acts on both tangential components at once
(a *condition* on two components, :meth:`ContactLaw.conditions`, :class:`TangentialBall`). Its
generalised derivative is I inside the disc (stick: both rows constrained, as in 2D) and
alpha (I - q q^T), alpha = s / |x| < 1, q = x / |x|, outside (slip). The semi-smooth Newton method
uses this exact derivative (not the Hueber-Stadler-Wohlmuth fixed point on the slip direction):
the slipping facets' rows are then those of a smooth Newton method, converging quadratically
(measured on the oblique patch test: NCP residuals 1e-2, 9e-5, 1e-8, 5e-16), and the dual
problem is the transposed linearisation that the error identity needs. The price is that a
slipping facet's rows, (I - J) M lambda - c J (B u), couple the two tangential rows and are not
the transpose of the columns B^T: the Newton matrix is not symmetric and is factored by LU
(:mod:`dwr_signorini.linalg.coupled`, :class:`Coupling`). In the facet's rotated basis (q, p) the
step reads lambda_q = s and (B u)_p = (1 - alpha) / (alpha c) M lambda_p, a symmetric form
with a compliant diagonal; the LU path is the one Coulomb's law needs anyway.

**Coulomb's law** (:class:`Coulomb`) has the threshold mu max(0, x_n), x_n the normal NCP
argument: one projection onto the Coulomb cone acts on all components of a facet
(:class:`CoulombCone`), and on a facet in contact that slips the tangential rows depend on x_n
(the derivative mu d, d = sign(x_t) or x_t / ``|x_t|``). Such a facet is a :class:`Coupling`
whose normal row is constrained (active) and whose tangential rows couple to the normal
column; the Newton matrix is not symmetric in 2D either. Its tangential arguments hold the slip
increment of a load step, x_t = lambda_t + c (u - u_old) . t (:func:`~dwr_signorini.solve_path`).

**Modules.** :mod:`~dwr_signorini.laws.base` holds the interface (:class:`Component`,
:class:`ContactLaw`, :class:`Coupling`, the set test's argument), which the laws implement:
:mod:`~dwr_signorini.laws.frictionless` (:class:`Normal`, :class:`Frictionless`,
:func:`check_law`) and :mod:`~dwr_signorini.laws.friction` (the tangential components, the
Coulomb cone, Tresca's and Coulomb's laws). Each module imports only those before it; every
name is imported from here, :mod:`dwr_signorini.laws` (the laws also as ``ds.Frictionless``,
``ds.Tresca``, ``ds.Coulomb``).
"""

from .base import (
    ROUNDOFF,
    Component,
    ContactLaw,
    Coupling,
    multiplier_names,
    set_test_argument,
)
from .friction import (
    Coulomb,
    CoulombCone,
    Tangential,
    TangentialBall,
    ThresholdData,
    Tresca,
    reversing,
    tangent_basis,
)
from .frictionless import Frictionless, Normal, check_law

__all__ = [
    "ROUNDOFF",
    "Component",
    "ContactLaw",
    "Coulomb",
    "CoulombCone",
    "Coupling",
    "Frictionless",
    "Normal",
    "Tangential",
    "TangentialBall",
    "ThresholdData",
    "Tresca",
    "check_law",
    "multiplier_names",
    "reversing",
    "set_test_argument",
    "tangent_basis",
]
