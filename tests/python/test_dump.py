"""The dump reader on the repository's LIGGGHTS files and on damaged copies of them."""
import gzip

import numpy as np
import pytest

import vfe
from conftest import DATA

BED = DATA / "liggghts" / "bed_mono_final.dump.gz"


def test_reads_the_settled_bed_by_column_name():
    f = vfe.read_dump(BED)
    assert f["timestep"] == 30000 and f["natoms"] == 20000
    np.testing.assert_array_equal(f["box"], [0, 0.02, 0, 0.02, 0, 0.06])
    assert f["box_flags"] == "ff ff ff" and f["tilt"] is None
    cols = f["columns"]
    assert list(cols)[:6] == ["id", "type", "x", "y", "z", "radius"]
    assert np.all(cols["radius"] == 0.0005)
    assert np.array_equal(np.sort(cols["id"]), np.arange(1, 20001))
    assert cols["x"][0] == 0.0169042 and cols["omegaz"][2] == 0.000749466  # the file's first lines
    assert np.shares_memory(cols["x"], f["data"])
    centres, radii = vfe.particles(f)
    assert centres.shape == (20000, 3) and np.shares_memory(centres, f["data"])
    assert np.all((centres >= 0) & (centres <= [0.02, 0.02, 0.06]))


def test_frames_come_in_timestep_order():
    frames = list(vfe.read_frames(str(DATA / "liggghts" / "bed_mono_frames" / "*.dump.gz")))
    steps = [f["timestep"] for f in frames]
    assert len(frames) == 20 and steps == sorted(steps) and steps[0] == 1500
    assert all(f["natoms"] == len(f["columns"]["x"]) for f in frames)
    with pytest.raises(vfe.DumpError, match="no file matches"):
        list(vfe.read_frames(str(DATA / "liggghts" / "nothing_*.dump")))


def text(path):
    with gzip.open(path, "rt") as f:
        return f.read()


SMALL = """ITEM: TIMESTEP
100
ITEM: NUMBER OF ATOMS
2
ITEM: BOX BOUNDS pp pp ff
0 1
0 1
0 2
ITEM: ATOMS id type x y z diameter
1 1 0.5 0.5 0.5 0.2
2 1 0.25 0.5 1.5 0.1
"""


def test_several_frames_a_diameter_column_and_a_triclinic_box(tmp_path):
    p = tmp_path / "two.dump"
    tri = SMALL.replace("100", "200").replace("BOUNDS pp pp ff", "BOUNDS xy xz yz pp pp ff")
    tri = tri.replace("0 1\n0 1\n0 2\n", "0 1 0.1\n0 1 0\n0 2 0\n")
    p.write_text(SMALL + tri)
    first, last = vfe.read_dump(p, frame=0), vfe.read_dump(p)
    assert (first["timestep"], last["timestep"]) == (100, 200)
    np.testing.assert_array_equal(last["tilt"], [0.1, 0, 0])
    assert last["box_flags"] == "pp pp ff"
    centres, radii = vfe.particles(first)
    np.testing.assert_array_equal(radii, [0.1, 0.05])
    np.testing.assert_array_equal(centres[1], [0.25, 0.5, 1.5])
    assert len(vfe.read_dump(p, frame="all")) == 2


@pytest.mark.parametrize("damage, message", [
    (lambda t: t[: t.index("2 1 0.25")], "truncated"),
    (lambda t: t.replace("2 1 0.25 0.5 1.5 0.1", "2 1 0.25 0.5 1.5"), "expected 6 values"),
    (lambda t: t.replace("0.25", "0.2x"), "not a number"),
    (lambda t: t.replace("ITEM: TIMESTEP\n", "ITEM: TIMESTEP\nabc\n", 1), "not a number"),
    (lambda t: t.replace("id type", "id id"), "distinct column names"),
    (lambda t: t.replace("ITEM: BOX BOUNDS pp pp ff\n0 1\n", "ITEM: BOX BOUNDS pp pp ff\n0\n"), "expected 2 numbers"),
    (lambda t: "garbage\n" + t, "expected 'ITEM: TIMESTEP'"),
])
def test_a_malformed_dump_raises_naming_the_line(tmp_path, damage, message):
    p = tmp_path / "bad.dump"
    p.write_text(damage(SMALL))
    with pytest.raises(vfe.DumpError, match=message) as info:
        vfe.read_dump(p)
    assert str(p) in str(info.value)


def test_a_truncated_gzip_dump_raises(tmp_path):
    raw = BED.read_bytes()
    p = tmp_path / "cut.dump.gz"
    p.write_bytes(raw[: len(raw) // 2])
    with pytest.raises(vfe.DumpError, match="truncated"):
        vfe.read_dump(p)
    q = tmp_path / "short.dump.gz"  # a whole gzip stream with fewer atoms than announced
    t = text(BED)
    q.write_bytes(gzip.compress(t[: t.index("\n", len(t) // 2) + 1].encode()))
    with pytest.raises(vfe.DumpError, match="the 20000 atom lines"):
        vfe.read_dump(q)


def test_missing_position_columns_are_named(tmp_path):
    p = tmp_path / "noz.dump"
    p.write_text(SMALL.replace("x y z diameter", "x y q diameter"))
    with pytest.raises(vfe.DumpError, match="no column 'z'"):
        vfe.particles(vfe.read_dump(p))
