"""Higher-order reconstructions for the weights of the estimators (Section 4).

* i_2h^(2): patch-wise quadratic reconstruction of a fine P1 (Q1) function. The fine mesh is one
  uniform refinement of the macro mesh, so the vertices of the children of a macro cell are exactly
  the P2 (Q2) nodes of that macro cell: reading the fine nodal values as macro P2 values *is* the
  reconstruction. It is returned as a function of the fine P2 space (exact: a macro P2 function is
  P2 on every child).
* i_2H^(1): a linear reconstruction of a P0 function on the macro contact facets. Choice: the
  vertex-averaged recovery, i.e. the lumped L2 projection onto continuous P1 on Gamma_C of T_H,
  ``r(p) = int_GC lam phi_p / int_GC phi_p`` (the facet-size weighted mean of the values of the
  macro facets around vertex p). It is linear on each macro facet and second-order accurate at
  interior vertices for smooth lambda. It is returned as a scalar P1 function on T_h whose trace on
  Gamma_C is the reconstruction.
"""

from __future__ import annotations

from petsc4py import PETSc

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from .spaces import Discretization

__all__ = ["Reconstructor"]


def _all_cells(V: fem.FunctionSpace) -> np.ndarray:
    imap = V.mesh.topology.index_map(V.mesh.topology.dim)
    return np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)


class _Transfer:
    """Interpolation between two spaces on different meshes, data built once."""

    def __init__(self, V_to: fem.FunctionSpace, V_from: fem.FunctionSpace) -> None:
        self.cells = _all_cells(V_to)
        self.data = fem.create_interpolation_data(V_to, V_from, self.cells, padding=1e-10)

    def __call__(self, target: fem.Function, source: fem.Function) -> fem.Function:
        target.interpolate_nonmatching(source, self.cells, self.data)
        target.x.scatter_forward()
        return target


class Reconstructor:
    """Patch-wise reconstructions on one discretisation (interpolation data built once)."""

    def __init__(self, disc: Discretization) -> None:
        self.disc = disc
        gdim = disc.mesh.geometry.dim
        macro = disc.macro_mesh
        self.V2H = fem.functionspace(macro, ("Lagrange", 2, (gdim,)))
        self.V2h = fem.functionspace(disc.mesh, ("Lagrange", 2, (gdim,)))
        self.P1H = fem.functionspace(macro, ("Lagrange", 1))
        self.P1h = fem.functionspace(disc.mesh, ("Lagrange", 1))
        self._fine_to_macro = _Transfer(self.V2H, disc.V)
        self._macro_to_fine = _Transfer(self.V2h, self.V2H)
        self._scalar_to_fine = _Transfer(self.P1h, self.P1H)

        # Lumped mass of Gamma_C on the macro mesh: int_GC phi_p.
        phi = ufl.TestFunction(self.P1H)
        ds_macro = ufl.Measure("ds", domain=macro, subdomain_data=disc.problem.facet_tags)
        self._ds_c = ds_macro(disc.problem.contact)
        self._phi = phi
        mass = fem_petsc.assemble_vector(fem.form(phi * self._ds_c))
        mass.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        mass.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        self._mass = mass

    def __del__(self) -> None:
        mass = getattr(self, "_mass", None)
        if mass is not None:
            mass.destroy()

    def as_fine_p2(self, v: fem.Function) -> fem.Function:
        """A fine P1 function written in the fine P2 space (exact)."""
        out = fem.Function(self.V2h)
        out.interpolate(v)
        return out

    def patch_quadratic(self, v: fem.Function) -> fem.Function:
        """i_2h^(2) v: fine P1 values read as macro P2 values, as a fine P2 function."""
        macro = fem.Function(self.V2H)
        self._fine_to_macro(macro, v)
        return self._macro_to_fine(fem.Function(self.V2h, name=f"i2h({v.name})"), macro)

    def patch_linear_multiplier(self, lam: fem.Function) -> fem.Function:
        """i_2H^(1) lam: vertex-averaged P1 recovery on Gamma_C, as a scalar P1 function on T_h."""
        form = self.disc.macro_form(lam * self._phi * self._ds_c)
        num = fem_petsc.assemble_vector(form)
        num.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        num.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        rec = fem.Function(self.P1H)
        with num.localForm() as n_loc, self._mass.localForm() as m_loc:
            mass = m_loc.array_r
            rec.x.array[:] = np.divide(n_loc.array_r, mass, out=np.zeros_like(mass), where=mass > 0)
        num.destroy()
        return self._scalar_to_fine(fem.Function(self.P1h, name=f"i2H({lam.name})"), rec)
