#!/usr/bin/python3
"""Checks of the function object's fields against independent computations.

  foam_fields.py diff A B [--max X]      max |A - B| over cells of two volScalarFields
  foam_fields.py momentum CASE TIME DUMP  sum_c Us Vs against sum_p v_p V_p of the dump

Prints the figure; exits 1 when it exceeds the bound (--max, default 1e-12)."""
import argparse
import re
import sys

import numpy as np


def internal_field(path):
    """The internalField of an ASCII OpenFOAM field: (cells,) or (cells, 3); uniform gives a
    single value."""
    text = open(path).read()
    m = re.search(r"internalField\s+nonuniform\s+List<(scalar|vector)>\s*(\d+)\s*\(", text)
    if not m:
        u = re.search(r"internalField\s+uniform\s+([^;]+);", text)
        if not u:
            sys.exit(f"{path}: no internalField")
        return np.array([float(v) for v in u.group(1).strip("() ").split()])
    body = text[m.end():]
    n = int(m.group(2))
    values = np.array(body[: body.index("\n)")].replace("(", " ").replace(")", " ").split(), dtype=float)
    return values.reshape(n, 3) if m.group(1) == "vector" else values


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("diff")
    d.add_argument("a")
    d.add_argument("b")
    d.add_argument("--max", type=float, default=1e-12)
    mo = sub.add_parser("momentum")
    mo.add_argument("case")
    mo.add_argument("time")
    mo.add_argument("dump")
    mo.add_argument("--cell-volume", type=float, required=True)
    mo.add_argument("--max", type=float, default=1e-12)
    a = ap.parse_args()
    if a.cmd == "diff":
        x, y = internal_field(a.a), internal_field(a.b)
        if x.shape != y.shape:
            sys.exit(f"{a.a} has {x.shape} values, {a.b} {y.shape}")
        err = float(np.max(np.abs(x - y)))
        print(f"max |{a.a} - {a.b}| = {err:.3e}")
    else:
        import vfe
        frame = vfe.read_dump(a.dump)
        _, radii = vfe.particles(frame)
        cols = frame["columns"]
        v = np.column_stack([cols["vx"], cols["vy"], cols["vz"]])
        dem = (v * (4 / 3 * np.pi * radii**3)[:, None]).sum(axis=0)
        eps = internal_field(f"{a.case}/{a.time}/voidfraction")
        us = internal_field(f"{a.case}/{a.time}/Us")
        cfd = (us * ((1 - eps) * a.cell_volume)[:, None]).sum(axis=0)
        err = float(np.max(np.abs(cfd - dem)) / np.max(np.abs(dem)))
        print(f"sum Us Vs = {cfd}, sum v V = {dem}: relative difference {err:.3e}")
    sys.exit(0 if err <= a.max else 1)


if __name__ == "__main__":
    main()
