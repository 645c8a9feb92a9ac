"""Run time against error of methods on one scene, as `vfe study` measures it.

    rows = vfe.study.run(engine, centres, radii, vfe.study.points("pmm", ["particle_grid=5", "particle_grid=40"]))
    print(vfe.study.table(rows))

Errors are against the reference method (exact) with the project's measures
(vfe.compare_fields: theta = mean |eps - eps_exact| over cells either touches, max error,
L1 = sum |Vs - Vs_exact| / sum V_p); time is the median of `repeats` computes after one
warm-up, every point once per round so a busy machine slows all points alike.
"""
import math
import time

import numpy as np

from ._core import Engine, compare_fields


def chi_grid(box, mean_diameter, chi):
    """A Cartesian engine over a dump's box with cubic cells of chi * mean_diameter; an axis the
    spacing does not divide is extended past the box (as `vfe study` makes its grids)."""
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
    return Engine.cartesian(origin=origin, spacing=spacing, cells=cells)


def points(method, settings=("",), label=None, options=""):
    """(label, setting, option string) for each setting of one method family."""
    label = label or method
    return [(label, s or "-", " ".join(x for x in (f"method={method}", options, s) if x)) for s in settings]


def run(engine, centres, radii, pts, reference="method=exact", repeats=5, options="outside=nearest threads=1"):
    """Times every point and measures it against the reference; one row (dict) per point:
    family, setting, options, time_ms (median), time_min_ms, theta, max_error, l1, volume_error,
    sub_elements."""
    volumes = engine.cell_volumes()
    engine.configure(options + " " + reference)
    exact = engine.compute(centres, radii)
    particle_volume = engine.report()["particle_volume"]
    rows, outs = [], []
    for family, setting, opts in pts:
        engine.configure(options + " " + opts)
        solid = engine.compute(centres, radii)  # the warm-up, and the field measured
        row = {"family": family, "setting": setting, "options": opts}
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
        out.append(f"| {r['family']} | {r['setting']} | {r['time_ms']:.3g} | {r['l1']:.3g} | {r['theta']:.3g} | "
                   f"{r['max_error']:.3g} | {'*' if id(r) in front_ids else ''} |")
    return "\n".join(out)


def plot(rows, path, title=""):
    """Time against L1 per family (log-log; exact, with L1 = 0, as a vertical line), the
    Pareto front dashed; saved as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    families = list(dict.fromkeys(r["family"] for r in rows))
    for fam in families:
        rs = [r for r in rows if r["family"] == fam and r["l1"] > 0]
        if rs:
            ax.plot([r["time_ms"] for r in rs], [r["l1"] for r in rs], "o-", label=fam, ms=4)
        for r in rows:
            if r["family"] == fam and r["l1"] == 0:
                ax.axvline(r["time_ms"], color="k", lw=0.8, ls=":", label=f"{fam} (L1 = 0)")
    front = [r for r in pareto(rows) if r["l1"] > 0]
    ax.plot([r["time_ms"] for r in front], [r["l1"] for r in front], "k--", lw=0.8, label="Pareto front")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("ms per compute")
    ax.set_ylabel("L1 = sum |Vs - Vs_exact| / sum V_p")
    ax.set_title(title)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
