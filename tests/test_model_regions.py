"""Friction per region (dwr_signorini.model_regions, solve_adaptive(..., model_regions=True)).

The scene: a long thin block (0, 4) x (0, 0.5) on a rigid plane, its top displaced by
(0.01, -0.005), Coulomb mu = 0.2 (the base slips everywhere); the goal is the slide of the base
under its first eighth, int_{x < 0.5} u_x. Friction changes J by -1.6e-3 of 3.8e-3, and the
model indicators fall from the goal's end to 0.3 % of their largest at the far end: friction
matters for J near x = 0 only. Truths: J of Coulomb solved on the run's own meshes (the true
model difference of each level) and on a finer mesh; mu = 0, where Coulomb is frictionless.
"""

import json

from mpi4py import MPI

import numpy as np
import pytest
import ufl

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.model_regions import RegionMap, RegionMu, flag_function, regional

from .problems import block
from .test_model_error import value

COMM = MPI.COMM_WORLD
MU = 0.2


def thin(msh, tags, law):
    """The long thin block with its top displaced by (0.01, -0.005)."""
    return ds.SignoriniProblem(
        msh, tags, contact=ex.CONTACT, dirichlet={ex.DIRICHLET: (0.01, -0.005)}, E=1.0,
        nu=0.3, friction=law,
    )


def near_end(u, lam, m):
    """The slide of the base under its first eighth, int_{x < 0.5} u_x."""
    return ufl.conditional(ufl.lt(m.x[0], 0.5), 1.0, 0.0) * u[0] * m.ds_contact


def thin_block(nx=16, ny=2):
    """The macro mesh (0, 4) x (0, 0.5) and its tags."""
    return block(COMM, nx, ny, lx=4.0, ly=0.5)


def rich_J(sol, mu=MU):
    """J_h of Coulomb(mu) on the mesh of ``sol`` (the truth of a level's model error)."""
    level = sol.disc.problem
    rich = level.with_mesh(level.mesh, level.facet_tags, level.cell_tags, law=ds.Coulomb(mu))
    with ds.solve(sol.disc.for_problem(rich)) as r:
        return value(r, near_end)


def owned_midpoints(disc):
    """x of the midpoints of the owned macro contact facets (in the order of Q's dofs)."""
    n_q = disc.Q.dofmap.index_map.size_local
    everywhere = RegionMap.gather(disc, np.zeros(n_q, dtype=bool)).facets.mean(axis=1)[:, 0]
    offset = sum(COMM.allgather(n_q)[: COMM.rank])
    return everywhere[offset : offset + n_q]


@pytest.mark.mpi
def test_mixed_model_error_against_rich():
    """Coulomb on x < 1, frictionless elsewhere: the estimate of J(rich) - J(mixed) against the
    truth (measured ieff 1.000: every facet slips, the Newton step lands on Coulomb); with R
    empty the mixed model is the frictionless one: the same J and the same estimate."""
    msh, tags = thin_block(32, 4)
    rich = thin(msh, tags, ds.Coulomb(MU))
    with ds.solve(thin(msh, tags, None)) as s, ds.estimate(s, near_end, model_error=rich) as e:
        J_simple, frictionless = value(s, near_end), e.model_error
        disc = s.disc
        chi = flag_function(disc, (owned_midpoints(disc) < 1.0).astype(float))
        mixed = disc.for_problem(thin(msh, tags, ds.Coulomb(RegionMu(MU, chi))))
        assert regional(mixed.problem.law)
        with ds.solve(mixed) as x, ds.estimate(x, near_end, model_error=rich) as ex_:
            true = rich_J(x) - value(x, near_end)
            assert 0.0 < abs(true) < abs(rich_J(x) - J_simple)  # R takes part of the change
            assert 0.5 <= true / ex_.model_error <= 2.0
            low, high = ex_.model_error_interval
            assert low <= true <= high
        empty = flag_function(disc, np.zeros_like(owned_midpoints(disc)))
        none = disc.for_problem(thin(msh, tags, ds.Coulomb(RegionMu(MU, empty))))
        with ds.solve(none) as x, ds.estimate(x, near_end, model_error=rich) as e0:
            assert abs(value(x, near_end) - J_simple) <= 1e-10 * abs(J_simple)
            assert abs(e0.model_error - frictionless) <= 1e-8 * abs(frictionless)


def region_run(mu, tol, max_levels=5, **kwargs):
    """The per-region run on the thin block and, per level, J of Coulomb on its mesh."""
    msh, tags = thin_block()
    simple = thin(msh, tags, None)
    truths = []

    def truth(record, sol, est):
        truths.append(rich_J(sol, mu))

    with ds.solve_adaptive(
        simple, near_end, tol=tol, max_levels=max_levels, models=[simple, thin(msh, tags,
        ds.Coulomb(mu))], model_regions=True, callback=truth, **kwargs,
    ) as res:
        return res.levels, res.converged, res.model_map, truths


@pytest.mark.mpi
def test_region_run_reaches_rich_J(capsys):
    """tol 2e-5: the run converges with Coulomb on part of Gamma_C (measured 0, 25, 50, 81 % on
    levels 0-3); its J_best 2.18243e-3 is within tol of Coulomb's J_h 2.17946e-3 on its last
    mesh and of the finer Coulomb reference 2.17855e-3 +- 1.0e-6; on every level that left
    friction out somewhere the estimate of the model error has effectivity in [0.5, 2] (measured
    1.000) and its interval holds the truth."""
    tol = 2e-5
    levels, converged, maps, truths = region_run(MU, tol, max_levels=6)
    assert converged
    assert 0.0 < levels[-1].rich_share < 1.0
    assert [m["share"] for m in maps] == [r.rich_share for r in levels]
    shares = [r.rich_share for r in levels]
    assert shares == sorted(shares) and shares[0] == 0.0
    for r, J_rich in zip(levels, truths, strict=True):
        if r.model_error is None:
            continue
        true = J_rich - r.J_h
        assert 0.5 <= true / r.model_error <= 2.0
        assert r.model_error_low <= true <= r.model_error_high
    last = levels[-1]
    assert abs(last.J_best - truths[-1]) <= tol
    msh, tags = thin_block(128, 16)
    with ds.solve(thin(msh, tags, ds.Coulomb(MU))) as r, ds.estimate(r, near_end) as e:
        reference, width = e.J_best, 0.5 * (e.interval[1] - e.interval[0])
    assert abs(last.J_best - reference) <= tol + width
    out = capsys.readouterr().out
    if COMM.rank == 0:
        assert "model error of leaving out friction" in out and "rich law on" in out


@pytest.mark.mpi
def test_mu_zero_leaves_every_facet_frictionless():
    """mu = 0: Coulomb is frictionless; the model error is exactly zero on every level, R
    stays empty and J_h is Coulomb's on each mesh."""
    levels, _, maps, truths = region_run(0.0, 1e-4, max_levels=2)
    for r, J_rich in zip(levels, truths, strict=True):
        assert r.model == "frictionless" and r.rich_share == 0.0
        assert r.model_error == 0.0
        assert abs(r.J_h - J_rich) <= 1e-10 * abs(J_rich)
    assert all(not any(m["rich"]) for m in maps)


@pytest.mark.mpi
def test_model_map_files(mpi_tmp_path):
    """With output_dir: model_map.json (one map per level, as AdaptiveResult.model_map) and
    model_map.png; the CSV has the rich_share column."""
    levels, _, maps, _ = region_run(MU, 2e-5, max_levels=2, output_dir=mpi_tmp_path,
                                    verbose=False)
    data = json.loads((mpi_tmp_path / "model_map.json").read_text())
    assert [m["rich"] for m in data["levels"]] == [m["rich"] for m in maps]
    assert len(data["levels"]) == len(levels) == 2
    assert (mpi_tmp_path / "model_map.png").stat().st_size > 0
    header = (mpi_tmp_path / "adaptive.csv").read_text().splitlines()[0].split(",")
    assert "rich_share" in header


def test_bad_model_regions():
    """model_regions without models, with Tresca, not a bool."""
    msh, tags = thin_block(4, 1)
    simple = thin(msh, tags, None)
    with pytest.raises(ValueError, match="needs models"):
        ds.solve_adaptive(simple, near_end, tol=1e-3, model_regions=True)
    with pytest.raises(ValueError, match="frictionless, Coulomb"):
        ds.solve_adaptive(simple, near_end, tol=1e-3, model_regions=True,
                          models=[simple, thin(msh, tags, ds.Tresca(0.01))])
    with pytest.raises(TypeError, match="True or False"):
        ds.solve_adaptive(simple, near_end, tol=1e-3, model_regions="yes",
                          models=[simple, thin(msh, tags, ds.Coulomb(MU))])
