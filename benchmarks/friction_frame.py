"""The contact frame of friction on curved surfaces: tangential traction where theory has none.

Cases (press step, then optionally shear):

1. ``discs``: two identical discs (``meshes/hertz_cylinders_2d.py``, R = 8, E = 200, nu = 0.3,
   Coulomb mu = 0.3, the top pressed down by 0.19), the upper arc the slave side and then the
   lower one. Dundurs' beta = 0: lambda_t = 0 by symmetry on the press step.
2. ``flat``: the half-disc of :func:`~dwr_signorini.cases.cattaneo_mindlin_path` on a rigid flat
   with nu = 0.4999 (beta -> 0): lambda_t -> 0 on the press step; with nu = 0.49 (the default)
   the shear steps against Cattaneo.

Printed per case and contact facet size: ``share`` = ||lambda_t|| / ||mu lambda_n|| (L2 over the
contact facets), ``half`` = the tangential force of the right half over mu times its normal
force, ``peak`` = max |lambda_t| / (mu p0); on shear steps the stick zone's centre over a and
the L2 error of lambda_t against Cattaneo's q::

    scripts/fenicsx python3 benchmarks/friction_frame.py            # ~2 min
    scripts/fenicsx python3 benchmarks/friction_frame.py --shear    # and the shear steps
    scripts/fenicsx python3 benchmarks/friction_frame.py --lower-radius 40 --sizes 0.04 --no-flat

(``measure_cattaneo_mindlin`` judges against one disc of radius 8 on a rigid flat, so with
another lower radius only ``share``, ``half`` and ``peak`` mean what they say.)
"""

from __future__ import annotations

import argparse

from mpi4py import MPI

import dwr_signorini as ds
from dwr_signorini import cases
from dwr_signorini.mesh_io import read_mesh
from dwr_signorini.meshes import hertz_cylinders_2d as cyl

comm = MPI.COMM_WORLD
R, E, NU, MU, PRESS, SHEAR = 8.0, 200.0, 0.3, 0.3, 0.19, 0.1


def print0(*args: object) -> None:
    if comm.rank == 0:
        print(*args, flush=True)


def disc_mesh(h_contact: float, r_lower: float = R):
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        if comm.rank == 0:
            gmsh.model.add("discs")
            cyl.build(gmsh.model, r_lower=r_lower, r_upper=R, h=1.6, h_contact=h_contact,
                      full=True)
        return read_mesh(gmsh.model, comm)
    finally:
        gmsh.finalize()


def disc_path(mesh, upper_slave: bool, steps: int, r_lower: float = R):
    msh, cells, facets = mesh
    pair = (ds.ContactPair(slave=cyl.UPPER_ARC, master=cyl.LOWER_ARC) if upper_slave
            else ds.ContactPair(slave=cyl.LOWER_ARC, master=cyl.UPPER_ARC))
    tops = [(k * SHEAR / max(steps, 1), -PRESS) for k in range(steps + 1)]
    return [ds.SignoriniProblem(
        msh, facets, contact=pair, dirichlet={cyl.LOWER_FLAT: (0.0, 0.0), cyl.UPPER_FLAT: top},
        E=E, nu=NU, cell_tags=cells, friction=ds.Coulomb(MU),
        boundary_projection=cyl.projections(r_lower, R)) for top in tops]


def measures(problems, **kw):
    rows = []

    def keep(record, sol, est):
        rows.append(cases.measure_cattaneo_mindlin(sol, **kw))

    def goal(u, lam, m, lam_t):
        return lam_t * m.ds_contact

    ds.solve_path(problems, goal, callback=keep, history=False, verbose=False).destroy()
    return rows


def show(label: str, rows) -> None:
    for k, m in enumerate(rows):
        if m is None:
            continue
        line = (f"{label} step {k}: h_facet {m.h_facet:.4f} a {m.a:.4f} share {m.rms_lam_t:.4f} "
                f"half {m.coupling:+.4f} peak {m.max_lam_t:.4f}")
        if k > 0:
            line += (f" Q/(mu P) {m.ratio:.3f} centre/a {m.stick_center / m.a:+.4f} "
                     f"c_h-c {(m.c_h - m.c) / m.h_facet:+.2f} facets l2_lam_t {m.l2_lam_t:.4f}")
        print0(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--shear", action="store_true", help="the shear steps too")
    parser.add_argument("--sizes", type=float, nargs="*", default=[0.04, 0.02])
    parser.add_argument("--lower-radius", type=float, default=R,
                        help="the lower disc's radius (8: two identical discs; larger: a disc "
                        "on a nearly flat body of the same material)")
    parser.add_argument("--no-flat", action="store_true", help="leave out the rigid flat")
    args = parser.parse_args()
    steps = 4 if args.shear else 0
    for h in args.sizes:
        mesh = disc_mesh(h, args.lower_radius)
        for upper in (True, False):
            rows = measures(disc_path(mesh, upper, steps, args.lower_radius), mu=MU, E=E, nu=NU,
                            radius=R)
            show(f"discs h {h} slave {'upper' if upper else 'lower'}", rows)
    for h in [] if args.no_flat else [s / 4 for s in args.sizes]:
        rows = measures(cases.cattaneo_mindlin_path(comm, h_contact=h, nu=0.4999, steps=1),
                        nu=0.4999)
        show(f"flat nu 0.4999 h {h}", rows[:1])
        if args.shear:
            rows = measures(cases.cattaneo_mindlin_path(comm, h_contact=h))
            show(f"flat nu 0.49 h {h}", rows)


if __name__ == "__main__":
    main()
