"""The answer to use, a level without contact, and P2 weights that fit, against the truth.

* a block pressed onto a cylinder without shear: J, the friction force, is 0 by symmetry; on a
  mirror-symmetric mesh J_h and the estimate are round-off, and every level's interval
  [J_low, J_high] contains 0 and J_best (Tresca and Coulomb, serial and 2 ranks); on a mesh
  that is not mirror-symmetric J_h is 0 on the first level too (every facet of Gamma_C sticks)
  and the interval contains 0 there;
* a block lifted off the obstacle: no facet is in contact, and the record and the progress line
  say so;
* ``weights="auto"`` takes the patch weights, and says why, where the P2 weights' predicted
  memory does not fit a (fake) budget, and the P2 weights where it does.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh as dmesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini import weights as auto_weights
from dwr_signorini.linalg import memory
from dwr_signorini.viz.tables import read_rows

from .problems import top_clamped_tags

COMM = MPI.COMM_WORLD
LAWS = {"tresca": lambda: ds.Tresca(0.2), "coulomb": lambda: ds.Coulomb(0.3)}


def pressed_block(law, comm=COMM, nx=8, ny=4, diagonal="crossed", press=0.02, nu=0.3):
    """The block (0, 1) x (0, 1/2) on a cylinder of radius 1 under its centre, its top pressed
    down by ``press`` and not sheared (``press < 0`` lifts it off)."""
    msh = dmesh.create_rectangle(
        comm, [np.array([0.0, 0.0]), np.array([1.0, 0.5])], [nx, ny], dmesh.CellType.triangle,
        ghost_mode=dmesh.GhostMode.none, diagonal=getattr(dmesh.DiagonalType, diagonal),
    )
    return ds.SignoriniProblem(
        msh, top_clamped_tags(msh, 0.5), contact=ex.CONTACT,
        dirichlet={ex.DIRICHLET: (0.0, -press)}, E=10.0, nu=nu, gap=ex.friction_gap(1.0),
        friction=law,
    )


@pytest.mark.mpi
@pytest.mark.parametrize("law", sorted(LAWS))
def test_every_interval_contains_the_zero_of_a_symmetric_block(law):
    goal = ex.goal_friction_force()
    with ds.solve_adaptive(pressed_block(LAWS[law]()), goal, max_levels=3,
                           verbose=False) as res:
        for r in res.levels:
            assert r.J_low <= 0.0 <= r.J_high, (r.level, r.J_h, r.J_low, r.J_high)
            assert r.J_best == pytest.approx(0.5 * (r.J_low + r.J_high), abs=1e-20)
            # J_h and the estimate are round-off of a J of size |lambda_t| ~ 0.1 x |Gamma_C| 1
            assert abs(r.J_h) < 1e-12 and abs(r.J_best) < 1e-12
            assert r.J_high - r.J_low < 1e-9
            assert not r.no_contact and r.num_active > 0


@pytest.mark.mpi
@pytest.mark.parametrize("law", sorted(LAWS))
def test_first_level_of_an_unsymmetric_mesh_contains_the_zero(law):
    """On the "right" diagonal mesh every facet sticks on the first level and J_h is 0 to
    round-off; the patch weights alone estimated -2.6e-5 there (Tresca)."""
    problem = pressed_block(LAWS[law](), nx=17, ny=7, diagonal="right")
    with ds.solve(problem) as sol, ds.estimate(sol, ex.goal_friction_force()) as est:
        J_low, J_high = est.interval
        assert abs(est.J_h) < 1e-12
        assert J_low <= 0.0 <= J_high, (est.J_h, est.weights, est.value, J_low, J_high)
        assert est.weights != "patch" and est.weights_fallback is None
        assert est.J_best == pytest.approx(0.5 * (J_low + J_high), abs=1e-20)


@pytest.mark.mpi
def test_a_level_without_contact_says_so(mpi_tmp_path, capsys):
    problem = pressed_block(LAWS["tresca"](), press=-0.01)
    with ds.solve_adaptive(problem, ex.goal_friction_force(), max_levels=1,
                           output_dir=mpi_tmp_path) as res:
        record = res.levels[0]
        assert record.num_active == 0 and record.no_contact
    rows = read_rows(mpi_tmp_path / "adaptive.csv") if COMM.rank == 0 else None
    if COMM.rank == 0:
        assert "no contact" in capsys.readouterr().out
        assert rows[0]["no_contact"] is True and "J_best" in rows[0]


@pytest.mark.mpi
def test_J_best_of_a_load_path_is_its_interval_centre():
    """A load path adds the history's interval to each step's: J_best moves with it."""
    first = pressed_block(ds.Tresca(0.2), nx=6, ny=3, press=0.01)
    second = ds.SignoriniProblem(
        first.mesh, first.facet_tags, contact=ex.CONTACT,
        dirichlet={ex.DIRICHLET: (0.002, -0.02)}, E=10.0, nu=0.3, gap=first.gap,
        friction=first.law,
    )
    with ds.solve_path([first, second], ex.goal_friction_force(), verbose=False) as res:
        for step in res.steps:
            assert step.J_best == pytest.approx(0.5 * (step.J_low + step.J_high), rel=1e-12)
        assert res.steps[-1].eta_history is not None


@pytest.mark.mpi
@pytest.mark.parametrize(("budget", "weights"), [(10**4, "patch"), (10**12, "hierarchical")])
def test_auto_weights_fall_back_to_patch_where_P2_does_not_fit(
    monkeypatch, caplog, budget, weights
):
    """A nearly incompressible block takes P2 weights on every level, if they fit."""
    monkeypatch.setattr(memory, "MEMORY_BUDGET", budget)
    problem = pressed_block(ds.Tresca(0.2), nx=6, ny=3, nu=0.49)
    with ds.solve(problem) as sol, ds.estimate(sol, ex.goal_friction_force()) as est:
        if COMM.rank == 0:  # one log line, on rank 0
            logged = [r.getMessage() for r in caplog.records if r.name.endswith("estimator")]
            assert logged == ([est.weights_fallback] if weights == "patch" else [])
        assert est.weights == weights
        assert (est.weights_fallback is not None) == (weights == "patch")
        if est.weights_fallback:
            assert "GiB" in est.weights_fallback and "'hierarchical'" in est.weights_fallback
        V2 = est.reconstructor.V2h
        need = auto_weights.p2_weights_memory(V2, "hierarchical")
        assert len(set(COMM.allgather(need))) == 1  # the same decision on every rank
        assert auto_weights.p2_weights_memory(V2, "higher_order") > need > 0
