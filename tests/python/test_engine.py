"""The module's engine against independent oracles: closed-form volumes, conservation, the
C API called directly (ctypes), geometry formulas, and the same cells as different meshes."""
import ctypes
import os

import numpy as np
import pytest

import vfe
from conftest import DATA, ball_volume, random_spheres

METHODS = ["direct", "pmm", "exact", "divided", "gaussian", "porous_cube", "big_particle", "trilinear", "auto"]


def test_method_names_are_the_engines():
    assert vfe.method_names() == METHODS


def grid(nx=4, ny=3, nz=5, h=1.0):
    return vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(h, h, h), cells=(nx, ny, nz))


def test_sphere_inside_one_cell_is_its_volume_in_that_cell():
    e = grid()
    e.configure(method="exact")
    i, j, k = 2, 1, 3
    solid = e.compute(np.array([[i + 0.5, j + 0.5, k + 0.45]]), np.array([0.3]))
    expected = np.zeros(e.cell_count)
    expected[i + 4 * (j + 3 * k)] = ball_volume(0.3)
    np.testing.assert_allclose(solid, expected, rtol=1e-14, atol=0)


def test_sphere_on_a_node_splits_into_eight_octants():
    e = grid(2, 2, 2)
    e.configure("method=exact")
    solid = e.compute(np.array([[1.0, 1.0, 1.0]]), np.array([0.7]))
    np.testing.assert_allclose(solid, np.full(8, ball_volume(0.7) / 8), rtol=1e-12)
    eps = e.void_fraction()
    np.testing.assert_allclose(eps, 1 - solid / 1.0, rtol=1e-14)


@pytest.mark.parametrize("method", METHODS)
def test_every_method_conserves_volume(method):
    e = grid(6, 6, 6, h=0.01)
    centres, radii = random_spheres(200, (0, 0, 0), (0.06, 0.06, 0.06), 0.002, 0.006, seed=3)
    e.configure(method=method, outside="nearest")
    solid = e.compute(centres, radii)
    total = ball_volume(radii).sum()
    assert solid.sum() == pytest.approx(total, rel=1e-12)
    r = e.report()
    assert r["particles"] == 200
    assert r["particle_volume"] == pytest.approx(total, rel=1e-14)
    assert r["deposited_volume"] == pytest.approx(solid.sum(), rel=1e-14)


def c_api():
    path = os.environ.get("VFE_LIBRARY")
    if not path:
        pytest.skip("VFE_LIBRARY (the built libvfe.so) is set by ctest")
    lib = ctypes.CDLL(path)
    d3, i3 = ctypes.c_double * 3, ctypes.c_int64 * 3
    lib.vfe_create_cartesian.argtypes = [d3, d3, i3, ctypes.POINTER(ctypes.c_void_p)]
    lib.vfe_configure.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
    lib.vfe_cell_count.argtypes = [ctypes.c_void_p]
    lib.vfe_cell_count.restype = ctypes.c_int64
    dp = ctypes.POINTER(ctypes.c_double)
    lib.vfe_compute.argtypes = [ctypes.c_void_p, ctypes.c_int64, dp, dp, dp, dp]
    lib.vfe_destroy.argtypes = [ctypes.c_void_p]
    return lib, d3, i3, dp


@pytest.mark.parametrize("options", ["method=pmm particle_grid=40", "method=exact", "method=gaussian",
                                     "method=pmm template=spherical particle_grid=auto"])
def test_equals_the_c_api_on_the_same_input(options):
    lib, d3, i3, dp = c_api()
    frame = vfe.read_dump(DATA / "liggghts" / "bed_mono_final.dump.gz")
    centres, radii = vfe.particles(frame)
    centres, radii = np.ascontiguousarray(centres[:3000]), np.ascontiguousarray(radii[:3000])
    handle = ctypes.c_void_p()
    assert lib.vfe_create_cartesian(d3(0, 0, 0), d3(0.002, 0.002, 0.002), i3(10, 10, 30), ctypes.byref(handle)) == 0
    try:
        assert lib.vfe_configure(handle, (options + " deterministic=1").encode()) == 0
        reference = np.zeros(lib.vfe_cell_count(handle))
        assert lib.vfe_compute(handle, len(radii), centres.ctypes.data_as(dp), radii.ctypes.data_as(dp), None,
                               reference.ctypes.data_as(dp)) == 0
    finally:
        lib.vfe_destroy(handle)
    e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.002,) * 3, cells=(10, 10, 30))
    e.configure(options, deterministic=True)
    assert np.array_equal(e.compute(centres, radii), reference)
    assert reference.sum() > 0


def test_cell_geometry_follows_the_index_rule():
    e = vfe.Engine.cartesian(origin=(1, 2, 3), spacing=(0.5, 0.25, 2), cells=(3, 4, 2))
    assert e.cell_count == 24 and not e.is_polymesh
    np.testing.assert_allclose(e.cell_volumes(), np.full(24, 0.25))
    c = e.cell_centres()
    assert c.shape == (24, 3)
    i, j, k = 2, 3, 1
    np.testing.assert_allclose(c[i + 3 * (j + 4 * k)], [1 + 2.5 * 0.5, 2 + 3.5 * 0.25, 3 + 1.5 * 2])


def test_rectilinear_with_even_nodes_equals_the_cartesian_grid():
    x, y, z = np.linspace(0, 0.04, 5), np.linspace(0, 0.03, 4), np.linspace(0, 0.05, 6)
    r = vfe.Engine.rectilinear(x, y, z)
    c = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.01, 0.01, 0.01), cells=(4, 3, 5))
    assert r.is_polymesh and r.cell_count == c.cell_count
    centres, radii = random_spheres(60, (0, 0, 0), (0.04, 0.03, 0.05), 0.002, 0.004, seed=5)
    for e in (r, c):
        e.configure(method="exact")
    np.testing.assert_allclose(r.compute(centres, radii), c.compute(centres, radii), rtol=0, atol=1e-12 * 1e-6)
    np.testing.assert_allclose(r.cell_centres(), c.cell_centres(), rtol=1e-12)


def test_polymesh_box_equals_the_cartesian_grid_of_its_cells():
    p = vfe.Engine.polymesh(DATA / "openfoam" / "box_uniform_10x10x30")
    assert p.is_polymesh and p.cell_count == 3000
    centres_p, volumes = p.cell_centres(), p.cell_volumes()
    h = np.cbrt(volumes.mean())
    lo = centres_p.min(axis=0) - h / 2
    cells = np.rint((centres_p.max(axis=0) + h / 2 - lo) / h).astype(int)
    assert tuple(cells) == (10, 10, 30)
    c = vfe.Engine.cartesian(origin=lo, spacing=(h, h, h), cells=cells)
    ijk = np.floor((centres_p - lo) / h).astype(int)
    index = ijk[:, 0] + cells[0] * (ijk[:, 1] + cells[1] * ijk[:, 2])
    spheres = random_spheres(300, lo, lo + cells * h, 0.2 * h, 0.6 * h, seed=7)
    for e in (p, c):
        e.configure("method=exact")
    solid_p, solid_c = p.compute(*spheres), c.compute(*spheres)
    np.testing.assert_allclose(solid_p, solid_c[index], rtol=0, atol=1e-9 * h ** 3)


def test_keywords_become_option_values():
    e = grid()
    e.configure("method=pmm", particle_grid=40, deterministic=True, alpha_min=0.125, template="voxel")
    o = e.options()
    assert (o["method"], o["particle_grid"], o["deterministic"], o["template"]) == ("pmm", "40", "1", "voxel")
    assert float(o["alpha_min"]) == 0.125 and e.option("alpha_min") == o["alpha_min"]
    e.configure(deterministic=False)
    assert e.option("deterministic") == "0"
    with pytest.raises(ValueError, match="blanks"):
        e.configure(method="pmm exact")
    with pytest.raises(ValueError, match="int, float, bool or str"):
        e.configure(particle_grid=[1, 2])


def test_errors_carry_the_status_name_and_message_and_leave_the_engine_usable():
    e = grid()
    with pytest.raises(vfe.Error) as info:
        e.configure("method=pmm bogus=1")
    assert isinstance(info.value, RuntimeError)
    assert info.value.status == "VFE_ERROR_INVALID_ARGUMENT"
    assert "bogus" in info.value.message and str(info.value).startswith("VFE_ERROR_INVALID_ARGUMENT: ")
    assert e.option("method") == "pmm"  # all or nothing
    with pytest.raises(vfe.Error) as info:
        vfe.Engine.polymesh(DATA / "no_such_case")
    assert info.value.status == "VFE_ERROR_IO"
    with pytest.raises(vfe.Error) as info:
        vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(1, 1, 1), cells=(0, 1, 1))
    assert info.value.status == "VFE_ERROR_INVALID_ARGUMENT"
    e.configure(method="gaussian")
    p = vfe.Engine.polymesh(DATA / "openfoam" / "box_uniform_10x10x30")
    with pytest.raises(vfe.Error) as info:  # a method the mesh kind cannot run: refused at once
        p.configure(method="trilinear")
    assert info.value.status == "VFE_ERROR_UNSUPPORTED"
    assert p.option("method") == "pmm"
    assert vfe.status_name(2) == "VFE_ERROR_OUT_OF_DOMAIN"


def test_report_has_every_field_and_the_named_facts():
    e = grid(6, 6, 6, h=0.01)
    centres, radii = random_spheres(100, (0, 0, 0), (0.06,) * 3, 0.002, 0.004, seed=11)
    e.configure(method="pmm", touched_only=True)
    solid = e.compute(centres, radii)
    r = e.report()
    assert set(r) == {"particles", "fast_path_particles", "sub_elements", "particle_grid_min",
                      "particle_grid_max", "particle_volume", "deposited_volume", "dropped_volume",
                      "outside_particles", "clipped_volume", "moved_particles", "touched_cells"}
    assert r["touched_cells"] == np.count_nonzero(solid)
    e.configure(touched_only=False, incremental=True)
    e.compute(centres, radii)
    assert e.report()["moved_particles"] == 100 and e.report()["touched_cells"] == -1
    centres2 = centres.copy()
    centres2[:7] += 1e-4
    e.compute(centres2, radii)
    assert e.report()["moved_particles"] == 7
    assert e.report_value("particles") == 100


def test_shapes_by_id_deposit_their_scaled_volume():
    e = grid(5, 5, 5, h=1.0)
    sphere, ell = e.add_shape("sphere"), e.add_shape("ellipsoid 1 0.5 0.25")
    assert e.shape_volume(ell) == pytest.approx(4 / 3 * np.pi * 0.125, rel=1e-12)
    centres = np.array([[1.2, 1.3, 1.4], [3.1, 2.9, 2.2], [2.5, 2.5, 3.5]])
    scales = np.array([0.4, 0.8, 0.6])
    ids = np.array([sphere, ell, ell], dtype=np.int32)
    expected = ball_volume(0.4) + 4 / 3 * np.pi * 0.125 * (0.8 ** 3 + 0.6 ** 3)
    for method in ("direct", "pmm"):
        e.configure(method=method)
        assert e.compute(centres, scales, shape_ids=ids).sum() == pytest.approx(expected, rel=1e-12)
    table = np.zeros((3, 2), dtype=np.int32)  # shape ids as a column of a wider table
    table[:, 0] = ids
    by_id = e.compute(centres, scales, shape_ids=ids)
    assert np.array_equal(e.compute(centres, scales, shape_ids=table[:, 0]), by_id) and e.input_copies == 0
    with pytest.raises(ValueError, match="int32"):
        e.compute(centres, scales, shape_ids=ids.astype(np.int64))
    with pytest.raises(vfe.Error):
        e.compute(centres, scales, shape_ids=np.array([0, 1, 9], dtype=np.int32))


def test_given_identity_orientations_equal_no_rotation():
    e = grid(6, 6, 6, h=0.01)
    centres, radii = random_spheres(80, (0, 0, 0), (0.06,) * 3, 0.003, 0.006, seed=13)
    e.configure(method="pmm", particle_grid=40, orientation="none")
    unrotated = e.compute(centres, radii)
    e.configure(orientation="given")
    with pytest.raises(vfe.Error, match="orientation"):
        e.compute(centres, radii)
    q = np.tile([1.0, 0, 0, 0], (80, 1))
    np.testing.assert_allclose(e.compute(centres, radii, q), unrotated, rtol=0, atol=1e-18)


def test_stability_test_direct_jumps_by_one_whole_particle():
    out = vfe.stability_test(chi=2, method="direct", trajectories=4, seed=3)
    (row,) = out["results"]
    # direct moves the whole particle at once: a jump of pi / (6 chi^3) = V_p / V_c.
    assert row["max_jump"] == pytest.approx(np.pi / 48, rel=1e-9)
    assert row["excess_jump"] > out["jump_criterion"] and not row["stable"]
    assert out["jump_criterion"] == vfe.DEFAULT_JUMP_CRITERION
    fine = vfe.stability_test(chi=2, method="pmm", particle_grids=[400], trajectories=2)["results"][0]
    assert fine["grid_max"] >= 400 and fine["excess_jump"] < row["excess_jump"] / 5
    with pytest.raises(TypeError, match="unknown option"):
        vfe.stability_test(chii=2)
    with pytest.raises(TypeError, match="wrong type"):
        vfe.stability_test(chi="two")
    single = vfe.stability_test(chi=2, method="pmm", particle_grids="auto", trajectories=1)["results"]
    assert [r["particle_grid"] for r in single] == ["auto"]
    with pytest.raises(vfe.Error):
        vfe.stability_test(chi=-1)
