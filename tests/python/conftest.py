"""Shared fixtures of the Python tests: the repository's data folder and seeded spheres.
ctest sets PYTHONPATH to the build tree's python folder and VFE_SOURCE_DIR, VFE_LIBRARY."""
import os
import pathlib

import numpy as np
import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("VFE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DATA = SOURCE_DIR / "data"


@pytest.fixture
def data_dir():
    return DATA


def random_spheres(n, lo, hi, r_min, r_max, seed=1):
    """n spheres with centres uniform in [lo + r_max, hi - r_max] per axis, radii uniform."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centres = rng.uniform(lo + r_max, hi - r_max, size=(n, 3))
    radii = rng.uniform(r_min, r_max, size=n)
    return centres, radii


def ball_volume(r):
    return 4.0 / 3.0 * np.pi * np.asarray(r, float) ** 3
