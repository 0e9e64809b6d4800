"""The discretisation of Section 4: macro mesh T_H, fine mesh T_h, V_h (P1/Q1) and Lambda_H (P0).

The mesh the user passes is the macro mesh T_H. Its uniform refinement is the fine mesh T_h, on
which the displacement lives (vector P1 on simplices, Q1 on quadrilaterals/hexahedra). The normal
contact force is piecewise constant on the macro contact facets (so H = 2h, the stable choice of
the paper): ``Q`` is DG0 on the facet submesh Sigma_H of the macro contact facets, and forms on
the fine mesh reach it through an entity map that sends each fine contact facet to its *parent*
macro facet. For a piecewise constant field that is exact, so no aggregation matrix is needed.

The same structure gives the paper's patches: the children of a macro cell form a patch, and the
fine P1 values on a patch are the P2 (Q2) nodal values of the macro cell.
"""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from . import compat
from .collective import shadow
from .fields import MeshFields
from .measures import Measures
from .pairs import MasterTrace, TraceGeometry
from .problem import SignoriniProblem
from .quadrature import expand_integer_powers, is_polynomial
from .refine import (  # noqa: F401  (re-exported: the refinement used to live here)
    cell_tags_on_fine,
    fine_to_macro_facets,
    num_entities,
    refine_marked,
    refine_uniform,
    refine_with_tags,
)
from .timing import timed
from .validation import call_user, nonzero_literal

__all__ = ["Discretization", "Measures", "discretize"]


class Discretization:
    """Macro mesh, fine mesh, the spaces V_h and Lambda_H and the maps between them.

    With contact pairs it owns the master traces of its mesh (:meth:`master_trace`): release
    them with :meth:`destroy` (collective; a :class:`~dwr_signorini.Solution` does it for the
    discretisation that :func:`~dwr_signorini.solve` or a driver made for it).

    Args:
        problem: The problem; its mesh is the macro mesh T_H (collective: T_h is refined on
            every rank).

    Raises:
        RuntimeError: If a fine contact facet has no parent macro contact facet (a refinement
            that broke the parent maps; not expected from dolfinx's refinement).

    Attributes:
        problem: The problem on the macro mesh.
        macro_mesh: T_H.
        mesh: T_h, one uniform refinement of T_H.
        parent_cell: Parent macro cell of each local fine cell.
        facet_tags: Facet tags carried to T_h.
        V: Vector P1 (Q1) on T_h.
        contact_mesh: Sigma_H, the submesh of macro contact facets.
        contact_mesh_to_macro: The macro facet of each local cell of Sigma_H.
        Q: DG0 on Sigma_H (the multiplier space Lambda_H).
        entity_maps: For forms on T_h that use Q: fine facet -> Sigma_H cell.
        macro_entity_maps: For forms on T_H that use Q: macro facet -> Sigma_H cell.
        bcs: Homogeneous Dirichlet conditions on V (the dual problem, corrections).
        prescribed_bcs: The Dirichlet conditions with their prescribed values on V.
        cell_tags: Cell tags of T_h (those of the parent macro cells), or None.
        fields: The problem's data on T_h (:class:`~dwr_signorini.fields.MeshFields`: the
            cell tags, the DG0 materials, the contact-tag indicators).
        macro_fields: The problem's data on T_H (the same contact-tag indicators).
        m: The :class:`Measures` on T_h.
        u_old: The displacement at the end of the previous load step (a function on V), whose
            tangential part a frictional law's slip is measured from (u_t - u_t^old); None
            (zero) outside a load path. Set it with :meth:`set_u_old` before solving.
        obstacle_translation: ``{rigid contact tag: t}``, the translation of the rigid
            obstacles since the previous load step (:mod:`~dwr_signorini.obstacle_motion`),
            or None (no obstacle moved); set with :meth:`set_u_old`.
    """

    def __init__(self, problem: SignoriniProblem) -> None:
        self.problem = problem
        macro = problem.mesh
        tdim = macro.topology.dim
        fdim = tdim - 1
        self.macro_mesh = macro
        #: The processes of T_H, as a duplicate that outlives the mesh (collective.shadow): the
        #: object collectives of the solve must leave no mpi4py state on the mesh's communicator.
        self.comm: MPI.Comm = shadow(macro.comm)
        macro.topology.create_entities(fdim)
        macro.topology.create_connectivity(fdim, tdim)

        fine, parent_cell, to_macro, self.facet_tags = refine_with_tags(problem, None)
        self.mesh = fine
        self.parent_cell = parent_cell
        self.fine_to_macro_facet = to_macro

        # Sigma_H: the macro contact facets (exterior facets only).
        exterior = dmesh.exterior_facet_indices(macro.topology)
        contact_macro = np.intersect1d(_find(problem.facet_tags, problem.contact_tags), exterior)
        self.contact_macro_facets = contact_macro.astype(np.int32)
        sub, sub_to_macro, _, _ = compat.create_submesh(macro, fdim, self.contact_macro_facets)
        self.contact_mesh = sub
        self.contact_mesh_to_macro = np.asarray(sub_to_macro, dtype=np.int32)
        macro_to_sub = np.full(num_entities(macro, fdim), -1, dtype=np.int32)
        macro_to_sub[sub_to_macro] = np.arange(len(sub_to_macro), dtype=np.int32)
        fine_to_sub = np.full(len(to_macro), -1, dtype=np.int32)
        fine_contact = _find(self.facet_tags, problem.contact_tags)
        fine_to_sub[fine_contact] = macro_to_sub[to_macro[fine_contact]]
        if np.any(fine_to_sub[fine_contact] < 0):
            raise RuntimeError("a fine contact facet has no parent macro contact facet")
        maps = {sub: fine_to_sub}
        self.slave_mesh: dmesh.Mesh | None = None
        if problem.pairs:  # Sigma_h: the fine contact facets, where the master trace lives
            slave, slave_to_fine, _, _ = compat.create_submesh(fine, fdim, fine_contact)
            self.slave_mesh = slave
            self.slave_to_fine = np.asarray(slave_to_fine, dtype=np.int32)
            fine_to_slave = np.full(len(to_macro), -1, dtype=np.int32)
            fine_to_slave[self.slave_to_fine] = np.arange(len(self.slave_to_fine), dtype=np.int32)
            maps[slave] = fine_to_slave
        #: The master traces (one geometry, one trace per space), shared by for_problem.
        self._traces: dict[Any, Any] = {}
        self._spaces: dict[int, fem.FunctionSpace] = {}
        # Many-to-one (2 or 4 fine facets per macro facet), built once per mesh pair.
        self.entity_maps = compat.entity_maps(fine, maps)
        self.macro_entity_maps = compat.entity_maps(macro, {sub: macro_to_sub})

        gdim = fine.geometry.dim
        self.V = fem.functionspace(fine, ("Lagrange", 1, (gdim,)))
        self.Q = fem.functionspace(sub, ("DG", 0))

        self._dirichlet_facets = {
            t: self.facet_tags.find(t).astype(np.int32) for t in problem.dirichlet
        }
        self.u_old: fem.Function | None = None
        self.obstacle_translation: dict[int, np.ndarray] | None = None
        self.bcs = self.dirichlet_bcs(self.V)
        self.prescribed_bcs = self.dirichlet_bcs(self.V, homogeneous=False)
        self._make_fields()

        dx = ufl.Measure("dx", domain=fine, subdomain_data=self.cell_tags)
        ds = ufl.Measure("ds", domain=fine, subdomain_data=self.facet_tags)
        self._body_force: tuple[Any, ufl.Measure] | None = None
        self.m = Measures(
            x=ufl.SpatialCoordinate(fine),
            dx=dx,
            ds_contact=ds(problem.contact),  # a tag, or a tuple of tags
            ds=ds,
            n=ufl.FacetNormal(fine),
            mesh=fine,
            problem=problem,
            fields=self.fields,
            obstacle_displacement=self.fields.obstacle_displacement,
        )

    def for_problem(self, problem: SignoriniProblem) -> Discretization:
        """This discretisation with another problem's data on the same macro mesh.

        The meshes, spaces and maps are shared (no refinement, the same dof layout: functions
        of one are functions of the other); the Dirichlet conditions, the measures and the
        fields are the new problem's. A load path's steps use it
        (:func:`~dwr_signorini.solve_path`).

        Args:
            problem: A problem on this discretisation's macro mesh, with the same contact tags.

        Returns:
            A new :class:`Discretization` sharing this one's meshes and spaces (``u_old``
            None).

        Raises:
            ValueError: ``problem`` lives on another mesh or has other contact tags.
        """
        if problem.mesh is not self.macro_mesh or problem.contact_tags != (
            self.problem.contact_tags
        ):
            raise ValueError(
                "for_problem: the problem must live on this discretisation's macro mesh, with "
                "the same contact tags"
            )
        out = copy.copy(self)
        out.problem = problem
        out.u_old = out.obstacle_translation = None
        out._dirichlet_facets = {
            t: self.facet_tags.find(t).astype(np.int32) for t in problem.dirichlet
        }
        out.bcs = out.dirichlet_bcs(out.V)
        out.prescribed_bcs = out.dirichlet_bcs(out.V, homogeneous=False)
        out._make_fields()
        out._body_force = None
        out.m = dataclasses.replace(self.m, problem=problem, fields=out.fields,
                                    obstacle_displacement=out.fields.obstacle_displacement)
        return out

    def vector_space(self, degree: int) -> fem.FunctionSpace:
        """The vector Lagrange space of ``degree`` on T_h, one per mesh (``V`` for degree 1).

        Args:
            degree: 1 (the solves) or 2 (the weights of the estimators).

        Returns:
            The space, built on first use and kept.
        """
        if degree == 1:
            return self.V
        if degree not in self._spaces:
            gdim = self.mesh.geometry.dim
            self._spaces[degree] = fem.functionspace(self.mesh, ("Lagrange", degree, (gdim,)))
        return self._spaces[degree]

    def master_trace(self, V: fem.FunctionSpace | None = None) -> MasterTrace | None:
        """The master trace of the contact pairs for a displacement space.

        One :class:`~dwr_signorini.pairs.TraceGeometry` per mesh and one trace per space,
        built on first use (collective) and kept until :meth:`destroy`.

        Args:
            V: ``self.V`` (the default) or ``self.vector_space(2)``.

        Returns:
            The :class:`~dwr_signorini.pairs.MasterTrace`, or None without contact pairs.

        Raises:
            ValueError: ``V`` is not one of this discretisation's vector spaces.
        """
        if self.slave_mesh is None:
            return None
        V = self.V if V is None else V
        degree = V.ufl_element().embedded_superdegree
        if V is not self.vector_space(degree):
            raise ValueError(
                "master_trace: V must be a displacement space of this discretisation "
                "(disc.V or disc.vector_space(2))"
            )
        if "geometry" not in self._traces:
            self._traces["geometry"] = TraceGeometry(self)
        if degree not in self._traces:
            self._traces[degree] = MasterTrace(self, V, self._traces["geometry"])
        return self._traces[degree]

    def trace_image(self, v: Any) -> Any:
        """P v, the projected master trace of ``v`` (:class:`~dwr_signorini.pairs.MasterTrace`).

        Args:
            v: A displacement on T_h (a Function of a vector Lagrange space, or a sum of
                them).

        Returns:
            A new function of the trace's space W whose ``trace_of`` is ``v`` (the sum of
            such functions for a sum), or None without pairs.

        Raises:
            TypeError: ``v`` is not a Function or a sum of them.
        """
        if self.slave_mesh is None:
            return None
        if isinstance(v, ufl.algebra.Sum):  # u_h + (A u_h - u_h), a reconstruction
            a, b = v.ufl_operands
            return self.trace_image(a) + self.trace_image(b)
        if not isinstance(v, fem.Function):
            raise TypeError(
                f"the master trace is taken of a Function, got {type(v).__name__}"
            )
        return self.master_trace(v.function_space).apply(v)

    def contact_frame(self) -> Any:
        """The normal of the contact frame on Gamma_C (UFL), in which the slip is measured.

        The tangential components of a frictional law act along the tangents of the plane
        normal to it (:meth:`~dwr_signorini.laws.Component.direction_in`), in the Newton
        matrix, the dual problem and the estimator alike: a rigid obstacle's normal where the
        body's normal ray enters it, the bisector of the two normals of a contact pair
        (:meth:`~dwr_signorini.fields.MeshFields.frame_normal`).

        Returns:
            The unit normal n_c of the contact frame, a UFL vector on Gamma_C.
        """
        return self.fields.frame_normal(self.m.x, self.m.n)

    def force_balance(self, mus: Any, per_component: bool = False) -> Any:
        """The force-balance row of an obstacle under a given force: w(mu), UFL.

        ``w(mu) = sum_k int_GC (-e_k . d) mu_k ds`` (:mod:`~dwr_signorini.force`: w^T lam = F),
        d the obstacle's direction of approach, e_0 = n_c and e_l the frame's tangents
        (:meth:`directions`): the body's traction on the obstacle is lam_n n_c + lam_l e_l.

        Args:
            mus: The multipliers of the law's components (a tuple, normal first; trial, test
                or discrete functions), or one multiplier for a frictionless law.
            per_component: Return each component's term instead of their sum.

        Returns:
            The linear form ``w(mu)`` (UFL), a scalar for discrete multipliers.

        Raises:
            ValueError: If the problem has no obstacle under a given force, or ``mus`` is
                not one multiplier per component of the law.
        """
        mus = tuple(mus) if isinstance(mus, (tuple, list)) else (mus,)
        d = self.fields.approach()
        directions = self.directions(self.problem.law.components(self.mesh.topology.dim))
        if len(mus) != len(directions):
            raise ValueError(
                f"force_balance: {len(directions)} multipliers expected (one per component of "
                f"the law {self.problem.law!r}), got {len(mus)}"
            )
        terms = [-ufl.dot(e, d) * mu * self.m.ds_contact
                 for e, mu in zip(directions, mus, strict=True)]
        return terms if per_component else sum(terms)

    def directions(self, components: Any) -> list[Any]:
        """The directions of a law's components in its contact frame.

        Args:
            components: The law's components (normal first).

        Returns:
            e_k of each component (:meth:`~dwr_signorini.laws.Component.direction_in`), UFL.
        """
        n, frame = self.m.n, self.contact_frame()
        return [comp.direction_in(n, frame) for comp in components]

    def normal_gap(self, components: Any, gap: Any) -> Any:
        """The normal component's offset in the contact frame.

        Args:
            components: The law's components (normal first).
            gap: The gap g along the body's normal n (UFL).

        Returns:
            g (n . n_c) (:meth:`contact_frame`).
        """
        return components[0].offset_in(gap, self.m.n, self.contact_frame())

    def relative(self, v: Any) -> Any:
        """The relative displacement v - P v on Gamma_C (:mod:`~dwr_signorini.pairs`).

        ``v`` itself on the rigid-obstacle contact (no pairs). P v is explicit in the
        expression: a new function (:meth:`trace_image`) whose ``trace_of`` is ``v``, which
        :func:`~dwr_signorini.pairs.images_of` finds in any form built from it.

        Args:
            v: A displacement on T_h (a Function of a vector Lagrange space, or a sum of
                them).

        Returns:
            The UFL expression v - P v (``v`` without pairs).

        Raises:
            TypeError: ``v`` is not a Function (with pairs, its trace is computed from its
                values).
        """
        if self.slave_mesh is None:
            return v
        return v - self.trace_image(v)

    def destroy(self) -> None:
        """Release the master traces of this mesh (collective; idempotent).

        Shared with the discretisations :meth:`for_problem` made; a later use builds them
        again.
        """
        for trace in self._traces.values():
            trace.destroy()
        self._traces.clear()

    def set_u_old(
        self, u_old: fem.Function | None, translation: dict[int, np.ndarray] | None = None,
        obstacle_start: float | None = None,
    ) -> None:
        """Measure the slip of this discretisation's solves from ``u_old`` (a load step's start).

        Args:
            u_old: A displacement on V (copied), or on another mesh of the same body
                (interpolated: exact for P1 on a mesh that T_h refines), or None (zero).
            translation: ``{rigid contact tag: t}``, the obstacles' translation since
                ``u_old`` (:func:`~dwr_signorini.obstacle_motion.path_translations`), or None:
                the slip is measured from u_old + t (:meth:`slip_origin`).
            obstacle_start: delta_0, the displacement of a force-controlled obstacle at
                ``u_old`` (the previous step's; None: 0).

        Raises:
            TypeError: ``u_old`` is not a vector function of the mesh's dimension.
        """
        self.obstacle_translation = None if u_old is None else translation
        if self.fields.obstacle_start is not None:
            start = None if u_old is None else obstacle_start
            self.fields.obstacle_start.value = 0.0 if start is None else start
        if u_old is None:
            self.u_old = None
            return
        if not isinstance(u_old, fem.Function) or u_old.ufl_shape != self.V.value_shape:
            raise TypeError(
                f"u_old must be a dolfinx Function with values of shape {self.V.value_shape} "
                f"(a displacement), got {type(u_old).__name__}"
            )
        out = fem.Function(self.V, name="u_old")
        if u_old.function_space == self.V:
            out.x.array[:] = u_old.x.array
        else:
            tdim = self.mesh.topology.dim
            cells = np.arange(self.mesh.topology.index_map(tdim).size_local, dtype=np.int32)
            data = fem.create_interpolation_data(self.V, u_old.function_space, cells, 1e-10)
            out.interpolate_nonmatching(u_old, cells, data)
            out.x.scatter_forward()
        self.u_old = out

    def slip_origin(self) -> Any:
        """Where a load step's slip is measured from: the tangential offsets' displacement.

        ``u_old - P u_old`` (:meth:`relative`), plus the translation t of a rigid obstacle that
        moved since the previous step (:mod:`~dwr_signorini.obstacle_motion`): the slip
        increment is (u - u_old - t) . e_l, and g_l = B_l (u_old + t), in the Newton matrix's
        right-hand side and in the estimator's residuals alike. A force-controlled obstacle
        adds its motion in the step, (delta - delta_0) d
        (:meth:`~dwr_signorini.fields.MeshFields.obstacle_motion`), with the Constant delta
        of the solve.

        Returns:
            A UFL vector on Gamma_C, or None (zero: outside a load path, no obstacle moved).
        """
        motion = self.fields.obstacle_motion()
        if self.u_old is None:
            return motion
        origin = self.relative(self.u_old)
        if self.obstacle_translation is not None:
            origin = origin + self.fields.translation(self.obstacle_translation)
        return origin if motion is None else origin + motion

    def _make_fields(self) -> None:
        """The problem's fields on T_h and T_H: cell tags of T_h (from the parents), indicators."""
        problem = self.problem
        tdim = self.mesh.topology.dim
        fine_tags = cell_tags_on_fine(
            problem.cell_tags, self.mesh, self.parent_cell, num_entities(self.macro_mesh, tdim)
        )
        self.cell_tags = fine_tags
        indicators = None
        if len(problem.contact_tags) > 1:  # data per contact tag (gap, friction)
            fdim = self.macro_mesh.topology.dim - 1
            tag_of = np.full(num_entities(self.macro_mesh, fdim), -1, dtype=np.int64)
            tag_of[problem.facet_tags.indices] = problem.facet_tags.values
            sub_tag = tag_of[self.contact_mesh_to_macro]
            cell_dof = self.Q.dofmap.list[: len(sub_tag), 0]
            indicators = {}
            for t in problem.contact_tags:
                chi = fem.Function(self.Q, name=f"contact_{t}")
                chi.x.array[cell_dof] = (sub_tag == t).astype(float)
                chi.x.scatter_forward()
                indicators[t] = chi
        pair_gap = None if self.slave_mesh is None else (lambda: self.master_trace().gap)
        pair_frame = None if self.slave_mesh is None else (lambda: self.master_trace().frame)
        self.fields = MeshFields(problem, self.mesh, fine_tags, indicators, pair_gap, pair_frame)
        self.macro_fields = MeshFields(problem, self.macro_mesh, problem.cell_tags, indicators)

    def load_form(self, v: Any) -> ufl.Form:
        """<l, v> on T_h (Section 2), for test functions or weights ``v`` of any degree.

        A non-polynomial body force is integrated with the rule of the problem's
        ``quadrature_degree`` wherever it appears (the Newton system, the residuals of the
        estimators), its integer powers
        written as products (:func:`~dwr_signorini.quadrature.expand_integer_powers`) once per
        mesh. Without ``pow`` calls, evaluating it inside each kernel costs less than storing
        its values at the quadrature points once (a quadrature space of 16 values per triangle
        to build, fill and pack into every kernel).

        Args:
            v: A test function or weight on T_h (UFL vector).

        Returns:
            The linear form of the body force and tractions against ``v``.
        """
        if self._body_force is None:
            with timed("assemble"):
                self._body_force = self._body_force_data()
        return self.problem.load_form(v, self.m, *self._body_force)

    def _body_force_data(self) -> tuple[Any, ufl.Measure]:
        expr = self.problem.vector(self.problem.body_force, self.m.x)
        if is_polynomial(expr):
            return expr, self.m.dx
        degree = {"quadrature_degree": self.problem.quadrature_degree}
        return expand_integer_powers(expr), self.m.dx(metadata=degree)

    def dirichlet_bcs(
        self, V: fem.FunctionSpace, homogeneous: bool = True
    ) -> list[fem.DirichletBC]:
        """The Dirichlet conditions on Gamma_D for a vector space V on T_h.

        Args:
            V: The displacement space (P1, or P2 for the higher-order solves).
            homogeneous: Zero values on the same dofs (the dual problem and every correction
                use these), or the prescribed values (the primal problem's lifting).

        Returns:
            One condition per tag on V for all components, or per prescribed component on
            ``V.sub(i)`` (``None`` components stay free), in the order of ``dirichlet``.
        """
        fdim = self.mesh.topology.dim - 1
        gdim = self.mesh.geometry.dim
        dtype = self.mesh.geometry.x.dtype
        bcs = []
        for tag, value in self.problem.dirichlet_values.items():
            facets = self._dirichlet_facets[tag]
            if callable(value) or all(c is not None for c in value):
                dofs = fem.locate_dofs_topological(V, fdim, facets)
                if homogeneous or not callable(value):
                    data = np.zeros(gdim, dtype=dtype)
                    if not homogeneous:
                        data[:] = value
                    bcs.append(fem.dirichletbc(data, dofs, V))
                else:
                    u_D = fem.Function(V, name=f"u_D_{tag}")
                    x = ufl.SpatialCoordinate(self.mesh)
                    where = f"dirichlet[{tag}]"
                    expr = ufl.as_vector(call_user(self.problem.mesh, where, value, x))
                    expr = nonzero_literal(expr, x)  # constant values: a Constant on the mesh
                    points = compat.interpolation_points(V.element)
                    u_D.interpolate(fem.Expression(expand_integer_powers(expr), points))
                    bcs.append(fem.dirichletbc(u_D, dofs))
                continue
            for i, c in enumerate(value):
                if c is not None:
                    dofs = fem.locate_dofs_topological(V.sub(i), fdim, facets)
                    data = dtype.type(0.0 if homogeneous else c)
                    bcs.append(fem.dirichletbc(data, dofs, V.sub(i)))
        return bcs

    # -- sizes, as in the paper's tables -----------------------------------------------------
    @property
    def num_cells(self) -> int:
        """M_Omega: number of cells of T_h."""
        return self.mesh.topology.index_map(self.mesh.topology.dim).size_global

    @property
    def num_macro_cells(self) -> int:
        """Number of cells of T_H."""
        return self.macro_mesh.topology.index_map(self.macro_mesh.topology.dim).size_global

    @property
    def num_contact_elements(self) -> int:
        """M_C: number of macro contact facets (multiplier unknowns)."""
        return self.Q.dofmap.index_map.size_global

    @property
    def num_dofs(self) -> int:
        """Displacement plus multiplier unknowns."""
        V_map = self.V.dofmap.index_map
        return V_map.size_global * self.V.dofmap.index_map_bs + self.num_contact_elements

    def form(self, expr: ufl.Form, **options: Any) -> fem.Form:
        """Compile a form on T_h that may use functions of Q (through the entity maps).

        Args:
            expr: The form.
            options: Passed to ``dolfinx.fem.form`` (``form_compiler_options``,
                ``jit_options``).

        Returns:
            The compiled ``dolfinx.fem.Form``.
        """
        return compat.form(expr, entity_maps=self.entity_maps, **options)

    def macro_form(self, expr: ufl.Form) -> fem.Form:
        """Compile a form on T_H that may use functions of Q.

        Args:
            expr: The form, on the macro mesh.

        Returns:
            The compiled ``dolfinx.fem.Form``.
        """
        return compat.form(expr, entity_maps=self.macro_entity_maps)


def _find(tags: dmesh.MeshTags, values: tuple[int, ...]) -> np.ndarray:
    """The (sorted, unique) entities carrying any of ``values``."""
    return np.unique(np.concatenate([tags.find(t) for t in values])).astype(np.int32)


def discretize(problem: SignoriniProblem) -> Discretization:
    """Build T_h, V_h and Lambda_H for ``problem`` (Section 4, H = 2h).

    Args:
        problem: The problem; its mesh is the macro mesh T_H.

    Returns:
        The :class:`Discretization` (collective: T_h is refined on every rank).
    """
    return Discretization(problem)
