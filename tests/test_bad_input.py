"""A sweep of the public API with bad input (issue 34), serially and on 2 ranks (``-m mpi``).

Every case calls one public function (``SignoriniProblem``, ``solve``, ``estimate``,
``solve_adaptive``, ``read_mesh``, the obstacles) with one bad argument and checks:

* the error's type, and that its message names the argument and says what is expected (a
  pattern per case, written from the argument's documentation, not from the code);
* PETSc's options database is as before the call;
* a good solve follows and gives the same displacement as the good solve before the sweep.

Load paths (``solve_path``) are in the sweep since issue 48.
"""

import math
from types import SimpleNamespace

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest
import ufl
from dolfinx import mesh

import dwr_signorini as ds
from dwr_signorini import compat
from dwr_signorini import examples as ex
from dwr_signorini.obstacles import Cylinder, Graph, Plane, Sphere
from tests.problems import strip_problem

pytestmark = pytest.mark.mpi

CONTACT, DIRICHLET, NEUMANN = ex.CONTACT, ex.DIRICHLET, ex.NEUMANN


def good_goal(u, lam, m):
    return lam * m.ds_contact


@pytest.fixture(scope="module")
def d(tmp_path_factory):
    """The good problem, a good solution and its displacement norm, shared by the cases."""
    comm = MPI.COMM_WORLD
    problem = strip_problem(comm, 8, 2)
    msh, tags = problem.mesh, problem.facet_tags
    other = strip_problem(comm, 4, 2)
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    cell_tags = mesh.meshtags(msh, tdim, cells, np.full(cells.size, 7, dtype=np.int32))
    msh.topology.create_connectivity(tdim - 1, tdim)
    interior = np.setdiff1d(
        np.arange(msh.topology.index_map(tdim - 1).size_local, dtype=np.int32),
        mesh.exterior_facet_indices(msh.topology),
    )
    inner_tags = mesh.meshtags(
        msh,
        tdim - 1,
        np.concatenate([tags.indices, interior]).astype(np.int32),
        np.concatenate([tags.values, np.full(interior.size, 5)]).astype(np.int32),
    )
    order = np.argsort(inner_tags.indices)
    inner_tags = mesh.meshtags(
        msh, tdim - 1, inner_tags.indices[order], inner_tags.values[order]
    )
    tmp = comm.bcast(tmp_path_factory.mktemp("bad_input") if comm.rank == 0 else None, root=0)
    if comm.rank == 0:
        (tmp / "a_file").write_text("not a directory")
        (tmp / "not_a_mesh.msh").write_text("this is not a gmsh file\n")
    comm.Barrier()
    sol = ds.solve(problem)
    kw = {
        "mesh": msh, "facet_tags": tags, "contact": CONTACT, "dirichlet": (DIRICHLET,),
        "E": ex.ANALYTIC_MATERIAL.E, "nu": ex.ANALYTIC_MATERIAL.nu, "body_force": (0.0, -1.0),
        "gap": problem.gap,
    }
    ns = SimpleNamespace(
        comm=comm, problem=problem, msh=msh, tags=tags, other=other, cell_tags=cell_tags,
        inner_tags=inner_tags, tmp=tmp, sol=sol, kw=kw, norm=sol.u.x.petsc_vec.norm(),
    )
    yield ns
    sol.destroy()


def P(d, **changes):
    """The good problem with some arguments changed."""
    return ds.SignoriniProblem(**{**d.kw, **changes})


def psi_raises(x):
    raise ValueError("psi cannot be evaluated here")


def destroyed_solution(d):
    sol = ds.solve(d.problem)
    sol.destroy()
    return ds.estimate(sol, good_goal)


#: (id, call, exception type, pattern of the message: the argument and what is expected).
CASES = [
    # -- SignoriniProblem: mesh and tags -----------------------------------------------------
    ("mesh-type", lambda d: P(d, mesh="mesh.msh"), TypeError, r"mesh must be a dolfinx.mesh"),
    ("facet_tags-none", lambda d: P(d, facet_tags=None), TypeError,
     r"facet_tags must be dolfinx.mesh.MeshTags"),
    ("facet_tags-other-mesh", lambda d: P(d, facet_tags=d.other.facet_tags), ValueError,
     r"facet_tags belong to another mesh"),
    ("facet_tags-cell-tags", lambda d: P(d, facet_tags=d.cell_tags), ValueError,
     r"facet_tags has dimension 2.*pass the facet tags"),
    ("mesh-empty", lambda d: P(d, **_empty_mesh(d)), ValueError, r"mesh has no cells"),
    ("contact-unknown-tag", lambda d: P(d, contact=99), ValueError,
     r"contact tag 99 marks no boundary facet.*tags present"),
    ("contact-interior-facets", lambda d: P(d, facet_tags=d.inner_tags, contact=5), ValueError,
     r"contact tag 5 marks no boundary facet"),
    ("contact-string", lambda d: P(d, contact="3"), TypeError,
     r"contact must be an integer facet tag"),
    ("contact-empty", lambda d: P(d, contact=()), ValueError, r"contact must name at least one"),
    ("contact-twice", lambda d: P(d, contact=(3, 3)), ValueError, r"contact names a tag twice"),
    # -- dirichlet ---------------------------------------------------------------------------
    ("dirichlet-empty", lambda d: P(d, dirichlet=()), ValueError,
     r"dirichlet must name at least one facet tag"),
    ("dirichlet-is-contact", lambda d: P(d, dirichlet=(CONTACT,)), ValueError,
     r"tag 3 is used both as contact and as dirichlet"),
    ("dirichlet-unknown-tag", lambda d: P(d, dirichlet=(42,)), ValueError,
     r"dirichlet tag 42 marks no boundary facet"),
    ("dirichlet-wrong-dimension", lambda d: P(d, dirichlet={1: (0.0, 0.0, 0.0)}), ValueError,
     r"dirichlet\[1\] must have 2 components"),
    ("dirichlet-nan", lambda d: P(d, dirichlet={1: (math.nan, 0.0)}), ValueError,
     r"dirichlet\[1\]\[0\] must be finite"),
    ("dirichlet-all-free", lambda d: P(d, dirichlet={1: (None, None)}), ValueError,
     r"dirichlet\[1\] prescribes no component"),
    ("dirichlet-string", lambda d: P(d, dirichlet={1: "fixed"}), TypeError,
     r"dirichlet\[1\] must be a number, a tuple of 2 numbers"),
    ("dirichlet-callable-shape", lambda d: P(d, dirichlet={1: lambda x: (x[0],)}), ValueError,
     r"dirichlet\[1\] must return a UFL vector with 2 components"),
    # -- material ----------------------------------------------------------------------------
    ("E-zero", lambda d: P(d, E=0.0), ValueError, r"E \(Young's modulus\) must be a finite"),
    ("E-nan", lambda d: P(d, E=math.nan), ValueError, r"E \(Young's modulus\) must be a finite"),
    ("E-inf", lambda d: P(d, E=math.inf), ValueError, r"E \(Young's modulus\) must be a finite"),
    ("E-string", lambda d: P(d, E="210e9"), TypeError, r"E must be a real number, a callable"),
    ("E-callable-negative", lambda d: P(d, E=lambda x: -1.0 - x[0]), ValueError,
     r"E\(x\) must be > 0 at every quadrature point"),
    ("E-per-tag-without-cell_tags", lambda d: P(d, E={7: 1.0}), ValueError,
     r"E is given per cell tag, so cell_tags"),
    ("E-per-tag-unknown", lambda d: P(d, E={8: 1.0}, cell_tags=d.cell_tags), ValueError,
     r"E is given for cell tags \[8\].*cell tags present: \[7\]"),
    ("cell_tags-facet-tags", lambda d: P(d, E={7: 1.0}, cell_tags=d.tags), ValueError,
     r"cell_tags has dimension 1"),
    ("nu-half", lambda d: P(d, nu=0.5), ValueError, r"nu \(Poisson's ratio\) must lie in"),
    ("nu-minus-one", lambda d: P(d, nu=-1.0), ValueError, r"nu \(Poisson's ratio\) must lie in"),
    ("nu-callable-constant", lambda d: P(d, nu=lambda x: 0.6 + 0 * x[0]), ValueError,
     r"nu\(x\) must be in \(-1, 0.5\)"),
    ("nu-callable-numpy", lambda d: P(d, nu=lambda x: np.full(3, 0.3)[x]), TypeError,
     r"nu must be a callable x -> UFL scalar.*calling it failed"),
    ("model-unknown", lambda d: P(d, model="plane"), ValueError, r"model must be one of"),
    ("model-3d-on-2d", lambda d: P(d, model="3d"), ValueError,
     r"model='3d' does not fit a 2D mesh"),
    ("quadrature_degree-negative", lambda d: P(d, quadrature_degree=-1), ValueError,
     r"quadrature_degree must be in \[0, 30\], got -1"),
    ("quadrature_degree-float", lambda d: P(d, quadrature_degree=4.0), TypeError,
     r"quadrature_degree must be an integer, got float"),
    # -- loads -------------------------------------------------------------------------------
    ("body_force-dimension", lambda d: P(d, body_force=(0.0, 0.0, -1.0)), ValueError,
     r"body_force must have 2 components"),
    ("body_force-nan", lambda d: P(d, body_force=(math.nan, 0.0)), ValueError,
     r"body_force must be finite"),
    ("body_force-string", lambda d: P(d, body_force="down"), TypeError,
     r"body_force must be a sequence of floats or a callable"),
    ("traction-not-dict", lambda d: P(d, traction=[(0.0, 1.0)]), TypeError,
     r"traction must be a dict \{facet tag: load\}"),
    ("traction-unknown-tag", lambda d: P(d, traction={99: (0.0, 1.0)}), ValueError,
     r"traction tag 99 marks no boundary facet"),
    ("traction-on-contact", lambda d: P(d, traction={CONTACT: (0.0, 1.0)}), ValueError,
     r"traction tag 3 is also a contact tag"),
    ("traction-on-prescribed-component",
     lambda d: P(d, dirichlet={DIRICHLET: (0.0, None)}, traction={DIRICHLET: (1.0, -1.0)}),
     ValueError, r"traction\[1\] has nonzero component\(s\) \[0\] that dirichlet\[1\] "
     r"prescribes.*set those traction components to 0.0"),
    ("traction-on-clamped-face", lambda d: P(d, traction={DIRICHLET: (0.0, -1.0)}), ValueError,
     r"traction\[1\] has nonzero component\(s\) \[1\]"),
    ("traction-on-callable-dirichlet",
     lambda d: P(d, dirichlet={DIRICHLET: lambda x: ufl.as_vector((0 * x[0], 0 * x[0]))},
                 traction={DIRICHLET: (0.0, -1.0)}),
     ValueError, r"traction tag 1 is a dirichlet tag with a callable value"),
    ("traction-callable-on-dirichlet",
     lambda d: P(d, dirichlet={DIRICHLET: (0.0, None)},
                 traction={DIRICHLET: lambda x: ufl.as_vector((0 * x[0], -1 + 0 * x[0]))}),
     ValueError, r"traction\[1\] is a callable on dirichlet face 1"),
    ("traction-inf", lambda d: P(d, traction={NEUMANN: (math.inf, 0.0)}), ValueError,
     r"traction\[2\] must be finite"),
    # -- gap and obstacles -------------------------------------------------------------------
    ("gap-inf", lambda d: P(d, gap=math.inf), ValueError, r"gap must be finite"),
    ("gap-string", lambda d: P(d, gap="0.0"), TypeError,
     r"gap must be a float, a callable x -> UFL scalar or an obstacle"),
    ("gap-missing-contact-tag", lambda d: P(d, gap={99: 0.0}), ValueError,
     r"gap is given per contact tag but misses the contact tag\(s\) \[3\]"),
    ("gap-vector-callable", lambda d: P(d, gap=lambda x: ufl.as_vector((x[0], x[1]))),
     ValueError, r"gap must return a UFL scalar"),
    ("gap-3d-obstacle-on-2d", lambda d: P(d, gap=Plane((0, 0, 0), (0, 0, -1))), ValueError,
     r"gap: a 3D obstacle .* on a 2D mesh"),
    ("gap-graph-raises", lambda d: P(d, gap=Graph(psi_raises)), TypeError,
     r"gap \(Graph psi\) must be a callable.*psi cannot be evaluated"),
    ("gap-Plane-behind-the-body", lambda d: P(d, gap=Plane((0.0, -0.01), (0.0, 1.0))),
     ValueError, r"gap: Plane.* lies behind the body.*\(0.0, -1.0\).*flip the normal"),
    ("gap-per-tag-Plane-behind-the-body",
     lambda d: P(d, gap={CONTACT: Plane((0.0, -0.01), (0.0, 1.0))}), ValueError,
     r"gap\[3\]: Plane.* lies behind the body.*normal=\(0.0, -1.0\)"),
    ("Graph-axis", lambda d: P(d, gap=Graph(lambda x: 0 * x[0] - 1.0, axis=5)), ValueError,
     r"gap: Graph axis 5 out of range for 2D"),
    ("Plane-zero-normal", lambda d: Plane((0.0, 0.0), (0.0, 0.0)), ValueError,
     r"Plane normal must not be the zero vector"),
    ("Sphere-negative-radius", lambda d: Sphere((0.0, 0.0), -1.0), ValueError,
     r"Sphere radius must be a finite number > 0"),
    ("Sphere-nan-center", lambda d: Sphere((0.0, math.nan), 1.0), ValueError,
     r"Sphere center must be a finite point"),
    ("Cylinder-radius-string", lambda d: Cylinder((0, 0, 0), (0, 0, 1), "1"), TypeError,
     r"Cylinder radius must be a number"),
    ("Cylinder-2d", lambda d: Cylinder((0, 0), (0, 1), 1.0), ValueError,
     r"Cylinder is a 3D obstacle"),
    ("Graph-psi-not-callable", lambda d: Graph(0.0), TypeError,
     r"Graph psi must be a callable x -> UFL scalar"),
    # -- friction ------------------------------------------------------------------------------
    ("friction-number", lambda d: P(d, friction=0.3), TypeError,
     r"friction must be None, ds.Frictionless\(\), ds.Tresca\(s\) or ds.Coulomb\(mu\)"),
    ("Tresca-zero", lambda d: P(d, friction=ds.Tresca(0.0)), ValueError,
     r"Tresca\(s\): the slip threshold s must be a finite number > 0"),
    ("Tresca-nan", lambda d: P(d, friction=ds.Tresca(math.nan)), ValueError,
     r"Tresca\(s\): the slip threshold s must be a finite number > 0"),
    ("Tresca-string", lambda d: P(d, friction=ds.Tresca("0.1")), TypeError,
     r"Tresca\(s\): s must be a number, a callable x -> UFL scalar or a dict"),
    ("Coulomb-negative", lambda d: P(d, friction=ds.Coulomb(-0.1)), ValueError,
     r"Coulomb\(mu\): the friction coefficient mu must be a finite number >= 0"),
    ("Coulomb-nan", lambda d: P(d, friction=ds.Coulomb(math.nan)), ValueError,
     r"Coulomb\(mu\): the friction coefficient mu must be a finite number >= 0"),
    ("Coulomb-string", lambda d: P(d, friction=ds.Coulomb("0.3")), TypeError,
     r"Coulomb\(mu\): mu must be a number, a callable x -> UFL scalar or a dict"),
    ("Tresca-not-contact-tag", lambda d: P(d, friction=ds.Tresca({CONTACT: 1.0, NEUMANN: 1.0})),
     ValueError, r"friction=Tresca\(s\): s has tag\(s\) \[2\] that are not contact tags"),
    ("Tresca-numpy-callable", lambda d: P(d, friction=ds.Tresca(lambda x: np.sin(x[0]))),
     TypeError, r"Tresca\(s\) must be a callable x -> UFL scalar"),
    ("estimate-goal-lam_t-frictionless",
     lambda d: ds.estimate(d.sol, lambda u, lam, m, lam_t: lam_t * m.ds_contact), ValueError,
     r"goal takes four arguments goal\(u, lam, m, lam_t\), but the problem is frictionless"),
    # -- boundary_projection -----------------------------------------------------------------
    ("boundary_projection-not-dict", lambda d: P(d, boundary_projection=[abs]), TypeError,
     r"boundary_projection must be a dict \{facet tag: callable"),
    ("boundary_projection-not-callable", lambda d: P(d, boundary_projection={2: "circle"}),
     TypeError, r"boundary_projection\[2\] must be callable"),
    ("boundary_projection-unknown-tag", lambda d: P(d, boundary_projection={99: abs}),
     ValueError, r"boundary_projection tag 99 marks no boundary facet"),
    # -- solve -------------------------------------------------------------------------------
    ("solve-problem-type", lambda d: ds.solve("problem"), TypeError,
     r"problem must be a SignoriniProblem or a Discretization"),
    ("solve-petsc_options-type", lambda d: ds.solve(d.problem, petsc_options="lu"), TypeError,
     r"petsc_options must be a dict of PETSc options"),
    ("solve-petsc_options-misspelt", lambda d: ds.solve(d.problem, {"pc_type": "lux"}),
     ValueError, r"petsc_options .*PETSc rejected.*PC type lux"),
    ("solve-max_iterations-zero", lambda d: ds.solve(d.problem, max_iterations=0), ValueError,
     r"max_iterations must be a positive integer"),
    ("solve-max_iterations-float", lambda d: ds.solve(d.problem, max_iterations=2.5),
     ValueError, r"max_iterations must be a positive integer"),
    ("solve-rtol-nan", lambda d: ds.solve(d.problem, rtol=math.nan), ValueError,
     r"rtol must be a finite number > 0"),
    ("solve-rtol-negative", lambda d: ds.solve(d.problem, rtol=-1e-8), ValueError,
     r"rtol must be a finite number > 0"),
    ("solve-ncp_scale-zero", lambda d: ds.solve(d.problem, ncp_scale=0.0), ValueError,
     r"ncp_scale must be 'physical'.*or a finite number c > 0"),
    ("solve-ncp_scale-string", lambda d: ds.solve(d.problem, ncp_scale="unit"), ValueError,
     r"ncp_scale must be 'physical'"),
    ("solve-method", lambda d: ds.solve(d.problem, method="lu"), ValueError,
     r"method must be one of \('block', 'schur', 'krylov'\)"),
    ("solve-prefix-no-underscore", lambda d: ds.solve(d.problem, petsc_options_prefix="p34"),
     ValueError, r"petsc_options_prefix must be a non-empty string ending with '_'"),
    ("solve-prefix-int", lambda d: ds.solve(d.problem, petsc_options_prefix=34), ValueError,
     r"petsc_options_prefix must be a non-empty string"),
    ("solve-initial_guess-string", lambda d: ds.solve(d.problem, initial_guess="zero"),
     TypeError, r"initial_guess must be a pair \(u0, lam0\)"),
    ("solve-initial_guess-other-mesh", lambda d: ds.solve(d.problem, initial_guess=(1, 2)),
     ValueError, r"initial_guess must be functions on this discretisation"),
    ("solve-form_compiler_options", lambda d: ds.solve(d.problem, form_compiler_options="O2"),
     TypeError, r"form_compiler_options must be a dict"),
    ("solve-jit_options", lambda d: ds.solve(d.problem, jit_options=["-O2"]), TypeError,
     r"jit_options must be a dict"),
    # -- estimate ----------------------------------------------------------------------------
    ("estimate-sol-type", lambda d: ds.estimate(d.problem, good_goal), TypeError,
     r"sol must be the Solution returned by solve\(\)"),
    ("estimate-sol-destroyed", destroyed_solution, ValueError, r"sol has been destroyed"),
    ("estimate-goal-number", lambda d: ds.estimate(d.sol, 1.0), TypeError,
     r"goal must be a callable goal\(u, lam, m\) -> ufl.Form"),
    ("estimate-goal-returns-float", lambda d: ds.estimate(d.sol, lambda u, lam, m: 1.0),
     TypeError, r"goal\(u, lam, m\) must return a UFL form"),
    ("estimate-goal-not-scalar",
     lambda d: ds.estimate(d.sol, lambda u, lam, m: ufl.inner(u, ufl.TestFunction(
         u.function_space)) * m.dx), ValueError,
     r"goal\(u, lam, m\) must return a scalar functional"),
    ("estimate-goal-other-mesh",
     lambda d: ds.estimate(d.sol, lambda u, lam, m: u[0] * ufl.dx(d.other.mesh)), ValueError,
     r"goal uses a measure of another mesh"),
    ("estimate-goal-bare-ds", lambda d: ds.estimate(d.sol, lambda u, lam, m: u[1] * ufl.ds(3)),
     ValueError, r"goal integrates over ufl.ds\(3\).*use m.ds_contact or m.ds\(tag\)"),
    ("estimate-goal-bare-dx-tag", lambda d: ds.estimate(d.sol, lambda u, lam, m: u[1] * ufl.dx(7)),
     ValueError, r"goal integrates over ufl.dx\(7\).*use m.dx"),
    ("estimate-goal-macro-coordinate",
     lambda d: ds.estimate(d.sol, lambda u, lam, m: ufl.SpatialCoordinate(d.msh)[0] * u[1] * m.dx),
     ValueError, r"goal uses a coordinate or function of the macro mesh T_H.*use m.x"),
    ("estimate-goal-other-mesh-coordinate",
     lambda d: ds.estimate(d.sol, lambda u, lam, m: ufl.SpatialCoordinate(d.other.mesh)[0]
                           * u[1] * m.dx),
     ValueError, r"goal uses a coordinate or function of another mesh.*use m.x"),
    ("estimate-goal-unknown-ds-tag",
     lambda d: ds.estimate(d.sol, lambda u, lam, m: u[1] * m.ds(99)), ValueError,
     r"goal integrates over m.ds\(99\), but no facet carries that tag.*facet tags present"),
    ("estimate-goal-None", lambda d: ds.estimate(d.sol, None), TypeError,
     r"goal must be a callable goal\(u, lam, m\)"),
    ("estimate-goal-lam-in-dx", lambda d: ds.estimate(d.sol, lambda u, lam, m: lam * m.dx),
     ValueError, r"goal integrates lam outside Gamma_C"),
    ("estimate-goal-raises", lambda d: ds.estimate(d.sol, lambda u, lam, m: 1 / 0),
     ZeroDivisionError, r"goal raised ZeroDivisionError"),
    ("estimate-estimator", lambda d: ds.estimate(d.sol, good_goal, estimator="eta_d"),
     ValueError, r"estimator must be one of \('eta', 'eta_p'\)"),
    ("estimate-weights", lambda d: ds.estimate(d.sol, good_goal, weights="quadratic"),
     ValueError, r"weights must be one of"),
    ("estimate-quadrature_degree", lambda d: ds.estimate(d.sol, good_goal, quadrature_degree=-1),
     ValueError, r"quadrature_degree must be an integer in \[0, 30\] or None"),
    ("estimate-petsc_options-type", lambda d: ds.estimate(d.sol, good_goal, petsc_options=1),
     TypeError, r"petsc_options must be a dict"),
    ("estimate-petsc_options-misspelt",
     lambda d: ds.estimate(d.sol, good_goal, weights="higher_order",
                           petsc_options={"ksp_type": "preonnly"}),
     ValueError, r"petsc_options .*PETSc rejected.*preonnly"),
    # -- solve_adaptive ----------------------------------------------------------------------
    ("adaptive-problem", lambda d: ds.solve_adaptive(None, good_goal), TypeError,
     r"problem must be a SignoriniProblem"),
    ("adaptive-goal", lambda d: ds.solve_adaptive(d.problem, "lam"), TypeError,
     r"goal must be a callable"),
    ("adaptive-fraction-nan", lambda d: _adaptive(d, fraction=math.nan), ValueError,
     r"fraction must be a number in \(0, 1\]"),
    ("adaptive-max_levels", lambda d: _adaptive(d, max_levels=0), ValueError,
     r"max_levels must be an integer >= 1"),
    ("adaptive-max_cells-bool", lambda d: _adaptive(d, max_cells=True), ValueError,
     r"max_cells must be a positive integer or None"),
    ("adaptive-tol-nan", lambda d: _adaptive(d, tol=math.nan), ValueError,
     r"tol must be a positive number or None"),
    ("adaptive-exact-inf", lambda d: _adaptive(d, exact=math.inf), ValueError,
     r"exact must be a finite number"),
    ("adaptive-growth", lambda d: _adaptive(d, growth=1.0), ValueError,
     r"growth must be a number in \(1, 1000\)"),
    ("adaptive-refinement_rule", lambda d: _adaptive(d, refinement_rule="shortest"), ValueError,
     r"refinement_rule must be one of"),
    ("adaptive-callback", lambda d: _adaptive(d, callback=5), TypeError,
     r"callback must be callable or None"),
    ("adaptive-verbose", lambda d: _adaptive(d, verbose="yes"), TypeError,
     r"verbose must be True or False"),
    ("adaptive-output_dir-file", lambda d: _adaptive(d, output_dir=d.tmp / "a_file"),
     ValueError, r"output_dir .* exists and is not a directory"),
    ("adaptive-output_dir-type", lambda d: _adaptive(d, output_dir=3), TypeError,
     r"output_dir must be a path"),
    ("adaptive-petsc_options", lambda d: _adaptive(d, petsc_options={"pc_type": "lux"}),
     ValueError, r"petsc_options .*PETSc rejected"),
    # -- solve_path --------------------------------------------------------------------------
    ("path-empty", lambda d: ds.solve_path([], good_goal), ValueError,
     r"problems is empty: a load path needs at least one step"),
    ("path-one-problem-not-a-list", lambda d: ds.solve_path(d.problem, good_goal), TypeError,
     r"problems must be a sequence \(list or tuple\) of SignoriniProblem"),
    ("path-string-step", lambda d: ds.solve_path(["step"], good_goal), TypeError,
     r"problems\[0\] must be a SignoriniProblem, got str"),
    ("path-two-meshes", lambda d: ds.solve_path([d.problem, d.other], good_goal), ValueError,
     r"problems\[1\] lives on another mesh than problems\[0\].*same mesh object"),
    ("path-goals-too-few", lambda d: ds.solve_path([d.problem] * 2, [good_goal]), TypeError,
     r"goal must be a callable .* or a sequence of 2 of them \(one per load step\)"),
    ("path-adaptive-string", lambda d: ds.solve_path([d.problem], good_goal, adaptive="yes"),
     TypeError, r"adaptive must be True or False"),
    ("path-callback", lambda d: ds.solve_path([d.problem], good_goal, callback=3), TypeError,
     r"callback must be callable or None"),
    # -- more data mistakes --------------------------------------------------------------------
    ("dirichlet-float-key", lambda d: P(d, dirichlet={1.0: 0.0}), TypeError,
     r"dirichlet keys must be integer facet tags, got 1.0"),
    ("E-bool", lambda d: P(d, E=True), TypeError, r"E must be a real number"),
    ("gap-per-tag-nan", lambda d: P(d, gap={CONTACT: math.nan}), ValueError,
     r"gap\[3\] must be finite"),
    ("body_force-callable-scalar", lambda d: P(d, body_force=lambda x: x[0]), ValueError,
     r"body_force must return a UFL vector with 2 components"),
    ("Plane-point-normal-dimensions", lambda d: Plane((0.0, 0.0), (0.0, 1.0, 0.0)), ValueError,
     r"Plane point and normal must have the same number of components"),
    # -- read_mesh ---------------------------------------------------------------------------
    ("read_mesh-missing", lambda d: ds.read_mesh(d.tmp / "missing.msh", d.comm),
     FileNotFoundError, r"read_mesh: no mesh file"),
    ("read_mesh-not-a-mesh", lambda d: ds.read_mesh(d.tmp / "not_a_mesh.msh", d.comm),
     ValueError, r"path_or_model .*could not be read as a gmsh mesh"),
    ("read_mesh-model-without-mesh", lambda d: _read_unmeshed_model(d), ValueError,
     r"path_or_model: the gmsh model has no mesh; generate it first"),
    ("read_mesh-type", lambda d: ds.read_mesh(42, d.comm), TypeError,
     r"path_or_model must be a path to a .msh file or a gmsh model"),
    ("read_mesh-comm", lambda d: ds.read_mesh(d.tmp / "missing.msh", "world"), TypeError,
     r"comm must be an mpi4py communicator"),
    ("read_mesh-rank", lambda d: ds.read_mesh(d.tmp / "missing.msh", d.comm, rank=5),
     ValueError, r"rank must be an integer in \[0, "),
    ("read_mesh-gdim", lambda d: ds.read_mesh(d.tmp / "missing.msh", d.comm, gdim=4),
     ValueError, r"gdim must be 2, 3 or None"),
]


def _adaptive(d, **kwargs):
    return ds.solve_adaptive(d.problem, good_goal, **{"max_levels": 1, "verbose": False, **kwargs})


def _read_unmeshed_model(d):
    """read_mesh of a gmsh model with a geometry and no mesh."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("unmeshed")
        gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        return ds.read_mesh(gmsh.model, d.comm)
    finally:
        gmsh.finalize()


def _empty_mesh(d):
    """A mesh of no cells (a submesh of none of the strip's) and its (empty) facet tags."""
    empty = compat.create_submesh(d.msh, d.msh.topology.dim, np.zeros(0, dtype=np.int32))[0]
    tags = mesh.meshtags(empty, 1, np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32))
    return {"mesh": empty, "facet_tags": tags}


def test_the_sweep_has_enough_cases():
    assert len(CASES) >= 40
    assert len({c[0] for c in CASES}) == len(CASES)


@pytest.mark.parametrize(("call", "error", "pattern"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_bad_input_is_named_and_leaves_nothing_behind(d, call, error, pattern):
    before = PETSc.Options().getAll()
    with pytest.raises(error, match=pattern):
        call(d)
    assert PETSc.Options().getAll() == before
    with ds.solve(d.problem) as sol:  # a good solve follows, with the same result
        assert sol.u.x.petsc_vec.norm() == pytest.approx(d.norm, rel=1e-12)
