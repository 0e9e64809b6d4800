"""Rigid body modes of a vector space: the near-nullspace of K for algebraic multigrid."""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np
from dolfinx import fem

__all__ = ["rigid_body_modes"]


def rigid_body_modes(V: fem.FunctionSpace, n_local: int) -> PETSc.NullSpace:
    """Rigid body modes of V (translations, rotations) as an orthonormal PETSc null space.

    Args:
        V: A vector space on the mesh.
        n_local: Owned rows of the vectors (owned dofs times the block size).

    Returns:
        The null space; its vectors are owned by it (destroy it when done).
    """
    x = V.tabulate_dof_coordinates()[: V.dofmap.index_map.size_local]
    gdim = V.mesh.geometry.dim
    modes = [np.zeros((len(x), gdim)) for _ in range(3 if gdim == 2 else 6)]
    for i in range(gdim):
        modes[i][:, i] = 1.0
    if gdim == 2:
        modes[2][:, 0], modes[2][:, 1] = -x[:, 1], x[:, 0]
    else:
        for k, (i, j) in enumerate([(0, 1), (1, 2), (2, 0)]):
            modes[3 + k][:, i], modes[3 + k][:, j] = -x[:, j], x[:, i]
    vecs = []
    for mode in modes:
        vec = PETSc.Vec().createMPI((n_local, None), comm=V.mesh.comm)
        vec.array[:] = mode.ravel()
        vecs.append(vec)
    for i, vec in enumerate(vecs):  # modified Gram-Schmidt
        for prev in vecs[:i]:
            vec.axpy(-vec.dot(prev), prev)
        vec.scale(1.0 / vec.norm())
    space = PETSc.NullSpace().create(vectors=vecs, comm=V.mesh.comm)
    for vec in vecs:  # the null space holds its own references
        vec.destroy()
    return space
