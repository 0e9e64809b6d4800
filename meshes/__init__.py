"""The gmsh scripts of the demos', examples' and cases' meshes, one module per mesh.

Each module has ``build(model, ...)`` (geometry, named physical groups and the mesh, in a gmsh
model), its tags as constants and, for curved faces, ``projections()`` for
``boundary_projection``; run as a script it writes ``<name>.msh`` beside itself
(``_common.py``). The folder is the checkout's ``meshes/`` and is installed with the
package as ``dwr_signorini.meshes``, so ``from dwr_signorini.meshes import hertz_2d`` works in
the checkout and after ``pip install .`` alike.
"""

__all__: list[str] = []
