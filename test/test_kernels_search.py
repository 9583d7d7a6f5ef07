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


def _neighbours_fields(neighbours) -> dict:
    return {name: getattr(neighbours, name) for name in ('n', 'shape', 'pixel', 'node', 'usable', 'normals', 'wraps',
                                                         'bridges')}


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.sampled_from(['surfaces', 'noise', 'lidar']))
def test_grid_neighbours_match_numpy(seed, kind):
    """The sub-grid's ranges, depth jumps, usable pixels, pitch and normals (bends too) from the kernels, exactly as
    the numpy passes give them: on random surfaces with steps and holes, on noise, and on a lidar-like image (pixels
    coarser down than across: wider normals and the bend test)."""
    from plane_validation.core.search.neighbours_grid import grid_neighbours, grid_neighbours_numpy
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 24, 2))
    if kind == 'lidar':
        elevation = np.radians(np.linspace(-15, 15, h))[:, None] + np.zeros((1, w))
        azimuth = np.linspace(0, 2 * np.pi, w, endpoint=False)[None, :] + np.zeros((h, 1))
        rays = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                         np.sin(elevation)], -1)
        image = rays * rng.uniform(2, 10, (h, w, 1)).round(rng.integers(0, 3))
    elif kind == 'surfaces':
        rows, cols = np.mgrid[0:h, 0:w]
        depth = 2.0 + 0.5 * (cols > rng.integers(0, w + 1)) + rng.normal(scale=rng.uniform(0, 0.02), size=(h, w))
        image = np.stack([(cols - w / 2) * 0.01 * depth, (rows - h / 2) * 0.01 * depth, depth], -1)
    else:
        image = rng.normal(size=(h, w, 3))
    valid = rng.random((h, w)) < rng.uniform(0.5, 1.0)
    image[~valid] = np.nan
    got, ref = _neighbours_fields(grid_neighbours(image, valid)), _neighbours_fields(grid_neighbours_numpy(image, valid))
    for name in got:
        if isinstance(ref[name], np.ndarray):
            np.testing.assert_array_equal(got[name], ref[name], err_msg=name)
        else:
            assert got[name] == ref[name], name
