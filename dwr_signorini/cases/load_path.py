"""The gmsh meshes and the press-then-shear load path of the Cattaneo-Mindlin cases.

What :mod:`~dwr_signorini.cases.cattaneo_mindlin_2d` (a cylinder) and
:mod:`~dwr_signorini.cases.cattaneo_mindlin_3d` (a sphere) share: the facet tags of their gmsh
scripts, the reading of a script of the package (:data:`MESHES`, the checkout's ``meshes/``
installed with it as :mod:`dwr_signorini.meshes`, so it works from the checkout and after
``pip install .``), the mesh made by gmsh on rank 0 and distributed, and the load path of
:func:`shear_path`.
"""

from __future__ import annotations

import importlib.resources
import importlib.util
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np
from dolfinx import mesh as dmesh

from ..laws import Coulomb
from ..mesh_io import read_mesh
from ..obstacles import Plane
from ..problem import SignoriniProblem

__all__ = ["CM_CONTACT", "CM_TOP", "MESHES", "check_steps", "gmsh_mesh", "mesh_script",
           "shear_path"]

#: Facet tags of ``meshes/cattaneo_2d.py`` (and of ``meshes/hertz_3d.py``): the arc Gamma_C
#: and the top.
CM_CONTACT, CM_TOP = 1, 2

#: The folder of the gmsh scripts: the checkout's meshes/, installed with the package as
#: dwr_signorini.meshes (found through the package, wherever it is imported from).
MESHES = Path(str(importlib.resources.files("dwr_signorini.meshes")))


def mesh_script(script: Path) -> Any:
    """The module of the gmsh script ``script`` (a file of :data:`MESHES`), with the CM tags.

    Args:
        script: The path of the script.

    Returns:
        The module.

    Raises:
        FileNotFoundError: If the script is missing.
        RuntimeError: If its tags differ from :data:`CM_CONTACT`, :data:`CM_TOP`.
    """
    if not script.is_file():
        raise FileNotFoundError(
            f"the Cattaneo-Mindlin mesh builders read the gmsh script {script}, which is missing "
            "(a package installed without its meshes/): pass mesh=(msh, cell_tags, facet_tags)"
        )
    spec = importlib.util.spec_from_file_location(f"meshes_{script.stem}", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    if (module.CONTACT, module.TOP) != (CM_CONTACT, CM_TOP):
        raise RuntimeError(f"{script}: tags differ from CM_CONTACT, CM_TOP")
    return module



def gmsh_mesh(
    comm: MPI.Comm, script_path: Path, **kwargs: Any
) -> tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags]:
    """The mesh of a gmsh script's ``build(model, **kwargs)``, made on rank 0 and distributed."""
    import gmsh

    script = mesh_script(script_path)
    started = not gmsh.isInitialized()
    if started:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.add(script_path.stem)
            script.build(gmsh.model, **kwargs)
        return read_mesh(gmsh.model, comm)
    finally:
        if started:
            gmsh.finalize()
        elif comm.rank == 0:
            gmsh.model.remove()


def check_steps(steps: int) -> None:
    """Raise a ValueError unless ``steps`` is a positive integer."""
    if int(steps) != steps or steps < 1:
        raise ValueError(f"steps must be a positive integer, got {steps!r}")


def shear_path(
    mesh: tuple[dmesh.Mesh, dmesh.MeshTags, dmesh.MeshTags],
    dim: int,
    *,
    mu: float,
    nu: float,
    steps: int,
    press: float,
    shear: float,
    E: float,
    radius: float,
    fixed: dict[int, tuple[float | None, ...]] | None = None,
) -> list[SignoriniProblem]:
    """The press step and the ``steps`` shear steps of a cylinder (2D) or sphere (3D).

    The body of radius ``radius`` centred at ``radius e_dim`` touches the rigid flat
    x_dim <= 0 at the origin (Coulomb friction ``mu``); its top :data:`CM_TOP` is displaced by
    ``-press e_dim + (k shear / steps) e_x`` in step k = 0, ..., ``steps``, and
    :data:`CM_CONTACT` is projected onto the circle (sphere) when the mesh is refined.

    Args:
        mesh: ``(msh, cell_tags, facet_tags)``.
        dim: 2 (plane strain) or 3.
        mu: Coulomb's friction coefficient.
        nu: Poisson's ratio.
        steps: The number of shear steps.
        press: The top's displacement towards the flat.
        shear: The top's final displacement along x.
        E: Young's modulus.
        radius: The radius R.
        fixed: Further Dirichlet conditions of every step, ``{tag: components}``.

    Returns:
        ``steps + 1`` problems on ``mesh``.
    """
    msh, cell_tags, facet_tags = mesh
    flat = Plane((0.0,) * dim, (0.0,) * (dim - 1) + (-1.0,))
    center = np.zeros(3)
    center[dim - 1] = radius
    center = center[:, None]

    def onto_surface(x: np.ndarray) -> np.ndarray:
        d = x - center
        d[dim:] = 0.0
        return center + radius * d / np.linalg.norm(d, axis=0)

    law = Coulomb(mu)
    model = "plane_strain" if dim == 2 else "3d"
    return [
        SignoriniProblem(
            msh, facet_tags, contact=CM_CONTACT,
            dirichlet={CM_TOP: (k * shear / steps, *(0.0,) * (dim - 2), -press), **(fixed or {})},
            E=E, nu=nu, model=model, gap=flat, friction=law, cell_tags=cell_tags,
            boundary_projection={CM_CONTACT: onto_surface},
        )
        for k in range(int(steps) + 1)
    ]
