#!/usr/bin/python3
"""Frame-to-frame jumps of the void fraction per method against exact's, on a dump series.

For consecutive frames k, k+1 and each cell: deps = eps(k+1) - eps(k). A method's excess
jump per cell is |deps_method| - |deps_exact|: how much more its eps jumps between the two
frames than the true void fraction does. Reported per method and grid: the max over cells
and frame pairs, and the mean over the cells where either field changed.

  PYTHONPATH=build/release/python hosts/liggghts/frame_jumps.py \\
      "data/liggghts/bed_mono_frames/bed_mono_*.dump.gz" --from 16500 --cells 0.001,0.002
"""
import argparse
import math

import numpy as np
import vfe

METHODS = ["direct", "pmm", "divided", "big_particle", "trilinear", "gaussian", "porous_cube"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dumps", help="glob of the dump series")
    ap.add_argument("--from", dest="first", type=int, default=0, help="first timestep used")
    ap.add_argument("--to", dest="last", type=int, default=None, help="last timestep used (default: the last)")
    ap.add_argument("--cells", default="0.001,0.002", help="cubic cell sizes, comma-separated")
    ap.add_argument("--box", default="0,0,0,0.02,0.02,0.06", help="grid box lo x,y,z, hi x,y,z")
    ap.add_argument("--csv", help="also write the table here")
    a = ap.parse_args()
    box = [float(v) for v in a.box.split(",")]
    frames = [f for f in vfe.read_frames(a.dumps)
              if f["timestep"] >= a.first and (a.last is None or f["timestep"] <= a.last)]
    if len(frames) < 2:
        ap.error("fewer than two frames between --from and --to")
    particles = [vfe.particles(f) for f in frames]
    d_mean = float(np.mean(2 * particles[0][1]))
    crit = math.pi / 162  # the default criterion of docs/design.md section 8: direct just stable at chi = 3
    rows = []
    for h in (float(v) for v in a.cells.split(",")):
        cells = [round((box[3 + i] - box[i]) / h) for i in range(3)]
        e = vfe.Engine.cartesian(origin=box[:3], spacing=(h, h, h), cells=cells)

        def eps_series(options):
            e.configure(options + " outside=nearest deterministic=1")
            out = []
            for c, r in particles:
                e.compute(c, r)
                out.append(e.void_fraction())
            return out

        exact = eps_series("method=exact")
        d_exact = [b - a_ for a_, b in zip(exact, exact[1:])]
        for m in METHODS:
            eps = eps_series(f"method={m}")
            excess_max, excess_sum, changed = -math.inf, 0.0, 0
            for k, de in enumerate(d_exact):
                dm = eps[k + 1] - eps[k]
                excess = np.abs(dm) - np.abs(de)
                mask = (dm != 0) | (de != 0)
                excess_max = max(excess_max, float(excess.max()))
                excess_sum += float(excess[mask].sum())
                changed += int(mask.sum())
            rows.append((h / d_mean, m, excess_max, excess_sum / max(changed, 1),
                         float(max(np.abs(de).max() for de in d_exact))))
    print(f"{len(frames)} frames (timesteps {frames[0]['timestep']} to {frames[-1]['timestep']}), "
          f"d = {d_mean:g}; deps_crit = pi/162 = {crit:.4f}")
    print(f"| chi | method | max excess jump | mean excess jump | max / deps_crit | max exact jump |")
    print(f"|---:|---|---:|---:|---:|---:|")
    for chi, m, mx, mean, dex in rows:
        print(f"| {chi:g} | {m} | {mx:.4f} | {mean:.2e} | {mx / crit:.2f} | {dex:.4f} |")
    if a.csv:
        with open(a.csv, "w") as f:
            f.write("chi,method,max_excess_jump,mean_excess_jump,max_exact_jump\n")
            for chi, m, mx, mean, dex in rows:
                f.write(f"{chi},{m},{mx},{mean},{dex}\n")


if __name__ == "__main__":
    main()
