#!/usr/bin/python3
"""The frame-to-frame jumps of `vfe run` on a series equal those of hosts/liggghts/frame_jumps.py.

Both run the first 3 settling frames of data/liggghts/bed_mono_frames (timesteps 16500 to
19500) on the 1 mm and 2 mm grids, every method against exact; per grid and method the max
excess jump, the mean excess jump and the max exact jump must agree to 1e-12.
Environment: VFE_CLI (the vfe tool), VFE_SOURCE_DIR, PYTHONPATH with the built module.
--from and --to choose other timesteps (--to none: to the last frame); the largest
difference found is printed.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile

TOLERANCE = 1e-12


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from", dest="first", default="16500", help="first timestep")
    ap.add_argument("--to", dest="last", default="19500", help="last timestep, or none")
    a = ap.parse_args()
    last = [] if a.last == "none" else ["--to", a.last]
    src = os.environ["VFE_SOURCE_DIR"]
    cli = os.environ["VFE_CLI"]
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([cli, "run", os.path.join(src, "configs", "bed_mono_frames.yaml"), "--timesteps",
                        a.first + ":" + ("" if a.last == "none" else a.last), "-o", os.path.join(tmp, "cpp"), "-q"], check=True, stdout=subprocess.DEVNULL)
        py_csv = os.path.join(tmp, "py.csv")
        subprocess.run([sys.executable, os.path.join(src, "hosts", "liggghts", "frame_jumps.py"),
                        os.path.join(src, "data", "liggghts", "bed_mono_frames", "bed_mono_*.dump.gz"),
                        "--from", a.first, *last, "--cells", "0.001,0.002", "--csv", py_csv],
                       check=True, stdout=subprocess.DEVNULL)
        with open(os.path.join(tmp, "cpp", "frame_jumps.csv")) as f:
            cpp = list(csv.DictReader(f))
        with open(py_csv) as f:
            py = list(csv.DictReader(f))
    if a.first == "16500" and a.last == "19500":
        assert all(int(r["frames"]) == 3 for r in cpp), "vfe run did not take 3 frames"
    failures, compared, worst = [], 0, 0.0
    for p in py:
        match = [c for c in cpp if c["method"] == p["method"] and abs(float(c["chi"]) - float(p["chi"])) < 1e-9]
        if len(match) != 1:
            failures.append(f"chi {p['chi']} {p['method']}: {len(match)} rows of vfe run match")
            continue
        c = match[0]
        for py_key, cpp_key in (("max_excess_jump", "max_excess"), ("mean_excess_jump", "mean_excess"),
                                ("max_exact_jump", "max_exact_jump")):
            py_value, cpp_value = float(p[py_key]), float(c[cpp_key])
            compared += 1
            worst = max(worst, abs(py_value - cpp_value))
            if not abs(py_value - cpp_value) <= TOLERANCE:
                failures.append(f"chi {p['chi']} {p['method']} {cpp_key}: Python {py_value!r}, vfe run {cpp_value!r}")
    if len(py) != 14:
        failures.append(f"frame_jumps.py gave {len(py)} rows, expected 7 methods x 2 grids")
    for line in failures:
        print("MISMATCH", line)
    print(f"{compared} values compared, largest difference {worst:.2g}, {len(failures)} mismatches "
          f"(tolerance {TOLERANCE})")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
