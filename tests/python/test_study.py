"""vfe.study and vfe.compare_fields against the measures computed here by hand with numpy."""
import numpy as np
import pytest

import vfe
from conftest import DATA, ball_volume, random_spheres


def measures_by_hand(solid, exact, volumes, particle_volume):
    touched = (solid != 0) | (exact != 0)
    d_eps = np.abs(solid - exact)[touched] / volumes[touched]
    return {"theta": d_eps.mean(), "max_error": d_eps.max(),
            "l1": np.abs(solid - exact).sum() / particle_volume,
            "volume_error": abs(solid.sum() - particle_volume) / particle_volume,
            "cells_compared": int(touched.sum())}


def test_compare_fields_equals_the_definitions():
    e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.01,) * 3, cells=(8, 8, 8))
    centres, radii = random_spheres(60, (0, 0, 0), (0.08,) * 3, 0.003, 0.006, seed=31)
    e.configure(method="exact")
    exact = e.compute(centres, radii)
    e.configure(method="direct")
    direct = e.compute(centres, radii)
    pv = ball_volume(radii).sum()
    got = vfe.compare_fields(direct, exact, e.cell_volumes(), pv)
    want = measures_by_hand(direct, exact, e.cell_volumes(), pv)
    assert got["cells_compared"] == want["cells_compared"]
    for k in ("theta", "max_error", "l1", "volume_error"):
        assert got[k] == pytest.approx(want[k], rel=1e-12, abs=1e-15), k
    with pytest.raises(ValueError, match="solid_exact must have shape"):
        vfe.compare_fields(direct, exact[:-1], e.cell_volumes(), pv)


def test_study_rows_measure_each_point_against_exact():
    frame = vfe.read_dump(DATA / "liggghts" / "bed_mono_final.dump.gz")
    centres, radii = vfe.particles(frame)
    engine = vfe.study.chi_grid(frame["box"], 2 * radii.mean(), chi=3)
    assert engine.cell_count == 7 * 7 * 20  # 3 mm cells; 20 mm is no multiple: extended past the box
    pts = vfe.study.points("direct") + vfe.study.points("pmm", ["particle_grid=5", "particle_grid=80"]) + \
        vfe.study.points("exact")
    rows = vfe.study.run(engine, centres, radii, pts, repeats=2)
    assert [(r["family"], r["setting"]) for r in rows] == [("direct", ""), ("pmm", "particle_grid=5"),
                                                         ("pmm", "particle_grid=80"), ("exact", "")]
    by = {r["setting"] if r["family"] == "pmm" else r["family"]: r for r in rows}
    assert by["exact"]["l1"] == 0 and by["exact"]["theta"] == 0 and by["exact"]["reference"]
    assert not any(r["reference"] for r in rows[:3])
    assert by["direct"]["l1"] > by["particle_grid=5"]["l1"] > by["particle_grid=80"]["l1"] > 0
    engine.configure("method=exact")
    exact = engine.compute(centres, radii)
    engine.configure("method=direct outside=nearest")
    want = measures_by_hand(engine.compute(centres, radii), exact, engine.cell_volumes(), ball_volume(radii).sum())
    assert by["direct"]["l1"] == pytest.approx(want["l1"], rel=1e-12)
    assert all(r["time_ms"] > 0 and r["volume_error"] < 1e-12 for r in rows)
    assert "| pmm | particle_grid=80 |" in vfe.study.table(rows)


def test_pareto_keeps_the_points_nothing_beats():
    rows = [{"time_ms": t, "l1": l} for t, l in [(1, 0.5), (2, 0.6), (3, 0.1), (4, 0.0), (5, 0.0)]]
    assert [(r["time_ms"], r["l1"]) for r in vfe.study.pareto(rows)] == [(1, 0.5), (3, 0.1), (4, 0.0)]


def test_study_equals_the_vfe_cli_study_on_the_same_points(tmp_path):
    """`vfe study configs/study_bed.yaml --chi 3` and vfe.study on the same option strings."""
    import csv
    import os
    import subprocess

    cli = os.environ.get("VFE_CLI")
    if not cli:
        pytest.skip("VFE_CLI (the built vfe tool) is set by ctest")
    from conftest import SOURCE_DIR
    subprocess.run([cli, "study", str(SOURCE_DIR / "configs" / "study_bed.yaml"), "--chi", "3", "--repeats", "1",
                    "--output", str(tmp_path), "-q"], check=True, capture_output=True)
    with open(tmp_path / "study.csv", newline="") as f:
        cli_rows = list(csv.DictReader(f))
    frame = vfe.read_dump(DATA / "liggghts" / "bed_mono_final.dump.gz")
    centres, radii = vfe.particles(frame)
    engine = vfe.study.chi_grid(frame["box"], 2 * radii.mean(), chi=3)
    assert [engine.cell_count] == list({int(r["cells"]) for r in cli_rows})
    pts = [(r["family"], r["setting"], r["options"]) for r in cli_rows]
    rows = vfe.study.run(engine, centres, radii, pts, repeats=0, options="")
    assert len(rows) == len(cli_rows) > 30
    for mine, theirs in zip(rows, cli_rows):
        for k in ("l1", "theta", "max_error"):
            where = (theirs["family"], theirs["setting"], k)
            assert mine[k] == pytest.approx(float(theirs[k]), rel=1e-9, abs=1e-15), where
