"""The model error estimate (dwr_signorini.model_error) against the true model difference.

The truth is J(w_rich) - J(w_simple), both laws solved on the same mesh. The scene: a block
(0, 2) x (0, 1) with its top displaced by (shear, -press), its bottom on a rigid plane, its
sides free. Checked:

* effectivity of the estimate in [0.5, 2] on three levels where friction matters (the block
  slips over most of its base): frictionless -> Coulomb and Tresca -> Coulomb;
* zero where the richer law's extra terms vanish: mu = 0 (Coulomb(0) is frictionless), and a
  block pressed without shear on a mirror-symmetric mesh (J odd in x by symmetry);
* the cell and facet indicators sum to the estimate; a linear goal's estimate is J of one
  Newton step of the richer law (the identity (M1) rests on);
* unit invariance: E and the displacements scaled, the relative model error unchanged;
* bad combinations named.
"""

from mpi4py import MPI

import numpy as np
import pytest
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.goal import GoalForms

from .friction_cases import UniformCase
from .problems import block, from_model, mesh_script, top_clamped_tags

COMM = MPI.COMM_WORLD
PRESS, SHEAR = 0.01, 0.02


def sheared(msh, tags, law, shear=SHEAR, press=PRESS, E=1.0, **kwargs):
    """The block with its top displaced by (shear, -press)."""
    return ds.SignoriniProblem(
        msh, tags, contact=ex.CONTACT, dirichlet={ex.DIRICHLET: (shear, -press)}, E=E,
        nu=0.3, friction=law, **kwargs,
    )


def slide(u, lam, m):
    """The tangential displacement of the base, int u_x."""
    return u[0] * m.ds_contact


def friction_force(u, lam, m, lam_t=None):
    """The tangential force on the base, int lambda_t."""
    return lam_t * m.ds_contact


def value(sol, goal):
    """J at a solution."""
    return GoalForms(goal, sol.u, sol.lam, sol.disc, sol.tangential or None).value()


def model_pair(n, simple_law, rich_law, goal, **kwargs):
    """(true model difference, ModelError) on the 2n x n block."""
    msh, tags = block(COMM, 2 * n, n, lx=2.0, ly=1.0)
    simple, rich = sheared(msh, tags, simple_law, **kwargs), sheared(msh, tags, rich_law, **kwargs)
    with ds.solve(simple) as s, ds.solve(rich) as r:
        true = value(r, goal) - value(s, goal)
        with ds.estimate(s, goal, model_error=rich) as est:
            return true, est.model


def local_sum(f):
    """Sum of a function's owned values over all ranks."""
    n = f.function_space.dofmap.index_map.size_local
    return COMM.allreduce(float(f.x.array[:n].sum()), op=MPI.SUM)


@pytest.mark.mpi
@pytest.mark.parametrize("n", [4, 8, 16])
def test_frictionless_in_place_of_coulomb(n):
    """Measured ieff 0.992, 0.984, 0.979 (mu = 0.5, n = 4, 8, 16)."""
    true, me = model_pair(n, None, ds.Coulomb(0.5), slide)
    assert abs(true) > 1e-2  # friction matters: the base slides 0.037 less
    assert 0.5 <= true / me.value <= 2.0
    low, high = me.interval
    assert low <= true <= high


@pytest.mark.mpi
@pytest.mark.parametrize("n", [4, 8, 16])
def test_tresca_in_place_of_coulomb(n):
    """Tresca with s = mu lambda_n of the frictionless solution; ieff 0.952, 0.812, 0.787."""
    mu = 0.5
    msh, tags = block(COMM, 2 * n, n, lx=2.0, ly=1.0)
    rich = sheared(msh, tags, ds.Coulomb(mu))
    with ds.solve(sheared(msh, tags, None)) as free:
        lam_n = free.lam
        tresca = sheared(msh, tags, ds.Tresca(lambda x: mu * lam_n))
        # on the frictionless solution's discretisation, where lambda_n lives
        with ds.solve(free.disc.for_problem(tresca)) as s, ds.solve(
            free.disc.for_problem(rich)
        ) as r:
            true = value(r, friction_force) - value(s, friction_force)
            with ds.estimate(s, friction_force, model_error=rich) as est:
                me = est.model
    assert abs(true) > 5e-4  # Coulomb's threshold follows lambda_n: about 10 % of the force
    assert 0.5 <= true / me.value <= 2.0


@pytest.mark.mpi
@pytest.mark.parametrize("ratio", [1.1, 2.0, 10.0])
def test_uniform_slip_is_exact(ratio):
    """The uniform slip patch test (exact Coulomb solution, slip a = D_t (1 - 1 / ratio)): the
    richer law's sets at the frictionless state are its final ones, so the estimate is the true
    model difference to round-off and its interval is round-off wide."""
    case = UniformCase("triangle", 0.3, ratio, n=8)
    meshed = case.mesh(COMM)
    rich = case.problem(COMM, None, meshed)
    with ds.solve(case.problem(COMM, ds.Frictionless(), meshed)) as s, ds.solve(rich) as r:
        J_rich = value(r, slide)
        true = J_rich - value(s, slide)
        with ds.estimate(s, slide, model_error=rich) as est:
            me = est.model
    assert abs(J_rich - case.exact()["slip"][0]) <= 1e-10 * case.exact()["shear"][0]
    assert me.num_changed == 0
    assert abs(me.value - true) <= 1e-10 * abs(true)
    low, high = me.interval
    assert low <= true <= high and high - low <= 1e-8 * abs(true)


@pytest.mark.xfail(
    strict=True,
    reason="measured: the uniform stick patch test (ratio 0.5): the estimate predicts slip "
    "with lambda_t = s = 2 tau, ieff 0.495 (true -6.20e-3, estimate -1.254e-2); the interval "
    "hull(0, 2 estimate) holds the truth (test_stick_interval)",
)
def test_uniform_stick_effectivity():
    case = UniformCase("triangle", 0.3, 0.5, n=8)
    meshed = case.mesh(COMM)
    rich = case.problem(COMM, None, meshed)
    with ds.solve(case.problem(COMM, ds.Frictionless(), meshed)) as s, ds.solve(rich) as r:
        true = value(r, slide) - value(s, slide)
        with ds.estimate(s, slide, model_error=rich) as est:
            assert 0.5 <= true / est.model_error <= 2.0


@pytest.mark.mpi
def test_stick_interval():
    """Where the richer law sticks (the block of mu = 0.9 under a small shear), the estimate
    overshoots (ieff 0.126) but its interval hull(0, 2 estimate) holds the truth."""
    true, me = model_pair(4, None, ds.Coulomb(0.9), slide, shear=0.005)
    low, high = me.interval
    assert me.num_changed > 0
    assert low <= true <= high


@pytest.mark.mpi
def test_indicators_sum_and_one_newton_step():
    """Cells and facets sum to the estimate; for a linear J it is J(w^1) - J(w_s^*)."""
    _, me = model_pair(4, None, ds.Coulomb(0.5), slide)
    assert abs(local_sum(me.indicators) - me.value) <= 1e-12 * abs(me.value)
    assert abs(local_sum(me.facet_indicators) - me.value) <= 1e-12 * abs(me.value)
    assert abs(me.newton_step - me.value) <= 1e-8 * abs(me.value)


@pytest.mark.mpi
def test_zero_friction_coefficient_is_zero():
    """Coulomb(0) against frictionless: the estimate vanishes to round-off."""
    true, me = model_pair(4, None, ds.Coulomb(0.0), slide)
    _, scale = model_pair(4, None, ds.Coulomb(0.5), slide)
    assert abs(me.value) <= 1e-12 * abs(scale.value)
    assert abs(true) <= 1e-10 * abs(scale.value)
    assert np.max(np.abs(me.indicators.x.array)) <= 1e-12 * abs(scale.value)


@pytest.mark.mpi
def test_no_shear_is_zero_by_symmetry():
    """Pressed only, on a mesh symmetric about x = 1: int u_x is zero in both models."""
    msh = mesh.create_rectangle(
        COMM, [(0.0, 0.0), (2.0, 1.0)], [8, 4], mesh.CellType.triangle,
        ghost_mode=mesh.GhostMode.none, diagonal=mesh.DiagonalType.crossed,
    )
    tags = top_clamped_tags(msh, 1.0)
    rich = sheared(msh, tags, ds.Coulomb(0.5), shear=0.0)
    with ds.solve(sheared(msh, tags, None, shear=0.0)) as s:
        with ds.estimate(s, slide, model_error=rich) as est:
            me = est.model
    _, scale = model_pair(4, None, ds.Coulomb(0.5), slide)
    assert abs(me.value) <= 1e-10 * abs(scale.value)
    assert np.max(np.abs(me.facet_indicators.x.array)) > 1e-3 * abs(scale.value)  # not trivial


@pytest.mark.mpi
def test_unit_invariance():
    """E x 1000 and the displacements x 10: the model error / J_h unchanged."""
    out = []
    for E, k in ((1.0, 1.0), (1000.0, 10.0)):
        msh, tags = block(COMM, 8, 4, lx=2.0, ly=1.0)
        args = {"shear": SHEAR * k, "press": PRESS * k, "E": E}
        rich = sheared(msh, tags, ds.Coulomb(0.5), **args)
        with ds.solve(sheared(msh, tags, None, **args)) as s:
            with ds.estimate(s, slide, model_error=rich) as est:
                out.append(est.model.value / est.J_h)
    assert abs(out[1] - out[0]) <= 1e-8 * abs(out[0])


@pytest.mark.xfail(
    strict=True,
    reason="measured: mu = 0.9, shear 0.005, the block sticks everywhere under Coulomb while "
    "the richer law's sets at the frictionless solution slip everywhere; ieff 0.126 on "
    "n = 4, 8, 16 (true -1.0e-2, estimate -7.96e-2)",
)
def test_sticking_block_is_a_linearisation_miss():
    true, me = model_pair(4, None, ds.Coulomb(0.9), slide, shear=0.005)
    assert 0.5 <= true / me.value <= 2.0


def test_bad_combinations():
    """Another mesh, a law that is not richer, other data: named errors."""
    msh, tags = block(COMM, 4, 2, lx=2.0, ly=1.0)
    other, other_tags = block(COMM, 4, 2, lx=2.0, ly=1.0)
    with ds.solve(sheared(msh, tags, ds.Coulomb(0.5))) as sol:
        with pytest.raises(ValueError, match="not richer"):
            ds.estimate(sol, slide, model_error=sheared(msh, tags, None))
        with pytest.raises(ValueError, match="not richer"):
            ds.estimate(sol, slide, model_error=sheared(msh, tags, ds.Coulomb(0.9)))
    with ds.solve(sheared(msh, tags, None)) as sol:
        with pytest.raises(ValueError, match="macro mesh"):
            ds.estimate(sol, slide, model_error=sheared(other, other_tags, ds.Coulomb(0.5)))
        with pytest.raises(ValueError, match="'E' differs"):
            ds.estimate(sol, slide, model_error=sheared(msh, tags, ds.Coulomb(0.5), E=2.0))
        with pytest.raises(TypeError, match="SignoriniProblem"):
            ds.estimate(sol, slide, model_error=ds.Coulomb(0.5))


@pytest.mark.mpi
@pytest.mark.parametrize("h_contact", [0.04, 0.02])
def test_hertz_press_friction_matters_little(h_contact):
    """The 2D Hertz press of tests/test_hertz.py with Coulomb(0.3): friction raises the force
    of the prescribed approach by about 1 % (small, as Spence's theory has it; measured 1.02 %
    and 0.90 % with every law in the flat's frame); measured ieff 0.944 and 0.926. The two
    problems are built separately, with equal but distinct obstacles: the same data."""
    module = mesh_script("hertz_2d")
    msh, cells, facets = from_model(module.build, h=0.2, h_contact=h_contact, refine_radius=0.1)

    def press(law):
        return ds.SignoriniProblem(
            msh, facets, contact=module.CONTACT,
            dirichlet={module.TOP: (None, -0.01), module.SYMMETRY: (0.0, None)},
            E=1.0, nu=0.3, gap=ds.obstacles.Plane((0.0, 0.0), (0.0, -1.0)), cell_tags=cells,
            friction=law,
        )

    def force(u, lam, m):
        return lam * m.ds_contact

    rich = press(ds.Coulomb(0.3))
    with ds.solve(press(None)) as s, ds.solve(s.disc.for_problem(rich)) as r:
        J_s = value(s, force)
        true = value(r, force) - J_s
        with ds.estimate(s, force, model_error=rich) as est:
            me = est.model
    assert 0.0 < true < 0.02 * J_s
    assert 0.5 <= true / me.value <= 2.0
    low, high = me.interval
    assert low <= true <= high


@pytest.mark.mpi
def test_adaptive_levels_report_the_model_error(mpi_tmp_path):
    """solve_adaptive(..., model_error=richer): every level's row holds the estimate and its
    interval; against Coulomb solved on each level's mesh, ieff in [0.5, 2] on 3 adaptive
    levels (measured 0.992, 0.987, 0.981 on 256, 504, 1112 cells). The CSV has the columns."""
    msh, tags = block(COMM, 8, 4, lx=2.0, ly=1.0)
    simple, law = sheared(msh, tags, None), ds.Coulomb(0.5)
    truths = []

    def truth(record, sol, est):
        level = sol.disc.problem
        rich = level.with_mesh(level.mesh, level.facet_tags, level.cell_tags, law=law)
        with ds.solve(sol.disc.for_problem(rich)) as r:
            truths.append(value(r, slide) - est.J_h)

    with ds.solve_adaptive(
        simple, slide, max_levels=3, model_error=sheared(msh, tags, law), callback=truth,
        verbose=False,
    ) as res:
        res.to_csv(mpi_tmp_path / "levels.csv")
        rows = res.levels
    assert len(rows) == 3
    for row, true in zip(rows, truths, strict=True):
        assert 0.5 <= true / row.model_error <= 2.0
        assert row.model_error_low <= true <= row.model_error_high
    header = (mpi_tmp_path / "levels.csv").read_text().splitlines()[0].split(",")
    assert {"model_error", "model_error_low", "model_error_high"} <= set(header)
