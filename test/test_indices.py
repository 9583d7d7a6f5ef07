"""Tests of plane_validation.core.indices against scikit-learn and brute-force scipy references."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import cdist, pdist
from sklearn import metrics

from plane_validation import scenes
from plane_validation.core import indices as pi
from plane_validation.core.clusters import as_clusters
from plane_validation.core.ransac import detect_planes

TOL = 1e-9


# ---------------------------------------------------------------------------------------------
# Brute-force references (O(n^2), small inputs only)


def ref_groups(points, labels):
    """Clusters in ascending label order (-1 first), as the module orders them."""
    labels = np.maximum(labels, -1)
    return [points[labels == c] for c in np.unique(labels)]


def ref_diameters(points, labels):
    return np.array([pdist(g).max() if len(g) > 1 else 0.0 for g in ref_groups(points, labels)])


def ref_distances(points, labels):
    groups = ref_groups(points, labels)
    k = len(groups)
    out = np.zeros((k, k))
    for i in range(k):
        for j in range(k):
            if i != j:
                out[i, j] = cdist(groups[i], groups[j]).min()
    return out


def ref_dunn(points, labels):
    diam, dist = ref_diameters(points, labels), ref_distances(points, labels)
    k = len(diam)
    return min(dist[i, j] for i in range(k) for j in range(k) if i != j) / diam.max()


def ref_db(points, labels):
    diam, dist = ref_diameters(points, labels), ref_distances(points, labels)
    k = len(diam)
    return np.mean([max((diam[i] + diam[j]) / dist[i, j] for j in range(k) if j != i) for i in range(k)])


def ref_gs(points, labels):
    """GS from sklearn: mean over clusters of the per-cluster mean silhouette."""
    s = metrics.silhouette_samples(points, labels)
    return np.mean([s[labels == c].mean() for c in np.unique(labels)])


def blobs(seed, n=400, k=4, unassigned=0.1, singleton=True):
    """Gaussian blobs with labels 0..k-1, some -1 points and optionally a one-point cluster."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-5, 5, size=(k, 3))
    labels = rng.integers(0, k, n)
    points = centres[labels] + rng.normal(size=(n, 3))
    labels[rng.random(n) < unassigned] = -1
    if singleton:
        labels[0] = k  # a cluster of one point
    return points, labels


def random_rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q


def flat_clusters(seed, n=300):
    """Three clusters, each exactly planar (2-D data rotated into 3-D), one lying in z = 0."""
    rng = np.random.default_rng(seed)
    parts, labels = [], []
    for c in range(3):
        flat = np.column_stack([rng.uniform(0, 4, n), rng.uniform(0, 2, n), np.zeros(n)])
        if c:
            flat = flat @ random_rotation(rng) + rng.uniform(-6, 6, 3)
        parts.append(flat)
        labels.append(np.full(n, c))
    return np.concatenate(parts), np.concatenate(labels)


def collinear_clusters(seed, n=200):
    """Three clusters each on a line (one axis-aligned, two in random directions)."""
    rng = np.random.default_rng(seed)
    parts, labels = [], []
    for c in range(3):
        direction = np.array([1.0, 0, 0]) if c == 0 else rng.normal(size=3)
        parts.append(np.outer(rng.uniform(-3, 3, n), direction) + rng.uniform(-8, 8, 3))
        labels.append(np.full(n, c))
    return np.concatenate(parts), np.concatenate(labels)


# ---------------------------------------------------------------------------------------------
# Agreement with scikit-learn


@pytest.mark.parametrize('seed', range(4))
def test_silhouettes_match_sklearn(seed):
    points, labels = blobs(seed)
    assert np.allclose(pi.silhouette_samples(points, labels), metrics.silhouette_samples(points, labels),
                       rtol=0, atol=TOL)
    assert pi.silhouette_score(points, labels) == pytest.approx(metrics.silhouette_score(points, labels),
                                                                abs=TOL)
    exact = pi.validity_indices(points, labels, sample_size=None)
    assert exact.silhouette == pytest.approx(metrics.silhouette_score(points, labels), abs=TOL)
    assert exact.davies_bouldin_classic == pytest.approx(metrics.davies_bouldin_score(points, labels), abs=TOL)


def test_singleton_cluster_silhouette_is_zero():
    points, labels = blobs(0)
    s = pi.silhouette_samples(points, labels)
    assert s[0] == 0.0 and (labels == labels[0]).sum() == 1


def _spread_unassigned_near_compact_clusters():
    """A 100 m line of unassigned points with two compact clusters 5 cm past its tip."""
    rng = np.random.default_rng(3)
    line = np.column_stack([np.linspace(0, 100, 1500), np.zeros(1500), np.zeros(1500)])
    tip = [np.array([100.05, 0, dz]) + 1e-3 * rng.normal(size=(20, 3)) for dz in (0.0, 0.02)]
    return (np.vstack([line + 1e-3 * rng.normal(size=line.shape), *tip]),
            np.r_[np.full(1500, -1), np.zeros(20, int), np.ones(20, int)])


@pytest.mark.parametrize('case', ['blobs far from the origin', 'spread unassigned', 'depth camera'])
def test_silhouettes_of_the_pair_pass_agree_with_cdist(case):
    """The compiled pass over all pairs against distances from cdist, silhouettes by the formula."""
    if case == 'blobs far from the origin':
        points, labels = blobs(1, n=1800, unassigned=0.3)
        points = points + [300.0, -40.0, 5.0]
    elif case == 'spread unassigned':
        points, labels = _spread_unassigned_near_compact_clusters()
    else:
        scene = scenes.depth_camera('room', seed=4)
        keep = np.flatnonzero(np.isfinite(scene.points).all(axis=1))[::97][:2000]
        points, labels = scene.points[keep], scene.labels[keep]
    cl = as_clusters(points, labels)
    s, s_planes = pi._silhouettes(cl)
    distances = cdist(cl.points, cl.points)
    sums = np.stack([distances[:, cl.codes == c].sum(axis=1) for c in range(cl.k)], axis=1)
    own = sums[np.arange(cl.n), cl.codes] / np.maximum(cl.sizes[cl.codes] - 1, 1)
    means = sums / cl.sizes
    means[np.arange(cl.n), cl.codes] = np.inf
    ref = (means.min(axis=1) - own) / np.maximum(own, means.min(axis=1))
    single = cl.sizes[cl.codes] == 1
    ref[single] = 0.0
    assert cl.k >= 3 and (case == 'depth camera' or np.isnan(s_planes).any())  # with unassigned points
    np.testing.assert_allclose(s, ref, rtol=1e-12, atol=1e-12)
    planes = cl.ids[cl.codes] >= 0
    b_planes = means[:, cl.ids >= 0].min(axis=1)
    ref_planes = np.where(planes, (b_planes - own) / np.maximum(own, b_planes), np.nan)
    ref_planes[single & planes] = 0.0
    np.testing.assert_allclose(s_planes, ref_planes, rtol=1e-12, atol=1e-12)  # NaN where NaN


@pytest.mark.parametrize('seed', range(3))
def test_davies_bouldin_classic_matches_sklearn(seed):
    points, labels = blobs(seed, unassigned=0.3, singleton=False)
    assert pi.davies_bouldin_classic(points, labels) == pytest.approx(
        metrics.davies_bouldin_score(points, labels), abs=TOL)


def test_davies_bouldin_classic_coincident_centroids_like_sklearn():
    """Two clusters sharing a centroid: sklearn's conventions (that distance counts as infinite)."""
    rng = np.random.default_rng(3)
    a, b = rng.integers(-5, 6, size=(25, 3)), rng.integers(-9, 10, size=(25, 3))
    # symmetric integer sets: both centroids are exactly 0 in floating point
    points = np.concatenate([a, -a, b, -b, rng.integers(20, 30, size=(50, 3))]).astype(float)
    labels = np.repeat([0, 1, 2], 50)
    assert pi.davies_bouldin_classic(points, labels) == pytest.approx(
        metrics.davies_bouldin_score(points, labels), abs=TOL)


@pytest.mark.parametrize('seed', range(3))
def test_gs_and_gs_planes_match_sklearn(seed):
    points, labels = blobs(seed)
    planes = labels >= 0
    expected_gs = ref_gs(points, labels)
    expected_planes = ref_gs(points[planes], labels[planes])
    assert pi.global_silhouette(points, labels) == pytest.approx(expected_gs, abs=TOL)
    assert pi.global_silhouette(points, labels, planes_only=True) == pytest.approx(expected_planes, abs=TOL)
    exact = pi.validity_indices(points, labels, sample_size=None)
    assert exact.gs == pytest.approx(expected_gs, abs=TOL)
    assert exact.gs_planes == pytest.approx(expected_planes, abs=TOL)
    assert exact.gs_planes != pytest.approx(exact.gs, abs=1e-6)  # the -1 points really are dropped


# ---------------------------------------------------------------------------------------------
# Dunn and paper Davies-Bouldin against brute force


CLOUDS = {
    'random': lambda seed: blobs(seed, n=300, k=3, unassigned=0.15, singleton=False),
    'random_singleton': lambda seed: blobs(seed, n=300, k=3, unassigned=0.0, singleton=True),
    'flat': flat_clusters,
    'collinear': collinear_clusters,
}


@pytest.mark.parametrize('kind', sorted(CLOUDS))
@pytest.mark.parametrize('seed', range(3))
def test_dunn_and_db_match_bruteforce(kind, seed):
    points, labels = CLOUDS[kind](seed)
    assert np.allclose(pi.cluster_diameters(points, labels), ref_diameters(points, labels), rtol=1e-12, atol=0)
    assert np.allclose(pi.cluster_distances(points, labels), ref_distances(points, labels), rtol=1e-12, atol=0)
    assert pi.dunn_index(points, labels) == pytest.approx(ref_dunn(points, labels), rel=1e-12)
    assert pi.davies_bouldin_index(points, labels) == pytest.approx(ref_db(points, labels), rel=1e-12)
    exact = pi.validity_indices(points, labels, sample_size=None)
    assert exact.dunn == pytest.approx(ref_dunn(points, labels), rel=1e-12)
    assert exact.davies_bouldin == pytest.approx(ref_db(points, labels), rel=1e-12)


def test_cluster_distances_on_a_noisy_scene():
    scene = scenes.cube(3000, noise=2.0, outlier_fraction=0.05, seed=4)
    assert np.allclose(pi.cluster_distances(scene.points, scene.labels),
                       ref_distances(scene.points, scene.labels), rtol=1e-12, atol=0)


@pytest.mark.parametrize('shape', ['random', 'flat_z0', 'flat_tilted', 'collinear', 'sphere', 'thin', 'duplicates'])
def test_diameter_is_exact(shape):
    rng = np.random.default_rng(11)
    n = 3000
    if shape == 'random':
        p = rng.normal(size=(n, 3)) * [5, 2, 1]
    elif shape == 'flat_z0':
        p = np.column_stack([rng.uniform(0, 3, n), rng.uniform(0, 1, n), np.zeros(n)])
    elif shape == 'flat_tilted':
        p = np.column_stack([rng.normal(size=(n, 2)), np.zeros(n)]) @ random_rotation(rng) + 7
    elif shape == 'collinear':
        p = np.outer(rng.uniform(-1, 4, n), rng.normal(size=3)) + 2
    elif shape == 'sphere':  # every point is a hull vertex: exercises the pruned search
        p = rng.normal(size=(n, 3))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
    elif shape == 'thin':  # a plane with tiny noise (Qhull 3-D succeeds)
        p = np.column_stack([rng.uniform(0, 3, n), rng.uniform(0, 1, n), rng.uniform(-1e-6, 1e-6, n)])
    else:
        p = np.repeat(rng.normal(size=(40, 3)), 50, axis=0)
    assert pi.diameter(p) == pytest.approx(pdist(p).max(), rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 400), st.sampled_from(['3d', 'plane', 'line', 'point']))
def test_diameter_property_on_integer_grids(seed, n, kind):
    """Integer grids are full of ties, duplicates and coplanar/collinear subsets."""
    rng = np.random.default_rng(seed)
    grid = rng.integers(-3, 4, size=(n, 3)).astype(float)
    if kind == 'plane':
        grid[:, 2] = grid[:, 0] - grid[:, 1]
    elif kind == 'line':
        grid = np.outer(grid[:, 0], [1.0, 2.0, -1.0])
    elif kind == 'point':
        grid[:] = grid[0]
    assert pi.diameter(grid) == pytest.approx(pdist(grid).max(), rel=1e-12, abs=0)


# ---------------------------------------------------------------------------------------------
# Edge cases


def test_empty_input():
    r = pi.validity_indices(np.empty((0, 3)), np.empty(0, dtype=int))
    assert (r.dunn, r.davies_bouldin, r.davies_bouldin_classic, r.silhouette, r.gs, r.gs_planes) == (
        0.0, math.inf, 0.0, 0.0, 0.0, 0.0)
    assert (r.n_points, r.n_clusters, r.n_planes, r.sample_size, r.sampled) == (0, 0, 0, 0, False)
    assert pi.cluster_diameters(np.empty((0, 3)), np.empty(0, int)).shape == (0,)
    assert pi.cluster_distances(np.empty((0, 3)), np.empty(0, int)).shape == (0, 0)
    assert pi.silhouette_samples(np.empty((0, 3)), np.empty(0, int)).shape == (0,)


@pytest.mark.parametrize('label', [-1, 0])
def test_single_cluster(label):
    """All unassigned (no planes at all), or one plane and nothing else."""
    points = scenes.sphere(500, seed=1).points
    labels = np.full(500, label)
    r = pi.validity_indices(points, labels, seed=0)
    assert (r.dunn, r.davies_bouldin, r.davies_bouldin_classic, r.silhouette, r.gs, r.gs_planes) == (
        0.0, math.inf, 0.0, 0.0, 0.0, 0.0)
    assert (r.n_clusters, r.n_planes) == (1, int(label >= 0))
    assert pi.dunn_index(points, labels) == 0.0
    assert pi.davies_bouldin_index(points, labels) == math.inf
    assert pi.davies_bouldin_classic(points, labels) == 0.0
    assert pi.global_silhouette(points, labels) == 0.0
    assert np.all(pi.silhouette_samples(points, labels) == 0.0)


def test_one_plane_plus_unassigned():
    """Two clusters for GS (plane and the -1 cluster), but fewer than two planes for GS_planes."""
    points, labels = blobs(2, k=1, unassigned=0.3, singleton=False)
    r = pi.validity_indices(points, labels, seed=0)
    assert (r.n_planes, r.n_clusters) == (1, 2)
    assert r.gs == pytest.approx(ref_gs(points, labels), abs=TOL)
    assert r.gs_planes == 0.0 and r.gs_planes_se == 0.0


def test_one_point_cluster_has_zero_diameter():
    points, labels = blobs(3, n=200, k=2, unassigned=0.0, singleton=True)
    diam = pi.cluster_diameters(points, labels)
    assert diam[-1] == 0.0 and np.all(diam[:-1] > 0)


def test_coincident_clusters():
    """Two clusters sharing a point: distance 0, so Dunn 0 and paper DB inf."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(30, 3)), rng.normal(size=(30, 3)) + 5
    b[0] = a[0]
    points, labels = np.concatenate([a, b]), np.repeat([0, 1], 30)
    assert pi.cluster_distances(points, labels)[0, 1] == 0.0
    assert pi.dunn_index(points, labels) == 0.0
    assert pi.davies_bouldin_index(points, labels) == math.inf
    r = pi.validity_indices(points, labels)
    assert r.dunn == 0.0 and r.davies_bouldin == math.inf
    # identical clusters (all points equal): every index defined
    r = pi.validity_indices(np.ones((6, 3)), np.array([0, 0, 0, 1, 1, 1]))
    assert (r.dunn, r.davies_bouldin, r.davies_bouldin_classic, r.silhouette, r.gs) == (0.0, math.inf, 0.0, 0.0, 0.0)


def test_all_singletons():
    """Every cluster one point: diameters 0, so Dunn inf and paper DB 0; silhouettes 0."""
    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0]])
    r = pi.validity_indices(points, np.array([0, 1, 2]))
    assert (r.dunn, r.davies_bouldin, r.davies_bouldin_classic, r.silhouette, r.gs, r.gs_planes) == (
        math.inf, 0.0, 0.0, 0.0, 0.0, 0.0)


def test_non_finite_rows_are_dropped():
    points, labels = blobs(1, n=200)
    dirty = points.copy()
    dirty[[3, 50, 120]] = [np.nan, 0, 0], [np.inf, 1, 1], [0, -np.inf, 0]
    keep = np.isfinite(dirty).all(axis=1)
    a = pi.validity_indices(dirty, labels, sample_size=None)
    b = pi.validity_indices(points[keep], labels[keep], sample_size=None)
    assert a == b and a.n_points == 197
    s = pi.silhouette_samples(dirty, labels)
    assert np.isnan(s[[3, 50, 120]]).all()
    assert np.allclose(s[keep], metrics.silhouette_samples(points[keep], labels[keep]), atol=TOL)


def test_labels_below_minus_one_are_unassigned():
    points, labels = blobs(4)
    other = labels.copy()
    other[labels == -1] = np.where(np.arange((labels == -1).sum()) % 2, -1, -7)
    assert pi.validity_indices(points, other, sample_size=None) == pi.validity_indices(points, labels,
                                                                                        sample_size=None)


@pytest.mark.parametrize('points, labels', [
    (np.zeros((5, 2)), np.zeros(5, int)),
    (np.zeros(5), np.zeros(5, int)),
    (np.zeros((5, 3, 1)), np.zeros(5, int)),
    (np.zeros((5, 3)), np.zeros(4, int)),
    (np.zeros((5, 3)), np.zeros((5, 1), int)),
    (np.zeros((5, 3)), np.full(5, 0.5)),
    (np.zeros((5, 3), bool), np.zeros(5, int)),  # as detect_planes: booleans are no coordinates
])
def test_bad_shapes_raise(points, labels):
    for fn in (pi.validity_indices, pi.dunn_index, pi.davies_bouldin_index, pi.davies_bouldin_classic,
               pi.silhouette_samples, pi.global_silhouette, pi.cluster_diameters, pi.cluster_distances):
        with pytest.raises(ValueError):
            fn(points, labels)


def test_bad_sample_size_raises():
    with pytest.raises(ValueError):
        pi.validity_indices(np.zeros((5, 3)), np.zeros(5, int), sample_size=1)


# ---------------------------------------------------------------------------------------------
# Sampled mode


def _cases():
    out = []
    for name, gen, n, noise in [('corner', scenes.corner, 3000, 2.5), ('cube', scenes.cube, 6000, 5.0)]:
        scene = gen(n, noise=noise, outlier_fraction=0.05, seed=1)
        out.append((f'{name}-truth', scene.points, scene.labels))
        seg = detect_planes(scene.points, tolerance=2 * noise, seed=0, connectivity=False)
        out.append((f'{name}-ransac', scene.points, seg.labels))
    return out


@pytest.fixture(scope='module')
def scene_cases():
    return {name: (points, labels, pi.validity_indices(points, labels, sample_size=None))
            for name, points, labels in _cases()}


@pytest.mark.parametrize('case', ['corner-truth', 'corner-ransac', 'cube-truth', 'cube-ransac'])
@pytest.mark.parametrize('sample_size', [1000])
def test_sampled_gs_is_accurate(scene_cases, case, sample_size):
    points, labels, exact = scene_cases[case]
    assert exact.n_clusters >= 4 and exact.n_planes >= 3
    seeds = range(50)
    runs = [pi.validity_indices(points, labels, sample_size=sample_size, seed=s) for s in seeds]
    assert all(r.sampled and abs(r.sample_size - sample_size) <= 0.05 * sample_size for r in runs)
    for field in ('gs', 'gs_planes', 'silhouette'):
        err = np.array([getattr(r, field) - getattr(exact, field) for r in runs])
        se = np.array([getattr(r, f'{field}_se') for r in runs])
        assert np.mean(np.abs(err) <= 0.02) >= 0.95, (field, np.abs(err).max())
        assert np.all(se > 0) and np.all(se < 0.02)
        assert np.mean(np.abs(err) <= 4 * se) >= 0.9, (field, np.abs(err) / se)
    # Dunn and both DB forms stay exact in sampled mode
    assert runs[0].dunn == exact.dunn and runs[0].davies_bouldin == exact.davies_bouldin
    assert runs[0].davies_bouldin_classic == pytest.approx(exact.davies_bouldin_classic, rel=1e-12)


def test_sampled_gs_at_default_sample_size(scene_cases):
    points, labels, exact = scene_cases['cube-ransac']
    errs = np.array([[r.gs - exact.gs, r.gs_planes - exact.gs_planes]
                     for r in (pi.validity_indices(points, labels, seed=s) for s in range(40))])
    assert np.mean(np.abs(errs) <= 0.02, axis=0).min() >= 0.95


def test_sampling_is_deterministic_with_a_seed(scene_cases):
    points, labels, _ = scene_cases['corner-ransac']
    a = pi.validity_indices(points, labels, sample_size=500, seed=7)
    b = pi.validity_indices(points, labels, sample_size=500, seed=7)
    c = pi.validity_indices(points, labels, sample_size=500, seed=8)
    assert a == b and a.sampled
    assert a.gs != c.gs
    g = pi.validity_indices(points, labels, sample_size=500, seed=np.random.default_rng(7))
    assert g == a


def test_exact_when_sample_covers_the_cloud():
    points, labels = blobs(6, n=300)
    exact = pi.validity_indices(points, labels, sample_size=None)
    for size in (300, 5000):
        r = pi.validity_indices(points, labels, sample_size=size, seed=1)
        assert r == exact
        assert not r.sampled and r.sample_size == 300
        assert r.silhouette_se == r.gs_se == r.gs_planes_se == 0.0


def test_stratified_sample_keeps_small_clusters():
    """A 3-point cluster is taken whole; a 1-point cluster contributes s = 0 exactly."""
    rng = np.random.default_rng(2)
    points = np.concatenate([rng.normal(size=(5000, 3)), rng.normal(size=(3, 3)) + 20, [[-30.0, 0, 0]]])
    labels = np.concatenate([np.zeros(5000, int), np.ones(3, int), [2]])
    exact = pi.validity_indices(points, labels, sample_size=None)
    r = pi.validity_indices(points, labels, sample_size=200, seed=0)
    assert r.sampled and r.n_clusters == 3
    assert abs(r.gs - exact.gs) < 0.02 and abs(r.gs_planes - exact.gs_planes) < 0.02


def test_as_dict_is_flat():
    points, labels = blobs(0)
    r = pi.validity_indices(points, labels, sample_size=100, seed=0)
    d = r.as_dict()
    assert set(d) >= {'dunn', 'davies_bouldin', 'davies_bouldin_classic', 'silhouette', 'gs', 'gs_planes',
                      'silhouette_se', 'gs_se', 'gs_planes_se', 'n_planes', 'n_clusters', 'n_points',
                      'sample_size', 'sampled'}
    assert all(isinstance(v, (int, float)) for v in d.values())
    assert d['sampled'] == 1 and d['n_points'] == 400


def test_50k_points_is_fast():
    """Target: well under 0.5 s; the bound is loose for slow CI machines (measured ~0.1 s)."""
    scene = scenes.cube(50_000, noise=1.0, outlier_fraction=0.05, seed=0)
    best = math.inf
    for seed in range(3):
        t0 = time.perf_counter()
        r = pi.validity_indices(scene.points, scene.labels, seed=seed)
        best = min(best, time.perf_counter() - t0)
    assert r.n_clusters == 7 and r.sampled
    assert best < 1.5


# ---------------------------------------------------------------------------------------------
# Dunn and Davies-Bouldin on the index sample (the node's default)


def test_sampled_separation_keeps_gs_and_samples_dunn_db():
    scene = scenes.cube(20_000, 2.5, seed=4)
    labels = detect_planes(scene.points, 5.0, seed=0).labels
    full = pi.validity_indices(scene.points, labels, sample_size=1500, seed=3)
    fast = pi.validity_indices(scene.points, labels, sample_size=1500, seed=3, sampled_separation=True)
    # the silhouette estimates come from the very same sample either way
    assert (fast.gs, fast.gs_planes, fast.silhouette, fast.gs_se) == (full.gs, full.gs_planes, full.silhouette,
                                                                      full.gs_se)
    assert full.separation_size == full.n_points == 20_000
    assert fast.separation_size == fast.sample_size and abs(fast.sample_size - 1500) <= 75
    # a sample's clusters lie farther apart than the full clusters: Dunn up, paper DB down
    assert fast.dunn >= full.dunn and fast.davies_bouldin <= full.davies_bouldin
    assert fast.davies_bouldin_classic == pytest.approx(full.davies_bouldin_classic, rel=0.1)


def test_sampled_separation_is_close_on_well_separated_clusters():
    rng = np.random.default_rng(5)
    centers = np.array([[0.0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]])
    labels = np.repeat(np.arange(4), 5000)
    points = centers[labels] + rng.uniform(-1, 1, (20_000, 3))
    full = pi.validity_indices(points, labels, sample_size=2000, seed=1)
    fast = pi.validity_indices(points, labels, sample_size=2000, seed=1, sampled_separation=True)
    assert fast.dunn == pytest.approx(full.dunn, rel=0.1)
    assert fast.davies_bouldin == pytest.approx(full.davies_bouldin, rel=0.1)


def test_sampled_separation_is_exact_when_the_cloud_fits_the_sample():
    scene = scenes.corner(1500, 2.5, seed=2)
    labels = detect_planes(scene.points, 5.0, seed=0).labels
    assert pi.validity_indices(scene.points, labels, sample_size=2000, sampled_separation=True) == \
        pi.validity_indices(scene.points, labels, sample_size=2000)


def test_sampled_silhouettes_survive_a_float_max_row_and_wide_clouds():
    # A driver's FLT_MAX row (unassigned) must not turn the float32 distance sums into NaN.
    scene = scenes.corner(10_000, 0.01, side=1.0, outlier_fraction=0.05, seed=0)
    labels = detect_planes(scene.points, 0.03, seed=0).labels
    points = scene.points.copy()
    points[np.flatnonzero(labels < 0)[0]] = np.finfo(np.float32).max
    clean = pi.validity_indices(scene.points, labels, seed=1)
    for seed in range(12):
        assert pi.validity_indices(points, labels, seed=seed).gs_planes > clean.gs_planes - 0.05
    # Two small corners 1 km apart: distances within a corner keep their precision.
    a = scenes.corner(6000, 0.002, side=0.2, seed=0)
    b = scenes.corner(6000, 0.002, side=0.2, seed=1)
    pts = np.vstack([a.points, b.points + [1000.0, 0, 0]])
    lab = np.concatenate([a.labels, np.where(b.labels >= 0, b.labels + 3, -1)])
    fast = pi.validity_indices(pts, lab, seed=0)
    near = pi.validity_indices(np.vstack([a.points, b.points + [10.0, 0, 0]]), lab, seed=0)
    assert fast.gs_planes == pytest.approx(near.gs_planes, abs=1e-3)


def test_cluster_distances_are_the_same_from_all_pairs_and_from_kd_trees(monkeypatch):
    from plane_validation.core import cluster_extent, indices
    rng = np.random.default_rng(5)
    pts = np.vstack([rng.normal(c, 0.3, (250, 3)) for c in rng.uniform(-3, 3, (12, 3))])
    labels = np.repeat(np.arange(-1, 11), 250)
    brute = indices.cluster_distances(pts, labels)  # 3000 points: every point queried
    monkeypatch.setattr(cluster_extent, 'BRUTE_DISTANCES', 0)
    trees = indices.cluster_distances(pts, labels)
    assert brute.shape == (12, 12) and np.all(np.diag(brute) == 0) and np.all(brute[~np.eye(12, dtype=bool)] > 0)
    assert np.array_equal(brute, trees)


def test_the_plane_silhouette_in_a_thread_is_the_same_value_under_the_callers_error_state(monkeypatch):
    from concurrent.futures import ThreadPoolExecutor
    cube = scenes.cube(6000, 0.005, side=1.0, seed=2)
    values = []
    for threshold in (10**9, 0):  # inline, then in the thread
        monkeypatch.setattr(pi, 'THREADED_PS_POINTS', threshold)
        values.append(pi.validity_indices(cube.points, cube.labels, seed=5))
    assert values[0] == values[1] and values[0].plane_silhouette > 0.5
    with ThreadPoolExecutor(1) as pool, np.errstate(over='raise'):
        assert pi._started(pool, lambda: np.geterr()['over'])() == 'raise'  # numpy's state goes along
    pool.shutdown()
    assert pi._started(pool, lambda: 7)() == 7  # no thread can start (as at interpreter exit): run here
