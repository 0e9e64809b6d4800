"""The model error along a load path (dwr_signorini.path_model_error, eq. (M7)) against the truth.

The scene: Cattaneo-Mindlin in 2D (``cases.cattaneo_mindlin_path``, a half-disc pressed onto a
rigid flat, then sheared in four steps to Q / (mu P) = 0.69 with Coulomb mu = 0.3) on a coarse
mesh (macro facets of 0.02 at the contact). The truth is J(richer path) - J(simpler path), both
paths solved on the same mesh, at every step; the estimate is ``ds.estimate(sol_k, goal,
model_error=richer[:k + 1])`` at step k of the simpler path (``solve_path(...,
keep_steps=True)``). The goal is the tangential displacement of the contact boundary,
int_GC u_x ds, which friction holds back.

* Frictionless in place of Coulomb: the frictionless slip increment of every step is a uniform
  sliding, so Coulomb's set test at the frictionless states slips everywhere and (M7) is the
  full-slip friction's effect: its effectivity is about Q / (mu P) of the step (measured 0.026,
  0.182, 0.355, 0.526, 0.694 on steps 0-4), within [0.5, 2] on the steps that slip over most
  of the contact (3, 4), a strict xfail on the others; the interval hull(0, 2 eta_M) holds the
  truth on every step.
* Tresca with Hertz's threshold mu p(x) in place of Coulomb: both paths stick in the centre,
  effectivity 1.015, 1.022, 1.035, 1.050 on the shear steps 1-4 (the press step, where the two
  thresholds hardly differ and J barely moves: 0.569 here, 0.261 on facets of 0.01, a strict
  xfail there).
* mu = 0 (the richer path Coulomb(0)): zero to round-off.
* The indicators (per cell and per macro facet) sum to the estimate; the summands per step sum
  to it.
* Unit invariance: E and Tresca's threshold times 1000, the model error unchanged.
* The backward chain of duals (the history goals): on a block whose third step sticks where its
  second slid, Tresca in place of Coulomb, the earlier steps' terms carry most of (M7) (ieff
  0.978 with them, 5.0 with the step's own term alone).

About 20 s serial without the ``slow`` tests (facets of 0.01, about 25 s more).
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini import examples as ex
from dwr_signorini.goal import GoalForms

from .problems import block

COMM = MPI.COMM_WORLD
H_CONTACT = 0.02
MU = cases.CM_DEFAULTS["mu"]
_CACHE: dict = {}


def slide(u, lam, m, lam_t=None):
    """The tangential displacement of the contact boundary, int_GC u_x ds."""
    return u[0] * m.ds_contact


def value(sol, goal=slide):
    """J at a solution."""
    return GoalForms(goal, sol.u, sol.lam, sol.disc, sol.tangential or None).value()


def local_sum(f):
    """Sum of a function's owned values over all ranks."""
    n = f.function_space.dofmap.index_map.size_local
    return COMM.allreduce(float(f.x.array[:n].sum()), op=MPI.SUM)


def coulomb_path(mu=MU, h_contact=H_CONTACT):
    """The Coulomb path's problems (one mesh per communicator and facet size)."""
    key = ("mesh", h_contact, COMM.size)
    if key not in _CACHE:
        _CACHE[key] = cases.cattaneo_mindlin_mesh(COMM, h_contact=h_contact)
    return cases.cattaneo_mindlin_path(COMM, mu=mu, mesh=_CACHE[key])


def with_law(problems, law):
    """The same path with another contact law."""
    return [p.with_mesh(p.mesh, p.facet_tags, p.cell_tags, law=law) for p in problems]


def hertz_threshold(h_contact=H_CONTACT):
    """Tresca's threshold mu p(x), Hertz's pressure of the press step (the half-plane's)."""
    with ds.solve(coulomb_path(h_contact=h_contact)[0]) as sol:
        m = cases.measure_cattaneo_mindlin(sol)
    a, p0 = m.a, m.p0

    def s(x):
        return MU * p0 * ufl.sqrt(ufl.max_value(1.0 - x[0] ** 2 / a**2, 1e-2))

    return s


def path_pairs(simple_law, rich_mu=MU, h_contact=H_CONTACT):
    """Per step: (true model difference, estimate, interval, steps' summands, indicator sums).

    ``simple_law(h_contact)`` gives the simpler path's law.
    """
    key = (simple_law.__name__, rich_mu, h_contact, COMM.size)
    if key in _CACHE:
        return _CACHE[key]
    rich = coulomb_path(rich_mu, h_contact)
    _CACHE[key] = model_error_rows(rich, with_law(rich, simple_law(h_contact)))
    return _CACHE[key]


def model_error_rows(rich, simple):
    """Per step of the simpler path ``simple``: the true model difference J(rich path) -
    J(simple path) of the goal ``slide``, the estimate along the path and its interval, its
    steps' summands and the local sums of its cell and facet indicators."""
    truth = []
    ds.solve_path(rich, slide, verbose=False,
                  callback=lambda r, sol, e: truth.append(value(sol))).destroy()
    rows = []

    def judge(record, sol, est):
        k = record.step
        assert len(sol.earlier) == k
        with ds.estimate(sol, slide, model_error=rich[: k + 1]) as e:
            me = e.model
            rows.append({
                "true": truth[k] - value(sol), "eta": me.value, "interval": me.interval,
                "steps": me.steps, "cells": local_sum(me.indicators),
                "facets": local_sum(me.facet_indicators),
            })

    ds.solve_path(simple, slide, callback=judge, verbose=False, keep_steps=True).destroy()
    return rows


def frictionless(h_contact):
    """The simpler law: frictionless."""
    return ds.Frictionless()


def tresca_hertz(h_contact):
    """The simpler law: Tresca with Hertz's threshold mu p(x)."""
    return ds.Tresca(hertz_threshold(h_contact))


@pytest.mark.mpi
@pytest.mark.parametrize("step", [3, 4])
def test_frictionless_path_slipping_steps(step):
    """Measured ieff 0.526, 0.694 on steps 3, 4 (Q / (mu P) = 0.52, 0.69)."""
    row = path_pairs(frictionless)[step]
    assert abs(row["true"]) > 5e-3  # friction holds the contact back by a third
    assert 0.5 <= row["true"] / row["eta"] <= 2.0, row


@pytest.mark.xfail(strict=True, reason=(
    "Coulomb's set test at a frictionless state (a uniform sliding increment) slips everywhere: "
    "(M7) is the effect of full-slip friction, the truth that of a stick zone; effectivity about "
    "Q / (mu P): measured 0.026, 0.182, 0.355 on steps 0, 1, 2 (true -7.95e-5, -2.05e-3, "
    "-4.00e-3 against -3.04e-3, -1.12e-2, -1.12e-2)"))
@pytest.mark.mpi
def test_frictionless_path_sticking_steps():
    """Effectivity in [0.5, 2] on the steps that stick over most of the contact (0, 1, 2)."""
    for row in path_pairs(frictionless)[:3]:
        assert 0.5 <= row["true"] / row["eta"] <= 2.0, row


@pytest.mark.mpi
def test_frictionless_path_interval_holds():
    """hull(0, 2 eta_M) summed over the steps holds J(Coulomb) - J(frictionless) on every step."""
    for row in path_pairs(frictionless):
        low, high = row["interval"]
        assert low <= row["true"] <= high, row


@pytest.mark.mpi
def test_tresca_path_effectivity():
    """Tresca with Hertz's threshold in place of Coulomb on the shear steps: measured ieff
    1.015, 1.022, 1.035, 1.050 on steps 1-4; the interval holds the truth on every step (the
    press step, where the two thresholds hardly differ, true 9.3e-5: ieff 0.569 here, a strict
    xfail on the finer mesh)."""
    check_tresca(path_pairs(tresca_hertz))


def check_tresca(rows):
    """Effectivity in [0.5, 2] on the shear steps, the interval on every step."""
    for row in rows[1:]:
        assert abs(row["true"]) > 1e-3
        assert 0.5 <= row["true"] / row["eta"] <= 2.0, row
    for row in rows:
        low, high = row["interval"]
        assert low <= row["true"] <= high, row


@pytest.mark.slow
@pytest.mark.mpi
def test_finer_mesh():
    """Macro facets of 0.01: frictionless ieff 0.519, 0.686 on steps 3, 4 (0.023, 0.174, 0.348
    on steps 0-2, the sticking miss); Tresca(mu p) 1.017, 1.032, 1.049, 1.053 on steps 1-4; the
    intervals hold the truth on every step."""
    rows = path_pairs(frictionless, h_contact=0.01)
    for row in rows[3:]:
        assert 0.5 <= row["true"] / row["eta"] <= 2.0, row
    for row in rows:
        low, high = row["interval"]
        assert low <= row["true"] <= high, row
    check_tresca(path_pairs(tresca_hertz, h_contact=0.01))


@pytest.mark.xfail(strict=True, reason=(
    "the press step, where Tresca's threshold mu p(x) and Coulomb's mu lambda_n differ only by "
    "the discrete pressure's deviation from Hertz's: true 2.42e-6 against 9.28e-6 (ieff 0.261) "
    "on macro facets of 0.01, 9.28e-5 against 1.63e-4 (0.569) on 0.02"))
@pytest.mark.slow
@pytest.mark.mpi
def test_tresca_press_step_finer_mesh():
    """Effectivity in [0.5, 2] on the press step with macro facets of 0.01."""
    row = path_pairs(tresca_hertz, h_contact=0.01)[0]
    assert 0.5 <= row["true"] / row["eta"] <= 2.0, row


@pytest.mark.mpi
def test_zero_friction_coefficient_is_zero():
    """Coulomb(0) along the path: (M7) and the truth vanish to round-off (relative to the
    estimate with mu = 0.3) on every step, and so does each step's summand."""
    for row, scale in zip(path_pairs(frictionless, rich_mu=0.0), path_pairs(frictionless),
                          strict=True):
        assert max(abs(v) for v in (row["eta"], *row["steps"])) <= 1e-12 * abs(scale["eta"])
        assert abs(row["true"]) <= 1e-10 * abs(scale["eta"]), row


@pytest.mark.mpi
def test_indicators_and_steps_sum_to_the_estimate():
    """The cell and the facet indicators and the steps' summands sum to eta_M."""
    for row in path_pairs(tresca_hertz) + path_pairs(frictionless):
        scale = max(abs(row["eta"]), 1e-14)
        assert abs(row["cells"] - row["eta"]) < 1e-10 * scale
        assert abs(row["facets"] - row["eta"]) < 1e-10 * scale
        assert abs(sum(row["steps"]) - row["eta"]) < 1e-12 * scale


def block_path(law, msh, tags, E=1.0):
    """A block (0, 4) x (0, 0.5) on a rigid plane, its top displaced by a press, a shear that
    slides the whole base, a second press that makes it stick, a small shear."""
    loads = [(0.0, -0.005), (0.03, -0.005), (0.03, -0.01), (0.035, -0.01)]
    return [ds.SignoriniProblem(msh, tags, contact=ex.CONTACT, dirichlet={ex.DIRICHLET: d},
                                E=E, nu=0.3, friction=law) for d in loads]


def block_rows(E=1.0):
    """:func:`model_error_rows` of the block path, Tresca(0.0015 E) in place of Coulomb(0.3)."""
    key = ("block", E, COMM.size)
    if key not in _CACHE:
        msh, tags = block(COMM, 16, 2, lx=4.0, ly=0.5)
        _CACHE[key] = model_error_rows(block_path(ds.Coulomb(0.3), msh, tags, E),
                                       block_path(ds.Tresca(0.0015 * E), msh, tags, E))
    return _CACHE[key]


@pytest.mark.mpi
def test_history_chain_carries_the_earlier_steps():
    """Tresca(s = 0.0015) in place of Coulomb(0.3) on a path whose third step sticks where the
    second slid: the slide that the second step's model error leaves is carried into the third
    step's J by the history goal. Measured ieff 1.000, 1.000, 0.978, 0.938 on steps 0-3; on
    step 2 the earlier steps' terms are -1.21e-2 of -1.51e-2 (the step's own term alone would
    give ieff 5.0)."""
    rows = block_rows()
    for row in rows:
        assert 0.5 <= row["true"] / row["eta"] <= 2.0, rows
        assert row["interval"][0] <= row["true"] <= row["interval"][1], rows
    true, eta, steps = rows[2]["true"], rows[2]["eta"], rows[2]["steps"]
    assert abs(true) > 1e-2
    assert abs(sum(steps[:-1])) > 0.5 * abs(eta)  # the chain carries most of it
    assert not 0.5 <= true / steps[-1] <= 2.0


@pytest.mark.mpi
def test_unit_invariance():
    """E and the threshold times 1000 (the loads displacements): J = int u_x, its model error
    and each step's term unchanged."""
    scale = max(abs(row["eta"]) for row in block_rows())
    for a, b in zip(block_rows(), block_rows(1e3), strict=True):
        for name in ("true", "eta"):
            assert abs(a[name] - b[name]) <= 1e-8 * scale, (a, b)
        assert np.allclose(a["steps"], b["steps"], rtol=0.0, atol=1e-8 * scale)


@pytest.mark.mpi
def test_bad_combinations():
    """A path step against one richer problem, a wrong count, keep_steps on an adaptive path."""
    rich = coulomb_path()[:2]
    simple = with_law(rich, ds.Frictionless())
    with ds.solve_path(simple, slide, verbose=False, keep_steps=True) as res:
        sol = res.solution
        assert len(sol.earlier) == 1
        with pytest.raises(ValueError, match="richer path's problems"):
            ds.estimate(sol, slide, model_error=rich[1])
        with pytest.raises(ValueError, match="3 richer problems for a path of 2 steps"):
            ds.estimate(sol, slide, model_error=[*rich, rich[1]])
        with pytest.raises(ValueError, match="not richer"):
            ds.estimate(sol, slide, model_error=simple)
    with pytest.raises(ValueError, match="keep_steps=True needs every step on one mesh"):
        ds.solve_path(simple, slide, adaptive=True, keep_steps=True, verbose=False)


@pytest.mark.mpi
def test_solve_path_reports_each_steps_model_error(tmp_path):
    """``solve_path(simple, goal, model_error=rich)``: each step's record carries (M7) over the
    steps so far; judged against the truth J(rich path) - J(simple path) of the block path
    (Tresca in place of Coulomb): effectivity in [0.5, 2] and the interval holding the truth on
    every step, and the CSV table has the columns. Measured: true -6.71e-10, -1.281e-2,
    -1.474e-2, -3.168e-2 against -6.71e-10, -1.281e-2, -1.507e-2, -3.376e-2 (ieff 1.000, 1.000,
    0.978, 0.938, the numbers of ``estimate(sol_k, goal, model_error=rich[:k + 1])``)."""
    msh, tags = block(COMM, 16, 2, lx=4.0, ly=0.5)
    rich = block_path(ds.Coulomb(0.3), msh, tags)
    simple = block_path(ds.Tresca(0.0015), msh, tags)
    truth = []
    ds.solve_path(rich, slide, verbose=False,
                  callback=lambda r, sol, e: truth.append(value(sol))).destroy()
    out = tmp_path if COMM.rank == 0 else None
    out = COMM.bcast(out, root=0)
    simple_J = []
    with ds.solve_path(simple, slide, verbose=False, model_error=rich, output_dir=out,
                       callback=lambda r, sol, e: simple_J.append(value(sol))) as res:
        assert len(res.solution.earlier) == len(rich) - 1
        records = res.steps
    for k, r in enumerate(records):
        true = truth[k] - simple_J[k]
        assert 0.5 <= true / r.model_error <= 2.0, (k, true, r.model_error)
        assert r.model_error_low <= true <= r.model_error_high, (k, true, r)
    if COMM.rank == 0:
        header = (tmp_path / "path.csv").read_text().splitlines()[0].split(",")
        assert {"model_error", "model_error_low", "model_error_high"} <= set(header)


@pytest.mark.mpi
def test_solve_path_model_error_bad_input():
    """One richer problem, a wrong count, an adaptive path, a step whose law is not richer."""
    rich = coulomb_path()[:2]
    simple = with_law(rich, ds.Frictionless())
    with pytest.raises(TypeError, match="one per step"):
        ds.solve_path(simple, slide, verbose=False, model_error=rich[1])
    with pytest.raises(ValueError, match="3 richer problems for 2 steps"):
        ds.solve_path(simple, slide, verbose=False, model_error=[*rich, rich[1]])
    with pytest.raises(ValueError, match="model_error needs every step on one mesh"):
        ds.solve_path(simple, slide, verbose=False, adaptive=True, model_error=rich)
    with pytest.raises(ValueError, match=r"step 1: .*not richer"):
        ds.solve_path(simple, slide, verbose=False, model_error=[rich[0], simple[1]])
