"""The adaptive loop at finite strain: solve, estimate, mark and refine a hyperelastic body.

Truths: on every level of an adaptive run the interval contains a reference J computed from
J_h alone on finer uniform meshes (ds.solve, no estimate), and that reference is closer to J
than half the interval is wide; one process and two give the same levels; what the estimate
does not take is refused before the first solve; a level whose Newton method fails from the
previous level's solution raises. Slow: the Neo-Hookean disc pressed by 25 % of its radius,
adaptive against uniform refinement.
"""

import itertools
import json

from mpi4py import MPI

import numpy as np
import pytest

import dwr_signorini as ds
from dwr_signorini import finite_strain
from dwr_signorini.goal import GoalForms
from dwr_signorini.refine import refine_with_tags
from dwr_signorini.semismooth import ConvergenceError

from .problems import from_model
from .test_finite_strain_estimate import GOALS, cylinder_problem, disc_mesh, quarter_disc

#: The quarter disc's mesh size and how far its top is pressed (20 % of the radius).
H, PRESS = 0.25, 0.2


@pytest.fixture(scope="module")
def coarse():
    return from_model(quarter_disc, h=H)


def uniform_values(msh, facets, press, levels):
    """J_h of every goal on the uniform refinements ``levels`` of the mesh (no estimate).

    Two load steps: from zero the Newton method inverts cells of fine meshes.
    """
    out = {}
    for level in range(max(levels) + 1):
        problem = cylinder_problem(msh, facets, press)
        if level in levels:
            with ds.solve_path(problem, None, load_factors=[0.5, 1.0]) as path:
                sol = path.solutions[-1]
                out[level] = {name: GoalForms(goal, sol.u, sol.lam, sol.disc).value()
                              for name, goal in GOALS.items()}
        msh, _, _, facets = refine_with_tags(problem, None)
    return out


@pytest.fixture(scope="module")
def reference(coarse):
    """J of both goals from J_h on uniform level 4 (37888 cells), with |J_4 - J_3| its error."""
    msh, _, facets = coarse
    values = uniform_values(msh, facets, PRESS, (3, 4))
    return {name: (values[4][name], abs(values[4][name] - values[3][name])) for name in GOALS}


def adaptive_rows(msh, facets, goal, max_levels=3, **kwargs):
    """(num_dofs, J_h, eta, J_low, J_high) per level of an adaptive run of the pressed disc."""
    with ds.solve_adaptive(cylinder_problem(msh, facets, PRESS), goal, max_levels=max_levels,
                           verbose=False, **kwargs) as result:
        assert isinstance(result.solution, finite_strain.FiniteStrainSolution)
        return [(r.num_dofs, r.J_h, r.eta, r.J_low, r.J_high, r.newton_iterations)
                for r in result.levels]


@pytest.mark.parametrize("goal", sorted(GOALS))
def test_adaptive_intervals_contain_reference(coarse, reference, goal, tmp_path):
    """Three adaptive levels: each interval contains J from J_h on uniform level 4, the DoFs
    grow, and the table is written as for the linear problem."""
    msh, _, facets = coarse
    J_ref, error = reference[goal]
    out = MPI.COMM_WORLD.bcast(tmp_path, root=0)
    rows = adaptive_rows(msh, facets, GOALS[goal], output_dir=out)
    print(f"\n{goal}: reference {J_ref:.8e} (|J_4 - J_3| = {error:.1e})")
    for level, (dofs, J_h, eta, low, high, newton) in enumerate(rows):
        print(f"level {level} dofs {dofs:5d} J_h {J_h:.8e} eta {eta:+.3e} newton {newton} "
              f"interval ({low:.8e}, {high:.8e}) Ieff {(J_ref - J_h) / eta:.2f}")
        assert low <= J_ref <= high
        assert error < (high - low) / 2  # the reference is finer than the interval
        assert newton >= 1
    dofs = [row[0] for row in rows]
    assert all(b > a for a, b in itertools.pairwise(dofs))
    table = json.loads((out / "adaptive.json").read_text())
    assert [row["J_h"] for row in table["levels"]] == [row[1] for row in rows]


@pytest.mark.mpi
@pytest.mark.parametrize("goal", sorted(GOALS))
def test_one_process_and_two_agree(goal):
    """The same levels (DoFs) and J_h, eta on COMM_WORLD as on COMM_SELF, to 1e-9."""
    rows = {}
    for name, comm in (("self", MPI.COMM_SELF), ("world", MPI.COMM_WORLD)):
        msh, _, facets = disc_mesh(comm, H)
        rows[name] = np.array(adaptive_rows(msh, facets, GOALS[goal]))
    print(goal, rows)
    assert np.array_equal(rows["world"][:, 0], rows["self"][:, 0])
    assert np.allclose(rows["world"][:, 1:3], rows["self"][:, 1:3], rtol=1e-9, atol=0.0)


def test_refused_before_the_first_solve(coarse, monkeypatch):
    """What a finite-strain level would refuse is refused by name before anything is solved."""
    msh, _, facets = coarse
    problem = cylinder_problem(msh, facets, PRESS)

    def no_solve(*args, **kwargs):
        raise AssertionError("solved before the options were checked")

    monkeypatch.setattr(finite_strain, "solve", no_solve)
    goal = GOALS["force"]
    for kwargs, match in (
        ({"weights": "higher_order"}, "higher_order"),
        ({"weights": "hierarchical"}, "hierarchical"),
        ({"model_error": problem}, "model_error"),
        ({"models": [problem, problem], "tol": 1e-3}, "models"),
        ({"petsc_options": {"ksp_type": "preonly"}}, "petsc_options"),
        ({"method": "schur"}, "method"),
    ):
        with pytest.raises(ValueError, match=match):
            ds.solve_adaptive(problem, goal, **kwargs)


def test_failed_level_raises(coarse, monkeypatch):
    """A level whose Newton method fails from the previous level's solution raises, saying so
    (no other start is tried)."""
    msh, _, facets = coarse
    newton, calls = finite_strain.newton, []

    def fails_on_level_1(system, *args):
        calls.append(system)
        if len(calls) == 2:
            raise ConvergenceError("finite strain: no convergence (made to fail)", [])
        return newton(system, *args)

    monkeypatch.setattr(finite_strain, "newton", fails_on_level_1)
    with pytest.raises(ConvergenceError, match="previous level's solution"):
        adaptive_rows(msh, facets, GOALS["force"], max_levels=3)
    assert len(calls) == 2
