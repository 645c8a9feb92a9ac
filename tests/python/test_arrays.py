"""numpy input: read in place at any row stride (input_copies == 0), other layouts copied
once with the same result, and bad arrays refused with ValueError or vfe.Error, leaving the
output untouched."""
import numpy as np
import pytest

import vfe
from conftest import random_spheres


@pytest.fixture
def engine():
    e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.01,) * 3, cells=(6, 6, 6))
    e.configure(method="pmm", particle_grid=40, deterministic=True)
    return e


@pytest.fixture
def spheres():
    return random_spheres(150, (0, 0, 0), (0.06,) * 3, 0.002, 0.005, seed=21)


def test_contiguous_float64_is_read_in_place(engine, spheres):
    engine.compute(*spheres)
    assert engine.input_copies == 0


def test_a_column_slice_of_a_wider_table_is_read_in_place_by_stride(engine, spheres):
    centres, radii = spheres
    reference = engine.compute(centres, radii)
    table = np.zeros((len(radii), 9))  # id type x y z radius ... as a dump's table
    table[:, 2:5], table[:, 5] = centres, radii
    view_c, view_r = table[:, 2:5], table[:, 5]
    assert not view_c.flags.c_contiguous and view_c.strides == (72, 8)
    assert np.array_equal(engine.compute(view_c, view_r), reference)
    assert engine.input_copies == 0
    every_other = np.repeat(centres, 2, axis=0)[::2]  # row stride of 6 doubles
    assert np.array_equal(engine.compute(every_other, np.repeat(radii, 2)[::2]), reference)
    assert engine.input_copies == 0


def test_other_layouts_are_copied_once_with_the_same_result(engine, spheres):
    centres, radii = spheres
    reference = engine.compute(centres, radii)
    fortran = np.asfortranarray(centres)  # inner axis not contiguous
    assert np.array_equal(engine.compute(fortran, radii), reference)
    assert engine.input_copies == 1
    backwards_c, backwards_r = centres[::-1], radii[::-1]  # negative strides
    assert np.array_equal(engine.compute(backwards_c[::-1], backwards_r[::-1]), reference)
    assert engine.input_copies == 0
    engine.configure(method="exact")
    exact = engine.compute(centres, radii)
    np.testing.assert_allclose(engine.compute(backwards_c, backwards_r), exact, rtol=1e-12, atol=1e-20)
    assert engine.input_copies == 2
    broadcast = np.broadcast_to(np.float64(0.003), radii.shape)  # stride 0
    engine.compute(centres, broadcast)
    assert engine.input_copies == 1 and engine.report()["particles"] == len(radii)


def test_out_is_filled_in_place(engine, spheres):
    reference = engine.compute(*spheres)
    out = np.full(engine.cell_count, 7.0)
    result = engine.compute(*spheres, out=out)
    assert result is out and np.array_equal(out, reference)
    for bad in (np.zeros(engine.cell_count - 1), np.zeros(engine.cell_count, dtype=np.float32),
                np.zeros((engine.cell_count, 2))[:, 0]):
        with pytest.raises(ValueError, match="out must be"):
            engine.compute(*spheres, out=bad)


@pytest.mark.parametrize("centres, radii, message", [
    (np.zeros((3, 3), dtype=np.float32), np.ones(3), "centres must have dtype float64 \\(got float32\\)"),
    (np.zeros((3, 3), dtype=np.int64), np.ones(3), "dtype float64"),
    (np.zeros((3, 3)), np.ones(3, dtype=np.float32), "radii must have dtype float64"),
    ([[0.0, 0.0, 0.0]], np.ones(1), "centres must be a numpy array"),
    (np.zeros((3, 2)), np.ones(3), "shape \\(n, 3\\) \\(got \\(3, 2\\)\\)"),
    (np.zeros(9), np.ones(3), "shape \\(n, 3\\)"),
    (np.zeros((3, 3)), np.ones(4), "radii must have shape \\(3,\\) \\(got \\(4,\\)\\)"),
    (np.zeros((3, 3)), np.ones((3, 1)), "radii must have shape"),
    (np.zeros((3, 3)), np.ones(3).astype(">f8"), "dtype float64"),
])
def test_wrong_dtype_or_shape_raises_value_error(engine, centres, radii, message):
    with pytest.raises(ValueError, match=message):
        engine.compute(centres, radii)


def test_orientations_are_checked_like_centres(engine, spheres):
    centres, radii = spheres
    with pytest.raises(ValueError, match="orientations must have shape \\(150, 4\\)"):
        engine.compute(centres, radii, np.zeros((150, 3)))


@pytest.mark.parametrize("poison", ["nan_centre", "inf_radius", "negative_radius", "zero_radius"])
def test_bad_values_raise_vfe_error_and_leave_out_untouched(engine, spheres, poison):
    centres, radii = spheres[0].copy(), spheres[1].copy()
    if poison == "nan_centre":
        centres[17, 1] = np.nan
    elif poison == "inf_radius":
        radii[17] = np.inf
    elif poison == "negative_radius":
        radii[17] = -0.001
    else:
        radii[17] = 0.0
    out = np.full(engine.cell_count, 3.0)
    with pytest.raises(vfe.Error) as info:
        engine.compute(centres, radii, out=out)
    assert info.value.status == "VFE_ERROR_INVALID_ARGUMENT" and "particle 17" in info.value.message
    assert np.all(out == 3.0)
    assert engine.compute(*spheres).sum() > 0  # still usable


def test_no_particles_give_an_empty_field(engine):
    solid = engine.compute(np.zeros((0, 3)), np.zeros(0))
    assert solid.shape == (engine.cell_count,) and not solid.any()
