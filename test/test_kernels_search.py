"""The search's compiled kernels (core/kernels.py, the search block) against their plain-numpy references, on random
inputs."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core.search.grid import grid_image, grid_image_numpy

SETTINGS = settings(max_examples=60, deadline=None)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_grid_sample_matches_numpy(seed, single):
    """The sub-grid's pixels and points: the block's valid pixel nearest to its centre, as the numpy search finds it
    (float32 points stay float32)."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 30, 2))
    step = int(rng.integers(1, 7))
    points = rng.normal(size=(h * w, 3)).astype(np.float32 if single else np.float64)
    finite = rng.random(h * w) < rng.uniform(0.0, 1.0)
    points[~finite] = np.nan
    image, pixels = grid_image(points, finite, (h, w), step)
    ref_image, ref_pixels = grid_image_numpy(points, finite, (h, w), step)
    np.testing.assert_array_equal(pixels, ref_pixels)
    np.testing.assert_array_equal(image, ref_image)
    assert image.dtype == ref_image.dtype
