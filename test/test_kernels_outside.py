"""The kernels of the frame's work outside the search (core/kernels.py, ``# --- frame outside the search ---`` and
``# --- frame outside 5 ---``) against plain-numpy references on random inputs: the no-return count, the tracker's
overlap, the verdict's beyond counts and its distinct points, and the labels renumbered by track id."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plane_validation.app.frame_rows import marks_as_nan
from plane_validation.app.tracking import _near_share, _near_share_kdtree
from plane_validation.core import kernels, plane_beyond, plane_shape, scenes
from plane_validation.core import verdict as V
from plane_validation.core.ransac import AT_VIEWPOINT, detect_planes, no_returns_as_nan

SETTINGS = settings(max_examples=60, deadline=None)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.sampled_from([(0.0, 0.0, 0.0), (0.5, -1.0, 2.0)]))
def test_marked_rows_and_the_pipelines_no_return_check_match_numpy(seed, n, view):
    rng = np.random.default_rng(seed)
    pts = rng.integers(-1, 2, (n, 3)).astype(np.float64) * rng.choice([1.0, 1e-7, 0.5], (n, 3)) + view
    pts[rng.random(n) < 0.1] = np.nan
    pts[rng.random(n) < 0.1, 1] = -0.0 + view[1]  # -0.0 is the mark too
    want, count = no_returns_as_nan(pts, view)
    assert kernels.marked_rows(pts, np.array(view), AT_VIEWPOINT) == count
    got, got_count = marks_as_nan(pts, view)
    assert got_count == count
    np.testing.assert_array_equal(got, want)
    if count == 0:
        assert got is pts  # the usual frame: no copy


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 80), st.integers(1, 80), st.booleans())
def test_near_share_matches_a_kd_tree_query(seed, m, p, lattice):
    rng = np.random.default_rng(seed)
    if lattice:  # many pairs exactly the radius apart (the bound is strict)
        a = rng.integers(0, 4, (m, 3)) * 0.1
        b = rng.integers(0, 4, (p, 3)) * 0.1
        radius = 0.1
    else:
        a, b = rng.normal(size=(m, 3)), rng.normal(size=(p, 3))
        radius = float(rng.uniform(0.05, 1.5))
    assert _near_share(a, b, radius) == _near_share_kdtree(a, b, radius)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 60), st.integers(0, 60), st.sampled_from([0.0, 4_012_345.6789]))
def test_near_count_matches_every_pair_tested(seed, m, p, offset):
    """Samples on a lattice (pairs exactly the radius apart), also far from the origin, with rows of NaN or inf (never
    near)."""
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 5, (m, 3)) * 0.1 + rng.choice([0.0, 1e-9], (m, 3)) + offset
    b = rng.integers(0, 5, (p, 3)) * 0.1 + rng.choice([0.0, -1e-9], (p, 3)) + offset
    a[rng.random(m) < 0.1, rng.integers(0, 3)] = rng.choice([np.nan, np.inf])
    b[rng.random(p) < 0.1, rng.integers(0, 3)] = rng.choice([np.nan, -np.inf])
    radius = float(rng.choice([0.1, 0.2, 0.3]))
    d = a[:, None, :] - b[None, :, :]
    with np.errstate(invalid='ignore'):
        near = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2] < radius * radius
    assert kernels.near_count(a, b, radius) == int(near.any(axis=1).sum())


def test_near_share_bound_is_strict_like_the_kd_tree():
    a, b = np.zeros((1, 3)), np.array([[0.3, 0.0, 0.0], [0.0, 0.0, 0.7]])
    assert _near_share(a, b, 0.3) == _near_share_kdtree(a, b, 0.3) == 0.0
    assert _near_share(a, b, np.nextafter(0.3, 1)) == _near_share_kdtree(a, b, np.nextafter(0.3, 1)) == 1.0


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 200), st.integers(1, 6), st.booleans())
def test_beyond_counts_match_numpy(seed, m, k, per_point):
    rng = np.random.default_rng(seed)
    box = rng.integers(-3, 4, (m, 2 * k)).astype(np.float64)  # on a lattice: points on the box's edges too
    lo, hi = rng.integers(-3, 1, 2 * k).astype(np.float64), rng.integers(0, 4, 2 * k).astype(np.float64)
    lo[rng.random(2 * k) < 0.1], hi[rng.random(2 * k) < 0.1] = np.inf, -np.inf  # a plane without inliers
    d = rng.integers(0, 5, (m, k)) * 0.5
    t = rng.uniform(0.5, 1.0, (m, 1)) if per_point else 1.0
    labels = rng.integers(-1, k, m).astype(np.int32)
    surface = rng.random((k, k)) < 0.4
    within, beyond = kernels.beyond_counts(box, d, labels, np.full(1, t) if not per_point else t[:, 0].copy(), lo,
                                           hi, surface)
    inside = (box >= lo) & (box <= hi)
    far = np.where(inside[:, 0::2] & inside[:, 1::2], d, np.inf)
    excused = np.where(labels[:, None] >= 0, surface.T[np.maximum(labels, 0)], False)
    np.testing.assert_array_equal(within, np.count_nonzero(far <= t, axis=0))
    np.testing.assert_array_equal(beyond, np.count_nonzero((far > t) & (far <= 2 * t) & ~excused, axis=0))


@pytest.mark.parametrize('noise_model', ['constant', 'depth_quadratic'])
@pytest.mark.parametrize('organized', [True, False])
def test_plane_beyond_equals_its_numpy_reference(noise_model, organized):
    scene = scenes.depth_camera('stairs', width=96, height=72, seed=3)
    pts = scene.points if organized else scene.points[np.isfinite(scene.points).all(axis=1)]
    t = 0.03 if noise_model == 'constant' else 0.005  # the quadratic model widens it with the range
    seg = detect_planes(pts, t, max_planes=6, seed=0, shape=scene.shape if organized else None,
                        noise_model=noise_model)
    assert seg.n_planes >= 3
    samples = plane_shape.inlier_samples(pts, seg)
    frames = [plane_shape.principal_frame(inl) for inl in samples]
    fill = np.array([V._fill(inl, p, seg) for inl, p in zip(samples, seg.planes)])
    got = plane_beyond.beyond_share(pts, seg, frames, fill < V.MAX_FILL)
    np.testing.assert_array_equal(got, plane_beyond.beyond_share_numpy(pts, seg, frames, fill < V.MAX_FILL))
    assert (got > 0).any()


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 120), st.integers(1, 8))
def test_distinct_rows_match_numpy_unique(seed, m, kinds):
    rng = np.random.default_rng(seed)
    pts = rng.integers(0, kinds, (200, 3)).astype(np.float64)
    pts[rng.random(200) < 0.2] *= -0.0  # -0.0 equals 0.0
    rows = rng.integers(0, 200, m)
    assert kernels.distinct_rows(pts, rows) == len(np.unique(pts[rows], axis=0))


def test_distinct_counts_past_the_pairwise_limit_as_before():
    pts = np.repeat(np.arange(12.0)[:, None] * [1.0, 0.0, 0.0], 200, axis=0)  # 12 points, 200 copies each
    rows = np.arange(len(pts))
    assert V._distinct(pts, rows) == 12  # the head grows past DISTINCT_PAIRS: numpy's sort counts it
    assert V._distinct(pts, rows[:300]) == 2


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(4, 60), st.integers(2, 6), st.booleans())
def test_silhouettes_match_numpy(seed, n, k, rest):
    from plane_validation.core import indices
    from plane_validation.core.clusters import as_clusters
    rng = np.random.default_rng(seed)
    labels = rng.integers(-1 if rest else 0, k, n)
    labels[:2] = [-1 if rest else 0, k - 1]  # at least two clusters
    labels[2:4] = rng.integers(0, k, 2)  # (singleton clusters are likely too)
    pts = rng.normal(size=(n, 3))
    cl = as_clusters(pts, labels)
    sums = indices._pair_pass(cl)[0]
    got = indices._silhouettes(cl, sums)
    want = indices._silhouettes_numpy(cl, sums)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 80), st.sampled_from([np.float32, np.float64]), st.booleans())
def test_coordinate_extent_gives_coordinate_step(seed, m, dtype, far):
    rng = np.random.default_rng(seed)
    pts = (rng.normal(scale=4e6 if far else 10.0, size=(100, 3)).astype(dtype)).astype(np.float64)
    pts[rng.random(100) < 0.2, rng.integers(0, 3)] = rng.choice([np.nan, np.inf, -np.inf])
    rows = rng.integers(0, 100, m)
    np.testing.assert_array_equal(V._coordinate_step(pts, rows), V.coordinate_step(pts[rows]))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 60), st.sampled_from([1.0, 1e-3, 1e-6]))
def test_patch_eigenvalues_match_the_numpy_closed_form(seed, p, flat):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(p, 20, 3)) * [1.0, rng.uniform(0.1, 1.0), flat]
    m = np.einsum('pni,pnj->pij', x, x) / 20
    m[rng.random(p) < 0.2] *= np.eye(3)  # diagonal scatters: their entries, sorted
    got, want = kernels.patch_eigenvalues(m), plane_shape.symmetric_eigenvalues(m)
    # the same steps; numpy's vectorized arccos and cos may round differently in the last place
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max(initial=0.0))


def test_the_verdict_is_the_same_on_any_layout_of_the_points():
    from plane_validation.core.indices import validity_indices
    scene = scenes.stairs(4000, 0.01, seed=1)
    seg = detect_planes(scene.points, 0.03, max_planes=6, seed=0)
    scores = validity_indices(scene.points, seg.labels, seed=0)
    want = V.judge(scene.points, seg, scores)
    frozen = scene.points.copy()
    frozen.flags.writeable = False
    strided = np.hstack([scene.points, scene.points])[:, :3]
    for pts in (np.asfortranarray(scene.points), frozen, strided):
        assert V.judge(pts, seg, scores) == want
    assert want.n_planes == seg.n_planes >= 2


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.integers(0, 6))
def test_relabel_rows_matches_numpy(seed, n, k):
    """An organized frame's labels (-1..k-1) and its finite rows: the renumbered labels of the rows, and of the valid
    points, as a rank index and a compress give them."""
    rng = np.random.default_rng(seed)
    labels = rng.integers(-1, k, n).astype(np.int32)
    finite = rng.random(n) < 0.8
    rank = np.append(rng.permutation(k), -1).astype(np.int32)
    rows, points = kernels.relabel_rows(labels, finite, rank)
    np.testing.assert_array_equal(rows, rank[labels])
    np.testing.assert_array_equal(points, np.compress(finite, rank[labels]))
    assert rows.dtype == points.dtype == np.int32


@SETTINGS
@given(st.integers(0, 2**31), st.integers(0, 400), st.floats(0.0, 1.0))
def test_labels_where_is_numpys_compress(seed, n, share):
    """The labels of an organized frame's valid points: np.compress of the rows' labels by the finite rows."""
    rng = np.random.default_rng(seed)
    labels = rng.integers(-1, 6, n).astype(np.int32)
    keep = rng.random(n) < share
    got = kernels.labels_where(labels, keep)
    assert got.dtype == np.int32
    np.testing.assert_array_equal(got, np.compress(keep, labels))
