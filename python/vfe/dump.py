"""LIGGGHTS/LAMMPS text dumps (plain or gzip) to numpy, columns by header name.

A frame is a dict: ``timestep`` (int), ``natoms`` (int), ``box`` ((6,) float64: xlo xhi ylo
yhi zlo zhi; the bounding box for triclinic boxes), ``box_flags`` (e.g. "pp pp ff"),
``tilt`` ((3,) xy xz yz, or None), ``path``, ``data`` ((natoms, ncols) float64, the ATOMS
table) and ``columns`` (name -> a view of one column of ``data``, no copy). Reading is
strict: a truncated or malformed file raises DumpError (a ValueError) naming the file and
line.
"""
import glob as _glob
import gzip
import os

import numpy as np


class DumpError(ValueError):
    """A dump that cannot be read: the message names the file, the line and what is wrong."""


def _open(path):
    with open(path, "rb") as f:
        gz = f.read(2) == b"\x1f\x8b"
    return gzip.open(path, "rt") if gz else open(path, "rt")


class _Lines:
    """Numbered lines of a file; truncated gzip streams raise DumpError."""

    def __init__(self, path):
        self.path = os.fspath(path)
        self.file = _open(self.path)
        self.number = 0

    def next(self):
        try:
            line = self.file.readline()
        except (EOFError, OSError, gzip.BadGzipFile) as e:
            raise DumpError(f"{self.path}:{self.number + 1}: cannot read past this line ({e}); the file is "
                            "truncated or damaged: re-write it, or check a gzip file with `gzip -t`") from None
        if line == "":
            return None
        self.number += 1
        return line.rstrip("\r\n")

    def fail(self, what):
        raise DumpError(f"{self.path}:{self.number}: {what}")

    def close(self):
        self.file.close()


def _expect(lines, what):
    line = lines.next()
    if line is None:
        raise DumpError(f"{lines.path}:{lines.number}: the file ends where {what} should follow; it is truncated")
    return line


def _numbers(lines, line, count, kind, what):
    fields = line.split()
    if len(fields) < count:
        lines.fail(f"{what}: expected {count} numbers, got '{line}'")
    try:
        return [kind(x) for x in fields[:count]]
    except ValueError:
        lines.fail(f"{what}: not a number in '{line}'")


def _frames(path):
    """Yields the frames of one file in file order."""
    lines = _Lines(path)
    try:
        line = lines.next()
        while line is not None:
            if line.strip() == "":
                line = lines.next()
                continue
            if not line.startswith("ITEM: TIMESTEP"):
                lines.fail(f"expected 'ITEM: TIMESTEP', got '{line}'; write the dump with LIGGGHTS/LAMMPS "
                           "`dump ID all custom N FILE id type x y z radius ...`")
            frame = {"path": lines.path, "tilt": None, "box_flags": ""}
            frame["timestep"] = _numbers(lines, _expect(lines, "the timestep"), 1, int, "TIMESTEP")[0]
            natoms = None
            while True:
                item = _expect(lines, "ITEM: ATOMS")
                if item.startswith("ITEM: NUMBER OF ATOMS"):
                    natoms = _numbers(lines, _expect(lines, "the atom count"), 1, int, "NUMBER OF ATOMS")[0]
                    if natoms < 0:
                        lines.fail(f"negative atom count {natoms}")
                elif item.startswith("ITEM: BOX BOUNDS"):
                    flags = item[len("ITEM: BOX BOUNDS"):].split()
                    triclinic = len(flags) >= 3 and flags[:3] == ["xy", "xz", "yz"]
                    frame["box_flags"] = " ".join(flags[3:] if triclinic else flags)
                    rows = [_numbers(lines, _expect(lines, "a box line"), 3 if triclinic else 2, float, "BOX BOUNDS")
                            for _ in range(3)]
                    frame["box"] = np.array([v for r in rows for v in r[:2]], dtype=np.float64)
                    if triclinic:
                        frame["tilt"] = np.array([r[2] for r in rows], dtype=np.float64)
                elif item.startswith("ITEM: ATOMS"):
                    names = item[len("ITEM: ATOMS"):].split()
                    break
                elif item.startswith("ITEM: TIME") or item.startswith("ITEM: UNITS"):
                    _expect(lines, item)
                else:
                    lines.fail(f"unknown section '{item}'")
            if natoms is None or "box" not in frame:
                lines.fail("ITEM: ATOMS before NUMBER OF ATOMS or BOX BOUNDS")
            if not names or len(set(names)) != len(names):
                lines.fail(f"the ATOMS header needs distinct column names, got '{item}'")
            width = len(names)
            rows = []
            for _ in range(natoms):
                row = _expect(lines, f"the {natoms} atom lines")
                if len(row.split()) != width:
                    lines.fail(f"expected {width} values ({' '.join(names)}), got {len(row.split())}")
                rows.append(row)
            try:
                data = np.array(" ".join(rows).split(), dtype=np.float64).reshape(natoms, width)
            except ValueError:
                lines.fail(f"a value in the {natoms} atom lines above is not a number")
            frame["natoms"] = natoms
            frame["data"] = data
            frame["columns"] = {name: data[:, k] for k, name in enumerate(names)}
            yield frame
            line = lines.next()
    finally:
        lines.close()


def read_dump(path, frame=-1):
    """One frame of a dump file: the last by default, or frame=i (file order, negative from
    the end), or frame="all" for the list of every frame."""
    frames = list(_frames(path))
    if not frames:
        raise DumpError(f"{os.fspath(path)}: no frame in the file")
    if frame == "all":
        return frames
    try:
        return frames[frame]
    except IndexError:
        raise DumpError(f"{os.fspath(path)}: frame {frame} asked, the file has {len(frames)}") from None


def read_frames(pattern):
    """Frames of the files matching a glob pattern (or of a list of paths), in timestep order;
    a generator (one file in memory at a time). Two frames with the same timestep raise."""
    paths = sorted(_glob.glob(pattern)) if isinstance(pattern, (str, os.PathLike)) else list(pattern)
    if isinstance(pattern, (str, os.PathLike)) and not paths:
        raise DumpError(f"no file matches '{os.fspath(pattern)}'")

    def first_timestep(p):
        lines = _Lines(p)
        try:
            head, value = lines.next(), lines.next()
        finally:
            lines.close()
        if head is None or not head.startswith("ITEM: TIMESTEP") or value is None:
            raise DumpError(f"{p}:1: expected 'ITEM: TIMESTEP' and a timestep")
        return _numbers(lines, value, 1, int, "TIMESTEP")[0]

    ordered = sorted(paths, key=first_timestep)
    last = None
    for p in ordered:
        for f in _frames(p):
            if last is not None and f["timestep"] <= last:
                raise DumpError(f"{p}: timestep {f['timestep']} is not after {last}; the series has overlapping "
                                "or unordered frames")
            last = f["timestep"]
            yield f


def particles(frame):
    """Centres (n, 3) and radii (n,) of a frame: x y z (a view when the columns are adjacent)
    and radius (or diameter / 2). Raises DumpError naming a missing column."""
    cols, names = frame["columns"], list(frame["columns"])
    for c in ("x", "y", "z"):
        if c not in cols:
            raise DumpError(f"{frame['path']}: no column '{c}' (columns: {' '.join(names)})")
    ix = names.index("x")
    if names[ix:ix + 3] == ["x", "y", "z"]:
        centres = frame["data"][:, ix:ix + 3]
    else:
        centres = np.column_stack([cols["x"], cols["y"], cols["z"]])
    if "radius" in cols:
        radii = cols["radius"]
    elif "diameter" in cols:
        radii = cols["diameter"] / 2
    else:
        raise DumpError(f"{frame['path']}: no column 'radius' or 'diameter' (columns: {' '.join(names)})")
    return centres, radii
