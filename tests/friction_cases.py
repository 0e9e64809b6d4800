"""Exact uniform patch tests of frictional contact: a block pressed onto a rigid plane and sheared.

A block [0, 1]^(d-1) x [0, H] (2D: plane strain; 3D) rests on the rigid plane x_d = 0 (gap 0,
the contact boundary Gamma_C its bottom face, n = -e_d). Its top is displaced by (D_t, -delta),
D_t a shear in the tangent plane at an angle ``angle`` to e_1 (3D), and its sides carry the
tractions sigma n of the uniform state below. The exact solution is linear,

    u(x) = a + (x_d / H) ((D_t, -delta) - a),

with the rigid slip a of the bottom face (tangential): sigma_dd = -(lambda + 2 mu_l) delta / H,
the other normal stresses -lambda delta / H, the shear stresses mu_l (D_t - a) / H. On Gamma_C
lambda_n = (lambda + 2 mu_l) delta / H and, with Coulomb's law of coefficient mu, the slip
threshold s = mu lambda_n. Where the stick traction tau = mu_l |D_t| / H is below s (``ratio``
= tau / s < 1) the block sticks (a = 0, lambda_t = tau along D_t); above it slips
(lambda_t = s along D_t, a = D_t (1 - 1 / ratio)). Both are exact in every P1/Q1 space, so
the discrete solution is the exact one to round-off on any mesh of the block.

The sweep of :func:`sweep` covers stick ratios from 0.05 to 0.999, slip ratios from 1.001 to
100, mu from 0.01 to 2, triangles, quadrilaterals, tetrahedra and hexahedra, and oblique shear
directions in 3D.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mpi4py import MPI

import numpy as np
from dolfinx import mesh

import dwr_signorini as ds

BOTTOM, TOP = 1, 2
#: Side tags: 2D left 3, right 4; 3D x = 0 3, x = 1 4, y = 0 5, y = 1 6.
SIDES = (3, 4, 5, 6)
HEIGHT, PRESS, E = 0.5, 0.01, 1.0

CELLS = {
    "triangle": mesh.CellType.triangle,
    "quadrilateral": mesh.CellType.quadrilateral,
    "tetrahedron": mesh.CellType.tetrahedron,
    "hexahedron": mesh.CellType.hexahedron,
}

#: Stick and slip ratios tau / (mu lambda_n) of the sweep.
STICK_RATIOS = (0.05, 0.5, 0.9, 0.999)
SLIP_RATIOS = (1.001, 1.1, 2.0, 10.0, 100.0)
#: Friction coefficients of the sweep.
MUS = (0.01, 0.3, 0.9, 2.0)


@dataclass(frozen=True)
class UniformCase:
    """One exact patch test (module docstring).

    Attributes:
        cell: A key of :data:`CELLS`.
        mu: Coulomb's friction coefficient.
        ratio: tau / (mu lambda_n): below 1 stick, above 1 slip.
        angle: The shear direction in the tangent plane, radians from e_1 (3D; 0 in 2D).
        nu: Poisson's ratio.
        n: Cells per unit length of the block's base (half as many across its height).
    """

    cell: str
    mu: float
    ratio: float
    angle: float = 0.0
    nu: float = 0.3
    n: int = 16

    @property
    def dim(self) -> int:
        """The dimension of the mesh."""
        return 2 if self.cell in ("triangle", "quadrilateral") else 3

    @property
    def label(self) -> str:
        """A short name for tables and test ids."""
        angle = f" {math.degrees(self.angle):.0f}deg" if self.dim == 3 else ""
        return f"{self.cell[:4]} mu={self.mu:g} ratio={self.ratio:g}{angle}"

    def lame(self) -> tuple[float, float]:
        """(lambda, mu_l) of E and nu (plane strain in 2D)."""
        nu = self.nu
        return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))

    def exact(self) -> dict[str, np.ndarray | float]:
        """lambda_n, the tangential traction vector, the slip a and the stresses.

        Returns:
            ``lam_n``, ``lam_t`` (vector of the tangent plane, length dim - 1), ``slip``
            (length dim - 1), ``shear`` (the top's D_t) and ``sigma`` (dim x dim).
        """
        lmbda, mu_l = self.lame()
        lam_n = (lmbda + 2 * mu_l) * PRESS / HEIGHT
        s = self.mu * lam_n
        tau = self.ratio * s
        direction = np.array([1.0]) if self.dim == 2 else np.array(
            [math.cos(self.angle), math.sin(self.angle)]
        )
        shear = direction * tau * HEIGHT / mu_l
        slip = np.zeros_like(shear) if self.ratio < 1 else shear * (1 - 1 / self.ratio)
        lam_t = direction * min(tau, s)
        d = self.dim
        sigma = np.diag([-lmbda] * (d - 1) + [-(lmbda + 2 * mu_l)]) * PRESS / HEIGHT
        sigma[:-1, -1] = sigma[-1, :-1] = mu_l * (shear - slip) / HEIGHT
        return {"lam_n": lam_n, "lam_t": lam_t, "slip": slip, "shear": shear, "sigma": sigma}

    def mesh(self, comm) -> tuple[mesh.Mesh, mesh.MeshTags]:
        """The block's mesh (unghosted) and its facet tags."""
        cell = CELLS[self.cell]
        ghost = mesh.GhostMode.none
        if self.dim == 2:
            msh = mesh.create_rectangle(
                comm, [np.zeros(2), np.array([1.0, HEIGHT])], [self.n, self.n // 2], cell,
                ghost_mode=ghost,
            )
        else:
            msh = mesh.create_box(
                comm, [np.zeros(3), np.array([1.0, 1.0, HEIGHT])],
                [self.n, self.n, max(self.n // 2, 1)], cell, ghost_mode=ghost,
            )
        return msh, block_tags(msh)

    def problem(
        self, comm, law: ds.laws.ContactLaw | None = None, meshed: tuple | None = None
    ) -> ds.SignoriniProblem:
        """The patch test as a problem with Coulomb's law (or ``law``), on ``meshed`` = (mesh,
        facet tags) of :meth:`mesh` if given."""
        msh, tags = self.mesh(comm) if meshed is None else meshed
        ex = self.exact()
        sigma = ex["sigma"]
        d = self.dim
        traction = {}
        for k, tag in enumerate(SIDES[: 2 * (d - 1)]):
            n = np.zeros(d)
            n[k // 2] = -1.0 if k % 2 == 0 else 1.0
            traction[tag] = tuple(sigma @ n)
        top = (*ex["shear"], -PRESS)
        return ds.SignoriniProblem(
            msh, tags, contact=BOTTOM, dirichlet={TOP: top}, E=E, nu=self.nu,
            model="plane_strain" if d == 2 else "3d", traction=traction, gap=0.0,
            friction=ds.Coulomb(self.mu) if law is None else law,
        )


def block_tags(msh: mesh.Mesh, height: float = HEIGHT) -> mesh.MeshTags:
    """Facet tags of the block of ``height`` (and width 1): bottom 1, top 2, then the sides
    (:data:`SIDES`: 2D left 3, right 4; 3D x = 0 3, x = 1 4, y = 0 5, y = 1 6)."""
    d = msh.topology.dim
    msh.topology.create_connectivity(d - 1, d)
    lower = d - 1
    sides = [(BOTTOM, lambda x: np.isclose(x[lower], 0.0)),
             (TOP, lambda x: np.isclose(x[lower], height))]
    for k in range(d - 1):
        sides.append((SIDES[2 * k], lambda x, k=k: np.isclose(x[k], 0.0)))
        sides.append((SIDES[2 * k + 1], lambda x, k=k: np.isclose(x[k], 1.0)))
    facets, values = [], []
    for tag, where in sides:
        found = mesh.locate_entities_boundary(msh, d - 1, where)
        facets.append(found)
        values.append(np.full(len(found), tag, dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    # an edge of two faces keeps its first tag (bottom and top win over the sides)
    facets, first = np.unique(facets, return_index=True)
    return mesh.meshtags(msh, d - 1, facets, values[first])


def sweep(quick: bool = False) -> list[UniformCase]:
    """The cases of the sweep (module docstring); ``quick``: one mu, the triangles and tets.

    Args:
        quick: Fewer cases (mu = 0.3 only, every ratio, triangles and tetrahedra).

    Returns:
        The cases.
    """
    cells = ("triangle", "tetrahedron") if quick else tuple(CELLS)
    mus = (0.3,) if quick else MUS
    out = []
    for cell in cells:
        dim = 2 if cell in ("triangle", "quadrilateral") else 3
        angles = (0.0,) if dim == 2 else (math.radians(30.0), math.radians(135.0))
        for mu in mus:
            for ratio in STICK_RATIOS + SLIP_RATIOS:
                for angle in angles[: 1 if quick else None]:
                    n = 16 if dim == 2 else 4
                    out.append(UniformCase(cell, mu, ratio, angle, n=n))
    return out


def errors(case: UniformCase, sol: ds.Solution) -> dict[str, float]:
    """The relative errors of lambda_n, lambda_t and the slip of a solution (all ranks).

    lambda_t is compared as the traction vector of the tangent plane; the slip is the
    tangential displacement of Gamma_C's vertices. Relative to lambda_n (both tractions) and
    to |D_t| + delta (the slip).

    Returns:
        ``lam_n``, ``lam_t``, ``slip``: the maxima over the contact facets and vertices.
    """
    comm = sol.disc.comm
    ex = case.exact()
    d = case.dim
    n_q = sol.system.algebra.n_q
    lam_n = sol.lam.x.array[:n_q]
    if d == 2:
        lam_t = sol.lam_t.x.array[:n_q, None]
    else:
        lam_t = sol.lam_t.x.array.reshape(-1, 3)[:n_q, :2]
    V = sol.disc.V
    x = V.tabulate_dof_coordinates()
    n_owned = V.dofmap.index_map.size_local
    on = np.isclose(x[:n_owned, d - 1], 0.0)
    u = sol.u.x.array.reshape(-1, d)[:n_owned][on]

    def worst(values: np.ndarray) -> float:
        return comm.allreduce(float(np.max(np.abs(values), initial=0.0)), op=MPI.MAX)

    scale_u = float(np.linalg.norm(ex["shear"])) + PRESS
    return {
        "lam_n": worst(lam_n - ex["lam_n"]) / ex["lam_n"],
        "lam_t": worst(lam_t - ex["lam_t"]) / ex["lam_n"],
        "slip": max(worst(u[:, :-1] - ex["slip"]), worst(u[:, -1])) / scale_u,
    }
