#!/usr/bin/env python3
"""Plots and fit of the stability stress test (`vfe stability --sweep`).

Reads the stability.csv and n_min.csv of one or more sweep folders (e.g. one per seed),
fits the jump model of docs/stability.md,

    J(n, chi) = pi / (6 n chi^3) * (b + a sqrt(n))     (step s = d/200)

to the measured n_min(chi) (at n_min the criterion holds with equality:
n chi^3 / C = b + a sqrt(n), C = pi / (6 deps_crit), a linear least-squares problem in
a and b), prints the constants with their uncertainty and a Markdown table, and writes

    <out>/stability_J_<template>_<orientation>.png   J against n for each chi, criterion line
    <out>/stability_n_min.png                        n_min against chi with the fitted formula

Usage: python3 scripts/plot_stability.py SWEEP_DIR [SWEEP_DIR ...] [--out DIR]
Needs numpy and matplotlib (Debian: python3-matplotlib).
"""

import argparse
import csv
import math
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

DEFAULT_CRIT = math.pi / (6 * 27)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def n_min_formula(chi, a, b, crit=DEFAULT_CRIT):
    """Smallest n with pi/(6 n chi^3) (b + a sqrt n) <= crit (real-valued, >= 1)."""
    chi = np.asarray(chi, dtype=float)
    c = math.pi / (6.0 * np.asarray(crit, dtype=float))
    x = (c * a + np.sqrt(np.maximum(0.0, (c * a) ** 2 + 4.0 * c * b * chi**3))) / (2.0 * chi**3)
    return np.maximum(1.0, x * x)


def fit(points):
    """points: list of (chi, n_min, crit). Weighted linear least squares of
    n chi^3 / C = b + a sqrt(n) with relative weights; returns a, b, cov."""
    rows, ys = [], []
    for chi, n, crit in points:
        c = math.pi / (6.0 * crit)
        y = n * chi**3 / c
        rows.append([math.sqrt(n) / y, 1.0 / y])  # divide by y: relative residuals
        ys.append(1.0)
    A = np.array(rows)
    y = np.array(ys)
    coef, res, rank, _ = np.linalg.lstsq(A, y, rcond=None)
    dof = max(1, len(y) - 2)
    sigma2 = float(np.sum((A @ coef - y) ** 2)) / dof
    cov = sigma2 * np.linalg.inv(A.T @ A)
    return coef[0], coef[1], cov


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dirs", nargs="+", help="sweep output folders (each with stability.csv and n_min.csv)")
    ap.add_argument("--out", default=None, help="folder for the PNGs (default: the first sweep folder)")
    args = ap.parse_args()
    out = args.out or args.dirs[0]
    os.makedirs(out, exist_ok=True)

    rows, nmins = [], []
    for i, d in enumerate(args.dirs):
        for r in read_csv(os.path.join(d, "stability.csv")):
            r["run"] = i
            rows.append(r)
        p = os.path.join(d, "n_min.csv")
        if os.path.exists(p):
            for r in read_csv(p):
                r["run"] = i
                nmins.append(r)
    if not rows:
        sys.exit("no rows in the given folders")

    # J against n for each chi, one figure per (template, orientation); its first run only.
    families = sorted({(r["template"], r["orientation"]) for r in rows})
    for tmpl, orient in families:
        fam = [r for r in rows if r["template"] == tmpl and r["orientation"] == orient]
        first_run = min(r["run"] for r in fam)
        sel = [r for r in fam if r["run"] == first_run]
        by_chi = defaultdict(list)
        for r in sel:
            by_chi[float(r["chi"])].append((int(r["n"]), float(r["J"]), float(r["jump_criterion"])))
        fig, ax = plt.subplots(figsize=(7, 5))
        cmap = plt.get_cmap("viridis")
        chis = sorted(by_chi)
        for k, chi in enumerate(chis):
            pts = sorted(by_chi[chi])
            ax.loglog([p[0] for p in pts], [max(p[1], 1e-6) for p in pts], "o-", ms=3,
                      color=cmap(k / max(1, len(chis) - 1)), label=f"chi={chi:g}")
        crit = float(sel[0]["jump_criterion"]) if sel else DEFAULT_CRIT
        ax.axhline(crit, color="r", ls="--", label=f"deps_crit={crit:.4g}")
        ax.set_xlabel("sub-elements per particle n")
        ax.set_ylabel("excess jump J")
        ax.set_title(f"stress test: template={tmpl} orientation={orient}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"stability_J_{tmpl}_{orient}.png"), dpi=90)
        plt.close(fig)

    if not nmins:
        return

    # Fit per (template, orientation) over all runs, and per run for the spread.
    print("fit of n chi^3 / C = b + a sqrt(n) at the measured n_min (points with n_min > 1):")
    fits = {}
    for tmpl, orient in sorted({(r["template"], r["orientation"]) for r in nmins}):
        sel = [r for r in nmins if r["template"] == tmpl and r["orientation"] == orient]
        pts = [(float(r["chi"]), int(r["n_min"]), float(r["jump_criterion"])) for r in sel if int(r["n_min"]) > 1]
        if len(pts) < 3:
            print(f"  {tmpl} {orient}: too few points ({len(pts)}) with 1 < n_min")
            continue
        a, b, cov = fit(pts)
        per_run = []
        for run in sorted({r["run"] for r in sel}):
            p = [(float(r["chi"]), int(r["n_min"]), float(r["jump_criterion"])) for r in sel
                 if r["run"] == run and int(r["n_min"]) > 1]
            if len(p) >= 3:
                per_run.append(fit(p)[:2])
        sa, sb = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
        if b < 0:
            print(f"  {tmpl} {orient}: the model does not fit (a = {a:.4g}, b = {b:.4g} < 0; {len(pts)} points):"
                  " whole groups of centroids cross together")
            continue
        fits[(tmpl, orient)] = (a, b)
        spread = ""
        if len(per_run) > 1:
            pa = np.array(per_run)
            spread = f"; per-run a = {pa[:, 0].mean():.4g} +- {pa[:, 0].std(ddof=1):.2g}, " \
                     f"b = {pa[:, 1].mean():.4g} +- {pa[:, 1].std(ddof=1):.2g} ({len(per_run)} runs)"
        resid = [math.log(n / float(n_min_formula(chi, a, b, crit))) for chi, n, crit in pts]
        print(f"  {tmpl} {orient}: a = {a:.4g} +- {sa:.2g}, b = {b:.4g} +- {sb:.2g} (1 sigma, {len(pts)} points)"
              f"{spread}; log residual rms {np.sqrt(np.mean(np.square(resid))):.2f}, "
              f"max |.| {np.max(np.abs(resid)):.2f}")
        # The flux form uses the same constants with C = pi dx / (6 U_s dt_f).
        fl = [(float(r["chi"]), int(r["n_min_flux"]), float(r["flux_criterion"])) for r in sel
              if int(r["n_min_flux"]) > 0 and float(r["flux_criterion"]) > 0]
        if fl:
            pred = [float(n_min_formula(chi, a, b, crit)) for chi, n, crit in fl]
            ratios = [n / p for (chi, n, crit), p in zip(fl, pred)]
            print(f"    flux n_min / formula: min {min(ratios):.2f}, max {max(ratios):.2f} over {len(fl)} points")

    # Markdown table: n_min per chi, families as columns (runs joined by '/').
    keys = sorted({(r["template"], r["orientation"]) for r in nmins})
    chis = sorted({float(r["chi"]) for r in nmins})
    print("\n| chi | 27/chi^3 | " + " | ".join(f"{t} {o}" for t, o in keys) + " |")
    print("|---|---|" + "---|" * len(keys))
    for chi in chis:
        cells = []
        for t, o in keys:
            v = [r for r in nmins if r["template"] == t and r["orientation"] == o and float(r["chi"]) == chi]
            v.sort(key=lambda r: r["run"])
            s = "/".join(("none" if int(r["n_min"]) < 0 else r["n_min"]) + ("" if int(r["n_min"]) > 0 else
                         f" (>{r['n_tested_max']})") for r in v)
            if (t, o) in fits and v:
                s += f" (fit {n_min_formula(chi, *fits[(t, o)]):.0f})"
            cells.append(s)
        print(f"| {chi:g} | {27 / chi**3:.1f} | " + " | ".join(cells) + " |")
    flux_rows = [r for r in nmins if int(r["n_min_flux"]) > 0]
    if flux_rows:
        print("\nflux form (n_min_flux per run, formula with the fitted a, b):")
        print("| chi | U_s dt_f / dx | " + " | ".join(f"{t} {o}" for t, o in keys) + " |")
        print("|---|---|" + "---|" * len(keys))
        for chi in chis:
            cells, fc = [], None
            for t, o in keys:
                v = sorted([r for r in flux_rows if r["template"] == t and r["orientation"] == o
                            and float(r["chi"]) == chi], key=lambda r: r["run"])
                if not v:
                    cells.append("-")
                    continue
                fc = float(v[0]["flux_criterion"])
                s = "/".join(r["n_min_flux"] for r in v)
                if (t, o) in fits:
                    s += f" (fit {n_min_formula(chi, *fits[(t, o)], crit=fc):.0f})"
                cells.append(s)
            print(f"| {chi:g} | {fc if fc else float('nan'):.4g} | " + " | ".join(cells) + " |")

    # n_min against chi with the fitted formula.
    fig, ax = plt.subplots(figsize=(7, 5))
    xs = np.geomspace(min(chis), max(chis), 200)
    colours = plt.get_cmap("tab10")
    for k, (t, o) in enumerate(keys):
        sel = [r for r in nmins if r["template"] == t and r["orientation"] == o and int(r["n_min"]) > 0]
        ax.loglog([float(r["chi"]) for r in sel], [int(r["n_min"]) for r in sel], "o", ms=4,
                  color=colours(k), alpha=0.7, label=f"{t} {o} (measured)")
        if (t, o) in fits:
            a, b = fits[(t, o)]
            ax.loglog(xs, n_min_formula(xs, a, b), "-", color=colours(k), label=f"{t} {o}: fit a={a:.3g}, b={b:.3g}")
    ax.loglog(xs, np.maximum(1, 27 / xs**3), "k:", label="27/chi^3 (one sub-element)")
    ax.set_xlabel("chi = cell size / particle diameter")
    ax.set_ylabel("n_min (J <= pi/162 on every trajectory)")
    ax.set_title("smallest stable particle grid")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "stability_n_min.png"), dpi=90)
    plt.close(fig)
    print(f"\nwrote the plots to {out}")


if __name__ == "__main__":
    main()
