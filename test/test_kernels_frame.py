"""The frame pass's kernels (core/kernels.py, ``# --- frame pass ---``) against plain-numpy references, on random
inputs: the records of both output clouds, each plane's count, centroid and extremes, the valid rows and the
widened x, y, z."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.app.frame_rows import valid_rows_numpy
from plane_validation.core import kernels
from plane_validation.core.geometry import _DIRECTIONS, outline_directions, plane_basis

SETTINGS = settings(max_examples=60, deadline=None)

SEGMENTED = np.dtype({'names': ['x', 'y', 'z', 'plane_id', 'rgb'], 'formats': ['<f4', '<f4', '<f4', '<i4', '<u4'],
                      'offsets': [0, 4, 8, 12, 16], 'itemsize': 20})


def _frame(seed: int, n: int, k: int):
    """n random rows (some NaN, some with an inf coordinate, some with one NaN coordinate), labels in -1..k-1
    on the finite rows only (as a segmentation's), a random keep mask, ids, palette and k planes' directions."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(scale=100, size=(n, 3))
    kind = rng.random(n)
    pts[kind < 0.1] = np.nan
    pts[(kind >= 0.1) & (kind < 0.15), rng.integers(0, 3)] = rng.choice([np.inf, -np.inf])
    pts[(kind >= 0.15) & (kind < 0.2), 1] = np.nan
    finite = np.isfinite(pts).all(axis=1)
    labels = rng.integers(-1, k, n).astype(np.int32) if k else np.full(n, -1, np.int32)
    labels[~finite] = -1
    keep = rng.random(n) < 0.6
    palette = rng.integers(0, 2**24, k + 1).astype(np.uint32)
    ids = np.append(rng.permutation(10)[:k], -1).astype(np.int32)
    normals = rng.normal(size=(k, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    directions = outline_directions([plane_basis(normal) for normal in normals])
    return pts, labels, keep, ids, palette, directions, finite


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.integers(0, 6), st.booleans())
def test_frame_pass_matches_numpy(seed, n, k, compact):
    pts, labels, keep, ids, palette, directions, finite = _frame(seed, n, k)
    if compact:  # the valid points of an unorganized frame: all finite
        pts, labels, keep = pts[finite], labels[finite], keep[finite]
        finite = finite[finite]
    kept = int(keep.sum()) if compact else len(pts)
    segmented, obstacles = np.zeros(20 * len(pts), np.uint8), np.zeros(12 * kept, np.uint8)
    count, centroid, extreme, seg_dense, obs_dense, largest = kernels.frame_pass(
        pts, labels, keep[finite], ids, palette, directions, segmented, obstacles, compact)  # keep: per finite row
    keep = keep & finite

    xyz = np.where(finite[:, None], pts, np.nan)
    ref = np.zeros(len(pts), SEGMENTED)
    ref['x'], ref['y'], ref['z'] = xyz.T
    ref['plane_id'], ref['rgb'] = ids[labels], palette[labels]  # -1: the last entries
    assert segmented.tobytes() == ref.tobytes()
    assert seg_dense == bool(finite.all())
    obs = xyz[keep] if compact else np.where(keep[:, None], pts, np.nan)
    assert obstacles.tobytes() == obs.astype('<f4').tobytes()
    assert obs_dense == (not np.isnan(obs).any())
    with np.errstate(invalid='ignore'):
        assert largest == np.abs(pts[np.isfinite(pts)]).max(initial=0.0)

    np.testing.assert_array_equal(count, np.bincount(labels[labels >= 0], minlength=k))
    for j in range(k):
        members = pts[labels == j]
        if len(members) == 0:
            assert np.isnan(centroid[j]).all() and (extreme[j] == -1).all()
            continue
        np.testing.assert_allclose(centroid[j], members.mean(axis=0), rtol=1e-12, atol=1e-9)
        along = members @ directions[j].T  # (m, 8)
        np.testing.assert_array_equal(extreme[j], np.argmax(along, axis=0))  # the first of equals


def test_frame_pass_agrees_with_centroids_and_extremes_on_ties():
    """A plane's points on a lattice (many equal projections): the frame pass picks the extremes and sums the
    centroid exactly as the kernel of plane_outlines does over the grouped rows."""
    grid = np.stack(np.meshgrid(np.arange(12.0), np.arange(9.0), [0.0], indexing='ij'), axis=-1).reshape(-1, 3)
    pts = np.vstack([grid, grid + [0, 0, 5]])
    labels = np.repeat(np.array([0, 1], np.int32), len(grid))
    labels[::7] = -1
    directions = outline_directions([plane_basis(np.array([0, 0, 1.0]))] * 2)
    assert len(_DIRECTIONS) == directions.shape[1]
    rows, bounds = kernels.group_by_label(labels, 2)
    want_centroid, want_extreme = kernels.centroids_and_extremes(pts, rows, bounds, directions)
    _, centroid, extreme, *_ = kernels.frame_pass(pts, labels, np.ones(len(pts), bool), np.array([3, 4, -1], np.int32),
                                                  np.zeros(3, np.uint32), directions,
                                                  np.zeros(20 * len(pts), np.uint8), np.zeros(12 * len(pts), np.uint8),
                                                  False)
    np.testing.assert_array_equal(extreme, want_extreme)
    np.testing.assert_array_equal(centroid, want_centroid)



@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.integers(1, 4))
def test_frame_pass_sums_each_plane_in_row_order_across_runs(seed, runs, k):
    """Labels in runs that come back to a plane after others (as an image's rows cross it): each plane's centroid
    and extremes are exactly those of the kernel of plane_outlines, which sums its rows in order."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(rng.integers(-1, k, runs), rng.integers(1, 30, runs)).astype(np.int32)
    pts = rng.normal(scale=3, size=(len(labels), 3)) + rng.normal(scale=50, size=3)
    pts[rng.random(len(pts)) < 0.05] = np.nan  # holes, unlabelled
    labels[np.isnan(pts[:, 0])] = -1
    normals = rng.normal(size=(k, 3))
    directions = outline_directions([plane_basis(normal / np.linalg.norm(normal)) for normal in normals])
    rows, bounds = kernels.group_by_label(labels, k)
    want_centroid, want_extreme = kernels.centroids_and_extremes(pts, rows, bounds, directions)
    count, centroid, extreme, *_ = kernels.frame_pass(
        pts, labels, np.ones(len(pts), bool), np.append(np.arange(k), -1).astype(np.int32), np.zeros(k + 1, np.uint32),
        directions, np.zeros(20 * len(pts), np.uint8), np.zeros(12 * len(pts), np.uint8), False)
    np.testing.assert_array_equal(count, np.diff(bounds))
    np.testing.assert_array_equal(extreme, want_extreme)
    np.testing.assert_array_equal(centroid, want_centroid)  # NaN for a plane without rows


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300))
def test_valid_rows_matches_numpy(seed, n):
    pts = _frame(seed, n, 0)[0]
    finite, valid, infinite = kernels.valid_rows(pts)
    ref_finite, ref_valid, ref_infinite = valid_rows_numpy(pts)
    np.testing.assert_array_equal(finite, ref_finite)
    np.testing.assert_array_equal(valid, ref_valid)
    assert valid.flags.c_contiguous and infinite == ref_infinite == np.isinf(pts[~finite]).any(axis=1).sum()


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200), st.integers(3, 9))
def test_widen_xyz_matches_numpy(seed, n, width):
    rng = np.random.default_rng(seed)
    words = rng.normal(scale=100, size=(n, width)).astype(np.float32)
    words[rng.random((n, width)) < 0.1] = np.nan
    columns = rng.permutation(width)[:3].astype(np.int64)
    np.testing.assert_array_equal(kernels.widen_xyz(words, columns), words[:, columns].astype(np.float64))
