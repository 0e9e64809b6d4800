"""Extreme meshes: high aspect ratios and strong grading (a uniaxial layer reproduced exactly),
a single macro contact facet, a gmsh half disc against Hertz's line contact, and contact facets
on two ranks against the serial solution."""

import math

from mpi4py import MPI

import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import compat
from dwr_signorini import examples as ex

from .helpers import (
    contact_conditions,
    global_max,
    integrate,
    owned,
)
from .problems import block, make

DIRICHLET, NEUMANN, CONTACT = ex.DIRICHLET, ex.NEUMANN, ex.CONTACT


# --------------------------------------------------------------------------------------------------
# 4. Meshes
# --------------------------------------------------------------------------------------------------


def _layer_patch_test(sol, t, E, g):
    """Uniaxial compression of a layer of thickness t by an obstacle penetrating it by -g > 0,
    nu = 0, clamped on top, sides free: u = (0, -g (1 - y/t)) is linear, so P1 reproduces it
    on any mesh, and lambda = E |g| / t on every facet."""
    comm = sol.disc.comm
    assert sol.num_active == sol.disc.num_contact_elements
    _, lam = owned(sol)
    assert global_max(lam - E * abs(g) / t, comm) <= 1e-9 * E * abs(g) / t
    m = sol.disc.m
    exact = ufl.as_vector((0.0, -g * (1.0 - m.x[1] / t)))
    err = integrate(sol, ufl.inner(sol.u - exact, sol.u - exact) * m.dx)
    assert math.sqrt(abs(err)) <= 1e-9 * abs(g)
    contact_conditions(sol)


@pytest.mark.mpi
@pytest.mark.parametrize(
    ("nx", "ny", "lx", "ly"),
    [(4, 8, 4.0, 0.08), (4, 1, 0.04, 1.0)],
    ids=["flat-cells-1:100", "tall-cells-100:1"],
)
def test_high_aspect_ratio_cells(nx, ny, lx, ly):
    """Cells with aspect ratio 1:100 (macro, flat and tall): the patch test is exact."""
    comm = MPI.COMM_WORLD
    msh, tags = block(comm, nx, ny, lx=lx, ly=ly)
    E, g = 3.0, -1e-3 * ly
    _layer_patch_test(ds.solve(make(msh, tags, E=E, nu=0.0, gap=g)), ly, E, g)


@pytest.mark.mpi
def test_strongly_graded_mesh():
    """A mesh graded by x -> x^4 towards one side and y -> y^3 towards Gamma_C (cell sizes
    spanning 3 orders of magnitude): the patch test is exact, and the error estimate of the
    exact solution is round-off (nothing to estimate)."""
    comm = MPI.COMM_WORLD
    msh, tags = block(comm, 8, 8, transform=lambda x: (x[0] ** 4, x[1] ** 3))
    E, g = 2.0, -0.01
    sol = ds.solve(make(msh, tags, E=E, nu=0.0, gap=g))
    _layer_patch_test(sol, 1.0, E, g)
    est = ds.estimate(sol, lambda u, lam, m: lam * m.ds_contact + u[1] * m.dx)
    assert abs(est.eta) <= 1e-8 * abs(est.J_h)
    assert abs(est.eta_p) <= 1e-8 * abs(est.J_h)


@pytest.mark.mpi
def test_single_macro_contact_facet():
    """Gamma_C is one macro facet (a 1 x 1 macro mesh): one multiplier, the patch test holds."""
    comm = MPI.COMM_WORLD
    msh, tags = block(comm, 1, 1)
    sol = ds.solve(make(msh, tags, E=1.0, nu=0.0, gap=-0.02))
    assert sol.disc.num_contact_elements == 1
    _layer_patch_test(sol, 1.0, 1.0, -0.02)


def _half_disc(comm, radius, h_far, h_near):
    """gmsh: half-disc {x^2 + y^2 < R^2, y < 0}, clamped on the diameter y = 0 (tag 1), the arc
    in possible contact (tag 3); mesh size h_near at the bottom point (0, -R)."""
    gmsh = pytest.importorskip("gmsh")

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            occ = gmsh.model.occ
            disc = occ.addDisk(0, 0, 0, radius, radius)
            upper = occ.addRectangle(-radius, 0, 0, 2 * radius, radius)
            occ.cut([(2, disc)], [(2, upper)])
            occ.synchronize()
            gmsh.model.addPhysicalGroup(2, [s for _, s in gmsh.model.getEntities(2)], 1)
            flat, arc = [], []
            for dim, tag in gmsh.model.getEntities(1):
                (flat if abs(occ.getCenterOfMass(dim, tag)[1]) < 1e-8 else arc).append(tag)
            gmsh.model.addPhysicalGroup(1, flat, DIRICHLET)
            gmsh.model.addPhysicalGroup(1, arc, CONTACT)
            field = gmsh.model.mesh.field
            field.add("MathEval", 1)
            field.setString(
                1,
                "F",
                f"{h_near} + ({h_far} - {h_near}) * Min(1, Sqrt(x^2 + (y + {radius})^2)"
                f" / {0.5 * radius})",
            )
            field.setAsBackgroundMesh(1)
            for option in (
                "MeshSizeExtendFromBoundary",
                "MeshSizeFromPoints",
                "MeshSizeFromCurvature",
            ):
                gmsh.option.setNumber(f"Mesh.{option}", 0)
            gmsh.model.mesh.generate(2)
        partitioner = compat.cell_partitioner(mesh.GhostMode.none)
        msh, _, facet_tags = compat.gmsh_model_to_mesh(
            gmsh.model, comm, 0, gdim=2, partitioner=partitioner
        )
    finally:
        gmsh.finalize()
    return msh, facet_tags


def _hertz(h_near, rel_a, rel_p0):
    comm = MPI.COMM_WORLD
    radius, delta, E, nu = 1.0, 0.05, 1.0, 0.3
    msh, tags = _half_disc(comm, radius, 20 * h_near, h_near)
    problem = make(msh, tags, E=E, nu=nu, gap=lambda x: x[1] + radius - delta)
    sol = ds.solve(problem)
    contact_conditions(sol)
    m = sol.disc.m
    P = integrate(sol, sol.lam * m.ds_contact)
    assert P > 0
    active = ufl.conditional(ufl.gt(sol.lam, 0.0), 1.0, 0.0)
    half_width = 0.5 * integrate(sol, active * m.ds_contact)
    a = math.sqrt(4 * P * radius / (math.pi * E / (1 - nu**2)))
    assert half_width == pytest.approx(a, rel=rel_a)
    p0 = 2 * P / (math.pi * a)
    assert global_max(owned(sol)[1], comm) == pytest.approx(p0, rel=rel_p0)
    assert abs(integrate(sol, sol.lam * m.x[0] * m.ds_contact)) <= 0.02 * a * P
    assert abs(integrate(sol, sol.lam * m.n[0] * m.ds_contact)) <= 1e-3 * P


@pytest.mark.mpi
def test_gmsh_half_disc_hertz_contact():
    """A gmsh half-disc (radius R = 1, curved boundary approximated by the polygon of the macro
    mesh; the fine mesh refines it along the chords) pressed by delta onto a rigid flat: a
    Hertz line contact. With the transmitted force P = int lambda ds, Hertz's theory gives the
    half-width a = sqrt(4 P R / (pi E*)) and the peak pressure p0 = 2 P / (pi a), E* = E /
    (1 - nu^2) (plane strain). Checked: a within 20 %, p0 within 10 %, the pressure centred
    (symmetry), no net tangential force, the contact conditions."""
    _hertz(0.005, 0.2, 0.1)


@pytest.mark.slow
@pytest.mark.mpi
def test_gmsh_half_disc_hertz_contact_fine():
    """As above on a 4x finer mesh near the contact, with tighter tolerances."""
    _hertz(0.00125, 0.05, 0.05)


def _long_strip(comm):
    msh, tags = block(comm, 16, 2, lx=8.0, ly=1.0)
    return make(msh, tags, body_force=(0.01, -0.1), gap=lambda x: 0.02 * (x[0] - 3.0) ** 2 - 0.01)


@pytest.mark.mpi
def test_contact_facets_on_two_ranks():
    """Gamma_C split over the ranks: every macro contact facet is one multiplier, counted once
    (M_C = 16, the number of bottom macro facets), and the results equal a serial run."""
    comm = MPI.COMM_WORLD
    par = ds.solve(_long_strip(comm))
    ser = ds.solve(_long_strip(MPI.COMM_SELF))
    owned_facets = comm.allgather(par.system.n_lam)
    if comm.size > 1:
        assert sum(n > 0 for n in owned_facets) >= 2, owned_facets
    assert par.disc.num_contact_elements == ser.disc.num_contact_elements == 16
    assert sum(owned_facets) == 16
    assert par.num_active == ser.num_active
    assert 0 < par.num_active < 16
    assert par.newton_iterations == ser.newton_iterations
    for form in (
        lambda s: s.lam * s.disc.m.ds_contact,
        lambda s: s.lam**2 * s.disc.m.ds_contact,
        lambda s: ufl.inner(s.u, s.u) * s.disc.m.dx,
    ):
        assert integrate(par, form(par)) == pytest.approx(integrate(ser, form(ser)), rel=1e-10)
