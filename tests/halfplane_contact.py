"""A boundary-element solver of frictional contact of a rigid profile on an elastic half-plane.

An independent reference for Spence's problem (:mod:`~dwr_signorini.cases.spence_block`):
the same half-plane theory solved by collocation, numpy only. The half-plane z >= 0
(plane strain, E, nu; z into the solid) carries on its surface the pressure p(x) >= 0 and the
shear q(x) (along +x, the traction on the solid). Johnson, *Contact Mechanics* (1985), eqs.
(2.25a, b), give the surface displacement gradients (u_z into the solid)

    (B1)  du_x/dx = -K p(x) - (2 / (pi E*)) PV int q(s) / (x - s) ds,
    (B2)  du_z/dx = -(2 / (pi E*)) PV int p(s) / (x - s) ds + K q(x),

with 1 / E* = (1 - nu^2) / E and K = (1 - 2 nu)(1 + nu) / E = 2 beta / E*, Dundurs' beta =
(1 - 2 nu) / (2 (1 - nu)) of a rigid indenter.
(A point force P pushes the surface in, u_z = -(2 P / (pi E*)) ln|x| + const, and draws it
towards itself, u_x = -(K P / 2) sign(x): the signs are checked by Hertz's and Cattaneo's
solutions in ``tests/test_halfplane_contact.py``.)

Discretisation: x in [-L, L] in N equal elements of width h, p and q constant on each, the
displacements collocated at the element centres x_i. Integrating (B1, B2) over a uniform
traction on [s1, s2] with F(t) = t ln|t| - t:

    (B3)  u_z = -(2 / (pi E*)) (F(x - s1) - F(x - s2)) p + (K / 2)(|x - s1| - |x - s2|) q,
          u_x = -(K / 2)(|x - s1| - |x - s2|) p - (2 / (pi E*)) (F(x - s1) - F(x - s2)) q.

The rigid constants that (B1, B2) leave free are fixed by these kernels themselves: both are
odd about the element (the step as sign(x - s) / 2, the logarithm without a constant), so
under an even p and an odd q, u_x is odd (u_x(0) = 0) and u_z even; the normal constant is
absorbed by the approach delta, which is an unknown fixed by the load P.

Contact with a rigid profile f(x) (``x^2 / (2 R)`` for a cylinder) pressed in by delta and
shifted sideways by s: the gap g_i = u_z(x_i) - delta + f(x_i) >= 0, p_i >= 0, p_i g_i = 0.
Coulomb with history, one quasi-static step at a time: the slip increment
Delta w_i = Delta (u_x(x_i) - s); stick: Delta w_i = 0 and |q_i| <= mu p_i; slip:
q_i = -mu p_i sign(Delta w_i) (the indenter's friction opposes the solid's slip). Each step
is load controlled in the normal direction (sum h p_i = P, delta unknown); tangentially either
the shift s is given (Spence: the indenter does not move sideways, s = 0) or the force
sum h q_i = Q (Cattaneo-Mindlin, s unknown). A primal-dual active set (semismooth Newton)
iteration solves each step exactly: the sets of separated, sticking and slipping elements
are guessed from p - c g and q - c_t Delta w, the linear system of those sets solved, until
the sets no longer change (a set seen before raises); the solution then satisfies every
condition to round-off. c = E* / h; c_t = 0.01 c, because with c_t = c the slip direction of
a whole half of the contact flipped back and forth in the first step of Spence's press (any
c_t from 0.1 c to 1e-4 c gave the same c / a on that press, nu = 0.3, mu = 0.3).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

#: Element states.
SEPARATE, STICK, SLIP = 0, 1, 2
#: The tangential complementarity constant relative to the normal one (module docstring).
TANGENTIAL_C = 0.01


def dundurs_beta(nu: float) -> float:
    """Dundurs' beta of a rigid indenter on a half-plane of Poisson ratio nu (plane strain)."""
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


@dataclass
class Step:
    """The solution of one load step.

    Attributes:
        p: Pressure per element.
        q: Shear traction per element (on the solid, along +x).
        ux: Tangential surface displacement at the centres.
        state: SEPARATE, STICK or SLIP per element.
        delta: The indenter's approach.
        shift: The indenter's sideways displacement.
        iterations: Active-set iterations taken.
    """

    p: np.ndarray
    q: np.ndarray
    ux: np.ndarray
    state: np.ndarray
    delta: float
    shift: float
    iterations: int


class HalfPlane:
    """The collocation matrices (B3) of a half-plane surface [-L, L] in N elements.

    Args:
        half_length: L.
        n: Number of elements N.
        E: Young's modulus.
        nu: Poisson's ratio (0 <= nu <= 1/2).
        coupled: False drops the shear's share of u_z in (B2) (Goodman's approximation: the
            normal problem is Hertz's whatever q; then c / a depends on beta / mu only).

    Raises:
        ValueError: For a non-positive L, E or N, or nu outside [0, 1/2].
    """

    def __init__(self, half_length: float, n: int, E: float = 1.0, nu: float = 0.3,
                 coupled: bool = True):
        if not (half_length > 0 and n >= 2 and E > 0 and 0.0 <= nu <= 0.5):
            raise ValueError(f"HalfPlane needs L > 0, N >= 2, E > 0, 0 <= nu <= 1/2, got "
                             f"{half_length}, {n}, {E}, {nu}")
        self.h = 2.0 * half_length / n
        self.x = -half_length + self.h * (np.arange(n) + 0.5)
        self.e_star = E / (1.0 - nu**2)
        self.beta = dundurs_beta(nu)
        k = 2.0 * self.beta / self.e_star
        s1, s2 = self.x - 0.5 * self.h, self.x + 0.5 * self.h
        d1, d2 = self.x[:, None] - s1[None, :], self.x[:, None] - s2[None, :]
        log_part = -(2.0 / (math.pi * self.e_star)) * (_f(d1) - _f(d2))
        step_part = 0.5 * k * (np.abs(d1) - np.abs(d2))
        #: u_z = zp p + zq q, u_x = xp p + xq q at the centres (B3).
        self.zp, self.zq, self.xp, self.xq = log_part, step_part, -step_part, log_part
        if not coupled:
            self.zq = np.zeros_like(step_part)

    def press(
        self, profile: Callable[[np.ndarray], np.ndarray], mu: float, loads: Sequence[float],
        *, shifts: Sequence[float] | None = None, forces: Sequence[float] | None = None,
        start: Step | None = None,
    ) -> list[Step]:
        """Solve a quasi-static path of load steps with Coulomb friction and history.

        Args:
            profile: f(x), the indenter's height above its lowest point.
            mu: Coulomb's coefficient (>= 0).
            loads: The normal force P of each step (> 0).
            shifts: The indenter's sideways displacement s of each step, or None.
            forces: The tangential force Q of each step, or None (exactly one of the two).
            start: The state the path starts from (None: unloaded).

        Returns:
            One :class:`Step` per load step.

        Raises:
            ValueError: For bad input.
            RuntimeError: If the active sets do not settle or the contact reaches the ends.
        """
        if (shifts is None) == (forces is None):
            raise ValueError("press: give the tangential shifts or the forces, exactly one")
        tangential = shifts if shifts is not None else forces
        if len(tangential) != len(loads) or mu < 0 or min(loads) <= 0:
            raise ValueError("press: one tangential value per step, mu >= 0 and loads > 0")
        fx = profile(self.x)
        prev = start if start is not None else self._unloaded()
        steps = []
        for load, tan in zip(loads, tangential, strict=True):
            prev = self._step(fx, mu, load, tan, shifts is not None, prev)
            steps.append(prev)
        return steps

    def _unloaded(self) -> Step:
        """The state before the first step: no traction, no displacement."""
        n = self.x.size
        zero = np.zeros(n)
        return Step(zero, zero, zero, np.full(n, SEPARATE), 0.0, 0.0, 0)

    def _step(self, fx, mu, load, tan, shift_given, prev: Step, max_iter: int = 200) -> Step:
        """One load step by the primal-dual active set iteration (module docstring)."""
        c = self.e_star / self.h
        ct = c * TANGENTIAL_C
        state = np.where(prev.state == SEPARATE, SEPARATE, STICK)
        if not np.any(state):
            state[np.argmin(fx)] = STICK
        sign = np.zeros(self.x.size)
        w_prev = prev.ux - prev.shift
        seen = set()
        for it in range(1, max_iter + 1):
            p, q, delta, shift = self._solve_sets(fx, mu, load, tan, shift_given, state, sign,
                                                  w_prev)
            uz = self.zp @ p + self.zq @ q
            ux = self.xp @ p + self.xq @ q
            gap = uz - delta + fx
            dw = ux - shift - w_prev
            new_state, new_sign = _sets(p - c * gap, q - ct * dw, mu * p)
            key = (new_state.tobytes(), new_sign.tobytes())
            if np.array_equal(new_state, state) and np.array_equal(new_sign, sign):
                if new_state[0] != SEPARATE or new_state[-1] != SEPARATE:
                    raise RuntimeError("press: the contact reaches the ends of [-L, L]")
                return Step(p, q, ux, state, delta, shift, it)
            if key in seen:
                raise RuntimeError(f"press: the active sets cycle (iteration {it})")
            seen.add(key)
            state, sign = new_state, new_sign
        raise RuntimeError(f"press: the active sets did not settle in {max_iter} iterations")

    def _solve_sets(self, fx, mu, load, tan, shift_given, state, sign, w_prev):
        """The linear system of given sets: unknowns p_A, q_A, delta, shift (A in contact)."""
        a = np.flatnonzero(state != SEPARATE)
        stick = state[a] == STICK
        m = a.size
        mat = np.zeros((2 * m + 2, 2 * m + 2))
        rhs = np.zeros(2 * m + 2)
        # Closed gap on A: zp p + zq q - delta = -f.
        mat[:m, :m], mat[:m, m:2 * m], mat[:m, 2 * m] = self.zp[np.ix_(a, a)], \
            self.zq[np.ix_(a, a)], -1.0
        rhs[:m] = -fx[a]
        # Stick: xp p + xq q - shift = w_prev; slip: q + sign mu p = 0.
        rows = m + np.arange(m)
        st, sl = rows[stick], rows[~stick]
        ia_st = a[stick]
        mat[st, :m], mat[st, m:2 * m], mat[st, 2 * m + 1] = self.xp[np.ix_(ia_st, a)], \
            self.xq[np.ix_(ia_st, a)], -1.0
        rhs[st] = w_prev[ia_st]
        k_sl = np.flatnonzero(~stick)
        mat[sl, m + k_sl] = 1.0
        mat[sl, k_sl] = sign[a[k_sl]] * mu
        # The normal load and the tangential shift or force.
        mat[2 * m, :m] = self.h
        rhs[2 * m] = load
        if shift_given:
            mat[2 * m + 1, 2 * m + 1] = 1.0
        else:
            mat[2 * m + 1, m:2 * m] = self.h
        rhs[2 * m + 1] = tan
        sol = np.linalg.solve(mat, rhs)
        p, q = np.zeros(self.x.size), np.zeros(self.x.size)
        p[a], q[a] = sol[:m], sol[m:2 * m]
        return p, q, sol[2 * m], sol[2 * m + 1]


def _f(t: np.ndarray) -> np.ndarray:
    """F(t) = t ln|t| - t, F(0) = 0: the integral of ln|t|."""
    out = -t.copy()
    nz = t != 0
    out[nz] += t[nz] * np.log(np.abs(t[nz]))
    return out


def _sets(normal: np.ndarray, tangential: np.ndarray, bound: np.ndarray):
    """The sets from the complementarity functions: contact where p - c g > 0; there stick
    where |q - c Delta w| <= mu p, else slip with sign(Delta w) = -sign(q - c Delta w)."""
    state = np.full(normal.size, SEPARATE)
    contact = normal > 0
    stick = contact & (np.abs(tangential) <= bound)
    state[contact] = SLIP
    state[stick] = STICK
    sign = np.where(state == SLIP, -np.sign(tangential), 0.0)
    return state, sign


def half_widths(step: Step, h: float) -> tuple[float, float]:
    """(a, c): half the extent of the contact and of the sticking elements (outer edges)."""
    return _extent(step.state != SEPARATE, h), _extent(step.state == STICK, h)


def _extent(mask: np.ndarray, h: float) -> float:
    idx = np.flatnonzero(mask)
    return 0.5 * h * (idx[-1] - idx[0] + 1) if idx.size else 0.0


def spence_press(
    nu: float, mu: float, per_a: int = 100, ratio: float = 1.03, grow: float = 8.0,
    coupled: bool = True,
) -> tuple[HalfPlane, list[Step], np.ndarray]:
    """Spence's monotone press of a rigid cylinder (R = 1, E = 1) with the indenter held
    sideways (s = 0): Hertz's load P = pi E* a^2 / (4 R) for a growing geometrically by
    ``ratio`` per step from 1 / ``grow`` to 1, the surface [-1.05, 1.05] in elements of
    1 / ``per_a``.

    Args:
        nu: Poisson's ratio.
        mu: Coulomb's coefficient.
        per_a: Elements per final contact half-width.
        ratio: The growth of a per step.
        grow: The growth of a over the press.
        coupled: See :class:`HalfPlane`.

    Returns:
        The half-plane, the steps and c / a of each step (from :func:`half_widths`).
    """
    half = 1.05
    plane = HalfPlane(half, round(2 * half * per_a), 1.0, nu, coupled=coupled)
    k = math.ceil(math.log(grow) / math.log(ratio))
    a = ratio ** -np.arange(k, -1, -1.0)
    loads = math.pi * plane.e_star * a**2 / 4.0
    steps = plane.press(lambda x: 0.5 * x**2, mu, loads, shifts=np.zeros(loads.size))
    widths = np.array([half_widths(st, plane.h) for st in steps])
    return plane, steps, widths[:, 1] / widths[:, 0]


def spence_ratio(nu: float, mu: float, per_a: int = 200, later: int = 10, **kw) -> float:
    """The mean c / a of the last ``later`` steps of :func:`spence_press`."""
    return float(np.mean(spence_press(nu, mu, per_a, **kw)[2][-later:]))


if __name__ == "__main__":
    # c / a(beta / mu): 100, 200, 400 elements per a with steps of 3 %; 200 with steps of
    # 1.5 % and 0.75 %; Goodman's approximation (200, 1.5 %).
    columns = ((100, 1.03, True), (200, 1.03, True), (400, 1.03, True), (200, 1.015, True),
               (200, 1.0075, True), (200, 1.015, False))
    for nu_, mu_ in ((0.3, 1.0), (0.3, 0.6), (0.3, 0.45), (0.3, 0.3), (0.4, 0.175),
                     (0.3, 0.2), (0.3, 0.15), (0.3, 0.12)):
        row = [spence_ratio(nu_, mu_, n_, ratio=r_, coupled=cp_) for n_, r_, cp_ in columns]
        print(f"nu {nu_} mu {mu_} beta/mu {dundurs_beta(nu_) / mu_:.3f}: c/a "
              + " ".join(f"{v:.3f}" for v in row), flush=True)
