"""The half-plane boundary-element solver of ``tests/halfplane_contact.py`` against exact results.

Before it serves as the reference of Spence's problem (``tests/test_spence.py``), the solver
meets: Betti's reciprocity and the inward draw of a pressed surface (the signs of eqs. B1, B2),
Hertz's line contact (frictionless, beta != 0), Cattaneo-Mindlin (beta = 0, a tangential force
after the press), symmetry under a press with large friction (no tangential force, q odd), and
the self-similarity of Spence's press (c / a constant under the press, converging in the
elements). numpy only, serial: the tests run on rank 0's process alone.

Measured (``scripts/fenicsx python3 -m pytest -s tests/test_halfplane_contact.py``): see the
tests' docstrings.
"""

import math

from mpi4py import MPI

import numpy as np
import pytest

from . import halfplane_contact as hc

pytestmark = pytest.mark.skipif(MPI.COMM_WORLD.size > 1,
                                reason="numpy, serial: one run is enough")


def _hertz(plane, load, radius=1.0):
    """Hertz's half-width and pressure of a line contact (Johnson eqs. 4.43, 4.45):
    a^2 = 4 P R / (pi E*), p = p0 sqrt(1 - x^2 / a^2), p0 = 2 P / (pi a)."""
    a = math.sqrt(4.0 * load * radius / (math.pi * plane.e_star))
    p0 = 2.0 * load / (math.pi * a)
    return a, p0, p0 * np.sqrt(np.maximum(0.0, 1.0 - plane.x**2 / a**2))


def test_influence_is_reciprocal_and_draws_the_surface_inwards():
    """Betti: the matrix [[zp, zq], [xp, xq]] (u_z, u_x from p, q) is symmetric; a pressure on
    the middle element pulls the surface towards it (u_x < 0 right of it, > 0 left) and pushes
    it in most under the load (u_z largest there)."""
    plane = hc.HalfPlane(1.0, 40, 1.0, 0.3)
    full = np.block([[plane.zp, plane.zq], [plane.xp, plane.xq]])
    assert np.allclose(full, full.T, rtol=0, atol=1e-14 * np.abs(full).max())
    assert np.abs(plane.zq).max() > 0
    j = 20
    ux, uz = plane.xp[:, j], plane.zp[:, j]
    assert np.all(ux[j + 1:] < 0) and np.all(ux[:j] > 0) and ux[j] == 0
    assert np.argmax(uz) == j


def test_frictionless_press_is_hertz():
    """mu = 0, nu = 0.3 (beta = 0.29): p within 2 % of Hertz's p0 (measured 1.8 %, 0.3 % in
    L2 on 0.0012 elements, a / h = 57), a within one element of Hertz's, q = 0, u_x odd and
    drawn inwards."""
    plane = hc.HalfPlane(0.12, 200, 1.0, 0.3)
    load = 0.004
    step = plane.press(lambda x: 0.5 * x**2, 0.0, [load], shifts=[0.0])[-1]
    a, p0, p = _hertz(plane, load)
    a_h, _ = hc.half_widths(step, plane.h)
    assert abs(a_h - a) <= plane.h, (a_h, a)
    assert np.abs(step.p - p).max() <= 0.02 * p0
    assert np.sum(step.p) * plane.h == pytest.approx(load, rel=1e-12)
    assert not np.any(step.q)
    assert np.allclose(step.ux, -step.ux[::-1], atol=1e-12 * np.abs(step.ux).max())
    assert step.ux[plane.x > 0].max() < 0


def test_cattaneo_mindlin_at_beta_zero():
    """nu = 1/2 (beta = 0), pressed, then Q / (mu P) = 0.2 to 0.6 in steps with the indenter's
    sideways shift free: c = a sqrt(1 - Q / (mu P)) within one element (measured within 0.4
    element), q = mu p0 (sqrt(1 - x^2/a^2) - (c/a) sqrt(1 - x^2/c^2)) within 3 % in L2
    (measured 3.0 % at 0.1 where c - a is two elements, 1.3 % to 0.5 % from 0.2 to 0.6)."""
    plane, mu, load = hc.HalfPlane(0.1, 200, 1.0, 0.5), 0.3, 0.004
    cylinder = lambda x: 0.5 * x**2  # noqa: E731
    pressed = plane.press(cylinder, mu, [load], forces=[0.0])[-1]
    assert not np.any(pressed.q)
    shares = np.linspace(0.2, 0.6, 5)
    steps = plane.press(cylinder, mu, [load] * shares.size, forces=shares * mu * load,
                        start=pressed)
    a, p0, _ = _hertz(plane, load)
    for share, step in zip(shares, steps, strict=True):
        c = a * math.sqrt(1.0 - share)
        q = mu * p0 * (np.sqrt(np.maximum(0.0, 1.0 - plane.x**2 / a**2))
                       - (c / a) * np.sqrt(np.maximum(0.0, 1.0 - plane.x**2 / c**2)))
        _, c_h = hc.half_widths(step, plane.h)
        assert abs(c_h - c) <= plane.h, (share, c_h, c)
        assert np.linalg.norm(step.q - q) <= 0.03 * np.linalg.norm(q), share
        assert np.sum(step.q) * plane.h == pytest.approx(share * mu * load, rel=1e-10)
        assert step.shift > 0


def test_press_with_large_friction_is_symmetric():
    """nu = 0.3, mu = 5 (beta / mu = 0.057), the indenter held sideways: no tangential force
    (int q = 0 to round-off, not imposed), q odd, p even, and all but the outer element or two
    stick (c / a >= 1 - 2 h / a, measured 0.99 on the last steps)."""
    _, steps, ratios = hc.spence_press(0.3, 5.0, per_a=100)
    for step in steps[-5:]:
        scale = np.abs(step.q).max()
        assert scale > 0
        assert abs(np.sum(step.q)) <= 1e-10 * scale * step.q.size
        assert np.allclose(step.q, -step.q[::-1], rtol=0, atol=1e-10 * scale)
        assert np.allclose(step.p, step.p[::-1], rtol=0, atol=1e-10 * np.abs(step.p).max())
    assert np.all(ratios[-5:] >= 1.0 - 2.0 / 100)


def test_spence_press_is_self_similar_and_converges():
    """Spence's press, nu = 0.3, mu = 0.3 (beta / mu = 0.95), a growing 3 % per step from
    1/8 to 1: over the last 10 steps c / a within one element of its mean (a / h = 50, 100,
    200), the means converging (measured 0.680, 0.680, 0.680); the indenter held sideways
    gets no tangential force."""
    means = []
    for per_a in (50, 100, 200):
        plane, steps, ratios = hc.spence_press(0.3, 0.3, per_a=per_a)
        later = ratios[-10:]
        means.append(float(later.mean()))
        print(f"elements per a {per_a}: c / a {means[-1]:.4f} (last 10 steps "
              f"{later.min():.4f} to {later.max():.4f})")
        assert np.all(np.abs(later - means[-1]) <= 1.0 / per_a), later
        assert abs(np.sum(steps[-1].q)) <= 1e-10 * np.abs(steps[-1].q).max() * plane.x.size
    assert abs(means[2] - means[1]) < 0.01 and abs(means[1] - means[0]) < 0.02, means


def test_goodman_ratio_depends_on_beta_over_mu_only():
    """Without the shear's share of the normal displacement (Goodman's approximation) the
    problem scales with beta / mu alone: nu = 0.3, mu = 0.3 and nu = 0.4, mu = 0.175 (both
    beta / mu = 0.952) give one c / a to round-off in the sets, every step; with it (the
    full half-plane theory) they differ (measured 0.680 and 0.717 on 100 elements per a)."""
    one = hc.spence_press(0.3, 0.3, coupled=False)[2]
    other = hc.spence_press(0.4, 0.175, coupled=False)[2]
    assert np.array_equal(one, other)
    coupled = [hc.spence_ratio(nu, mu, per_a=100) for nu, mu in ((0.3, 0.3), (0.4, 0.175))]
    assert coupled[1] - coupled[0] > 0.02, coupled


def test_bad_input_is_refused():
    """A half-plane of no length, a press with both or neither tangential controls."""
    with pytest.raises(ValueError, match="HalfPlane"):
        hc.HalfPlane(0.0, 10)
    plane = hc.HalfPlane(1.0, 10)
    with pytest.raises(ValueError, match="exactly one"):
        plane.press(lambda x: x**2, 0.1, [1.0])
    with pytest.raises(ValueError, match="one tangential value"):
        plane.press(lambda x: x**2, 0.1, [1.0], shifts=[0.0, 0.0])
