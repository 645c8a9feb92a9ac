#!/usr/bin/python3
"""method=auto against pmm at particle_grid=auto and exact, per study mesh: the time and L1
of each (from `vfe study` output folders), auto's time over the faster of pmm auto and
exact, its front gap (its time over that of the fastest point of the run at least as
accurate: 1 on the Pareto front), and the share of spheres on each of auto's paths
(recomputed here with the Python module, which reports auto_fast, auto_pmm, auto_exact).

    PYTHONPATH=build/release/python /usr/bin/python3 scripts/auto_table.py out/study_bed_auto ...

Each folder holds a study.csv of `vfe study CONFIG --families ...` that ran the config's pmm,
exact and auto families; the config is found from the scene name (configs/<scene>.yaml).
"""
import csv
import pathlib
import sys

import numpy as np
import vfe
import vfe.dump
import vfe.study
import yaml

ROOT = pathlib.Path(__file__).resolve().parent.parent


def shares(config, mesh, options):
    """Fractions of the scene's spheres on auto's fast, pmm and exact paths on one mesh."""
    cfg = yaml.safe_load(open(config))
    part = cfg["particles"]
    frame = vfe.dump.read_dump(config.parent / part["file"])
    centres, radii = vfe.dump.particles(frame)
    if mesh.startswith("chi_"):
        engine = vfe.study.chi_grid(frame["box"], float(np.mean(2 * radii)), float(mesh[4:]))
    else:
        spec = next(m for m in cfg["meshes"] if m["name"] == mesh)
        engine = vfe.Engine.polymesh(str(config.parent / spec["path"]))
    engine.configure(f"method=auto threads=1 {cfg.get('options', '')} {options}")
    engine.compute(np.ascontiguousarray(centres), np.ascontiguousarray(radii))
    n = len(radii)
    return [engine.report_value(k) / n for k in ("auto_fast", "auto_pmm", "auto_exact")]


def main(folders):
    print("| scene | mesh | chi | template | pmm auto ms / L1 | exact ms | auto ms / L1 | auto / min | front gap "
          "| fast / pmm / exact |")
    print("|---|---|---:|---|---|---:|---|---:|---:|---|")
    for folder in folders:
        rows = list(csv.DictReader(open(pathlib.Path(folder) / "study.csv")))
        scene = rows[0]["scene"]
        config = ROOT / "configs" / f"{scene}.yaml"
        for mesh in dict.fromkeys(r["mesh"] for r in rows):
            here = [r for r in rows if r["mesh"] == mesh and r["status"] == "ok"]
            exact = next(r for r in here if r["family"] == "exact")
            for auto in (r for r in here if r["family"] == "auto"):
                template = auto["setting"].split("=")[1] if "template=" in auto["setting"] else "fibonacci"
                pmm = next(r for r in here if r["method"] == "pmm" and r["setting"] == "particle_grid=auto"
                           and f"template={template}" in r["options"])
                t_pmm, t_exact, t_auto = (float(r["time_median_ms"]) for r in (pmm, exact, auto))
                # auto's time over that of the fastest point of the run at least as accurate (1: on the front)
                gap = t_auto / min(float(r["time_median_ms"]) for r in here if float(r["l1"]) <= float(auto["l1"]))
                f = shares(config, mesh, "" if auto["setting"] == "-" else auto["setting"])
                print(f"| {scene} | {mesh} | {float(auto['chi']):.3g} | {template} | {t_pmm:.1f} / {float(pmm['l1']):.3g} "
                      f"| {t_exact:.1f} | {t_auto:.1f} / {float(auto['l1']):.3g} | {t_auto / min(t_pmm, t_exact):.2f} "
                      f"| {gap:.2f} | {f[0]:.0%} / {f[1]:.0%} / {f[2]:.0%} |")


if __name__ == "__main__":
    main(sys.argv[1:])
