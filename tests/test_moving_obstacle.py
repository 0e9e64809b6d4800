"""A rigid obstacle moved between the steps of a frictional load path (obstacle_motion).

The slip is the body's displacement relative to the obstacle, so moving the obstacle by t_k or
the body by -t_k (its prescribed displacement) is one physical motion seen from two frames, and
must give the same tractions, J and estimates (to the solver's tolerance):

* (a) a block pressed by a rigid disc from below: the disc moved up, or the block's top moved
  down (its flat contact face is normal to the motion, so the gap and the contact frame are
  the same in both descriptions; the disc's frame is tilted away from the face's normal, and
  the approach has a tangential part there);
* (a) again with a gap per contact tag (a disc and a flat, each with its own translation);
* (b) a flat moved along its normal against the block moved onto it;
* (c) a tangential drag: a flat (2D) and a cylinder along its axis (3D) dragged sideways under
  a pressed block against the block dragged the other way (the sign of the translation);
* (d) the refusals: another radius, another callable gap, a force-controlled disc.

Measured without the translation in the slip (``path_translations`` returning None), on the
steps after the first: ||lambda_t^A - lambda_t^B|| / ||lambda_t^B|| = 0.041, 0.52, 0.57 and
J 5e-4, 1.3e-3, 2.8e-3 relative for the disc of (a); 0.27, 0.49, 0.66 and J 5e-3, 1.2e-2,
2.1e-2 for the dragged flat of (c). With it: 0 (the same arrays) on 1 rank.

The first step's obstacle is where the slip starts from (there is no step before it): the
paths start with the obstacle touching, before either description moves anything.
"""

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import examples as ex
from dwr_signorini.obstacles import Cylinder, Plane, Sphere

COMM = MPI.COMM_WORLD
R = 1.0
PRESSES = (0.0, 0.004, 0.008, 0.012)


def block(nx=24, ny=8, dim=2):
    """The block [0, 1] x [0, 0.5] (x [0, 0.25] in 3D): contact at y = 0, the top moved."""
    if dim == 2:
        msh = mesh.create_rectangle(COMM, [(0.0, 0.0), (1.0, 0.5)], [nx, ny],
                                    mesh.CellType.triangle, ghost_mode=mesh.GhostMode.none)
    else:
        msh = mesh.create_box(COMM, [(0.0, 0.0, 0.0), (1.0, 0.25, 0.5)], [nx, 2, ny],
                              mesh.CellType.tetrahedron, ghost_mode=mesh.GhostMode.none)
    return msh, ex.tag_block_facets(msh, 0.5)


def path(msh, tags, gaps, tops, law=None, model="plane_strain"):
    """One problem per step: gap ``gaps[k]``, the top's displacement ``tops[k]``."""
    return [ds.SignoriniProblem(msh, tags, contact=ex.CONTACT, dirichlet={ex.DIRICHLET: top},
                                E=10.0, nu=0.3, model=model, gap=gap,
                                friction=law or ds.Coulomb(0.3))
            for gap, top in zip(gaps, tops, strict=True)]


def goal(u, lam, m, lam_t):
    """Frame-invariant: the normal force, a moment of lambda_t and the strain energy."""
    eps = ufl.sym(ufl.grad(u))
    lam_t = lam_t if lam_t.ufl_shape == () else lam_t[0]  # the first tangent in 3D
    return (lam + lam_t * (m.x[0] - 0.4)) * m.ds_contact + ufl.inner(eps, eps) * m.dx


def run(problems):
    """Each step's (lambda_n, lambda_t, J_h, eta, estimate with history)."""
    rows = []

    def keep(record, sol, est):
        rows.append((sol.lam.x.array.copy(), sol.lam_t.x.array.copy(), record.J_h,
                     record.eta))

    with ds.solve_path(problems, goal, weights="patch", callback=keep, verbose=False) as res:
        last = res.steps[-1]
        return rows, (last.estimate, last.eta_history, last.J_low, last.J_high)


def norm(a):
    return np.sqrt(COMM.allreduce(float(a @ a), op=MPI.SUM))


def assert_same_paths(moved, held, rel=1e-8):
    """The two descriptions' tractions, J, eta and the last step's history terms agree."""
    rows_a, last_a = run(moved)
    rows_b, last_b = run(held)
    assert len(rows_a) == len(rows_b)
    for (lam_a, lt_a, J_a, eta_a), (lam_b, lt_b, J_b, eta_b) in zip(rows_a, rows_b,
                                                                     strict=True):
        assert norm(lam_a - lam_b) <= rel * norm(lam_b) + 1e-14
        assert norm(lt_a - lt_b) <= rel * max(norm(lt_b), 1e-3 * norm(lam_b))
        assert J_a == pytest.approx(J_b, rel=rel)
        # eta is a small difference of terms of the size of J: to the solver's tolerance in J
        assert eta_a == pytest.approx(eta_b, rel=1e-6, abs=1e-7 * abs(J_b))
    assert last_a == pytest.approx(last_b, rel=1e-6, abs=1e-7 * abs(rows_b[-1][2]))
    assert norm(rows_b[-1][0]) > 0.0
    return rows_b


@pytest.mark.mpi
def test_disc_moved_up_is_the_block_moved_down():
    """(a) The disc pressed up by d_k (block's top held) against the block's top moved down by
    d_k (the disc held): the same lambda_n, lambda_t, J, eta and history estimate."""
    msh, tags = block()
    zero = [(0.0, 0.0)] * len(PRESSES)
    moved = path(msh, tags, [Sphere((0.5, -R + d), R) for d in PRESSES], zero)
    held = path(msh, tags, [Sphere((0.5, -R), R)] * len(PRESSES),
                [(0.0, -d) for d in PRESSES])
    rows = assert_same_paths(moved, held)
    assert norm(rows[-1][1]) > 0.05 * norm(rows[-1][0])  # a tangential traction to compare


@pytest.mark.mpi
def test_flat_moved_along_its_normal():
    """(b) A flat moved up along its normal against the block moved down onto a held flat.

    The translation has no part along the flat's tangent (its frame), so this holds with or
    without it in the slip: it guards that such a path is accepted and its offsets unchanged."""
    msh, tags = block(16, 6)
    zero = [(0.0, 0.0)] * len(PRESSES)
    moved = path(msh, tags, [Plane((0.3, d), (0.0, -1.0)) for d in PRESSES], zero)
    held = path(msh, tags, [Plane((0.3, 0.0), (0.0, -1.0))] * len(PRESSES),
                [(0.0, -d) for d in PRESSES])
    assert_same_paths(moved, held)


@pytest.mark.mpi
def test_an_obstacle_per_contact_tag():
    """(a) with a gap per contact tag: a disc under the left half of the bottom moved up by d_k
    and a flat under the right half by d_k / 2, against the disc held, the flat moved down by
    d_k / 2 and the top by d_k (each tag's own translation, through the tags' indicators)."""
    msh, halves = block(16, 6)
    contact = (ex.CONTACT, ex.CONTACT + 10)
    facets = halves.indices
    x = mesh.compute_midpoints(msh, 1, facets)[:, 0]
    values = np.where((halves.values == ex.CONTACT) & (x > 0.5), contact[1], halves.values)
    tags = mesh.meshtags(msh, 1, facets, values.astype(np.int32))

    def steps(discs, flats, tops):
        return [ds.SignoriniProblem(msh, tags, contact=contact, dirichlet={ex.DIRICHLET: top},
                                    E=10.0, nu=0.3, gap={contact[0]: d, contact[1]: f},
                                    friction=ds.Coulomb(0.3))
                for d, f, top in zip(discs, flats, tops, strict=True)]

    held_disc = Sphere((0.3, -R), R)
    moved = steps([Sphere((0.3, -R + d), R) for d in PRESSES],
                  [Plane((0.7, 0.5 * d), (0.0, -1.0)) for d in PRESSES],
                  [(0.0, 0.0)] * len(PRESSES))
    held = steps([held_disc] * len(PRESSES),
                 [Plane((0.7, -0.5 * d), (0.0, -1.0)) for d in PRESSES],
                 [(0.0, -d) for d in PRESSES])
    assert_same_paths(moved, held)


DRAG = (0.0, 0.002, 0.004, 0.006)


@pytest.mark.mpi
def test_flat_dragged_sideways():
    """(c) A pressed block, the flat under it dragged by +s_k along x, against the block's top
    moved by -s_k over a held flat: the same tractions (the translation's sign), the block
    sliding on the last steps (|lambda_t| = mu lambda_n somewhere)."""
    msh, tags = block(16, 6)
    moved = path(msh, tags, [Plane((s, 0.0), (0.0, -1.0)) for s in DRAG],
                 [(0.0, -0.01)] * len(DRAG))
    held = path(msh, tags, [Plane((0.0, 0.0), (0.0, -1.0))] * len(DRAG),
                [(-s, -0.01) for s in DRAG])
    rows = assert_same_paths(moved, held)
    lam, lam_t = rows[-1][:2]
    assert COMM.allreduce(float(np.max(lam_t, initial=0.0)), op=MPI.MAX) > 0.0
    assert np.all(np.abs(lam_t) <= 0.3 * lam + 1e-10)


@pytest.mark.slow
@pytest.mark.mpi
def test_cylinder_dragged_along_its_axis():
    """(c) 3D: a cylinder along x under a block, dragged along its axis by +s_k, against the
    block's top moved by -s_k over the held cylinder (the same set at every step, the
    translation only in the slip)."""
    msh, tags = block(4, 2, dim=3)
    axis = (1.0, 0.0, 0.0)
    drag = DRAG[:3]
    moved = path(msh, tags, [Cylinder((s, 0.125, -R), axis, R) for s in drag],
                 [(0.0, 0.0, -0.01)] * len(drag), model="3d")
    held = path(msh, tags, [Cylinder((0.0, 0.125, -R), axis, R)] * len(drag),
                [(-s, 0.0, -0.01) for s in drag], model="3d")
    assert_same_paths(moved, held)


def test_translation_from():
    """The translation between obstacles: a moved point, or None for another shape."""
    assert np.allclose(Sphere((1.0, 2.0), 1.0).translation_from(Sphere((0.0, 0.5), 1.0)),
                       [1.0, 1.5])
    assert Sphere((1.0, 2.0), 1.0).translation_from(Sphere((1.0, 2.0), 1.1)) is None
    assert Sphere((1.0, 2.0), 1.0).translation_from(Plane((1.0, 2.0), (0.0, 1.0))) is None
    axis = (0.0, 0.0, 1.0)
    flipped = Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), 1.0)
    assert np.allclose(Cylinder((1.0, 0.0, 0.0), axis, 1.0).translation_from(flipped),
                       [1.0, 0.0, 0.0])
    assert Cylinder((0.0, 0.0, 0.0), (0.0, 1.0, 1.0), 1.0).translation_from(flipped) is None
    assert Plane((0.0, 1.0), (0.0, 1.0)).translation_from(Plane((0.0, 0.0), (1.0, 1.0))) is None
    psi = lambda x: 0.1 * x[0]  # noqa: E731
    assert np.all(ds.obstacles.Graph(psi).translation_from(ds.obstacles.Graph(psi)) == 0.0)
    assert ds.obstacles.Graph(psi).translation_from(ds.obstacles.Graph(lambda x: x[0])) is None


@pytest.mark.parametrize("second, match", [
    (lambda: Sphere((0.5, -R + 0.004), 1.1 * R), "step 1's gap on contact tag"),
    (lambda: (lambda x: 0.01 * x[0]), "not step 0's"),
    (lambda: 0.0, "translated"),
])
def test_refused_changes(second, match):
    """(d) A frictional step whose obstacle is not the previous one translated is refused
    before the first solve; a frictionless path takes it (no slip)."""
    msh, tags = block(4, 2)
    gaps = [Sphere((0.5, -R), R), second()]
    tops = [(0.0, 0.0)] * 2
    with pytest.raises(ValueError, match=match):
        ds.solve_path(path(msh, tags, gaps, tops), goal, verbose=False)
    problems = path(msh, tags, gaps, tops, law=ds.Frictionless())
    ds.solve_path(problems, lambda u, lam, m: lam * m.ds_contact, weights="patch",
                  verbose=False).destroy()


def test_refused_force_controlled_disc():
    """(d) A force-controlled disc with friction is accepted (its unknown approach enters the
    slip, :mod:`dwr_signorini.force`, ``tests/test_force_friction.py``); a frictional path
    refuses one whose direction changes between steps, or that is given by its position after
    a step under a given force (the previous step's delta would be lost); a force-controlled
    flat approached along its normal has no tangential motion."""
    msh, tags = block(4, 2)
    disc = Sphere((0.5, -R), R, force=0.1, direction=(0.0, 1.0))
    for law in (ds.Coulomb(0.3), ds.Tresca(0.01), ds.Frictionless()):
        assert path(msh, tags, [disc], [(0.0, 0.0)], law=law)[0].force_obstacle is disc
    from dwr_signorini.obstacle_motion import path_translations

    tilted = Sphere((0.5, -R), R, force=0.1, direction=(0.1, 1.0))
    for second in (tilted, Sphere((0.5, -R), R)):
        with pytest.raises(ValueError, match="under a given force"):
            path_translations(path(msh, tags, [disc, second], [(0.0, 0.0)] * 2))
    flat = Plane((0.0, 0.0), (0.0, -1.0), force=0.1)
    assert path_translations(path(msh, tags, [flat, flat], [(0.0, 0.0)] * 2)) == [None, None]
