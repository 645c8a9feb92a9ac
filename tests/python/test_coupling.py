"""The coupling functions: weights, deposit and interpolate against the solid field and
hand-computed averages, meshes from arrays against the Cartesian grid of the same cells,
host ids keeping a particle's orientation when particles are reordered."""
import numpy as np
import pytest

import vfe
from conftest import ball_volume, random_spheres


@pytest.fixture
def computed():
    e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.01,) * 3, cells=(5, 5, 5))
    e.configure(method="exact", weights=True)
    centres, radii = random_spheres(40, (0, 0, 0), (0.05,) * 3, 0.003, 0.007, seed=41)
    solid = e.compute(centres, radii)
    return e, centres, radii, solid


def test_weights_rebuild_the_solid_field(computed):
    e, centres, radii, solid = computed
    offsets, cells, fractions = e.weights()
    assert offsets.shape == (41,) and offsets[0] == 0 and offsets[-1] == len(cells) == len(fractions)
    per_particle = np.add.reduceat(fractions, offsets[:-1])
    np.testing.assert_allclose(per_particle, 1, rtol=1e-12)
    particle = np.repeat(np.arange(40), np.diff(offsets))
    rebuilt = np.bincount(cells, weights=fractions * ball_volume(radii)[particle], minlength=e.cell_count)
    np.testing.assert_allclose(rebuilt, solid, rtol=1e-12, atol=1e-20)


def test_deposit_and_interpolate_follow_the_weights(computed):
    e, centres, radii, solid = computed
    offsets, cells, fractions = e.weights()
    particle = np.repeat(np.arange(40), np.diff(offsets))
    np.testing.assert_allclose(e.deposit(ball_volume(radii)), solid, rtol=1e-12, atol=1e-20)
    two = np.column_stack([np.ones(40), np.arange(40.0)])
    dep = e.deposit(two)
    assert dep.shape == (e.cell_count, 2)
    np.testing.assert_allclose(dep[:, 1], np.bincount(cells, fractions * particle, minlength=e.cell_count),
                               rtol=1e-12)
    assert dep[:, 0].sum() == pytest.approx(40, rel=1e-12)  # conserves the sum
    field = np.arange(e.cell_count, dtype=float)
    by_hand = np.bincount(particle, fractions * field[cells]) / np.bincount(particle, fractions)
    np.testing.assert_allclose(e.interpolate(field), by_hand, rtol=1e-12)
    assert e.interpolate(np.column_stack([field, field])).shape == (40, 2)
    with pytest.raises(ValueError, match="one row per cell_count"):
        e.interpolate(field[:-1])
    with pytest.raises(ValueError, match="float64"):
        e.deposit(np.ones(40, dtype=np.float32))


def two_cubes():
    """Cells [0,1]^3 and [1,2]x[0,1]^2 as OpenFOAM orders faces: the internal one first."""
    points = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1, 2)], dtype=float)
    p = lambda i, j, k: i + 3 * (j + 2 * k)  # noqa: E731
    faces, owner = [[p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)]], [0]
    faces += [[p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0)], [p(2, 0, 0), p(2, 1, 0), p(2, 1, 1), p(2, 0, 1)]]
    owner += [0, 1]
    for c in (0, 1):
        faces += [[p(c, 0, 0), p(c + 1, 0, 0), p(c + 1, 0, 1), p(c, 0, 1)],
                  [p(c, 1, 0), p(c, 1, 1), p(c + 1, 1, 1), p(c + 1, 1, 0)],
                  [p(c, 0, 0), p(c, 1, 0), p(c + 1, 1, 0), p(c + 1, 0, 0)],
                  [p(c, 0, 1), p(c + 1, 0, 1), p(c + 1, 1, 1), p(c, 1, 1)]]
        owner += [c] * 4
    offsets = np.concatenate([[0], np.cumsum([len(f) for f in faces])]).astype(np.int64)
    return points, offsets, np.concatenate(faces).astype(np.int64), np.array(owner, np.int64), np.array([1], np.int64)


def test_a_mesh_from_arrays_equals_the_cartesian_grid_of_its_cells():
    e = vfe.Engine.polymesh_arrays(*two_cubes())
    assert e.cell_count == 2 and e.is_polymesh
    np.testing.assert_allclose(e.cell_volumes(), [1, 1], rtol=1e-14)
    np.testing.assert_allclose(e.cell_centres(), [[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], rtol=1e-14)
    c = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(1, 1, 1), cells=(2, 1, 1))
    spheres = (np.array([[1.0, 0.5, 0.5], [0.4, 0.6, 0.5]]), np.array([0.3, 0.2]))
    for x in (e, c):
        x.configure(method="exact")
    np.testing.assert_allclose(e.compute(*spheres), c.compute(*spheres), rtol=1e-12)


def test_a_bad_mesh_from_arrays_is_refused():
    points, offsets, face_points, owner, neighbour = two_cubes()
    with pytest.raises(ValueError, match="one entry per face plus one"):
        vfe.Engine.polymesh_arrays(points, offsets[:-1], face_points, owner, neighbour)
    with pytest.raises(ValueError, match="int64"):
        vfe.Engine.polymesh_arrays(points, offsets, face_points, owner.astype(np.int32), neighbour)
    with pytest.raises(ValueError, match="shape \\(n, 3\\)"):
        vfe.Engine.polymesh_arrays(points[:, :2], offsets, face_points, owner, neighbour)
    bad = face_points.copy()
    bad[0] = 99
    with pytest.raises(vfe.Error):
        vfe.Engine.polymesh_arrays(points, offsets, bad, owner, neighbour)


def test_host_ids_keep_each_particles_orientation_when_reordered():
    e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.01,) * 3, cells=(5, 5, 5))
    e.configure(method="pmm", particle_grid=40, orientation="random")
    centres, radii = random_spheres(60, (0, 0, 0), (0.05,) * 3, 0.004, 0.008, seed=43)
    ids = np.arange(1000, 1060, dtype=np.int64)
    reference = e.compute(centres, radii, ids=ids)
    order = np.random.default_rng(5).permutation(60)
    np.testing.assert_allclose(e.compute(centres[order], radii[order], ids=ids[order]), reference,
                               rtol=1e-12, atol=1e-20)
    assert not np.allclose(e.compute(centres[order], radii[order]), reference, rtol=1e-6, atol=0)
    table = np.zeros((60, 2), dtype=np.int64)
    table[:, 1] = ids
    np.testing.assert_array_equal(e.compute(centres, radii, ids=table[:, 1]), reference)  # strided ids
    assert e.input_copies == 0
    with pytest.raises(ValueError, match="ids must have dtype int64"):
        e.compute(centres, radii, ids=ids.astype(np.int32))
