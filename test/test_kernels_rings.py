"""The kernels of a lidar scan's ring image (core/kernels.py, ``# -- a spinning lidar's ring image``) against their
plain-numpy references in core/geometry.py on random inputs: the steps along each ring and its elevations, the phase
sums, and the image with the first point on each pixel."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.core import geometry, kernels, scenes

SETTINGS = settings(max_examples=60, deadline=None)


def _rings(seed: int, n: int, rings: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ring numbers with every ring present, and azimuths on a coarse lattice (repeated values, zero steps) or
    anywhere, and elevations with ties."""
    rng = np.random.default_rng(seed)
    row = np.concatenate([np.arange(rings), rng.integers(0, rings, n)]).astype(np.int64)
    rng.shuffle(row)
    azimuth = rng.integers(0, 40, len(row)) * (2 * np.pi / 40) if seed % 2 else rng.uniform(0, 2 * np.pi, len(row))
    elevation = rng.integers(-5, 6, len(row)) * 0.01 + row * 0.1
    return row, azimuth, elevation


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200), st.integers(1, 9))
def test_ring_steps_match_numpy(seed, n, rings):
    row, azimuth, elevation = _rings(seed, n, rings)
    got = kernels.ring_steps(row, azimuth, elevation, rings)
    want = geometry.ring_steps_numpy(row, azimuth, elevation, rings)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200), st.integers(1, 9), st.integers(3, 4000))
def test_ring_turns_match_numpy(seed, n, rings, width):
    row, azimuth, _ = _rings(seed, n, rings)
    step = geometry.TURN / width
    got = kernels.ring_turns(azimuth, row, rings, geometry.TURN, 1.0 / step)
    want = geometry.ring_turns_numpy(azimuth, row, rings, geometry.TURN, 1.0 / step)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.integers(1, 400))
def test_ring_scatter_matches_numpy(seed, n, size):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n, 3))
    pixel = rng.integers(0, size, n)  # many points on one pixel: the first stands for it
    image, taken = kernels.ring_scatter(points, pixel, size)
    want, want_taken = geometry.ring_scatter_numpy(points, pixel, size)
    np.testing.assert_array_equal(image, want)
    assert taken == want_taken


def test_the_ring_image_of_a_real_sized_scan_is_the_numpy_references():
    """The whole layout of a 32-ring street scan from the references gives the kernels' image and pixels."""
    scan = scenes.lidar(seed=1)
    image, shape, pixel = geometry.ring_image(scan.points, scan.rings)
    ids, row = np.unique(scan.rings, return_inverse=True)
    azimuth = np.arctan2(scan.points[:, 1], scan.points[:, 0]) % geometry.TURN
    elevation = np.arctan2(scan.points[:, 2], np.hypot(scan.points[:, 0], scan.points[:, 1]))
    gaps, middle, _ = geometry.ring_steps_numpy(row, azimuth, elevation, len(ids))
    width = int(round(geometry.TURN / float(np.median(gaps))))
    step = geometry.TURN / width
    cos_sum, sin_sum = geometry.ring_turns_numpy(azimuth, row, len(ids), geometry.TURN, 1.0 / step)
    rank = np.empty(len(ids), np.int64)
    rank[np.argsort(-middle, kind='stable')] = np.arange(len(ids))
    column = np.round((azimuth - (np.arctan2(sin_sum, cos_sum) * step / geometry.TURN)[row]) / step).astype(int)
    want_pixel = rank[row] * width + column % width
    assert shape == (len(ids), width) == (32, 1800)
    np.testing.assert_array_equal(pixel, want_pixel)
    np.testing.assert_array_equal(image, geometry.ring_scatter_numpy(scan.points, want_pixel, shape[0] * width)[0])
