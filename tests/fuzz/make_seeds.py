#!/usr/bin/env python3
"""Writes the hand-made seed inputs of tests/fuzz/corpus (run from anywhere; idempotent).

Each target's folder also keeps the inputs that once crashed or were accepted wrongly
(files named regress_*); those are written here too so they can be regenerated."""
import gzip, os, struct

HERE = os.path.dirname(os.path.abspath(__file__))
SEP = b"\n//@@\n"


def put(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def header(cls, obj, fmt="ascii", arch=""):
    a = f"    arch        \"{arch}\";\n" if arch else ""
    return (f"FoamFile\n{{\n    version     2.0;\n    format      {fmt};\n{a}    class       {cls};\n"
            f"    object      {obj};\n}}\n").encode()


# A unit hexahedron: 8 points, 6 outward faces, one cell, one patch.
PTS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (3, 7, 6, 2), (0, 4, 7, 3), (1, 2, 6, 5)]


def boundary(n_faces=6, start=0, fmt="ascii"):
    return header("polyBoundaryMesh", "boundary", fmt) + (
        f"1\n(\n    walls\n    {{\n        type wall;\n        nFaces {n_faces};\n        startFace {start};\n    }}\n)\n").encode()


def ascii_mesh(owner=None, n_faces=6):
    owner = owner or [0] * 6
    pts = header("vectorField", "points") + b"8\n(\n" + b"".join(f"({x} {y} {z})\n".encode() for x, y, z in PTS) + b")\n"
    fcs = header("faceList", "faces") + b"6\n(\n" + b"".join(("4(" + " ".join(map(str, f)) + ")\n").encode() for f in FACES) + b")\n"
    own = header("labelList", "owner") + b"6\n(\n" + b"".join(f"{c}\n".encode() for c in owner) + b")\n"
    nbr = header("labelList", "neighbour") + b"0\n(\n)\n"
    return [pts, fcs, own, nbr, boundary(n_faces)]


def binary_mesh(label_bits, owner=None):
    owner = owner or [0] * 6
    arch = f"LSB;label={label_bits};scalar=64"
    lf = "<i" if label_bits == 32 else "<q"
    labels = lambda v: f"\n{len(v)}\n(".encode() + b"".join(struct.pack(lf, x) for x in v) + b")\n"
    pts = header("vectorField", "points", "binary", arch) + b"\n8\n(" + b"".join(struct.pack("<3d", *p) for p in PTS) + b")\n"
    offsets = [4 * i for i in range(7)]
    fcs = header("faceCompactList", "faces", "binary", arch) + labels(offsets) + labels([q for f in FACES for q in f])
    own = header("labelList", "owner", "binary", arch) + labels(owner)
    nbr = header("labelList", "neighbour", "binary", arch) + b"\n0\n"
    return [pts, fcs, own, nbr, boundary(6, 0, "binary")]


def bundle(files, gz=False):
    return bytes([1 if gz else 0]) + SEP.join(files)


HUGE = 2**63 - 2
put("polymesh", "hex_ascii", bundle(ascii_mesh()))
put("polymesh", "hex_ascii_gz", bundle(ascii_mesh(), gz=True))
put("polymesh", "hex_binary32", bundle(binary_mesh(32)))
put("polymesh", "hex_binary64", bundle(binary_mesh(64)))
put("polymesh", "regress_owner_label_near_2p63_ascii", bundle(ascii_mesh(owner=[0, 0, 0, 0, 0, HUGE])))
put("polymesh", "regress_owner_label_near_2p63_gz", bundle(ascii_mesh(owner=[0, 0, 0, 0, 0, HUGE]), gz=True))
put("polymesh", "regress_owner_label_near_2p63_binary64", bundle(binary_mesh(64, owner=[0, 0, 0, 0, 0, HUGE])))
put("polymesh", "regress_boundary_nfaces_near_2p63", bundle(ascii_mesh(n_faces=2**63 - 1)))
put("polymesh", "regress_uniform_points_huge", bundle([header("vectorField", "points") + b"67108864{(0 0 0)}\n"] + ascii_mesh()[1:]))

# Shapes: byte 0 = STL, 1 = OBJ, 2 = spec.
TRI = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)]
V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
obj = "".join(f"v {x} {y} {z}\n" for x, y, z in V) + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in TRI)
put("shapes", "tetra_obj", b"\x01" + obj.encode())
stl = "solid t\n" + "".join("facet normal 0 0 0\nouter loop\n" + "".join(f"vertex {V[i][0]} {V[i][1]} {V[i][2]}\n" for i in t)
                            + "endloop\nendfacet\n" for t in TRI) + "endsolid t\n"
put("shapes", "tetra_stl_ascii", b"\x00" + stl.encode())
binstl = b"\0" * 80 + struct.pack("<I", 4) + b"".join(struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *V[i]) for i in t) + b"\0\0" for t in TRI)
put("shapes", "tetra_stl_binary", b"\x00" + binstl)
for name, spec in [("sphere", "sphere"), ("ellipsoid", "ellipsoid 1 2 3"), ("superquadric", "superquadric 1 1 1 0.5 0.5"),
                   ("clump", "clump 0 0 0 1; 1 0 0 0.5")]:
    put("shapes", "spec_" + name, b"\x02" + spec.encode())
put("shapes", "regress_obj_index_4294967300", b"\x01" + (obj.replace("f 1 3 2", "f 4294967300 3 2")).encode())
put("shapes", "regress_obj_index_1x", b"\x01" + (obj.replace("f 1 3 2", "f 1x 3 2")).encode())
put("shapes", "regress_obj_index_2.9", b"\x01" + (obj.replace("f 1 3 2", "f 1 2.9 2")).encode())
put("shapes", "regress_stray_vertex_far_away", b"\x01" + (obj + "v 1e300 1e300 1e300\n").encode())
put("shapes", "regress_clump_spheres_far_apart", b"\x02clump 0 0 0 1; 1e9 0 0 1")
put("shapes", "regress_sliver_tetra", b"\x01" + obj.replace("v 0 0 1", "v 0 0 1e-9").encode())

# Dumps: byte 0 bit 0 = gzip.
dump = ("ITEM: TIMESTEP\n100\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS ff ff ff\n0 0.02\n0 0.02\n0 0.06\n"
        "ITEM: ATOMS id type x y z radius \n1 1 0.01 0.01 0.01 0.0005 \n2 1 0.01 0.012 0.02 0.0005 \n")
put("dump", "two_atoms", b"\x00" + dump.encode())
put("dump", "two_atoms_gz", b"\x01" + dump.encode())
put("dump", "regress_cut_inside_a_number", b"\x00" + dump[:-9].encode())
put("dump", "regress_atoms_count_huge", b"\x00" + dump.replace("ATOMS\n2\n", "ATOMS\n9223372036854775807\n").encode())

# Scene configs.
scene = ("name: fuzz\nparticles: {dump: a.dump}\nmeshes:\n  - {name: g, origin: [0, 0, 0], spacing: 0.002, cells: [10, 10, 30]}\n"
         "  - {name: b, bounds: particles_box, spacing: 0.004}\nmethods:\n  - {method: pmm}\n")
put("scene_config", "cartesian", scene)
put("scene_config", "regress_spacing_5e-324", scene.replace("spacing: 0.002", "spacing: 5e-324"))
put("scene_config", "regress_spacing_1e-200", scene.replace("spacing: 0.002", "spacing: 1e-200"))
put("scene_config", "regress_bounds_spacing_1e-200", scene.replace("spacing: 0.004", "spacing: 1e-200"))

# Option strings.
for i, o in enumerate(["method=pmm particle_grid=auto", "method=gaussian sigma=0.25 threads=2",
                       "particle_grid=9223372036854775807", "sigma=1e-400 gamma=1e400", "orientation=given seed=18446744073709551616"]):
    put("options", f"seed_{i}", o)
