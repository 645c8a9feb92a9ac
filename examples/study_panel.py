#!/usr/bin/python3
"""One panel of docs/study.md from Python: every method on the settled packed bed at chi = 2
(10 x 10 x 30 cells of 2 mm), time against L1 error with exact as the reference; prints the
table (Pareto front marked) and plots the panel with scripts/plot_study.py.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/study_panel.py [--chi 2] [-o out/study_panel]

The points are those of configs/study_bed.yaml (one thread, median of 9 computes, every point
once per round; pmm with the spherical template the doc was made with, not the engine's
default fibonacci), so the errors equal `vfe study configs/study_bed.yaml --chi 2`'s and, but
for pmm (its random rotations and particle_grid=auto have changed since, see docs/study.md),
the doc's.
"""
import argparse
import pathlib
import subprocess
import sys

import vfe

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chi", type=float, default=2.0)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("-o", "--output", default=str(ROOT / "out" / "study_panel"))
    args = ap.parse_args()

    frame = vfe.read_dump(ROOT / "data" / "liggghts" / "bed_mono_final.dump.gz")
    centres, radii = vfe.particles(frame)
    origin, spacing, (nx, ny, nz) = vfe.study.chi_grid_spec(frame["box"], 2 * radii.mean(), args.chi)
    engine = vfe.Engine.cartesian(origin=origin, spacing=spacing, cells=(nx, ny, nz))
    grids = [f"particle_grid={n}" for n in (5, 10, 20, 40, 80, 160, 320, 640, 1280)] + ["particle_grid=auto"]
    pts = (vfe.study.points("direct")
           + vfe.study.points("pmm", grids, "pmm", "template=spherical")
           + vfe.study.points("pmm", [f"particle_grid={n}" for n in (10, 40, 160, 640)], "pmm_fibonacci",
                              "template=fibonacci")
           + vfe.study.points("pmm", [f"particle_grid={n}" for n in (8, 19, 81, 136, 280, 552, 1189)], "pmm_voxel",
                              "template=voxel")
           + vfe.study.points("divided")
           + vfe.study.points("gaussian", [f"sigma={s}" for s in (0.125, 0.25, 0.5, 1)])
           + vfe.study.points("porous_cube", [f"gamma={g}" for g in (0.5, 0.806, 1, 2, 3)])
           + vfe.study.points("big_particle") + vfe.study.points("trilinear") + vfe.study.points("exact"))
    rows = vfe.study.run(engine, centres, radii, pts, repeats=args.repeats)

    print(f"study_bed, chi = {args.chi:g}: {nx} x {ny} x {nz} cells, {len(radii)} particles, 1 thread, "
          f"median of {args.repeats}\n")
    print(vfe.study.table(rows))
    out = pathlib.Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    vfe.study.write_csv(out / "study.csv", rows, scene="study_bed", mesh=f"chi_{args.chi:g}", chi=args.chi,
                        nx=nx, ny=ny, nz=nz, cells=engine.cell_count, particles=len(radii), threads=1,
                        repeats=args.repeats)
    subprocess.run([sys.executable, str(ROOT / "scripts" / "plot_study.py"), str(out / "study.csv"),
                    "-o", str(out / "study_panel.png")], check=True)


if __name__ == "__main__":
    main()
