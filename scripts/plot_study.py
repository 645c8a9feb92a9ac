#!/usr/bin/python3
"""Plot a `vfe study` result: run time against error, one panel per chi, one line per
method family, points labelled by setting, the Pareto front marked.

    scripts/plot_study.py out/study_bed/study.csv -o docs/study_bed.png
    scripts/plot_study.py STUDY.csv [-o PNG] [--error l1|theta|max_error] [--time median|min]
                          [--markdown MD]

--markdown also writes, per grid, the Pareto front as a table and how pmm compares with
exact, divided and direct (read from comparisons.csv next to the CSV, which `vfe study`
writes, or comparisons_X.csv next to a copy named study_X.csv: pmm's time at a point's L1 and pmm's L1 at a point's time, log-log interpolated
along pmm's front).

The Pareto front is recomputed here for the chosen error measure (a point is on it when no
other point of the same grid is both faster and more accurate). The reference (exact, error 0)
cannot sit on a log error axis: it is drawn as a dashed horizontal line at its run time.
"""

import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ZERO = 1e-12  # errors below this count as 0 (the reference against itself)

STYLE = {  # family -> (colour, marker)
    "pmm": ("tab:red", "o"),
    "pmm_fibonacci": ("tab:orange", "v"),
    "pmm_voxel": ("tab:brown", "s"),
    "direct": ("black", "X"),
    "divided": ("tab:blue", "D"),
    "gaussian": ("tab:green", "^"),
    "porous_cube": ("tab:purple", "P"),
    "big_particle": ("tab:gray", "*"),
    "trilinear": ("tab:cyan", "h"),
}
EXTRA = [("tab:olive", "<"), ("tab:pink", ">"), ("navy", "d"), ("teal", "p")]


def short_setting(setting):
    """'particle_grid=20' -> '20', 'sigma=0.25' -> 's0.25', 'gamma=1' -> 'g1'."""
    parts = []
    for token in setting.split():
        key, _, value = token.partition("=")
        if key == "particle_grid":
            parts.append(value)
        elif key == "sigma":
            parts.append("\u03c3" + value)
        elif key == "gamma":
            parts.append("\u03b3" + value)
        elif key == "template":
            continue
        else:
            parts.append(token)
    return " ".join(parts)


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{path}: no rows; run `vfe study CONFIG.yaml` first")
    for r in rows:
        for k in ("chi", "time_median_ms", "time_min_ms", "theta", "max_error", "l1"):
            r[k] = float(r[k])
        r["reference"] = r["reference"] == "1"
    # A point the mesh kind does not offer (status skipped, e.g. trilinear on a polyMesh) has
    # no time or error: it is left out of the plot and the fronts.
    return [r for r in rows if r.get("status", "ok") != "skipped"]


def mesh_text(r):
    """The mesh's name and a comma on a listed mesh; nothing on a chi grid (its name is its chi)."""
    return "" if r["mesh"].startswith("chi_") else f"{r['mesh']}, "


def cells_text(r):
    """'10 x 10 x 30' on a grid, '1920 polyMesh' cells on a polyMesh (no cells per axis)."""
    if r.get("mesh_type") == "polymesh" or r["nx"] in ("0", ""):
        return f"{r['cells']} polyMesh"
    return f"{r['nx']} x {r['ny']} x {r['nz']}"


def pareto(points):
    """Indices of the points (time, error) no other point beats in both."""
    keep = []
    for i, (ti, ei) in enumerate(points):
        dominated = any(
            tj <= ti and ej <= ei and (tj < ti or ej < ei) for j, (tj, ej) in enumerate(points) if j != i
        )
        if not dominated:
            keep.append(i)
    return keep


def fmt_ms(x):
    return "-" if x is None or math.isnan(x) else f"{x:.3g}"


def fmt_e(x):
    return "-" if x is None or math.isnan(x) else f"{x:.3g}"


def markdown(rows, comps, ekey, tkey):
    """Pareto tables and pmm's comparisons with exact, divided and direct, per grid."""
    out = []
    meshes = []
    for r in rows:
        if r["mesh"] not in meshes:
            meshes.append(r["mesh"])
    for mesh in meshes:
        pts = [r for r in rows if r["mesh"] == mesh]
        p0 = pts[0]
        out.append(f"#### {p0['scene']}, {mesh_text(p0)}chi = {p0['chi']:.3g} ({cells_text(p0)} cells, "
                   f"{p0['particles']} particles, {p0['threads']} thread(s), median of {p0['repeats']})\n")
        cand = [(r[tkey], r[ekey] if r[ekey] > ZERO else 0.0) for r in pts]
        front = sorted((pts[i] for i in pareto(cand)), key=lambda r: r[tkey])
        out.append("Pareto front (no other point is both faster and more accurate):\n")
        out.append("| family | setting | ms/compute | L1 | theta | max error |")
        out.append("|---|---|---:|---:|---:|---:|")
        for r in front:
            out.append(f"| {r['family']} | {r['setting'] or '-'} | {r[tkey]:.3g} | {r['l1']:.3g} | "
                       f"{r['theta']:.3g} | {r['max_error']:.3g} |")
        out.append("")
        c = {(x["family"], x["setting"]): x for x in comps if x["mesh"] == mesh}
        get = lambda fam: next((r for r in pts if r["family"] == fam and not r["setting"]), None)  # noqa: E731
        ex, dv, dr = get("exact"), get("divided"), get("direct")
        pmm = sorted((r for r in pts if r["family"] == "pmm"), key=lambda r: r[tkey])
        if not (ex and dv and dr and pmm and ("divided", "") in c and ("exact", "") in c):
            continue
        cd, ce = c[("divided", "")], c[("exact", "")]
        t_at_div = float(cd["base_time_at_error"])
        e_at_div = float(cd["base_error_at_time"])
        e_at_ex = float(ce["base_error_at_time"])
        cheap = pmm[0]
        out.append("pmm against exact, divided and direct (L1):\n")
        out.append("| question | figure |")
        out.append("|---|---|")
        out.append(f"| exact | {ex[tkey]:.3g} ms, L1 0 |")
        out.append(f"| divided | {dv[tkey]:.3g} ms, L1 {dv['l1']:.3g} |")
        out.append(f"| direct | {dr[tkey]:.3g} ms, L1 {dr['l1']:.3g} |")
        note = cd["speedup_note"]
        out.append(f"| pmm at divided's L1 | {note}{fmt_ms(t_at_div)} ms: {note}{dv[tkey] / t_at_div:.2f} x the speed "
                   f"of divided, {note}{ex[tkey] / t_at_div:.2f} x the speed of exact |")
        gnote = cd["gain_note"]
        gain = "-" if math.isnan(e_at_div) else f"{gnote}{dv['l1'] / e_at_div:.2f} x divided's accuracy"
        out.append(f"| pmm at divided's time | L1 {fmt_e(e_at_div)}: {gain} |")
        ex_note = ce["gain_note"] if ce["gain_note"] != "n/a" else ""
        out.append(f"| pmm at exact's time | L1 {ex_note}{fmt_e(e_at_ex)} |")
        out.append(f"| pmm's cheapest setting ({cheap['setting']}) against direct | {cheap[tkey] / dr[tkey]:.1f} x "
                   f"direct's time, {dr['l1'] / cheap['l1']:.2f} x direct's accuracy (pmm cannot be as cheap as "
                   f"direct; at equal time there is no pmm point) |")
        out.append("")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", help="study.csv written by `vfe study`")
    ap.add_argument("-o", "--output", help="PNG file (default: next to the CSV, study.png)")
    ap.add_argument("--error", default="l1", choices=["l1", "theta", "max_error"], help="error measure (x axis)")
    ap.add_argument("--time", default="median", choices=["median", "min"], help="time per compute (y axis)")
    ap.add_argument("--markdown", help="also write the Pareto tables and pmm's comparisons to this file")
    args = ap.parse_args()

    rows = load(args.csv)
    out = args.output or os.path.join(os.path.dirname(args.csv), "study.png")
    tkey = "time_median_ms" if args.time == "median" else "time_min_ms"
    ekey = args.error
    scene = rows[0]["scene"]
    meshes = []
    for r in rows:
        if r["mesh"] not in meshes:
            meshes.append(r["mesh"])
    families = []
    for r in rows:
        if r["family"] not in families and not r["reference"]:
            families.append(r["family"])
    style = dict(STYLE)
    for i, fam in enumerate(f for f in families if f not in style):
        style[fam] = EXTRA[i % len(EXTRA)]

    n = len(meshes)
    cols = 2 if n > 1 else 1
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(7.5 * cols, 6.0 * nrows), squeeze=False)
    label_of = {"l1": "L1 = sum |Vs - Vs_exact| / sum Vp", "theta": "theta = mean |eps - eps_exact|",
                "max_error": "max |eps - eps_exact|"}
    for idx, mesh in enumerate(meshes):
        ax = axes[idx // cols][idx % cols]
        pts = [r for r in rows if r["mesh"] == mesh]
        chi = pts[0]["chi"]
        errs = [r[ekey] for r in pts if r[ekey] > ZERO]
        lo = min(errs) if errs else 1e-4
        for fam in families:
            fp = sorted((r for r in pts if r["family"] == fam and not r["reference"]), key=lambda r: r[tkey])
            if not fp:
                continue
            colour, marker = style[fam]
            xs = [max(r[ekey], lo * 0.5) for r in fp]
            ys = [r[tkey] for r in fp]
            ax.plot(xs, ys, color=colour, marker=marker, ms=6, lw=1.2, label=fam, alpha=0.9)
            for r, x, y in zip(fp, xs, ys):
                if r["setting"]:
                    ax.annotate(short_setting(r["setting"]), (x, y), textcoords="offset points", xytext=(4, 3),
                                fontsize=6.5, color=colour)
        for r in pts:
            if r["reference"] or r[ekey] <= ZERO:
                ax.axhline(r[tkey], color="black", ls="--", lw=1)
                ax.annotate(f"{r['family']} (error 0)", (1, r[tkey]), xycoords=("axes fraction", "data"),
                            xytext=(-4, 3), textcoords="offset points", ha="right", fontsize=7)
        # Pareto front over all points of the grid (the reference included, at error 0).
        cand = [(r[tkey], r[ekey] if r[ekey] > ZERO else 0.0) for r in pts]
        front = sorted((cand[i] for i in pareto(cand) if cand[i][1] > 0), key=lambda p: p[1])
        if front:
            fx = [p[1] for p in front]
            fy = [p[0] for p in front]
            ax.step(fx, fy, where="post", color="0.3", lw=5, alpha=0.25, zorder=0, label="Pareto front")
            ax.scatter(fx, fy, s=140, facecolors="none", edgecolors="0.2", lw=1.2, zorder=3)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(label_of[ekey])
        ax.set_ylabel(f"time per compute, ms ({args.time}, {pts[0]['threads']} thread(s))")
        ax.set_title(f"{scene}: {mesh_text(pts[0])}chi = {chi:.3g} ({cells_text(pts[0])} cells, {pts[0]['particles']} "
                     "particles)", fontsize=10)
        ax.grid(True, which="both", alpha=0.25)
        if idx == 0:
            ax.legend(fontsize=7.5, loc="upper right", ncol=2)
    for idx in range(n, nrows * cols):
        axes[idx // cols][idx % cols].axis("off")
    # One panel is narrow: the title takes two lines there.
    fig.suptitle("run time against error (lower left is better); circled: Pareto front;" + ("\n" if cols == 1 else " ")
                 + "labels: setting (particle grid, \u03c3 or \u03b3 in particle diameters)", fontsize=10)
    top = 0.93 if cols == 1 else 0.97
    fig.tight_layout(rect=(0, 0, 1, top))
    fig.savefig(out, dpi=130)
    print(f"wrote {out}")
    if args.markdown:
        # comparisons.csv next to study.csv (or comparisons_X.csv next to a copy named study_X.csv).
        folder, name = os.path.split(args.csv)
        comp_file = os.path.join(folder, name.replace("study", "comparisons", 1))
        if name == os.path.basename(comp_file) or not os.path.exists(comp_file):
            comp_file = os.path.join(folder, "comparisons.csv")
        with open(comp_file, newline="") as f:
            comps = list(csv.DictReader(f))
        with open(args.markdown, "w") as f:
            f.write(markdown(rows, comps, ekey, tkey))
        print(f"wrote {args.markdown}")


if __name__ == "__main__":
    main()
