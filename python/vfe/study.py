"""Run time against error of methods on one scene, as `vfe study` measures it.

    rows = vfe.study.run(engine, centres, radii, vfe.study.points("pmm", ["particle_grid=5", "particle_grid=40"]))
    print(vfe.study.table(rows))
    vfe.study.write_csv("study.csv", rows, scene="bed", mesh="chi2", chi=2)  # scripts/plot_study.py plots it

Errors are against the reference method (exact) with the project's measures
(vfe.compare_fields: theta = mean |eps - eps_exact| over cells either touches, max error,
L1 = sum |Vs - Vs_exact| / sum V_p); time is the median of `repeats` computes after one
warm-up, every point once per round so a busy machine slows all points alike.
"""
import math
import time

import numpy as np

from ._core import Engine, compare_fields


def chi_grid_spec(box, mean_diameter, chi):
    """(origin, spacing, cells) of a Cartesian grid over a dump's box with cubic cells of
    chi * mean_diameter; an axis the spacing does not divide is extended past the box (as
    `vfe study` makes its grids)."""
    h = chi * mean_diameter
    origin, spacing, cells = [], [], []
    for d in range(3):
        lo, length = box[2 * d], box[2 * d + 1] - box[2 * d]
        ratio = length / h
        r = round(ratio)
        origin.append(lo)
        if r >= 1 and abs(ratio - r) <= 1e-6 * max(1.0, r):
            cells.append(int(r))
            spacing.append(length / r)  # fit the box exactly
        else:
            cells.append(max(1, math.ceil(ratio)))
            spacing.append(h)
    return origin, spacing, cells


def chi_grid(box, mean_diameter, chi):
    """The engine on chi_grid_spec's grid."""
    origin, spacing, cells = chi_grid_spec(box, mean_diameter, chi)
    return Engine.cartesian(origin=origin, spacing=spacing, cells=cells)


def points(method, settings=("",), label=None, options=""):
    """(label, setting, option string) for each setting of one method family."""
    label = label or method
    return [(label, s, " ".join(x for x in (f"method={method}", options, s) if x)) for s in settings]


def run(engine, centres, radii, pts, reference="method=exact", repeats=5, options="outside=nearest threads=1"):
    """Times every point and measures it against the reference; one row (dict) per point:
    family, setting, options, reference (the point is the reference method), time_ms (median),
    time_min_ms, theta, max_error, l1, volume_error, cells_compared, sub_elements."""
    volumes = engine.cell_volumes()
    engine.configure(options + " " + reference)
    exact = engine.compute(centres, radii)
    particle_volume = engine.report()["particle_volume"]
    rows, outs = [], []
    for family, setting, opts in pts:
        engine.configure(options + " " + opts)
        solid = engine.compute(centres, radii)  # the warm-up, and the field measured
        row = {"family": family, "setting": setting, "options": opts,
               "reference": set(opts.split()) >= set(reference.split())}
        row.update(compare_fields(solid, exact, volumes, particle_volume))
        row["sub_elements"] = engine.report()["sub_elements"]
        row["times"] = []
        rows.append(row)
        outs.append(solid)
    for _ in range(repeats):
        for row, out in zip(rows, outs):
            engine.configure(options + " " + row["options"])
            t0 = time.perf_counter()
            engine.compute(centres, radii, out=out)
            row["times"].append(time.perf_counter() - t0)
    for row in rows:
        t = row.pop("times")
        row["time_ms"] = 1e3 * float(np.median(t)) if t else math.nan
        row["time_min_ms"] = 1e3 * min(t) if t else math.nan
    return rows


def pareto(rows):
    """The rows no other row beats in both time and L1, fastest first."""
    front = [r for r in rows
             if not any(o["time_ms"] <= r["time_ms"] and o["l1"] <= r["l1"] and
                        (o["time_ms"] < r["time_ms"] or o["l1"] < r["l1"]) for o in rows)]
    return sorted(front, key=lambda r: r["time_ms"])


def table(rows, front=None):
    """A markdown table of the rows (those on the front marked *)."""
    front_ids = {id(r) for r in (pareto(rows) if front is None else front)}
    out = ["| family | setting | ms/compute | L1 | theta | max error | front |",
           "|---|---|---:|---:|---:|---:|:-:|"]
    for r in rows:
        out.append(f"| {r['family']} | {r['setting'] or '-'} | {r['time_ms']:.3g} | {r['l1']:.3g} | {r['theta']:.3g} | "
                   f"{r['max_error']:.3g} | {'*' if id(r) in front_ids else ''} |")
    return "\n".join(out)


CSV_COLUMNS = ["scene", "mesh", "chi", "nx", "ny", "nz", "cells", "particles", "threads", "repeats", "family",
               "method", "setting", "options", "reference", "time_median_ms", "time_min_ms", "theta",
               "max_error", "l1", "volume_error", "cells_compared", "sub_elements"]


def write_csv(path, rows, **columns):
    """Writes rows as `vfe study`'s study.csv (the columns scripts/plot_study.py reads);
    columns gives the per-file values: scene, mesh, chi, nx, ny, nz, particles, threads, ..."""
    import csv

    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            out = dict(columns, **r)
            out["time_median_ms"], out["reference"] = r["time_ms"], int(r["reference"])
            out["method"] = next((t.split("=", 1)[1] for t in r["options"].split() if t.startswith("method=")), "")
            w.writerow(out)
