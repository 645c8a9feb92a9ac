#!/usr/bin/python3
"""Accuracy of direct and pmm with smoothing_length 0, 0.5 and 1 mm against the unsmoothed
exact field, on the settled LIGGGHTS bed on 2 mm and 1 mm grids (docs/coupling.md):

    PYTHONPATH=build/release/python /usr/bin/python3 scripts/smoothing_accuracy.py
"""
import pathlib

import numpy as np
import vfe

ROOT = pathlib.Path(__file__).resolve().parent.parent
centres, radii = vfe.particles(vfe.read_dump(ROOT / "data/liggghts/bed_mono_final.dump.gz"))
for h in (0.002, 0.001):
    cells = (round(0.02 / h), round(0.02 / h), round(0.06 / h))
    exact = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(h, h, h), cells=cells)
    exact.configure("method=exact")
    reference = exact.compute(centres, radii) / h**3
    for method in ("direct", "pmm"):
        for length in (0, 0.5e-3, 1e-3):
            e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(h, h, h), cells=cells)
            e.configure(f"method={method} smoothing_length={length}")
            fraction = e.compute(centres, radii) / h**3
            touched = (fraction > 0) | (reference > 0)
            error = np.abs(fraction - reference)
            print(f"h={h * 1e3:g} mm  {method:6s} L={length * 1e3:g} mm  theta={error[touched].mean():.4f}  "
                  f"max={error.max():.3f}")
