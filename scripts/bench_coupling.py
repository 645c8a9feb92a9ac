#!/usr/bin/python3
"""Cost of the coupling functions against the compute itself, per method, in one run:
median wall time of a compute with weights=0 and with weights=1, of vfe_deposit (3
components, a drag force) and of vfe_interpolate (3 components, a fluid velocity), and the
weights' memory per particle. The settled LIGGGHTS bed (20000 spheres of 1 mm) on a 2 mm and
a 1 mm Cartesian grid.

    PYTHONPATH=build/release/python /usr/bin/python3 scripts/bench_coupling.py [--threads N] [--repeats R]
"""
import argparse
import pathlib
import statistics
import time

import numpy as np
import vfe

ROOT = pathlib.Path(__file__).resolve().parent.parent


def median_ms(f, repeats):
    f()  # warm-up
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return 1e3 * statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    frame = vfe.read_dump(ROOT / "data/liggghts/bed_mono_final.dump.gz")
    centres, radii = vfe.particles(frame)
    n = len(radii)
    force = np.random.default_rng(1).standard_normal((n, 3))
    print("| grid | method | compute ms | with weights ms | ratio | deposit ms | interpolate ms | bytes/particle |")
    print("|---|---|---|---|---|---|---|---|")
    for h in (0.002, 0.001):
        cells = (round(0.02 / h), round(0.02 / h), round(0.06 / h))
        for method in vfe.method_names():
            e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(h, h, h), cells=cells)
            e.configure(f"method={method} threads={args.threads} weights=0")
            plain = median_ms(lambda: e.compute(centres, radii), args.repeats)
            e.configure("weights=1")
            weighted = median_ms(lambda: e.compute(centres, radii), args.repeats)
            offsets, cell_ids, fractions = e.weights()
            field = np.ones((e.cell_count, 3))
            dep = median_ms(lambda: e.deposit(force), args.repeats)
            itp = median_ms(lambda: e.interpolate(field), args.repeats)
            per_particle = 16 * len(fractions) / n + 4  # deposits (cell, volume) + offsets
            print(f"| {h * 1e3:g} mm | {method} | {plain:.2f} | {weighted:.2f} | {weighted / plain:.2f} | "
                  f"{dep:.2f} | {itp:.2f} | {per_particle:.0f} |")


if __name__ == "__main__":
    main()
