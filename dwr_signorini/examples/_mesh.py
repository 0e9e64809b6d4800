"""Boundary tags and mesh checks shared by the examples' mesh builders.

Every example mesh tags all its exterior facets with :data:`DIRICHLET` (1, the clamped boundary
Gamma_D), :data:`NEUMANN` (2, traction-free) or :data:`CONTACT` (3, the possible contact boundary
Gamma_C).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt
from dolfinx import mesh as _mesh
from dolfinx.mesh import CellType, Mesh, MeshTags

__all__ = ["CONTACT", "DIRICHLET", "NEUMANN", "check_cell_type", "tag_exterior_facets"]

#: Facet tag of the Dirichlet boundary Gamma_D.
DIRICHLET = 1
#: Facet tag of the (homogeneous, traction-free) Neumann boundary Gamma_N.
NEUMANN = 2
#: Facet tag of the possible contact boundary Gamma_C.
CONTACT = 3


def tag_exterior_facets(
    msh: Mesh, classify: Callable[[npt.NDArray[np.float64]], npt.ArrayLike]
) -> MeshTags:
    """Tag every exterior facet of ``msh`` by its midpoint.

    Works in parallel: each process tags the exterior facets it sees (owned or ghost); facets on
    process boundaries are interior and are not returned by ``exterior_facet_indices``.

    Args:
        msh: The mesh.
        classify: Maps midpoints, shape ``(3, num_facets)``, to tags in
            {:data:`DIRICHLET`, :data:`NEUMANN`, :data:`CONTACT`}.

    Returns:
        Facet tags on all exterior facets.

    Raises:
        RuntimeError: If ``classify`` returns another tag.
    """
    tdim = msh.topology.dim
    fdim = tdim - 1
    msh.topology.create_connectivity(fdim, tdim)
    facets = _mesh.exterior_facet_indices(msh.topology)
    midpoints = _mesh.compute_midpoints(msh, fdim, facets).reshape(-1, 3)
    values = np.asarray(classify(midpoints.T), dtype=np.int32)
    if not np.all(np.isin(values, (DIRICHLET, NEUMANN, CONTACT))):
        raise RuntimeError("an exterior facet was not classified as Dirichlet, Neumann or contact")
    order = np.argsort(facets)
    return _mesh.meshtags(msh, fdim, facets[order], values[order])


def tag_block_facets(msh: Mesh, clamped_at: float, contact_at: float = 0.0) -> MeshTags:
    """Tag the exterior facets of a block by their height (the last coordinate).

    The facets in the plane at height ``clamped_at`` get :data:`DIRICHLET`, those at
    ``contact_at`` :data:`CONTACT` and the others (the sides) :data:`NEUMANN`: a block clamped
    (or moved) on one face and in possible contact on the opposite one.

    Args:
        msh: The mesh of a box or rectangle whose two faces are planes of constant height.
        clamped_at: Height of the Dirichlet face.
        contact_at: Height of the contact face.

    Returns:
        Facet tags on all exterior facets (:func:`tag_exterior_facets`).
    """
    up = msh.topology.dim - 1

    def classify(x: npt.NDArray[np.float64]) -> npt.NDArray[np.int32]:
        tags = np.full(x.shape[1], NEUMANN, dtype=np.int32)
        tags[np.isclose(x[up], clamped_at)] = DIRICHLET
        tags[np.isclose(x[up], contact_at)] = CONTACT
        return tags

    return tag_exterior_facets(msh, classify)


def check_cell_type(cell_type: CellType, allowed: Sequence[CellType]) -> None:
    """Check that a mesh builder was asked for one of the cell types it supports.

    Args:
        cell_type: The requested cell type.
        allowed: The cell types the builder supports.

    Raises:
        ValueError: If ``cell_type`` is not in ``allowed``.
    """
    if cell_type not in allowed:
        names = " or ".join(c.name for c in allowed)
        raise ValueError(f"cell_type must be {names}, got {cell_type}")
