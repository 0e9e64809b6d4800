"""Problem data of issue 21: boundary conditions, contact zones, materials, obstacles.

Every check has an independent truth: a closed form (uniaxial stress or strain, springs in
series, ray-quadric intersections) or an equivalent problem (a quarter model, a union of gaps).
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

import dwr_signorini as ds
from dwr_signorini import obstacles as ob

from .problems import estimate_rel, from_model, mesh_script

COMM = MPI.COMM_WORLD


def tagged(msh, parts, dim=None):
    """Tags of the boundary facets (or, with ``dim``, of the entities) where ``f(x)`` holds."""
    dim = msh.topology.dim - 1 if dim is None else dim
    msh.topology.create_connectivity(msh.topology.dim - 1, msh.topology.dim)
    idx, val = [], []
    for tag, where in parts.items():
        if dim == msh.topology.dim:
            e = dmesh.locate_entities(msh, dim, where)
        else:
            e = dmesh.locate_entities_boundary(msh, dim, where)
        idx.append(e)
        val.append(np.full(len(e), tag, dtype=np.int32))
    idx, val = np.concatenate(idx), np.concatenate(val)
    order = np.argsort(idx, kind="stable")
    return dmesh.meshtags(msh, dim, idx[order].astype(np.int32), val[order])


def box_2d(nx=4, ny=4, height=1.0, comm=COMM):
    msh = dmesh.create_rectangle(
        comm, [[0.0, 0.0], [1.0, height]], [nx, ny], ghost_mode=dmesh.GhostMode.none
    )
    tags = tagged(msh, {
        1: lambda x: np.isclose(x[1], 0.0),
        2: lambda x: np.isclose(x[1], height),
        3: lambda x: np.isclose(x[0], 0.0),
        4: lambda x: np.isclose(x[0], 1.0),
    })
    return msh, tags


def box_3d(n=2, lower=(0.0, 0.0), cell=dmesh.CellType.tetrahedron, nz=None):
    msh = dmesh.create_box(
        COMM, [[lower[0], lower[1], 0.0], [1.0, 1.0, 1.0]], [n, n, nz or n], cell,
        ghost_mode=dmesh.GhostMode.none,
    )
    tags = tagged(msh, {
        1: lambda x: np.isclose(x[2], 0.0),
        2: lambda x: np.isclose(x[2], 1.0),
        3: lambda x: np.isclose(x[0], lower[0]),
        4: lambda x: np.isclose(x[1], lower[1]),
        5: lambda x: np.isclose(x[0], 1.0),
        6: lambda x: np.isclose(x[1], 1.0),
    })
    return msh, tags


def total(sol, expr_of_m):
    m = sol.disc.m
    return COMM.allreduce(fem.assemble_scalar(sol.disc.form(expr_of_m(sol, m))), op=MPI.SUM)


def contact_force(sol):
    return total(sol, lambda s, m: s.lam * m.ds_contact)


def lam_range(sol):
    n = sol.disc.Q.dofmap.index_map.size_local
    a = sol.lam.x.array[:n]
    lo = COMM.allreduce(float(np.min(a, initial=np.inf)), op=MPI.MIN)
    hi = COMM.allreduce(float(np.max(a, initial=-np.inf)), op=MPI.MAX)
    return lo, hi


def force_goal(u, lam, m):
    return lam * m.ds_contact


def energy_goal(u, lam, m):
    return ufl.inner(u, u) * m.dx


# -- contact patch tests ------------------------------------------------------------------------

D, G0, E, NU = 0.01, 0.002, 10.0, 0.3


@pytest.mark.mpi
@pytest.mark.parametrize("model", ["plane_strain", "plane_stress"])
def test_patch_2d_uniform_pressure(model):
    """Block pressed by u_y = -D on top onto a plane at gap G0, symmetry plane u_x = 0:
    uniaxial stress, p = E' (D - G0) / L with E' = E / (1 - nu^2) in plane strain."""
    msh, tags = box_2d()
    problem = ds.SignoriniProblem(
        msh, tags, contact=1, dirichlet={2: (None, -D), 3: (0.0, None)}, E=E, nu=NU,
        model=model, gap=ob.Plane((0.0, -G0), (0.0, -1.0)),
    )
    E_eff = E / (1 - NU**2) if model == "plane_strain" else E
    p = E_eff * (D - G0)
    with ds.solve(problem) as sol:
        lo, hi = lam_range(sol)
        assert lo == pytest.approx(p, rel=1e-12) and hi == pytest.approx(p, rel=1e-12)
        uy = sol.u.x.array.reshape(-1, 2)[:, 1]
        y = sol.u.function_space.tabulate_dof_coordinates()[:, 1]
        assert np.allclose(uy, -G0 - (D - G0) * y, rtol=0, atol=1e-14)
        with ds.estimate(sol, force_goal) as est:
            assert est.J_h == pytest.approx(p, rel=1e-12)
            assert abs(est.eta) <= 1e-12 * p and abs(est.eta_p) <= 1e-12 * p


@pytest.mark.mpi
@pytest.mark.parametrize("top", ["component", "callable"])
def test_patch_3d_uniform_pressure(top):
    """3D block on symmetry planes x = 0, y = 0: p = E (D - G0) / L; the top is prescribed
    u_z = -D only, or all components by the exact (linear) uniaxial-stress field."""
    msh, tags = box_3d()
    s = D - G0
    if top == "component":
        top_value = (None, None, -D)
    else:
        def top_value(x):
            return ufl.as_vector([NU * s * x[0], NU * s * x[1], -D + 0.0 * x[0]])
    problem = ds.SignoriniProblem(
        msh, tags, contact=1, dirichlet={2: top_value, 3: (0.0, None, None),
                                         4: (None, 0.0, None)},
        E=E, nu=NU, gap=ob.Plane((0.0, 0.0, -G0), (0.0, 0.0, -1.0)),
    )
    with ds.solve(problem) as sol:
        lo, hi = lam_range(sol)
        assert lo == pytest.approx(E * s, rel=1e-11) and hi == pytest.approx(E * s, rel=1e-11)
        x = sol.u.function_space.tabulate_dof_coordinates()
        exact = np.stack([NU * s * x[:, 0], NU * s * x[:, 1], -G0 - s * x[:, 2]], axis=1)
        assert np.allclose(sol.u.x.array.reshape(-1, 3), exact, rtol=0, atol=1e-13)
        with ds.estimate(sol, force_goal) as est:
            assert abs(est.eta) <= 1e-11 * E * s


@pytest.mark.mpi
def test_two_materials_in_series():
    """Lower half E1, upper half E2 (cell tags), rollers u_x = 0 on both sides (uniaxial
    strain): the pressure of springs in series, p = delta / (L1 / M1 + L2 / M2), exactly;
    c_n = E / H uses the modulus of the cell at each contact facet."""
    msh, tags = box_2d(4, 4, height=2.0)
    cells = tagged(msh, {7: lambda x: x[1] <= 1.0 + 1e-12, 8: lambda x: x[1] >= 1.0 - 1e-12},
                   dim=2)
    E1, E2 = 10.0, 40.0
    problem = ds.SignoriniProblem(
        msh, tags, contact=1, dirichlet={2: (None, -D), 3: (0.0, None), 4: (0.0, None)},
        E={7: E1, 8: E2}, nu=NU, cell_tags=cells, gap=G0,
    )

    def modulus(E_):
        return E_ * (1 - NU) / ((1 + NU) * (1 - 2 * NU))

    p = (D - G0) / (1.0 / modulus(E1) + 1.0 / modulus(E2))
    with ds.solve(problem) as sol:
        lo, hi = lam_range(sol)
        assert lo == pytest.approx(p, rel=1e-12) and hi == pytest.approx(p, rel=1e-12)
        H = 0.25
        assert np.allclose(sol.system.c_n, E1 / H, rtol=1e-13)
        # The fine mesh carries the parents' tags: E on T_h integrates to E1 + E2 (per unit).
        E_h, _ = sol.disc.fields.material(sol.disc.m.x)
        assert total(sol, lambda s, m: E_h * m.dx) == pytest.approx(E1 + E2, rel=1e-13)
        # The problem holds no data per fine mesh: there, per-tag data are the fields'.
        with pytest.raises(ValueError, match=r"use m\.sigma\(u\)"):
            problem.sigma(sol.u)
        with pytest.raises(AttributeError, match="frozen"):
            problem.E = E1
    E_H, _ = problem.material(ufl.SpatialCoordinate(msh))  # on T_H: its own cell tags
    assert E_H.function_space.mesh is msh
    # Uniform refinement: the next level's T_H is T_h, with the discretisation's cell tags.
    with ds.solve_adaptive(problem, force_goal, refinement="uniform", max_levels=2,
                           verbose=False) as res:
        assert len(res.levels) == 2
        lo, hi = lam_range(res.solution)
        assert lo == pytest.approx(p, rel=1e-12) and hi == pytest.approx(p, rel=1e-12)


def test_quarter_model_equals_full_model():
    """Hexahedral block pressed onto a ball: the quarter model with symmetry planes gives a
    quarter of the full model's contact force and of its J = int |u|^2."""
    obstacle = ob.Sphere((0.0, 0.0, -3.0), 3.0)
    results = []
    for lower, n, sym in (((-1.0, -1.0), 4, False), ((0.0, 0.0), 2, True)):
        msh, tags = box_3d(n, lower, dmesh.CellType.hexahedron, nz=2)
        bcs = {2: (0.0, 0.0, -3 * D)}
        if sym:
            bcs.update({3: (0.0, None, None), 4: (None, 0.0, None)})
        problem = ds.SignoriniProblem(msh, tags, contact=1, dirichlet=bcs, E=E, nu=NU,
                                      gap=obstacle)
        with ds.solve(problem) as sol:
            with ds.estimate(sol, energy_goal) as est:
                results.append((contact_force(sol), est.J_h, sol.num_active))
    (F_full, J_full, a_full), (F_q, J_q, a_q) = results
    assert 0 < a_q < 4 * 4 and a_full == 4 * a_q
    assert F_q == pytest.approx(F_full / 4, rel=1e-10)
    assert J_q == pytest.approx(J_full / 4, rel=1e-10)


@pytest.mark.mpi
def test_two_contact_tags_equal_union():
    """Bottom split in two tags with two planes at different heights: the same solution as one
    tag whose gap is the piecewise union of the two obstacles' gaps. (Planes of one normal: a
    curved obstacle's contact frame is its own normal, a function gap's the body's.)"""
    msh = dmesh.create_rectangle(COMM, [[0.0, 0.0], [1.0, 1.0]], [4, 4],
                                 ghost_mode=dmesh.GhostMode.none)
    left = lambda x: np.isclose(x[1], 0.0) & (x[0] <= 0.5 + 1e-12)  # noqa: E731
    right = lambda x: np.isclose(x[1], 0.0) & (x[0] >= 0.5 - 1e-12)  # noqa: E731
    top = lambda x: np.isclose(x[1], 1.0)  # noqa: E731
    plane = ob.Plane((0.0, -0.004), (0.0, -1.0))
    disc = ob.Plane((0.0, -0.001), (0.0, -1.0))  # the same normal: the same contact frame
    bcs = {2: (0.0, -D)}
    split = ds.SignoriniProblem(msh, tagged(msh, {1: left, 5: right, 2: top}), contact=(1, 5),
                                dirichlet=bcs, E=E, nu=NU, gap={1: plane, 5: disc})

    def union(x):
        n = ufl.FacetNormal(ufl.domain.extract_unique_domain(x))
        miss = split.miss_gap
        return ufl.conditional(ufl.lt(x[0], 0.5), plane.gap(x, n, miss), disc.gap(x, n, miss))

    one = ds.SignoriniProblem(msh, tagged(msh, {1: lambda x: np.isclose(x[1], 0.0), 2: top}),
                              contact=1, dirichlet=bcs, E=E, nu=NU, gap=union)
    out = []
    for problem in (split, one):
        with ds.solve(problem) as sol, ds.estimate(sol, energy_goal) as est:
            out.append((contact_force(sol), est.J_h, est.eta, sol.num_active,
                        sol.u.x.array.copy()))
            if problem is split:  # the gap per tag needs the discretisation's indicators
                with pytest.raises(ValueError, match=r"disc\.fields"):
                    split.gap_expr(sol.disc.m.x)
    assert 0 < out[0][3] < 8 and out[0][3] == out[1][3]
    for a, b in zip(out[0][:3], out[1][:3], strict=True):
        assert a == pytest.approx(b, rel=1e-10, abs=1e-15)
    assert np.allclose(out[0][4], out[1][4], rtol=0, atol=1e-14)


# -- obstacles against closed forms -------------------------------------------------------------

MISS = 123.0


def gap_at(obstacle, x, n):
    return float(obstacle.gap(ufl.as_vector(list(map(float, x))),
                              ufl.as_vector(list(map(float, n))), MISS))


def test_plane_gap():
    plane = ob.Plane((0.0, 0.0, -1.0), (0.0, 0.0, -2.0))
    assert gap_at(plane, (0.3, 0.2, 0.0), (0.0, 0.0, -1.0)) == pytest.approx(1.0)
    c = np.cos(0.3)
    n = (np.sin(0.3), 0.0, -c)
    assert gap_at(plane, (0.3, 0.2, 0.0), n) == pytest.approx(1.0 / c)
    assert gap_at(plane, (0.0, 0.0, -1.5), (0.0, 0.0, -1.0)) == pytest.approx(-0.5)  # inside
    assert gap_at(plane, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)) == MISS  # parallel
    assert gap_at(plane, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)) == MISS  # away


@pytest.mark.parametrize("dim", [2, 3])
def test_sphere_gap(dim):
    R, c = 2.0, np.array([1.0, -3.0, 0.5])[:dim]
    ball = ob.Sphere(c, R)
    x = c + np.eye(dim)[1] * 3.0  # at distance 3 above the center
    n = -np.eye(dim)[1]
    assert gap_at(ball, x, n) == pytest.approx(1.0)
    # An oblique ray through the point at height 3, horizontal offset b from the center line:
    # entry at t = (3 cos a + b sin a) - sqrt(R^2 - (3 sin a - b cos a)^2) (closed form).
    a, b = 0.2, 0.4
    xo = c + np.eye(dim)[1] * 3.0 + np.eye(dim)[0] * b
    no = -np.cos(a) * np.eye(dim)[1] - np.sin(a) * np.eye(dim)[0]
    t = (3 * np.cos(a) + b * np.sin(a)) - np.sqrt(R**2 - (3 * np.sin(a) - b * np.cos(a)) ** 2)
    assert gap_at(ball, xo, no) == pytest.approx(t, rel=1e-14)
    assert gap_at(ball, c + np.eye(dim)[1] * 1.5, n) == pytest.approx(-0.5)  # inside
    assert gap_at(ball, x, np.eye(dim)[0]) == MISS  # passes beside
    assert gap_at(ball, x, -n) == MISS  # away


def test_cylinder_gap():
    cyl = ob.Cylinder((0.0, 0.0, -2.0), (1.0, 0.0, 0.0), 1.5)
    assert gap_at(cyl, (7.0, 0.0, 0.0), (0.0, 0.0, -1.0)) == pytest.approx(0.5)
    a = 0.3  # a ray tilted along the axis travels 0.5 / cos(a)
    assert gap_at(cyl, (0.0, 0.0, 0.0), (np.sin(a), 0.0, -np.cos(a))) == pytest.approx(
        0.5 / np.cos(a), rel=1e-14)
    assert gap_at(cyl, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)) == MISS  # parallel to the axis
    assert gap_at(cyl, (0.0, 0.0, -1.0), (0.0, 0.0, -1.0)) == pytest.approx(-0.5)  # inside
    assert gap_at(cyl, (0.0, 2.0, 0.0), (0.0, 0.0, -1.0)) == MISS  # beside


def test_graph_gap():
    graph = ob.Graph(lambda x: 1.0 + 0.1 * x[0] ** 2, axis=1)
    assert gap_at(graph, (2.0, 0.5), (0.0, 1.0)) == pytest.approx(0.9)
    s = 1 / np.sqrt(2)
    assert gap_at(graph, (2.0, 0.5), (s, s)) == pytest.approx(0.9 * s)  # paper's formula
    assert gap_at(graph, (2.0, 0.5), (1.0, 0.0)) == MISS
    assert gap_at(graph, (0.0, 1.5), (0.0, 1.0)) == pytest.approx(-0.5)


def test_obstacle_on_the_mesh_integrates_the_closed_form():
    """The gap of a disc under a flat bottom, integrated over Gamma_C: int (y_c + R - sqrt(R^2 -
    x^2)) dx in closed form (the UFL expression at the quadrature points with m.n)."""
    msh, tags = box_2d()
    R, yc = 2.0, -2.5
    problem = ds.SignoriniProblem(msh, tags, contact=1, dirichlet=(2,), E=E, nu=NU,
                                  gap=ob.Sphere((0.0, yc), R))
    disc = ds.discretize(problem)
    m = disc.m
    form = fem.form(problem.gap_expr(m.x, m.n) * m.ds_contact(metadata={"quadrature_degree": 20}))
    value = COMM.allreduce(fem.assemble_scalar(form), op=MPI.SUM)
    # int_0^1 (-yc - sqrt(R^2 - x^2)) dx
    exact = -yc - 0.5 * (np.sqrt(R**2 - 1) + R**2 * np.arcsin(1 / R))
    assert value == pytest.approx(exact, rel=1e-10)
    assert problem.gap_expr(m.x) is not None  # the default normal is m.n


# -- bad input ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def square():
    return box_2d(2, 2)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"dirichlet": {2: (0.0, 0.0, 0.0)}}, ValueError, r"dirichlet\[2\] must have 2"),
        ({"dirichlet": {2: (0.0, "a")}}, TypeError, r"dirichlet\[2\]\[1\] must be a number"),
        ({"dirichlet": {2: (None, None)}}, ValueError, r"dirichlet\[2\] prescribes no"),
        ({"dirichlet": {1: 0.0}}, ValueError, "contact.*dirichlet"),
        ({"dirichlet": {2: "x"}}, TypeError, r"dirichlet\[2\] must be"),
        ({"contact": (1, 1)}, ValueError, "contact names a tag twice"),
        ({"contact": (1, 9)}, ValueError, "contact tag 9"),
        ({"E": {7: 1.0}}, ValueError, "E is given per cell tag.*cell_tags"),
        ({"E": lambda x: 1.0 - x[0] * 2.0}, ValueError, r"E\(x\) must be > 0"),
        ({"nu": lambda x: 0.3 + x[1]}, ValueError, r"nu\(x\) must be in \(-1, 0.5\)"),
        ({"nu": {7: 0.7}}, ValueError, "nu is given per cell tag"),
        ({"gap": ob.Sphere((0.0, 0.0, 0.0), 1.0)}, ValueError, "gap: a 3D obstacle"),
        ({"gap": ob.Cylinder((0, 0, 0), (1, 0, 0), 1.0)}, ValueError, "gap: a 3D obstacle"),
        ({"contact": (1, 3), "dirichlet": (2,), "gap": {1: 0.0}}, ValueError,
         r"gap is given per contact tag but misses .*\[3\]"),
        ({"gap": {1: 0.0, 4: 0.0}}, ValueError, "gap has tag"),
        ({"gap": "far"}, TypeError, "gap must be"),
        ({"boundary_projection": {4: 1.0}}, TypeError, r"boundary_projection\[4\]"),
    ],
)
def test_bad_input(square, kwargs, error, match):
    msh, tags = square
    args = {"contact": 1, "dirichlet": (2,), "E": E, "nu": NU} | kwargs
    with pytest.raises(error, match=match):
        ds.SignoriniProblem(msh, tags, **args)


def test_cell_tags_must_cover_the_cells(square):
    msh, tags = square
    cells = tagged(msh, {7: lambda x: x[1] <= 0.5 + 1e-12}, dim=2)
    with pytest.raises(ValueError, match=r"E is given for cell tags \[7\], but \d+ cells"):
        ds.SignoriniProblem(msh, tags, contact=1, dirichlet=(2,), E={7: 1.0}, cell_tags=cells)


def test_overlapping_contact_tags(square):
    msh, _ = square
    tags = tagged(msh, {1: lambda x: np.isclose(x[1], 0.0), 5: lambda x: x[1] < 1e-12,
                        2: lambda x: np.isclose(x[1], 1.0)})
    with pytest.raises(ValueError, match=r"contact tags .* overlap"):
        ds.SignoriniProblem(msh, tags, contact=(1, 5), dirichlet=(2,))


def test_material_callables_at_quadrature_points(square):
    """A modulus that is positive at the vertices but not at interior quadrature points is
    caught (the check runs where the forms evaluate it), and a valid one solves."""
    msh, tags = square
    # 1 at every vertex of the 2 x 2 mesh (x in {0, 0.5, 1}), -1 at x = 0.25
    bump = lambda x: 1.0 - 2.0 * ufl.sin(2.0 * ufl.pi * x[0]) ** 2  # noqa: E731
    with pytest.raises(ValueError, match=r"E\(x\) must be > 0 .* ranges over \[-"):
        ds.SignoriniProblem(msh, tags, contact=1, dirichlet=(2,), E=bump)
    problem = ds.SignoriniProblem(msh, tags, contact=1, dirichlet={2: (0.0, -D)},
                                  E=lambda x: E * (1.0 + x[0]), nu=lambda x: 0.2 + 0.1 * x[1])
    with ds.solve(problem) as sol:
        assert sol.num_active > 0


def test_callable_modulus_uniaxial_strain():
    """E(y) = E (1 + y) in uniaxial strain: p = delta M0 / ln 2, to the discretisation error."""
    msh, tags = box_2d(2, 8)
    problem = ds.SignoriniProblem(
        msh, tags, contact=1, dirichlet={2: (None, -D), 3: (0.0, None), 4: (0.0, None)},
        E=lambda x: E * (1.0 + x[1]), nu=NU, gap=G0,
    )
    M0 = E * (1 - NU) / ((1 + NU) * (1 - 2 * NU))
    with ds.solve(problem) as sol:
        lo, hi = lam_range(sol)
        assert hi - lo <= 1e-12 * hi
        assert lo == pytest.approx((D - G0) * M0 / np.log(2.0), rel=2e-4)


# -- gmsh meshes, read_mesh and curved boundaries -----------------------------------------------





def measure(msh, tags, tag, dim):
    m = ufl.Measure("dx" if dim == msh.topology.dim else "ds", domain=msh, subdomain_data=tags)
    one = fem.Constant(msh, 1.0)
    return COMM.allreduce(fem.assemble_scalar(fem.form(one * m(tag))), op=MPI.SUM)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("script", "builder", "kwargs", "sizes"),
    [
        ("paper_examples", "analytic_2d", {"h": 0.5}, {"dx": 6.0, 1: 2.0, 2: 6.0, 3: 2.0}),
        ("paper_examples", "bar_2d", {"h": 0.025}, {"dx": 0.01, 1: 0.05, 3: 0.05}),
        ("paper_examples", "obstacle_3d", {"h": 0.25}, {"dx": 0.25, 1: 1.0, 3: 0.25}),
        ("hertz_2d", "build", {"h": 0.2, "h_contact": 0.05},
         {"dx": (np.pi / 4, 5e-3), 1: (np.pi / 2, 2e-3), 2: 1.0, 3: 1.0}),
        ("hertz_3d", "build", {"h": 0.4, "h_contact": 0.2},
         {"dx": (np.pi / 6, 5e-2), 2: (np.pi / 4, 5e-2), 3: (np.pi / 4, 5e-2)}),
        ("curved_3d", "build", {"h": 0.3}, {"dx": (np.pi / 4, 5e-2), 2: 1.0, 3: 1.0}),
    ],
)
def test_gmsh_meshes_read_with_tags(script, builder, kwargs, sizes):
    """Every mesh script builds named groups that read_mesh returns as tags: the measures of
    the body and of its tagged faces against the exact ones (polygonal ones within h^2)."""
    module = mesh_script(script)
    msh, cell_tags, facet_tags = from_model(getattr(module, builder), **kwargs)
    assert msh.topology.index_map(msh.topology.dim).num_ghosts == 0
    for key, exact in sizes.items():
        exact, rel = exact if isinstance(exact, tuple) else (exact, 1e-12)
        if key == "dx":
            value = measure(msh, cell_tags, 1, msh.topology.dim)
        else:
            value = measure(msh, facet_tags, key, msh.topology.dim - 1)
        assert value == pytest.approx(exact, rel=rel)


def test_read_mesh_from_file(tmp_path):
    gmsh = pytest.importorskip("gmsh")
    path = COMM.bcast(str(tmp_path / "hertz_2d.msh") if COMM.rank == 0 else None, root=0)
    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        mesh_script("hertz_2d").build(gmsh.model, h=0.3, h_contact=0.1)
        gmsh.write(path)
        gmsh.finalize()
    msh, _, facets = ds.read_mesh(path, COMM)
    assert msh.geometry.dim == 2 and sorted(set(facets.values)) == [1, 2, 3]
    with pytest.raises(FileNotFoundError, match="no mesh file"):
        ds.read_mesh(str(tmp_path / "missing.msh"), COMM)


def hertz_2d_problem(projection, h=0.2, h_contact=0.05):
    module = mesh_script("hertz_2d")
    msh, cells, facets = from_model(module.build, h=h, h_contact=h_contact)
    return module, ds.SignoriniProblem(
        msh, facets, contact=module.CONTACT,
        dirichlet={module.TOP: (None, -0.002), module.SYMMETRY: (0.0, None)},
        E=1.0, nu=0.3, gap=ob.Plane((0.0, 0.0), (0.0, -1.0)), cell_tags=cells,
        boundary_projection=module.projections() if projection else None,
    )


@pytest.mark.mpi
def test_boundary_projection_puts_new_vertices_on_the_circle():
    """After refine_marked the contact vertices of T_H lie on the circle (without projection
    the new ones stay on the chords), T_h is the uniform refinement of that T_H, and the
    area converges to the disc's pi/4 at the rate of the projected mesh."""
    from dwr_signorini.refine import refine_marked

    areas = {}
    for projection in (False, True):
        module, problem = hertz_2d_problem(projection)
        for _ in range(2):
            problem, _ = refine_marked(problem, None)
        msh = problem.mesh
        nodes = np.unique(dmesh.entities_to_geometry(
            msh, 1, problem.facet_tags.find(module.CONTACT), False))
        r = np.linalg.norm(msh.geometry.x[nodes] - [0.0, 1.0, 0.0], axis=1)
        err = COMM.allreduce(float(np.max(np.abs(r - 1.0), initial=0.0)), op=MPI.MAX)
        assert (err < 1e-14) if projection else (err > 1e-4)
        areas[projection] = measure(msh, problem.cell_tags, 1, 2)
        disc = ds.discretize(problem)
        assert disc.num_cells == 4 * disc.num_macro_cells
    assert abs(areas[True] - np.pi / 4) < abs(areas[False] - np.pi / 4) / 10


def test_boundary_projection_refuses_to_invert_cells():
    """A move within the allowed share of the local mesh size that still inverts a cell: flat
    cells (0.25 x 0.1, after refinement 0.125 x 0.05) whose new bottom vertices rise by 0.06."""
    from dwr_signorini.refine import refine_marked

    msh = dmesh.create_rectangle(COMM, [[0.0, 0.0], [1.0, 0.1]], [4, 1],
                                 ghost_mode=dmesh.GhostMode.none)
    tags = tagged(msh, {1: lambda x: np.isclose(x[1], 0.0), 2: lambda x: np.isclose(x[1], 0.1)})
    problem = ds.SignoriniProblem(
        msh, tags, contact=1, dirichlet=(2,),
        boundary_projection={1: lambda x: x + np.array([[0.0], [0.06], [0.0]])},
    )
    with pytest.raises(RuntimeError, match=r"boundary_projection\[1\].*invert"):
        refine_marked(problem, None)


def _all_of_it(comm):
    """A prescribed displacement, a symmetry plane, two materials and a disc obstacle."""
    msh, tags = box_2d(4, 4, comm=comm)
    cells = tagged(msh, {7: lambda x: x[1] <= 0.5 + 1e-12, 8: lambda x: x[1] >= 0.5 - 1e-12},
                   dim=2)
    return ds.SignoriniProblem(
        msh, tags, contact=1, dirichlet={2: (None, -0.02), 3: (0.0, None)},
        E={7: 10.0, 8: 40.0}, nu=0.3, cell_tags=cells, gap=ob.Sphere((0.0, -3.0), 3.0),
    )


@pytest.mark.mpi
def test_adaptive_run_with_all_of_it():
    """All of it in one adaptive run: the same levels on all ranks as on one process, and the
    estimate of the size of the error, against a reference from J_h alone (the finest of 10
    levels, its uncertainty the change from the level before): Ieff in [1/3, 3] on every level
    the reference can judge (error >= 10 x its uncertainty)."""
    kwargs = {"refinement": "adaptive", "fraction": 0.3, "verbose": False}
    with ds.solve_adaptive(_all_of_it(COMM), force_goal, max_levels=10, **kwargs) as res:
        levels = res.levels
    with ds.solve_adaptive(_all_of_it(MPI.COMM_SELF), force_goal, max_levels=4, **kwargs) as ser:
        for p, s_ in zip(levels[:4], ser.levels, strict=True):
            assert (p.num_cells, p.num_active) == (s_.num_cells, s_.num_active)
            assert p.J_h == pytest.approx(s_.J_h, rel=1e-9)
            assert p.weights == s_.weights
            assert p.eta == pytest.approx(s_.eta, rel=estimate_rel(p))
    reference, uncertainty = levels[-1].J_h, abs(levels[-1].J_h - levels[-2].J_h)
    judged = [(r.level, (reference - r.J_h) / r.eta) for r in levels[:-2]
              if abs(reference - r.J_h) >= 10 * uncertainty]
    assert len(judged) >= 3, judged
    for level, ieff in judged:
        assert 1 / 3 <= ieff <= 3, (level, ieff, judged)
