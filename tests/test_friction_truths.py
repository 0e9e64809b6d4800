"""Friction truths on curved surfaces beyond monotone loading: Mindlin-Deresiewicz reversal.

The two identical cylinders of :mod:`tests.test_pairs_friction` (R = 8, E = 200, nu = 0.3,
Coulomb mu = 0.3, Dundurs' beta = 0, the upper arc the slave side) are pressed by (0, -0.19)
and then sheared along the path of the upper flat's horizontal displacement 0.0375, 0.075
(monotone: Q* = 0.74 mu P), 0.025 (partial unloading), -0.075 (full reversal) and 0 (reloading
from -Q*), carried by ``ds.solve_path`` (each step's slip measured from the step before). Truth
(:func:`~dwr_signorini.cases.reversal_stick_half_width`, eq. MD1 of
:mod:`~dwr_signorini.cases.cattaneo_mindlin_2d`; Mindlin and Deresiewicz 1953, Johnson 1985
Sect. 7.4, Hills and Nowell 1994 Sect. 2.4): after the tangential force turns back at Q_turn,
the contact sticks on |x| <= c' = a sqrt(1 - |Q_turn - Q| / (2 mu P)) and slips backwards
outside, with P, Q, a from the computed forces (Hertz's a of the two cylinders, as in
:mod:`tests.test_pairs_friction`). Measured (c_h - c' in facets; ``python3 -m pytest -s``
prints the rows):

  facets   Q/(mu P): 0.38   0.74   0.23   -0.74   0.02      ||lam_t - q|| / ||q|| (steps 3, 4)
  0.04     c_h - c:  +0.07  +0.01  -0.28  +0.01   +0.07     0.168, 0.066
  0.02     c_h - c:  -0.62  +0.18  -0.30  +0.17   -0.62     0.102, 0.036

(c is Cattaneo's on the first two steps, Mindlin-Deresiewicz's c' after; the reloading from -Q*
by 0.76 mu P has the stick zone of the first shear step, 0.38 mu P from 0, as Masing's rule
says.)

The load path is symmetric: at -0.075 the force is -Q* to 3e-4 of itself (the hysteresis loop
of Mindlin-Deresiewicz is closed by symmetry), and c' = c*.

On a rigid flat, Spence's theory (1975) is not met by the half-disc of the 2D Cattaneo-Mindlin
case, two strict xfails with their numbers: the limit beta -> 0 (nu -> 1/2: the press leaves no
tangential traction), and the self-similar stick zone of a press in many steps (c / a constant;
its value as a function of beta / mu is not checked). On a large block indented by a rigid
cylinder, the half-plane's nearer approximant, the self-similar stick zone is met and the
tangential traction falls with h at nu = 0.49; at nu = 0.499 P1 locks there too
(:mod:`tests.test_spence`).
"""

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini.cases.cattaneo_mindlin_measure import _facet_l2

from .test_pairs_friction import MU, NU, PRESS, E, R, pair_path

COMM = MPI.COMM_WORLD
#: The upper flat's horizontal displacements: press, two shear steps to Q*, partial
#: unloading, full reversal, reloading.
SHEARS = (0.0, 0.0375, 0.075, 0.025, -0.075, 0.0)
#: The step whose force each step's reversal turned back from (None: monotone from 0).
TURNS = (None, None, None, 2, 2, 4)
_CACHE: dict = {}


def reversal_rows(h_contact):
    """(measure, c', relative L2 error of lambda_t against eq. MD2) of every step, cached."""
    key = (h_contact, COMM.size)
    if key not in _CACHE:
        rows = []

        def keep(record, sol, est):
            rows.append((cases.measure_cattaneo_mindlin(sol, mu=MU, E=E, nu=NU, radius=R),
                         cases.gather_contact_profile(sol)))

        tops = [(s, -PRESS) for s in SHEARS]
        ds.solve_path(pair_path(h_contact, tops=tops), lambda u, lam, m, lam_t:
                      lam_t * m.ds_contact, callback=keep, history=False,
                      verbose=False).destroy()
        _CACHE[key] = [_against_reversal(rows, k) for k in range(len(rows))]
    return _CACHE[key]


def _half_width(rows, k, m):
    """The stick half-width of step k's theory (Cattaneo, or Mindlin-Deresiewicz after a
    reversal), with the a and P of the measure m."""
    Q = rows[k][0].Q
    if TURNS[k] is None:
        return cases.stick_half_width(m.a, Q, MU, m.P)
    return cases.reversal_stick_half_width(m.a, rows[TURNS[k]][0].Q, Q, MU, m.P)


def _traction(rows, k, m, x):
    """The theory's q(x) at step k (Masing's rule: each reversal subtracts a Cattaneo traction
    of 2 mu in the direction of the turn, eq. MD2, from the traction at the turn)."""
    c = _half_width(rows, k, m)
    if TURNS[k] is None:
        return np.sign(rows[k][0].Q) * cases.cm_traction(x, m.a, c, m.p0, MU)
    turn = TURNS[k]
    before = 0.0 if TURNS[turn] is None else rows[TURNS[turn]][0].Q
    return (_traction(rows, turn, m, x)
            - np.sign(rows[turn][0].Q - before) * 2.0 * cases.cm_traction(x, m.a, c, m.p0, MU))


def _against_reversal(rows, k):
    """(measure, c', L2 error of lambda_t) of step k against Mindlin-Deresiewicz (None, None
    before the first reversal). The L2 error is computed on rank 0 and broadcast."""
    m, profile = rows[k]
    if TURNS[k] is None:
        return m, None, None
    error = None
    if COMM.rank == 0:
        err, norm = _facet_l2(profile, profile.lam_t, lambda x: _traction(rows, k, m, x), 16)
        error = float(np.sqrt(err / norm))
    return m, _half_width(rows, k, m), COMM.bcast(error, root=0)


def _show(rows):
    for k, (m, c_rev, error) in enumerate(rows):
        c = m.c if c_rev is None else c_rev
        print(f"step {k}: Q/(mu P) {m.ratio:+.4f} c_h {m.c_h:.4f} c {c:.4f} "
              f"(c_h - c)/h {(m.c_h - c) / m.h_facet:+.2f} centre {m.stick_center:+.2e} "
              f"L2 {error}")


def _check_reversal(rows, steps):
    """c_h within one facet of c' and the stick zone centred to half a facet on ``steps``."""
    _show(rows)
    for k in steps:
        m, c_rev, _ = rows[k]
        assert m.num_stick > 0 and m.num_slip > 0, k
        assert abs(m.c_h - c_rev) <= m.h_facet, (k, m.c_h, c_rev, m.h_facet)
        assert abs(m.stick_center) <= 0.5 * m.h_facet, (k, m.stick_center)


@pytest.mark.mpi
def test_reversal_stick_zone_within_one_facet():
    """Partial unloading (Q from 0.74 to 0.23 mu P), full reversal (to -Q*) and reloading (from
    -Q* to 0.02 mu P): the stick half-width within one facet of Mindlin-Deresiewicz's c'
    (measured -0.28, +0.01, +0.07 facets of 0.04), centred; the monotone steps before within
    one facet of Cattaneo's c."""
    rows = reversal_rows(0.04)
    for m, _, _ in rows[1:3]:
        assert abs(m.c_h - m.c) <= m.h_facet, (m.c_h, m.c)
    _check_reversal(rows, (3, 4, 5))


@pytest.mark.mpi
def test_full_reversal_is_the_mirror_image():
    """At the shear -0.075 the force is -Q* (the closed, symmetric hysteresis loop) to 2e-3
    (3e-4 measured: the mesh is not exactly mirror symmetric), the stick zone that of Q*, and
    lambda_t is the reversed traction of eq. (MD2) to 10 % in L2 (0.066 measured)."""
    rows = reversal_rows(0.04)
    turn, (m, c_rev, error) = rows[2][0], rows[4]
    assert m.Q == pytest.approx(-turn.Q, rel=2e-3)
    assert c_rev == pytest.approx(turn.c, rel=2e-3)
    assert abs(m.c_h - turn.c_h) <= 0.5 * m.h_facet
    assert error < 0.1, error


@pytest.mark.slow
@pytest.mark.mpi
def test_reversal_on_finer_facets():
    """As above on facets of 0.02: c_h within one facet of c' (measured -0.30, +0.17, -0.62),
    and the L2 error of lambda_t against eq. (MD2) falling from facets of 0.04 to 0.02 on the
    partial unloading and the full reversal (0.168, 0.066 to 0.102, 0.036)."""
    coarse, fine = reversal_rows(0.04), reversal_rows(0.02)
    _check_reversal(fine, (3, 4, 5))
    for k in (3, 4):
        assert fine[k][2] < 0.85 * coarse[k][2], (k, coarse[k][2], fine[k][2])


def test_reversal_theory():
    """Eqs. (MD1), (MD2): the traction integrates to Q, is -mu p on the reverse slip zone
    c' <= |x| <= a and within the Coulomb limit in the stick zone; c' = a at the reversal and
    c' = c* at Q = -Q*; a Q beyond -Q* or beyond Q* is refused."""
    P, mu = 10.0, 0.3
    a, p0 = cases.hertz_half_width(P, R, E, NU)
    Q_turn = 0.7 * mu * P
    c_turn = cases.stick_half_width(a, Q_turn, mu, P)
    assert cases.reversal_stick_half_width(a, Q_turn, Q_turn, mu, P) == pytest.approx(a)
    assert cases.reversal_stick_half_width(a, Q_turn, -Q_turn, mu, P) == pytest.approx(c_turn)
    for Q in (-1.01 * Q_turn, 1.01 * Q_turn):
        with pytest.raises(ValueError, match="no reversal"):
            cases.reversal_stick_half_width(a, Q_turn, Q, mu, P)
    x = np.linspace(-a, a, 200001)
    p = cases.hertz_pressure(x, a, p0)
    for Q in (0.4 * mu * P, -0.2 * mu * P, -Q_turn):
        c_rev = cases.reversal_stick_half_width(a, Q_turn, Q, mu, P)
        q = cases.reversal_traction(x, a, c_turn, c_rev, p0, mu, 1.0)
        assert np.trapezoid(q, x) == pytest.approx(Q, rel=1e-4)
        slip = np.abs(x) >= c_rev
        assert np.allclose(q[slip], -mu * p[slip])
        assert np.all(np.abs(q[~slip]) <= mu * p[~slip] + 1e-12)


# --------------------------------------------------------------------------------------------------
# nu -> 1/2 on a rigid flat (beta -> 0)
# --------------------------------------------------------------------------------------------------


@pytest.mark.xfail(strict=True, reason=(
    "the half-disc of cases.cattaneo_mindlin_path at nu = 0.4999 (beta = 2e-4) on facets of "
    "0.01, 0.005: ||lambda_t|| / ||mu lambda_n|| = 1.12, 0.91, the press's friction force of "
    "each half 0.60, 0.55 of its Coulomb limit, falling slowly with h but far from 0: the "
    "finite half-disc bulges its contact points outwards by a strain of order P / (E* R) that "
    "beta -> 0 does not remove (0.21 of the limit at half the a / R), and P1 displacements lock "
    "at lambda / mu = 5000 (lambda_n oscillates too)"))
@pytest.mark.slow
@pytest.mark.mpi
def test_incompressible_limit_on_a_rigid_flat():
    """Spence's limit beta -> 0 (nu -> 1/2 on a rigid flat): the press leaves lambda_t -> 0:
    ||lambda_t|| / ||mu lambda_n|| under 0.1 and falling from facets of 0.01 to 0.005."""
    nu, shares = 0.4999, []
    for h_contact in (0.01, 0.005):
        press = cases.cattaneo_mindlin_path(COMM, h_contact=h_contact, nu=nu, steps=1)[0]
        with ds.solve(press) as sol:
            shares.append(cases.measure_cattaneo_mindlin(sol, nu=nu).rms_lam_t)
    assert shares[1] < 0.85 * shares[0] and shares[1] < 0.1, shares


@pytest.mark.xfail(strict=True, reason=(
    "the half-disc of cases.cattaneo_mindlin_mesh (facets of 0.005) at nu = 0.3, mu = 0.3 "
    "(beta / mu = 0.95), pressed by 0.012 (k / 8)^2, k = 1, ..., 8: c_h / a_h = 0.50, 0.50, "
    "0.63, 0.70, 0.75, 0.73, 0.82 on steps 2-8 (a_h = 0.020 to 0.083, 4 to 17 facets), growing "
    "with a: the finite half-disc's bulge (a strain of order P / (E* R), against the half-plane's "
    "beta term of order beta P / (E* a)) grows with a / R and frees the centre"))
@pytest.mark.slow
@pytest.mark.mpi
def test_spence_stick_zone_is_self_similar():
    """Spence (1975): under a monotone press with friction the stick zone of a Hertz contact
    grows in proportion to the contact (c / a depends on beta / mu only). The press in eight
    steps (the contact growing from about 1 to 17 facets): on steps 4-8, c_h within one facet of
    (c_h / a_h) a_h of the last step."""
    from dwr_signorini.cases.load_path import shear_path

    nu, mu, n, rows = 0.3, 0.3, 8, []
    mesh = cases.cattaneo_mindlin_mesh(COMM, h_contact=0.005)
    problems = [shear_path(mesh, 2, mu=mu, nu=nu, steps=1, press=0.012 * (k / n) ** 2, shear=0.0,
                           E=1.0, radius=1.0)[0] for k in range(1, n + 1)]

    def keep(record, sol, est):
        rows.append(cases.measure_cattaneo_mindlin(sol, mu=mu, nu=nu))

    ds.solve_path(problems, lambda u, lam, m, lam_t: lam_t * m.ds_contact, callback=keep,
                  history=False, verbose=False).destroy()
    ratio = rows[-1].c_h / rows[-1].a_h
    for m in rows[3:]:
        assert abs(m.c_h - ratio * m.a_h) <= m.h_facet, (m.c_h / m.a_h, ratio)
