"""Spence's problem: a rigid cylinder pressed with friction into a large elastic block.

The half-plane of Spence's theory (1975; :mod:`~dwr_signorini.cases.spence_block`) approximated
by a block 40 x 20 with facets of 0.005 where a rigid cylinder of radius R = 10 presses on it
(a / R <= 0.012), pressed in geometric steps (a grows by 7 % per step from 0.025 to 0.12,
:func:`~dwr_signorini.cases.spence_presses`) with ``ds.solve_path``. Truths:

* self-similarity, eq. (S2): under the monotone press c / a stays constant;
* c / a depends on beta / mu only: two materials and friction coefficients with one beta / mu
  give one c / a (to 0.036 in the half-plane theory itself, which couples the normal problem
  through beta mu: ``tests/test_halfplane_contact.py``);
* c / a is the half-plane theory's, computed in the test by the boundary elements of
  ``tests/halfplane_contact.py`` (the same theory solved by another method);
* the press stated by the cylinder's force, as the theory states it (the bottom clamped, the
  cylinder under Hertz loads, ``spence_block_path(..., loads=...)``): a_h is Hertz's a(P) and
  c_h / a_h the boundary elements', within one facet.

Measured (``scripts/fenicsx python3 -m pytest -s tests/test_spence.py`` prints the rows):
see the tests' docstrings.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import cases

from . import halfplane_contact as hc

COMM = MPI.COMM_WORLD
#: The later steps whose c_h / a_h is judged (a_h from about 0.05 to 0.12: 10 to 22 facets).
LATER = 10
_CACHE: dict = {}
_BEM: dict = {}


def hertz_loads(nu, ratio=1.07, a=0.12):
    """Loads P per unit length whose Hertz half-widths grow by ``ratio`` per step up to ``a``
    (a = sqrt(4 P R / (pi E*)), the schedule of :func:`~dwr_signorini.cases.spence_presses`)."""
    e_star = cases.SPENCE_DEFAULTS["E"] / (1.0 - nu**2)
    load = math.pi * e_star * a**2 / (4.0 * cases.SPENCE_DEFAULTS["radius"])
    return cases.spence_presses(press=load, ratio=ratio)


def hertz_half_width(load, nu):
    """Hertz's a = sqrt(4 P R / (pi E*)) of the cylinder of the case."""
    e_star = cases.SPENCE_DEFAULTS["E"] / (1.0 - nu**2)
    return math.sqrt(4.0 * load * cases.SPENCE_DEFAULTS["radius"] / (math.pi * e_star))


def spence_rows(nu, mu, h_contact=0.005, ratio=1.07, forced=False):
    """The :class:`~dwr_signorini.cases.CMMeasure` of every step of the press, cached; with
    ``forced`` the press by the cylinder's force (:func:`hertz_loads`)."""
    key = (nu, mu, h_contact, ratio, forced, COMM.size)
    if key not in _CACHE:
        rows = []
        if forced:
            problems = cases.spence_block_path(COMM, loads=hertz_loads(nu, ratio), mu=mu,
                                               nu=nu, h_contact=h_contact)
        else:
            problems = cases.spence_block_path(COMM, cases.spence_presses(ratio=ratio), mu=mu,
                                               nu=nu, h_contact=h_contact)
        radius = cases.SPENCE_DEFAULTS["radius"]

        def keep(record, sol, est):
            rows.append(cases.measure_cattaneo_mindlin(sol, mu=mu, nu=nu, radius=radius))

        ds.solve_path(problems, lambda u, lam, m, lam_t: lam_t * m.ds_contact, callback=keep,
                      history=False, verbose=False).destroy()
        for k, m in enumerate(rows):
            if COMM.rank == 0:
                print(f"nu {nu} mu {mu} step {k}: a_h {m.a_h:.4f} c_h {m.c_h:.4f} "
                      f"c_h / a_h {m.c_h / m.a_h:.3f} centre {m.stick_center:+.1e} "
                      f"rms lam_t {m.rms_lam_t:.3f} coupling {m.coupling:+.3f}")
        _CACHE[key] = rows
    return _CACHE[key]


def _ratio(rows):
    """The mean c_h / a_h of the later steps."""
    later = rows[-LATER:]
    return sum(m.c_h / m.a_h for m in later) / len(later)


def bem_ratio(nu, mu):
    """The half-plane theory's c / a at nu, mu: the boundary-element press of
    ``tests/halfplane_contact.py`` (200 elements per a, a growing 1.5 % per step: converged
    to 0.01), computed on rank 0 and broadcast, cached."""
    if (nu, mu) not in _BEM:
        value = hc.spence_ratio(nu, mu, per_a=200, ratio=1.015) if COMM.rank == 0 else None
        _BEM[(nu, mu)] = COMM.bcast(value, root=0)
    return _BEM[(nu, mu)]


@pytest.mark.slow
@pytest.mark.mpi
def test_stick_zone_is_self_similar_on_a_block():
    """Eq. (S2), nu = 0.3, mu = 0.3 (beta / mu = 0.95): on the later steps (a_h 0.05 to 0.12)
    c_h within one facet of r a_h, r the steps' mean c_h / a_h (0.69 measured), a stick zone
    and a slip zone on each, centred to half a facet."""
    rows = spence_rows(0.3, 0.3)
    r = _ratio(rows)
    for m in rows[-LATER:]:
        assert m.num_stick > 0 and m.num_slip > 0, (m.num_stick, m.num_slip)
        assert abs(m.c_h - r * m.a_h) <= m.h_facet, (m.c_h / m.a_h, r)
        assert abs(m.stick_center) <= 0.5 * m.h_facet, m.stick_center



@pytest.mark.slow
@pytest.mark.mpi
def test_press_by_force_is_the_half_plane_theory():
    """The press stated by the cylinder's force (the half-plane theory's load-controlled
    press, ``tests/halfplane_contact.py``), nu = 0.3, mu = 0.3: on the later steps a_h within
    one facet of Hertz's a(P), and the mean c_h / a_h within h_facet / a_h of the boundary
    elements' c / a. Measured (serial): a_h 0.2 to 0.95 facets below Hertz's a (the outer
    facet, partly in contact, not counted), mean c_h / a_h 0.704 against 0.685 (0.691 under
    the displacement-controlled press), h_facet / a_h 0.045."""
    nu, mu = 0.3, 0.3
    rows, loads = spence_rows(nu, mu, forced=True), hertz_loads(nu)
    for m, load in zip(rows[-LATER:], loads[-LATER:], strict=True):
        assert abs(m.a_h - hertz_half_width(load, nu)) <= m.h_facet, (m.a_h, load)
        assert m.num_stick > 0 and m.num_slip > 0, (m.num_stick, m.num_slip)
    measured, theory = _ratio(rows), bem_ratio(nu, mu)
    assert abs(measured - theory) <= rows[-1].h_facet / rows[-1].a_h, (measured, theory)


@pytest.mark.slow
@pytest.mark.mpi
def test_stick_ratio_depends_on_beta_over_mu_only():
    """Eq. (S2): nu = 0.4 with mu = 0.175 has the beta / mu = 0.95 of nu = 0.3, mu = 0.3 and
    the same c / a to 0.1 (later steps' mean c_h / a_h 0.75 and 0.69 measured: one facet at
    the last a_h), while doubling mu (beta / mu = 0.48) moves it by more than 0.15 (to 0.92;
    mu = 0.15, beta / mu = 1.9, gives 0.19)."""
    same = _ratio(spence_rows(0.3, 0.3))
    assert abs(_ratio(spence_rows(0.4, 0.175)) - same) < 0.1
    assert _ratio(spence_rows(0.3, 0.6)) > same + 0.15


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("nu, mu", [(0.3, 0.3), (0.4, 0.175), (0.3, 0.6), (0.3, 0.15)])
def test_stick_ratio_is_the_half_plane_theory(nu, mu):
    """The block's mean c_h / a_h over the later steps against the half-plane's c / a from
    the boundary elements (``tests/halfplane_contact.py``), within the resolution of a ratio
    of two lengths each measured to one facet at the last step, h_facet / a_h = 0.043
    (measured 0.691, 0.749, 0.924, 0.187 against 0.685, 0.720, 0.966, 0.170, serially and on
    2 ranks; the gap of 0.042 at mu = 0.6 is the block's step of 7 %: 0.940 with 3.5 %)."""
    rows, theory = spence_rows(nu, mu), bem_ratio(nu, mu)
    measured = _ratio(rows)
    if COMM.rank == 0:
        print(f"nu {nu} mu {mu} beta / mu {hc.dundurs_beta(nu) / mu:.3f}: c_h / a_h "
              f"{measured:.3f}, boundary elements {theory:.3f}")
    assert abs(measured - theory) <= rows[-1].h_facet / rows[-1].a_h, (measured, theory)


def test_presses_are_geometric():
    """spence_presses: a grows by ``ratio`` per step (the press by ratio^2), the last press
    the given one; bad input refused."""
    presses = cases.spence_presses(0.004, 0.0625, 1.07)
    assert presses[-1] == pytest.approx(0.004)
    assert presses[0] <= 0.0625 * 0.004 < presses[1]
    assert np.diff(np.log(presses)) == pytest.approx(2 * np.log(1.07))
    for bad in ((0.0, 0.5, 1.1), (1.0, 1.0, 1.1), (1.0, 0.5, 1.0)):
        with pytest.raises(ValueError, match="spence_presses"):
            cases.spence_presses(*bad)
    with pytest.raises(ValueError, match="increasing"):
        cases.spence_block_path(COMM, [0.002, 0.001], mesh=(None, None, None))
    with pytest.raises(TypeError, match="unknown sizes"):
        cases.spence_block_mesh(COMM, radius=2.0)


def _single_press(nu, h_contact):
    """The measure of the last press of the path in one step (no history to carry)."""
    press = cases.spence_block_path(COMM, [cases.SPENCE_DEFAULTS["press"]], nu=nu,
                                    h_contact=h_contact)[0]
    with ds.solve(press) as sol:
        m = cases.measure_cattaneo_mindlin(sol, mu=cases.SPENCE_DEFAULTS["mu"], nu=nu,
                                           radius=cases.SPENCE_DEFAULTS["radius"])
    if COMM.rank == 0:
        print(f"nu {nu} facets {h_contact}: rms lam_t {m.rms_lam_t:.4f} coupling "
              f"{m.coupling:+.4f} c_h / a_h {m.c_h / m.a_h:.3f} l2 lam_n {m.l2_lam:.3f}")
    return m


@pytest.mark.mpi
def test_tangential_traction_vanishes_as_beta_goes_to_zero():
    """beta -> 0 (nu -> 1/2) leaves no tangential traction: at nu = 0.49 (beta / mu = 0.065,
    against 0.95 at nu = 0.3 with rms 0.67) ||lambda_t|| / ||mu lambda_n|| under 0.2 and
    falling from facets of 0.005 to 0.0025 (measured 0.147, 0.104)."""
    shares = [_single_press(0.49, h).rms_lam_t for h in (0.005, 0.0025)]
    assert shares[0] < 0.2 and shares[1] < 0.85 * shares[0], shares


@pytest.mark.xfail(strict=True, reason=(
    "P1 displacements lock at nu = 0.499 (lambda / mu = 500): on the block pressed by the "
    "cylinder in one step, facets of 0.005, 0.0025, ||lambda_t|| / ||mu lambda_n|| = 0.90, "
    "0.72 and lambda_n off Hertz by 0.32, 0.25 in L2 (0.076, 0.054 at nu = 0.49)"))
@pytest.mark.slow
@pytest.mark.mpi
def test_tangential_traction_vanishes_nearer_incompressibility():
    """As above at nu = 0.499 (beta = 0.002): ||lambda_t|| / ||mu lambda_n|| under 0.1 and
    falling from facets of 0.005 to 0.0025."""
    shares = [_single_press(0.499, h).rms_lam_t for h in (0.005, 0.0025)]
    assert shares[0] < 0.1 and shares[1] < 0.85 * shares[0], shares
