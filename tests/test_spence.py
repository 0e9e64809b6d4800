"""Spence's problem: a rigid cylinder pressed with friction into a large elastic block.

The half-plane of Spence's theory (1975; :mod:`~dwr_signorini.cases.spence_block`) approximated
by a block 40 x 20 with facets of 0.005 where a rigid cylinder of radius R = 10 presses on it
(a / R <= 0.012), pressed in geometric steps (a grows by 7 % per step from 0.025 to 0.12,
:func:`~dwr_signorini.cases.spence_presses`) with ``ds.solve_path``. Truths:

* self-similarity, eq. (S2): under the monotone press c / a stays constant;
* c / a depends on beta / mu only: two materials and friction coefficients with one beta / mu
  give one c / a.

Measured (``scripts/fenicsx python3 -m pytest -s tests/test_spence.py`` prints the rows):
see the tests' docstrings.
"""

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import cases

COMM = MPI.COMM_WORLD
#: The later steps whose c_h / a_h is judged (a_h from about 0.05 to 0.12: 10 to 22 facets).
LATER = 10
_CACHE: dict = {}


def spence_rows(nu, mu, h_contact=0.005, ratio=1.07):
    """The :class:`~dwr_signorini.cases.CMMeasure` of every step of the press, cached."""
    key = (nu, mu, h_contact, ratio, COMM.size)
    if key not in _CACHE:
        rows = []
        presses = cases.spence_presses(ratio=ratio)
        problems = cases.spence_block_path(COMM, presses, mu=mu, nu=nu, h_contact=h_contact)
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
