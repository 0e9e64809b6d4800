"""One place for the differences between dolfinx 0.9 (Debian trixie) and 0.11 (Debian sid).

Every wrapper detects the feature it needs (``hasattr``, ``inspect.signature``, an import that may
fail), never a version string, so a dolfinx between or after the two works as long as it has one
of the two APIs. Each docstring says what differs. Nothing here changes behaviour on 0.9: there
the wrappers call the 0.9 API with the arguments the package has always used.

Differences the package meets, in short:

* ``create_submesh`` returns :class:`dolfinx.mesh.EntityMap` objects (0.11) instead of arrays
  (0.9) for the entity and vertex maps: :func:`create_submesh` returns arrays on both.
* ``fem.form(..., entity_maps=...)`` takes a list of ``EntityMap`` (0.11) instead of a dict
  ``{mesh: array}`` indexed by the integration domain's entities (0.9): :func:`entity_maps` builds
  either from the 0.9 dict, including the many-to-one map from fine facets to the cells of a
  macro facet submesh; :func:`form` compiles with it.
* ``dolfinx.mesh.refine``: the default partitioner changed (0.11: keep cells on their rank but
  add a ghost layer); ``partitioner=None`` keeps the refined mesh free of ghost cells on both, and
  on both the parent arrays come in creation order, not local cell order: :func:`refine`.
* ``create_mesh(comm, cells, x, e)`` (0.9) became ``create_mesh(comm, cells, e, x)`` (0.11):
  :func:`create_mesh` passes them by name.
* ``create_cell_partitioner(mode)`` (0.9) needs ``max_facet_to_cell_links`` (0.11):
  :func:`cell_partitioner`; ``graph.adjacencylist`` returns a Python wrapper (0.11) where a
  Python cell partitioner must return the C++ object: :func:`cpp_adjacencylist`.
* ``dolfinx.io.gmshio.model_to_mesh`` -> ``dolfinx.io.gmsh.model_to_mesh``, returning a
  ``MeshData`` named tuple of six fields instead of three values: :func:`gmsh_model_to_mesh`.
* ``element.interpolation_points`` is a property (0.11) instead of a method:
  :func:`interpolation_points`; ``ufl.Cell.is_simplex`` likewise (ufl 2026): :func:`is_simplex`.
* ``Geometry.dofmap`` / ``Geometry.cmap`` are deprecated for ``dofmaps[0]`` / ``cmaps[0]``
  (0.11): :func:`geometry_dofmap`, :func:`geometry_cmap`.
* ``dolfinx.io.VTXWriter`` exists where dolfinx was built with ADIOS2 (``common.has_adios2``);
  in 0.9 all functions of one writer need the same element (degree and continuity), in 0.11
  not: :func:`has_vtx` (the writers group the functions by element on every version).

The wrappers only the tests use (``LinearProblem``, ``create_vector``, block assembly,
``bb_tree``, ``PointOwnershipData``) are in the tests (``tests/fem_compat.py``).

Unchanged (checked): ``fem.create_interpolation_data(V_to, V_from, cells, padding)`` and
``Function.interpolate_nonmatching(u, cells, data)`` (0.11 adds optional ``tol``, ``maxit``);
``mesh.topology`` is a Python ``Topology`` with ``_cpp_object`` on both; ``fem.petsc.set_bc``,
``assemble_matrix(form, bcs=...)``, ``assemble_vector(form)``.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
from dolfinx import fem
from dolfinx import mesh as dmesh

__all__ = [
    "HAS_ENTITY_MAP",
    "cell_partitioner",
    "cpp_adjacencylist",
    "create_mesh",
    "create_submesh",
    "entity_maps",
    "form",
    "geometry_cmap",
    "geometry_dofmap",
    "gmsh_model_to_mesh",
    "has_vtx",
    "interpolation_points",
    "is_simplex",
    "memoize_jit_modules",
    "parameter_names",
    "refine",
]

#: dolfinx has ``mesh.EntityMap`` (0.10 and later): submesh maps are objects, and forms take a
#: list of them instead of a dict of arrays.
HAS_ENTITY_MAP: bool = hasattr(dmesh, "EntityMap") and hasattr(dmesh, "entity_map")


def _num_entities(msh: dmesh.Mesh, dim: int) -> int:
    imap = msh.topology.index_map(dim)
    return imap.size_local + imap.num_ghosts


def parameter_names(func: Callable) -> list[str]:
    """Parameter names of ``func``, a feature test.

    Args:
        func: A function or class.

    Returns:
        Its parameter names; empty if it has no Python signature (e.g. a nanobind one).
    """
    try:
        return list(inspect.signature(func).parameters)
    except (TypeError, ValueError):
        return []


# -- submeshes and entity maps ---------------------------------------------------------------


def _entity_map_array(emap: Any, num: int) -> npt.NDArray[np.int32]:
    """The sub -> parent array of a 0.11 ``EntityMap`` (or a 0.9 array, as it is)."""
    if hasattr(emap, "sub_topology_to_topology"):
        return np.asarray(
            emap.sub_topology_to_topology(np.arange(num, dtype=np.int32), False), dtype=np.int32
        )
    return np.asarray(emap, dtype=np.int32)


def create_submesh(
    msh: dmesh.Mesh, dim: int, entities: npt.NDArray[np.int32]
) -> tuple[dmesh.Mesh, npt.NDArray[np.int32], npt.NDArray[np.int32], npt.NDArray[np.int32]]:
    """``dolfinx.mesh.create_submesh`` with the maps as arrays, as dolfinx 0.9 returns them.

    What differs: 0.9 returns ``(submesh, entity_map, vertex_map, node_map)`` with int32 arrays
    (local sub entity -> local parent entity); 0.11 returns :class:`dolfinx.mesh.EntityMap`
    objects for the first two maps (the node map stays an array). Here all three are arrays on
    both, covering the submesh's local and ghost entities.

    Returns:
        ``(submesh, sub_to_parent_entity, sub_to_parent_vertex, sub_to_parent_node)``.
    """
    sub, emap, vmap, nodes = dmesh.create_submesh(msh, dim, entities)
    tdim = sub.topology.dim
    sub_to_parent = _entity_map_array(emap, _num_entities(sub, tdim))
    vertices = _entity_map_array(vmap, _num_entities(sub, 0))
    return sub, sub_to_parent, vertices, np.asarray(nodes, dtype=np.int32)


def entity_maps(
    integration_mesh: dmesh.Mesh, maps: Mapping[dmesh.Mesh, npt.NDArray[np.int32]]
) -> Any:
    """The ``entity_maps`` argument of ``fem.form`` from dolfinx 0.9's dict.

    ``maps[other][e]`` is the cell of ``other`` (a mesh whose functions appear in the form) that
    corresponds to entity ``e`` of ``integration_mesh`` (the mesh of the measures), or -1. The
    entities are those of dimension ``other.topology.dim``: cells for a cell submesh, facets for
    a facet submesh; the array covers local and ghost entities. Several entities may map to the
    same cell: e.g. the 2 (2D) or 4 (3D) fine facets of one macro facet map to that macro facet's
    cell of a facet submesh of the macro mesh.

    What differs: 0.9 takes this dict as it is. 0.11 takes a list of
    :class:`dolfinx.mesh.EntityMap`, each relating a "topology" and a "sub_topology" by an array
    indexed by the sub_topology's entities; a form maps the integration entities to a function's
    mesh through it, looking the array up directly when the integration mesh is the
    sub_topology. So the map is built with ``topology=other``, ``sub_topology=integration_mesh``
    and the same array, which expresses a many-to-one map exactly (the direction
    ``create_submesh`` uses, submesh -> parent, could not: it holds one parent entity per
    submesh cell). Checked on 1 and 2 ranks in 2D and 3D against 0.9's assembly.

    Note:
        In 0.11 the ``EntityMap`` docstring asks for sub_topology to be a sub-topology of
        topology; this use relies on ``Form`` only reading the array in the direction
        integration entity -> other cell, which it does in 0.11. Build the result once per
        mesh pair and reuse it: constructing it copies the arrays.
    """
    return _entity_maps(integration_mesh, maps)


def _entity_maps(
    integration_mesh: dmesh.Mesh, maps: Mapping[dmesh.Mesh, npt.NDArray[np.int32]]
) -> Any:
    if not HAS_ENTITY_MAP:
        return {other: np.asarray(array, dtype=np.int32) for other, array in maps.items()}
    out = []
    for other, array in maps.items():
        dim = other.topology.dim
        integration_mesh.topology.create_entities(dim)
        array = np.ascontiguousarray(array, dtype=np.int32)
        if array.shape != (_num_entities(integration_mesh, dim),):
            raise ValueError(
                f"entity map has {array.size} entries, the integration mesh has "
                f"{_num_entities(integration_mesh, dim)} entities of dimension {dim}"
            )
        out.append(
            dmesh.entity_map(
                _py_topology(other.topology), _py_topology(integration_mesh.topology), dim, array
            )
        )
    return out


def _py_topology(topology: Any) -> Any:
    """The Python ``Topology`` of a Python or C++ topology (a UFL domain carries the C++ mesh)."""
    return topology if hasattr(topology, "_cpp_object") else dmesh.Topology(topology)


def _integration_mesh(expr: Any) -> dmesh.Mesh:
    integrals = expr.integrals()
    if not integrals:
        raise ValueError("the form has no integrals")
    return integrals[0].ufl_domain().ufl_cargo()


#: FFCx JIT modules loaded in this process, by (module name, object names, cache directory).
_JIT_MODULES: dict[tuple[str, tuple[str, ...], str], tuple[Any, Any]] = {}


def memoize_jit_modules() -> bool:
    """Load each FFCx JIT module from the disk cache once per process.

    ``ffcx.codegeneration.jit.get_cached_module`` (0.9 and 0.11) lists the whole cache
    directory (``importlib``'s ``FileFinder``) and executes the module again for every form it
    finds compiled: with the thousands of modules of a used cache that took 4.6 ms per form,
    0.07 s per level of example 5.1 (15 forms). The same module name is the same code (the name
    is the signature of the forms and the options), so it is loaded once and its objects reused.
    Switched on once, where the package is imported (``dwr_signorini/__init__.py``), before
    any form is compiled; a no-op where FFCx lacks the function or its signature differs, and
    when called again.

    Returns:
        Whether the memo is installed.
    """
    try:
        from ffcx.codegeneration import jit as ffcx_jit
    except ImportError:
        return False
    original = getattr(ffcx_jit, "get_cached_module", None)
    if original is None:
        return False
    if getattr(original, "_dwr_signorini_memo", False):
        return True
    if list(inspect.signature(original).parameters)[:3] != [
        "module_name",
        "object_names",
        "cache_dir",
    ]:
        return False

    def get_cached_module(
        module_name: str, object_names: Any, cache_dir: Any, *args: Any, **kwargs: Any
    ) -> tuple[Any, Any]:
        key = (module_name, tuple(object_names), str(cache_dir))
        found = _JIT_MODULES.get(key)
        if found is None:
            found = original(module_name, object_names, cache_dir, *args, **kwargs)
            if found[0] is not None:
                _JIT_MODULES[key] = found
        return found

    get_cached_module._dwr_signorini_memo = True  # type: ignore[attr-defined]
    ffcx_jit.get_cached_module = get_cached_module
    return True


def form(expr: Any, entity_maps: Any = None, **kwargs: Any) -> fem.Form:
    """``fem.form`` with ``entity_maps`` given as 0.9's dict (or as :func:`entity_maps` built it).

    What differs: see :func:`entity_maps`. A dict is converted for the form's integration mesh
    (the mesh of its first integral's measure); a value already built by :func:`entity_maps`
    (a dict on 0.9, a list on 0.11) is passed through. ``expr`` is a single UFL form.
    """
    if entity_maps is None:
        return fem.form(expr, **kwargs)
    if HAS_ENTITY_MAP and isinstance(entity_maps, Mapping):
        entity_maps = _entity_maps(_integration_mesh(expr), entity_maps)
    return fem.form(expr, entity_maps=entity_maps, **kwargs)


# -- meshes ------------------------------------------------------------------------------------


def refine(
    msh: dmesh.Mesh, edges: npt.NDArray[np.int32] | None = None, *, facets: bool = False
) -> tuple[dmesh.Mesh, npt.NDArray[np.int32], npt.NDArray[np.int8] | None]:
    """Refine a simplex mesh (Plaza), children on their parent's rank, no ghost cells.

    Returns ``(fine, parent_cell, parent_facet)`` indexed by the *local cell order of the fine
    mesh*: ``parent_cell[c]`` is the local parent cell of fine cell ``c`` and, if ``facets``,
    ``parent_facet[c * nf + j]`` the local facet index (in the parent cell) of the parent facet
    containing local facet ``j`` of ``c``, or -1 (else ``None``).

    What differs: the default partitioner of ``dolfinx.mesh.refine`` is a redistributing
    partitioner (0.9) and ``IdentityPartitionerPlaceholder()`` (0.11: cells stay, a ghost layer
    is added); ``partitioner=None`` means no redistribution and no ghost cells on both (checked on
    1 and 2 ranks, ghosted and unghosted parents). Common to both: the parent arrays come in the
    order in which the cells were created, so they are permuted here with
    ``topology.original_cell_index``.

    Raises:
        RuntimeError: If the refined mesh has ghost cells or an unexpected cell numbering.
    """
    tdim = msh.topology.dim
    msh.topology.create_entities(1)
    option = (
        dmesh.RefinementOption.parent_cell_and_facet
        if facets
        else dmesh.RefinementOption.parent_cell
    )
    fine, parent_cell, parent_facet = dmesh.refine(msh, edges, partitioner=None, option=option)
    cells = fine.topology.index_map(tdim)
    if cells.num_ghosts:
        raise RuntimeError("the refined mesh has ghost cells")
    num_local = cells.size_local
    offset = fine.comm.exscan(num_local) or 0
    order = np.asarray(fine.topology.original_cell_index[:num_local], dtype=np.int64) - offset
    parent_cell = np.asarray(parent_cell, dtype=np.int32)
    if order.size and (order.min() < 0 or order.max() >= len(parent_cell)):
        raise RuntimeError("unexpected cell numbering of the refined mesh")
    parent_cell = np.ascontiguousarray(parent_cell[order])
    if not facets:
        return fine, parent_cell, None
    nf = tdim + 1
    parent_facet = np.asarray(parent_facet, dtype=np.int8).reshape(-1, nf)[order].reshape(-1)
    return fine, parent_cell, np.ascontiguousarray(parent_facet)


def create_mesh(
    comm: Any, cells: npt.ArrayLike, x: npt.ArrayLike, e: Any, partitioner: Callable | None = None
) -> dmesh.Mesh:
    """``dolfinx.mesh.create_mesh`` with 0.9's argument order ``(comm, cells, x, e)``.

    What differs: 0.11 swapped ``x`` and ``e``: ``create_mesh(comm, cells, e, x, partitioner,
    max_facet_to_cell_links)``. Both name the parameters ``x`` and ``e``, so they are passed by
    name. The partitioner's signature, ``(comm, nparts, cell_types, cells) -> AdjacencyList``,
    is the same on both, but a Python partitioner must return the C++ adjacency list
    (:func:`cpp_adjacencylist`).
    """
    return dmesh.create_mesh(comm, cells, x=x, e=e, partitioner=partitioner)


def cell_partitioner(ghost_mode: dmesh.GhostMode, max_facet_to_cell_links: int = 2) -> Callable:
    """``dolfinx.mesh.create_cell_partitioner(ghost_mode)``.

    What differs: 0.11 requires ``max_facet_to_cell_links`` (2 for a manifold mesh); 0.9's
    binding accepts only the ghost mode.
    """
    if "max_facet_to_cell_links" in parameter_names(dmesh.create_cell_partitioner):
        return dmesh.create_cell_partitioner(ghost_mode, max_facet_to_cell_links)
    return dmesh.create_cell_partitioner(ghost_mode)


def cpp_adjacencylist(
    data: npt.NDArray[np.int32], offsets: npt.NDArray[np.int32] | None = None
) -> Any:
    """A C++ ``AdjacencyList_int32``, as a Python cell partitioner must return it.

    What differs: ``dolfinx.graph.adjacencylist`` returns the C++ object in 0.9 and a Python
    ``dolfinx.graph.AdjacencyList`` wrapping it in 0.11; C++ calling back into a Python
    partitioner (``create_mesh(..., partitioner=f)``) needs the C++ object and fails with
    ``std::bad_cast`` on the wrapper. The callback's arguments ``(comm, nparts, cell_types,
    cells)`` are the same on both.
    """
    from dolfinx import graph

    data = np.asarray(data, dtype=np.int32)
    adj = graph.adjacencylist(data, offsets) if offsets is not None else graph.adjacencylist(data)
    return getattr(adj, "_cpp_object", adj)


def gmsh_model_to_mesh(
    model: Any, comm: Any, rank: int, gdim: int = 3, partitioner: Callable | None = None
) -> tuple[dmesh.Mesh, dmesh.MeshTags | None, dmesh.MeshTags | None]:
    """A dolfinx mesh from a gmsh model: ``(mesh, cell_tags, facet_tags)``.

    What differs: 0.9 has ``dolfinx.io.gmshio.model_to_mesh`` returning these three values; 0.11
    has ``dolfinx.io.gmsh.model_to_mesh`` returning ``MeshData(mesh, cell_tags, facet_tags,
    ridge_tags, peak_tags, physical_groups)``. Needs the gmsh Python module.
    """
    try:
        from dolfinx.io import gmsh as _gmsh

        model_to_mesh = _gmsh.model_to_mesh
    except ImportError:
        from dolfinx.io import gmshio as _gmsh

        model_to_mesh = _gmsh.model_to_mesh
    data = model_to_mesh(model, comm, rank, gdim=gdim, partitioner=partitioner)
    if hasattr(data, "facet_tags"):
        return data.mesh, data.cell_tags, data.facet_tags
    msh, cell_tags, facet_tags = data
    return msh, cell_tags, facet_tags


def geometry_dofmap(msh: dmesh.Mesh) -> npt.NDArray[np.int32]:
    """The geometry dofmap (cells x nodes) of a single-cell-type mesh.

    What differs: 0.11 deprecates ``geometry.dofmap`` for ``geometry.dofmaps[0]`` (a
    ``DeprecationWarning``); 0.9's Python ``Geometry`` has only ``dofmap``.
    """
    geometry = msh.geometry
    if hasattr(geometry, "dofmaps"):
        dofmaps = geometry.dofmaps
        return (dofmaps() if callable(dofmaps) else dofmaps)[0]
    return geometry.dofmap


def geometry_cmap(msh: dmesh.Mesh) -> Any:
    """The coordinate element of a single-cell-type mesh.

    What differs: 0.11 deprecates ``geometry.cmap`` for ``geometry.cmaps[0]``; 0.9's Python
    ``Geometry`` has only ``cmap``.
    """
    geometry = msh.geometry
    if hasattr(geometry, "cmaps"):
        cmaps = geometry.cmaps
        return (cmaps() if callable(cmaps) else cmaps)[0]
    return geometry.cmap





# -- forms, elements, solvers ------------------------------------------------------------------


def interpolation_points(element: Any) -> np.ndarray:
    """The reference interpolation points of a ``FunctionSpace.element``.

    What differs: a method in 0.9, a property in 0.11.
    """
    points = element.interpolation_points
    return points() if callable(points) else points


def is_simplex(cell: Any) -> bool:
    """Whether a UFL cell (``domain.ufl_cell()``) is a simplex.

    What differs: ``ufl.Cell.is_simplex`` is a method in ufl 2024.2 (with dolfinx 0.9) and a
    property in ufl 2026.1 (with dolfinx 0.11).
    """
    value = cell.is_simplex
    return bool(value() if callable(value) else value)


def has_vtx() -> bool:
    """Whether ``dolfinx.io.VTXWriter`` (ADIOS2) is available.

    What differs: dolfinx built without ADIOS2 has no ``VTXWriter`` (``common.has_adios2`` is
    False or missing).
    """
    from dolfinx import common, io

    return bool(getattr(common, "has_adios2", False)) and hasattr(io, "VTXWriter")
