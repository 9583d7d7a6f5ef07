"""The validity indices' compiled kernels (core/kernels.py, the indices block) against plain-numpy references."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import cdist

from plane_validation.core import cluster_extent, clusters, indices, kernels
from plane_validation.core.plane_silhouette import clipped_plane_distances, plane_silhouette, region_frames

SETTINGS = settings(max_examples=60, deadline=None)


def _cloud(seed: int, n: int, spread: int):
    """n random points (some rows NaN or inf) and labels from -3 to spread - 1, in runs as an image's."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-3, 3)
    bad = rng.random(n) < 0.15
    pts[bad, rng.integers(0, 3, int(bad.sum()))] = rng.choice([np.nan, np.inf, -np.inf], int(bad.sum()))
    labels = np.repeat(rng.integers(-3, spread, n), rng.integers(1, 6, n))[:n]
    return pts, labels


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 400), st.sampled_from([1, 3, 12, 5000, 10**12]),
       st.sampled_from([np.int32, np.int64]))
def test_label_census_counts_as_numpy(seed, n, spread, dtype):
    pts, labels = _cloud(seed, n, spread)
    labels = labels.astype(dtype) if spread < 2**31 else labels
    compact = np.empty(n, np.int32)
    n_valid, n_assigned, low, count = kernels.label_census(pts, labels, compact, False)
    finite = np.isfinite(pts).all(axis=1)
    merged = np.maximum(labels[finite], -1)
    assert n_valid == finite.sum() and n_assigned == (merged >= 0).sum()
    if n_valid == 0:
        assert len(count) == 0
        return
    assert low == merged.min()
    span = int(merged.max()) - low + 1
    if span > 4 * n_valid + 1024 or merged.max() > np.iinfo(np.int32).max:
        assert len(count) == 0  # no table: the caller sorts instead
        return
    np.testing.assert_array_equal(count, np.bincount(merged - low, minlength=span))
    np.testing.assert_array_equal(compact[finite], merged)
    assert np.all(compact[~finite] == kernels.NOT_FINITE)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 400), st.sampled_from([1, 3, 12, 5000, 10**12]),
       st.sampled_from([np.int32, np.int64]))
def test_label_census_of_rows_known_finite_reads_only_the_labels(seed, n, spread, dtype):
    """``finite``: the same counts and compact labels as the checking pass on finite rows, without the points."""
    pts, labels = _cloud(seed, n, spread)
    keep = np.isfinite(pts).all(axis=1)
    pts, labels = np.ascontiguousarray(pts[keep]), labels[keep]
    labels = labels.astype(dtype) if spread < 2**31 else labels
    checked, known = np.empty(len(labels), np.int32), np.empty(len(labels), np.int32)
    expected = kernels.label_census(pts, labels, checked, False)
    unread = np.full_like(pts, np.nan)  # the points are not read: NaN rows still count as finite
    got = kernels.label_census(unread, labels, known, True)
    assert got[:3] == expected[:3]
    np.testing.assert_array_equal(got[3], expected[3])
    if len(expected[3]):
        np.testing.assert_array_equal(known, checked)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 100), st.sampled_from([np.int32, np.int64]))
def test_run_end_finds_where_a_run_stops_as_numpy(seed, n, dtype):
    """Eight values at a time and then one by one: runs shorter and longer than eight, at the end and not."""
    rng = np.random.default_rng(seed)
    values = np.repeat(rng.integers(-2, 3, n), rng.integers(1, 20, n)).astype(dtype)
    for start in range(len(values) + 1):
        value = values[start] if start < len(values) else dtype(0)
        other = np.flatnonzero(values[start:] != value)
        assert kernels._run_end(values, start, value) == (start + other[0] if len(other) else len(values))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(3, 300), st.sampled_from([1, 4, 40]), st.booleans())
def test_validity_indices_of_rows_known_finite_are_the_checked_ones(seed, n, spread, separation):
    pts, labels = _cloud(seed, n, spread)
    keep = np.isfinite(pts).all(axis=1)
    pts, labels = pts[keep], labels[keep]
    checked = indices.validity_indices(pts, labels, sample_size=50, seed=seed, sampled_separation=separation)
    known = indices.validity_indices(pts, labels, sample_size=50, seed=seed, sampled_separation=separation,
                                     finite=True)
    assert repr(known) == repr(checked)  # NaN fields compare by their text


def test_validity_indices_refuse_a_finite_flag_that_is_no_bool():
    pts = np.random.default_rng(0).normal(size=(10, 3))
    with pytest.raises(ValueError, match='finite must be True or False'):
        indices.validity_indices(pts, np.zeros(10, int), finite='yes')


def test_label_census_counts_labels_past_the_one_pass_table():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(2000, 3))
    labels = np.repeat([-1, 4100, 0, 4100, -7], 400)
    compact = np.empty(2000, np.int32)
    n_valid, n_assigned, low, count = kernels.label_census(pts, labels, compact, False)
    assert (n_valid, n_assigned, low) == (2000, 1200, -1) and len(count) == 4102
    assert count[0] == 800 and count[1] == 400 and count[4101] == 800 and count.sum() == 2000


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 400), st.booleans())
def test_rows_at_ranks_picks_the_ranked_members(seed, n, one_cluster):
    rng = np.random.default_rng(seed)
    pts, labels = _cloud(seed, n, 6)
    compact = np.empty(n, np.int32)
    _, _, low, count = kernels.label_census(pts, labels, compact, False)
    if len(count) == 0:
        return
    values = np.arange(low, low + len(count))
    cluster = np.where(values >= 0, 0, -1) if one_cluster else np.where(count > 0, np.cumsum(count > 0) - 1, -1)
    finite = np.isfinite(pts).all(axis=1)
    merged = np.maximum(labels, -1)
    members = [np.flatnonzero(finite & (cluster[np.clip(merged - low, 0, len(count) - 1)] == c))
               for c in range(int(cluster.max()) + 1)]
    ranks = [np.sort(rng.integers(0, len(m), rng.integers(0, 2 * len(m) + 1))) if len(m) else np.zeros(0, int)
             for m in members]
    bounds = np.concatenate([[0], np.cumsum([len(r) for r in ranks])]).astype(np.int64)
    flat = np.concatenate(ranks).astype(np.int64) if ranks else np.zeros(0, np.int64)
    rows = kernels.rows_at_ranks(compact, low, cluster.astype(np.int64), flat, bounds)
    expected = np.concatenate([m[r] for m, r in zip(members, ranks)]) if ranks else np.zeros(0, int)
    np.testing.assert_array_equal(rows, expected)


def _grouped(seed: int, n: int, k: int, scale: float):
    """n points in k non-empty clusters, contiguous: (points (n, 3), starts (k,), sizes (k,))."""
    rng = np.random.default_rng(seed)
    sizes = np.ones(k, np.int64) + np.bincount(rng.integers(0, k, n - k), minlength=k)
    centres = rng.uniform(-5, 5, (k, 3)) * scale
    pts = np.repeat(centres, sizes, axis=0) + rng.normal(size=(n, 3)) * scale * rng.uniform(0.01, 2)
    if rng.random() < 0.2:  # repeated points: distances of exactly 0
        pts[rng.integers(0, n, n // 3)] = pts[0]
    return pts, (np.cumsum(sizes) - sizes).astype(np.int64), sizes


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 8), st.integers(0, 150), st.sampled_from([1e-3, 1.0, 1e4]))
def test_cluster_distance_pass_matches_cdist(seed, k, extra, scale):
    pts, starts, sizes = _grouped(seed, k + extra, k, scale)
    sums, diameters, gaps = kernels.cluster_distance_pass(pts, starts, sizes)
    d = cdist(pts, pts)
    code = np.repeat(np.arange(k), sizes)
    np.testing.assert_allclose(sums, np.stack([d[:, code == c].sum(axis=1) for c in range(k)], axis=1),
                               rtol=1e-12, atol=1e-12 * scale)
    for a in range(k):
        assert diameters[a] == d[np.ix_(code == a, code == a)].max()  # the same rounding as cdist: equal
        for b in range(k):
            assert gaps[a, b] == (0.0 if a == b else d[np.ix_(code == a, code == b)].min())


def test_the_pair_pass_gives_the_diameters_and_distances_of_hulls_and_kd_trees():
    rng = np.random.default_rng(3)
    pts = np.vstack([rng.normal(c, 0.3, (200, 3)) for c in rng.uniform(-3, 3, (5, 3))])
    labels = np.repeat(np.arange(-1, 4), 200)
    cl = clusters.as_clusters(pts, labels)
    _, diameters, gaps = indices._pair_pass(cl)
    np.testing.assert_array_equal(diameters, cluster_extent.diameters_of(cl))
    np.testing.assert_array_equal(gaps, cluster_extent.distances_of(cl))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 6), st.integers(0, 300))
def test_region_frames_match_numpy(seed, k, n):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * [3.0, 1.0, 0.05] + rng.normal(size=3) * 100
    labels = rng.integers(0, k, n) if k else np.zeros(n, np.int64)
    centroids, axes, lo, hi, radius = region_frames(pts, labels, k, np.random.default_rng(1))
    for j in range(k):
        p = pts[labels == j]
        if len(p) == 0:
            assert np.array_equal(axes[j], np.eye(3)) and radius[j] == 0.0 and not lo[j].any()
            continue
        c = p.mean(axis=0)
        np.testing.assert_allclose(centroids[j], c, rtol=1e-12, atol=1e-9)
        _, vectors = np.linalg.eigh((p - c).T @ (p - c))
        frame = vectors[:, [2, 1, 0]].T
        assert np.allclose(np.abs(np.sum(axes[j] * frame, axis=1)), 1.0, atol=1e-6) or len(p) < 4  # up to sign
        uv = (p - centroids[j]) @ axes[j, :2].T
        np.testing.assert_allclose(lo[j], np.percentile(uv, 0.5, axis=0), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(hi[j], np.percentile(uv, 99.5, axis=0), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(radius[j], np.sqrt((uv ** 2).sum(axis=1).mean()), rtol=1e-12, atol=1e-12)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 6), st.integers(1, 300))
def test_plane_silhouette_sum_matches_numpy(seed, k, m):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(m, 3))
    own = rng.integers(0, k, m)
    centroids = rng.normal(size=(k, 3))
    axes = np.linalg.qr(rng.normal(size=(k, 3, 3)))[0]
    lo, hi = -rng.uniform(0, 1, (k, 2)), rng.uniform(0, 1, (k, 2))
    radius = rng.uniform(0, 1, k)
    if rng.random() < 0.2:
        x[rng.integers(0, m)] = centroids[0]  # on a plane: a = 0
    total = kernels.plane_silhouette_sum(x, own, centroids, axes, lo, hi, radius)
    clipped, perp = clipped_plane_distances(x, centroids, axes, lo, hi)
    a = perp[np.arange(m), own]
    clipped[np.arange(m), own] = np.inf
    b = np.minimum(clipped.min(axis=1), radius[own])
    top = np.maximum(a, b)
    with np.errstate(invalid='ignore', divide='ignore'):
        expected = np.where(top > 0, (b - a) / top, 0.0).sum()
    assert abs(total - expected) <= 1e-12 * max(1.0, m)


def test_a_nan_distance_counts_zero_as_in_numpy():
    x = np.array([[0.0, 0.0, 0.0]])
    centroids = np.zeros((2, 3))
    axes = np.tile(np.eye(3), (2, 1, 1))
    lo, hi = np.array([[-1.0, -1.0], [np.nan, -1.0]]), np.ones((2, 2))
    assert kernels.plane_silhouette_sum(x, np.array([0]), centroids, axes, lo, hi, np.ones(2)) == 0.0


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(2, 400), st.sampled_from([1, 4, 40]))
def test_the_sample_picked_in_a_stream_is_the_sample_of_the_sorted_clusters(seed, n, spread):
    pts, labels = _cloud(seed, n, spread)
    census = clusters.take_census(pts, labels)
    if len(census.ids) < 2 or census.n < 3:
        return
    total = max(2, census.n // 2)
    streamed = clusters.stratified_census(census, total, np.random.default_rng(seed))
    sorted_ = clusters.stratified_coded(clusters.coded(pts, labels), total, np.random.default_rng(seed))
    for field in ('points', 'codes', 'starts', 'sizes', 'ids', 'order'):
        np.testing.assert_array_equal(getattr(streamed, field), getattr(sorted_, field))


def test_validity_indices_with_labels_beyond_a_table_agree():
    """Labels too far apart for a lookup table take the sorting path: the same values as small labels."""
    rng = np.random.default_rng(2)
    pts = rng.normal(size=(3000, 3)) + np.repeat(rng.uniform(-9, 9, (3, 3)), 1000, axis=0)
    small = np.repeat([-1, 0, 1], 1000)
    wide = np.where(small == 1, 10**12, small)
    for separation in (False, True):
        a = indices.validity_indices(pts, small, seed=4, sampled_separation=separation)
        b = indices.validity_indices(pts, wide, seed=4, sampled_separation=separation)
        assert a == b
    assert plane_silhouette(pts, small, seed=1) == plane_silhouette(pts, wide, seed=1)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200), st.integers(1, 40), st.sampled_from([1e-3, 1.0, 1e3]))
def test_polygon_distances_match_numpy(seed, m, corners, scale):
    """Points inside, on and outside convex polygons, also degenerate ones (one corner, two, collinear corners)."""
    from scipy.spatial import ConvexHull, QhullError

    from plane_validation.core.plane_silhouette import polygon_distances_numpy
    rng = np.random.default_rng(seed)
    corners_uv = rng.normal(size=(corners, 2)) * scale
    try:
        polygon = corners_uv[ConvexHull(corners_uv).vertices]
    except (QhullError, ValueError):  # fewer than 3 corners, or all on a line: the kernel still gets them as given
        polygon = corners_uv
    p = np.concatenate([rng.normal(size=(m, 2)) * scale * 2, polygon[: min(m, len(polygon))]])
    got = kernels.polygon_distances(np.ascontiguousarray(p), np.ascontiguousarray(polygon))
    np.testing.assert_allclose(got, polygon_distances_numpy(p, polygon), rtol=1e-12, atol=1e-12 * scale)
