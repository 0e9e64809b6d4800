"""Mesh and model adaptivity (dwr_signorini.model_choice): solve_adaptive(..., models=[...]).

Truths: the Coulomb law solved on a fine uniform mesh (128 x 64 x 2 cells, its own interval
about 1e-6 wide) for J of the rich model; the mirror symmetry of a block pressed without shear
(int u_x on the base vanishes in both laws); Coulomb solved on the run's own meshes.
"""

from mpi4py import MPI

import pytest
from dolfinx import mesh

import dwr_signorini as ds

from .problems import block, top_clamped_tags
from .test_model_error import sheared, slide, value

COMM = MPI.COMM_WORLD


def reference(mu):
    """J of Coulomb(mu) on the sheared block: J_best and the half-width of its interval."""
    msh, tags = block(COMM, 128, 64, lx=2.0, ly=1.0)
    with ds.solve(sheared(msh, tags, ds.Coulomb(mu))) as s, ds.estimate(s, slide) as e:
        return e.J_best, 0.5 * (e.interval[1] - e.interval[0])


def run(mu, tol, **kwargs):
    """The adaptive run on the 8 x 4 x 2 sheared block with models [frictionless, Coulomb(mu)]."""
    msh, tags = block(COMM, 8, 4, lx=2.0, ly=1.0)
    simple = sheared(msh, tags, None, **kwargs)
    models = [simple, sheared(msh, tags, ds.Coulomb(mu), **kwargs)]
    with ds.solve_adaptive(
        simple, slide, tol=tol, max_levels=5, models=models, verbose=False
    ) as res:
        return res.levels, res.converged


@pytest.mark.mpi
def test_friction_matters_ends_on_coulomb():
    """mu = 0.5: leaving out friction changes J by -0.038 of 0.040: level 0 is solved again
    with Coulomb and the run converges on it; measured J_best 3.117e-3 against the fine
    Coulomb reference 2.973e-3 (tol 2e-4)."""
    tol = 2e-4
    levels, converged = run(0.5, tol)
    assert converged
    assert all(r.model == "coulomb" for r in levels)
    assert all(r.model_error is None for r in levels)  # nothing richer to estimate
    J_ref, width = reference(0.5)
    assert abs(levels[-1].J_best - J_ref) <= tol + width


@pytest.mark.mpi
def test_friction_matters_little_stays_frictionless():
    """mu = 0.002: the model error -1.43e-4 is below 0.5 tol = 2.5e-4: the run stays
    frictionless and its J_best 4.0015e-2 is within tol of Coulomb's fine reference 3.9857e-2,
    as the stopping rule (M3) says; with tol 2e-4 the same level switches to Coulomb."""
    tol = 5e-4
    levels, converged = run(0.002, tol)
    assert converged and all(r.model == "frictionless" for r in levels)
    last = levels[-1]
    bound = max(abs(last.model_error_low), abs(last.model_error_high))
    assert 0.0 < bound <= 0.5 * tol
    assert 0.5 * (last.J_high - last.J_low) + bound <= tol
    J_ref, width = reference(0.002)
    assert abs(last.J_best - J_ref) <= tol + width
    levels, _ = run(0.002, 2e-4)
    assert levels[0].model == "coulomb"


@pytest.mark.mpi
def test_no_shear_stays_frictionless_and_equals_coulomb():
    """Pressed only, mirror-symmetric meshes (uniform refinement keeps the symmetry): int u_x
    on the base is zero in both laws, the model error is round-off: every level frictionless,
    and J_h equals Coulomb's J_h on the same mesh to round-off."""
    msh = mesh.create_rectangle(
        COMM, [(0.0, 0.0), (2.0, 1.0)], [8, 4], mesh.CellType.triangle,
        ghost_mode=mesh.GhostMode.none, diagonal=mesh.DiagonalType.crossed,
    )
    tags = top_clamped_tags(msh, 1.0)
    simple = sheared(msh, tags, None, shear=0.0)
    models = [simple, sheared(msh, tags, ds.Coulomb(0.5), shear=0.0)]
    rich_J = []

    def coulomb(record, sol, est):
        level = sol.disc.problem
        rich = level.with_mesh(level.mesh, level.facet_tags, level.cell_tags,
                               law=ds.Coulomb(0.5))
        with ds.solve(sol.disc.for_problem(rich)) as r:
            rich_J.append(value(r, slide))

    with ds.solve_adaptive(simple, slide, tol=1e-6, refinement="uniform", max_levels=2,
                           models=models, callback=coulomb, verbose=False) as res:
        levels = res.levels
    assert all(r.model == "frictionless" for r in levels)
    for r, J in zip(levels, rich_J, strict=True):
        assert abs(r.J_h - J) <= 1e-12 * 0.01 and abs(r.model_error) <= 1e-12 * 0.01


@pytest.mark.mpi
def test_switch_line_and_table(mpi_tmp_path, capsys):
    """The progress says why a level runs Coulomb; the CSV has the model column."""
    msh, tags = block(COMM, 8, 4, lx=2.0, ly=1.0)
    simple = sheared(msh, tags, None)
    with ds.solve_adaptive(simple, slide, tol=2e-4, max_levels=1, output_dir=mpi_tmp_path,
                           models=[simple, sheared(msh, tags, ds.Coulomb(0.5))]):
        pass
    out = capsys.readouterr().out
    if COMM.rank == 0:
        assert "model error of leaving out friction" in out and "solved again with coulomb" in out
    header = (mpi_tmp_path / "adaptive.csv").read_text().splitlines()
    assert "model" in header[0].split(",")


def test_bad_models():
    """models not starting with the problem, without tol, a law not richer, a bad share."""
    msh, tags = block(COMM, 4, 2, lx=2.0, ly=1.0)
    simple, rich = sheared(msh, tags, None), sheared(msh, tags, ds.Coulomb(0.5))
    with pytest.raises(ValueError, match="first model"):
        ds.solve_adaptive(simple, slide, tol=1e-3, models=[rich, simple])
    with pytest.raises(ValueError, match="needs tol"):
        ds.solve_adaptive(simple, slide, models=[simple, rich])
    with pytest.raises(ValueError, match="not richer"):
        ds.solve_adaptive(simple, slide, tol=1e-3, models=[simple, simple])
    with pytest.raises(ValueError, match="model_share"):
        ds.solve_adaptive(simple, slide, tol=1e-3, models=[simple, rich], model_share=1.5)
    with pytest.raises(TypeError, match="two or more"):
        ds.solve_adaptive(simple, slide, tol=1e-3, models=[simple])
    with pytest.raises(ValueError, match="not both"):
        ds.solve_adaptive(simple, slide, tol=1e-3, models=[simple, rich], model_error=rich)


@pytest.mark.mpi
def test_chain_through_tresca_equals_the_coulomb_run():
    """models = [frictionless, Tresca(0.005), Coulomb(0.5)]: level 0 climbs both steps (model
    errors -3.1e-2 and -6.6e-3, far above 0.5 tol) and the run then is the Coulomb run of
    solve_adaptive(coulomb, ...) itself: the same meshes and J_h to the Newton tolerance."""
    msh, tags = block(COMM, 8, 4, lx=2.0, ly=1.0)
    laws = (None, ds.Tresca(0.005), ds.Coulomb(0.5))
    models = [sheared(msh, tags, law) for law in laws]
    with ds.solve_adaptive(models[0], slide, tol=2e-4, max_levels=3, models=models,
                           verbose=False) as res:
        chain = res.levels
    with ds.solve_adaptive(models[2], slide, tol=2e-4, max_levels=3, verbose=False) as res:
        rich = res.levels
    assert [r.model for r in chain] == ["coulomb"] * len(rich)
    for a, b in zip(chain, rich, strict=True):
        assert a.num_cells == b.num_cells
        assert abs(a.J_h - b.J_h) <= 1e-8 * abs(b.J_h)
