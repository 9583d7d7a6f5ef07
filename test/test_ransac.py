"""Sequential RANSAC core: accuracy on scenes with ground truth, bad input, determinism."""
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import plane_validation as pv
from plane_validation import scenes
from plane_validation.core.search import hypotheses


def match_planes(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """For each true plane (k, 4) the index of the found plane nearest in normal angle and offset."""
    cost = np.array([[same_plane(f, t)[0] + same_plane(f, t)[1] for f in found] for t in truth])
    return np.argmin(cost, axis=1)


def angle_deg(n1: np.ndarray, n2: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(n1 @ n2), -1, 1))))


def same_plane(found: np.ndarray, true: np.ndarray) -> tuple[float, float]:
    """(angle in degrees, offset difference) after aligning the sign of the normals."""
    sign = 1.0 if found[:3] @ true[:3] >= 0 else -1.0
    return angle_deg(found[:3], true[:3]), abs(sign * found[3] - true[3])


def label_accuracy(seg: pv.Segmentation, scene: scenes.Scene) -> float:
    """Fraction of scene points whose found plane is the one matched to their true plane."""
    mapping = match_planes(seg.coefficients, scene.planes)
    expected = np.where(scene.labels >= 0, mapping[np.maximum(scene.labels, 0)], -1)
    return float(np.mean(seg.labels == expected))


@pytest.mark.parametrize('make, k', [(scenes.corner, 3), (scenes.cube, 6)])
def test_noise_free_scene_exact(make, k):
    scene = make(3000 if k == 3 else 6000, 0.0, seed=11)
    seg = pv.detect_planes(scene.points, 1e-6 * 100, max_planes=10, seed=3, connectivity=False)
    assert seg.n_planes == k
    mapping = match_planes(seg.coefficients, scene.planes)
    assert sorted(mapping) == list(range(k))
    for true, j in zip(scene.planes, mapping):
        angle, doffset = same_plane(seg.coefficients[j], true)
        assert angle < 0.5
        assert doffset < 1e-6 * 100
    assert label_accuracy(seg, scene) == 1.0
    for plane in seg.planes:
        assert np.isclose(np.linalg.norm(plane.normal), 1.0)
        assert plane.rms < 1e-9
        np.testing.assert_array_equal(plane.inliers, np.flatnonzero(seg.labels == seg.planes.index(plane)))


def test_noisy_corner_nearest_plane_labels():
    scene = scenes.corner(6000, 2.5, seed=5)
    seg = pv.detect_planes(scene.points, 5.0, seed=1)
    assert seg.n_planes == 3
    mapping = match_planes(seg.coefficients, scene.planes)
    for true, j in zip(scene.planes, mapping):
        assert same_plane(seg.coefficients[j], true)[0] < 2.0
    assert label_accuracy(seg, scene) >= 0.95
    for plane in seg.planes:  # uniform noise on [-2.5, 2.5] has an RMS of 2.5/sqrt(3)
        assert 1.0 < plane.rms < 3.0  # edge bands of the neighbours add a little


def test_sequential_removal_alone_would_be_worse():
    """The nearest-plane reassignment is what lifts the noisy corner above 95 %."""
    scene = scenes.corner(6000, 2.5, seed=5)
    seg = pv.detect_planes(scene.points, 5.0, seed=1, connectivity=False)
    dist = np.abs(scene.points @ seg.coefficients[:, :3].T + seg.coefficients[:, 3])
    within = dist <= 5.0
    ambiguous = within.sum(axis=1) > 1
    assert ambiguous.mean() > 0.03  # a real band of points near the edges is within t of two planes
    nearest = np.argmin(dist, axis=1)
    assert np.all(seg.labels[ambiguous] == nearest[ambiguous])


@pytest.mark.parametrize('fraction', [0.02, 0.04, 0.05])
def test_stairs_parallel_planes_are_separate(fraction):
    """Treads (and risers) one step apart are separate planes for t well below half a step.

    Above about 0.065 * rise a slanted plane through the nosings holds more points than one tread
    (the distance to the stair slope is uniform along the profile), so larger t is not asserted here.
    """
    rise = 0.17
    scene = scenes.stairs(8000, steps=4, rise=rise, seed=2)
    seg = pv.detect_planes(scene.points, fraction * rise, max_planes=12, min_inliers=100, seed=0)
    assert seg.n_planes == scene.n_planes
    match = []
    for true in scene.planes:  # each true plane has its own found plane, same normal and offset
        close = [j for j, f in enumerate(seg.coefficients)
                 if same_plane(f, true)[0] < 2.0 and same_plane(f, true)[1] < rise / 4]
        assert len(close) == 1
        match.append(close[0])
    assert sorted(match) == list(range(scene.n_planes))
    expected = np.asarray(match)[scene.labels]
    assert np.mean(seg.labels == expected) > 0.97


def test_sphere_has_no_plane():
    scene = scenes.sphere(5000, seed=4)
    seg = pv.detect_planes(scene.points, 0.005, min_inliers=0.02, seed=0)
    assert seg.n_planes == 0
    assert 'min_inliers' in seg.reason
    assert np.all(seg.labels == -1)


def test_min_inliers_absolute_and_fraction():
    scene = scenes.table(20000, seed=7)
    few = pv.detect_planes(scene.points, 0.003, min_inliers=0.05, max_planes=20, seed=0)
    many = pv.detect_planes(scene.points, 0.003, min_inliers=120, max_planes=20, seed=0)
    assert few.n_planes == 2  # floor and table top are the only planes above 5 %
    assert many.n_planes == 12
    assert all(len(p.inliers) >= 120 for p in many.planes)


def test_max_planes_stops_early():
    scene = scenes.cube(3000, seed=1)
    seg = pv.detect_planes(scene.points, 0.01, max_planes=2, seed=0)
    assert seg.n_planes == 2
    assert 'max_planes' in seg.reason


def test_a_masked_arrays_masked_rows_are_no_points():
    """An outside probe: np.asarray dropped the mask, so the junk under it was searched and scored."""
    scene = scenes.corner(1000, 1.0, seed=0)
    junk = scene.points.copy()
    junk[:300] = np.random.default_rng(0).random((300, 3)) * 50
    masked = np.ma.masked_array(junk, mask=np.zeros(junk.shape, bool))
    masked.mask[:300, 1] = True  # one masked coordinate: the row is no point
    for connectivity in (True, False):
        seg = pv.detect_planes(masked, 2.5, seed=0, connectivity=connectivity)
        alone = pv.detect_planes(scene.points[300:], 2.5, seed=0, connectivity=connectivity)
        assert seg.n_valid == 700 and np.all(seg.labels[:300] == -1)
        np.testing.assert_array_equal(seg.labels[300:], alone.labels)
        assert pv.validity_indices(masked, seg.labels, seed=0) == pv.validity_indices(scene.points[300:],
                                                                                     alone.labels, seed=0)
    assert pv.tune_tolerance(masked, seed=0).segmentation.n_valid == 700
    assert pv.detect_planes(np.ma.masked_array(junk), 2.5, seed=0).n_valid == 1000  # nothing masked


def test_nan_rows_are_ignored_and_labelled_unassigned():
    scene = scenes.corner(3000, 1.0, seed=2)
    pts = scene.points.astype(np.float32)
    rng = np.random.default_rng(0)
    bad = rng.choice(len(pts), 300, replace=False)
    pts[bad[:100], 0] = np.nan
    pts[bad[100:200], 1] = np.inf
    pts[bad[200:], 2] = -np.inf
    seg = pv.detect_planes(pts, 2.5, seed=0)
    assert seg.n_planes == 3
    assert seg.n_valid == len(pts) - 300
    assert np.all(seg.labels[bad] == -1)
    assert all(np.isfinite(p.coefficients).all() for p in seg.planes)
    assert seg.labels.dtype == np.int32



def test_an_extent_given_by_the_caller_is_used_and_checked():
    """detect_planes with the finite rows and largest coordinate its caller found gives what it finds itself; a
    given extent is what it checks the magnitude against, and finite rows of another shape or type are refused."""
    scene = scenes.corner(3000, 1.0, seed=2)
    pts = scene.points.copy()
    pts[::17] = np.nan
    finite = np.isfinite(pts).all(axis=1)
    largest = float(np.abs(pts[finite]).max())
    own = pv.detect_planes(pts, 2.5, seed=0)
    given = pv.detect_planes(pts, 2.5, seed=0, extent=(finite, largest))
    np.testing.assert_array_equal(given.labels, own.labels)
    assert [p.coefficients.tolist() for p in given.planes] == [p.coefficients.tolist() for p in own.planes]
    far = pts.copy()
    far[5, 1] = 1e160  # beyond MAX_COORDINATE: refused with the extent that says so
    with pytest.raises(ValueError, match='reaches'):
        pv.detect_planes(far, 2.5, seed=0, extent=(np.isfinite(far).all(axis=1), 1e160))
    with pytest.raises(ValueError, match='extent'):
        pv.detect_planes(pts, 2.5, seed=0, extent=(finite[1:], largest))
    with pytest.raises(ValueError, match='extent'):
        pv.detect_planes(pts, 2.5, seed=0, extent=(finite.astype(np.int8), largest))

@pytest.mark.parametrize('points, why', [
    (np.empty((0, 3)), 'fewer than 3'),
    (np.array([[0.0, 0, 0], [1, 1, 1]]), 'fewer than 3'),
    (np.full((50, 3), np.nan), 'fewer than 3'),
    (np.ones((100, 3)), 'identical'),
    (np.outer(np.linspace(0, 1, 100), [1.0, 2.0, 3.0]), 'collinear'),
])
def test_degenerate_input_gives_no_planes_with_reason(points, why):
    seg = pv.detect_planes(points, 0.01, seed=0)
    assert seg.n_planes == 0
    assert why in seg.reason
    assert seg.labels.shape == (len(points),)
    assert np.all(seg.labels == -1)
    assert seg.coefficients.shape == (0, 4)


@pytest.mark.parametrize('points', [np.zeros((10, 2)), np.zeros(30), np.zeros((10, 3), dtype=complex),
                                    np.array([['a', 'b', 'c']]), np.zeros((2, 10, 3))])
def test_wrong_shape_or_dtype_raises(points):
    with pytest.raises(ValueError, match='points'):
        pv.detect_planes(points, 0.01)


def test_fit_plane_fits_n_by_3_points_and_refuses_others():
    """An outside probe: a (3, N) array gave an N-vector "normal" (through an N x N matrix), (N, 4) a 4-vector,
    2 points an arbitrary plane, a NaN row numpy's LinAlgError and 1-D input an AxisError."""
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(0, 1, (50, 2)), np.full(50, 2.0)])  # the plane z = 2
    normal, offset = pv.fit_plane(points)
    np.testing.assert_allclose(abs(normal @ [0, 0, 1]), 1.0)
    np.testing.assert_allclose(offset * np.sign(normal[2]), -2.0)
    for bad, why in [(points.T, r'shape \(N, 3\), got \(3, 50\)'), (np.column_stack([points, points[:, :1]]), 'shape'),
                     (points[:, 2], 'shape'), (points[:2], 'at least 3 points, got 2'),
                     (np.vstack([points, [np.nan] * 3]), '1 of 51 rows hold NaN or inf'),
                     (np.vstack([points, [np.inf, 0, 0]]), 'finite'), (points[:, [0, 0, 2]], 'lie on one line'),
                     (np.ones((5, 3)), 'identical')]:
        with pytest.raises(ValueError, match=why):
            pv.fit_plane(bad)
    on_line = np.vstack([np.column_stack([np.linspace(0, 1, 98), np.zeros((98, 2))]), [[0.5, 1, 0], [0.2, -1, 0]]])
    normal, offset = pv.fit_plane(on_line)  # 98 points on a line and 2 off it: they span z = 0
    np.testing.assert_allclose(np.abs(normal), [0, 0, 1], atol=1e-12)


@pytest.mark.parametrize('kwargs, name', [({'tolerance': 0}, 'tolerance'), ({'tolerance': np.nan}, 'tolerance'),
                                          ({'tolerance': True}, 'tolerance'),
                                          ({'tolerance': np.array(True)}, 'tolerance'),
                                          ({'tolerance': -1}, 'tolerance'), ({'probability': 1.0}, 'probability'),
                                          ({'max_iterations': 0}, 'max_iterations'), ({'max_planes': -1}, 'max_planes'),
                                          ({'min_inliers': -0.5}, 'min_inliers'),
                                          # an outside probe: numpy's or Python's messages, or taken silently
                                          ({'seed': -1}, 'seed'), ({'seed': 1.5}, 'seed'),
                                          ({'max_planes': None}, 'max_planes'), ({'max_planes': 2.5}, 'max_planes'),
                                          ({'connectivity': 'no'}, 'connectivity'),
                                          ({'shape': (100.5, 3)}, 'shape'),
                                          # a second probe: taken silently, or an error from numpy's internals
                                          ({'tolerance': '0.05'}, 'tolerance'), ({'probability': None}, 'probability'),
                                          ({'ransac_points': np.inf}, 'ransac_points'),
                                          ({'ransac_points': np.nan}, 'ransac_points'),
                                          ({'min_inliers': '0.1'}, 'min_inliers'), ({'graph': 'x'}, 'graph'),
                                          ({'noise_model': 'depth_quadratic', 'noise_reference': True},
                                           'noise_reference')])
def test_invalid_parameters_raise(kwargs, name):
    args = {'tolerance': 0.01, **kwargs}
    with pytest.raises(ValueError, match=name):
        pv.detect_planes(scenes.corner(300, seed=0).points, **args)


@pytest.mark.parametrize('call', [lambda p: pv.tune_tolerance(p, seed=-1), lambda p: pv.tune_tolerance(p, count=2.5),
                                  lambda p: pv.tune_tolerance(p, connectivity=0),
                                  lambda p: pv.validity_indices(p, np.zeros(len(p), int), seed=-1),
                                  lambda p: pv.select_plane_count(p, 1.0, seed=-1),
                                  lambda p: pv.tune_tolerance(p, max_planes='3', seed=0),
                                  lambda p: pv.tune_tolerance(p, t_min=np.nan, seed=0),
                                  lambda p: pv.validity_indices(p, np.zeros(len(p), int), sample_size=np.inf),
                                  lambda p: pv.validity_indices(p, np.zeros(len(p), int), sampled_separation='no'),
                                  lambda p: pv.validity_indices(p, np.full(len(p), 2**63 + 1, np.uint64))])
def test_invalid_tuning_and_index_arguments_raise_a_clear_error(call):
    points = scenes.corner(300, seed=0).points
    for seed in (np.random.SeedSequence(3), np.random.PCG64(3), [1, 2], np.int64(5)):  # what default_rng takes
        assert pv.detect_planes(points, 0.01, seed=seed).n_planes >= 1
    with pytest.raises(ValueError, match='seed|count|connectivity|max_planes|t_min|sample_size|sampled_separation|'
                                         'labels must fit'):
        call(scenes.corner(300, seed=0).points)


def test_a_min_inliers_given_as_a_0d_array_means_its_number():
    """A second outside probe: np.array(0.5) was taken as the count int(0.5), not as the fraction 0.5."""
    points = scenes.corner(600, noise=0.01, seed=0).points  # three faces of about a third each
    for value in (0.5, np.float32(0.5), np.array(0.5), Decimal('0.5'), Fraction(1, 2)):  # a Decimal was a count 0
        assert pv.detect_planes(points, 0.05, seed=0, min_inliers=value).n_planes == 0, value
    for value in (np.array(100), Decimal(100), 100.0):
        assert pv.detect_planes(points, 0.05, seed=0, min_inliers=value).n_planes == 3, value
    tuned = pv.tune_tolerance(points, seed=0, min_inliers=Decimal('0.5'))
    assert tuned.segmentation.n_planes == 0 and all(row.n_planes == 0 for row in tuned.rows)


def test_a_count_beyond_int64_is_a_count_and_beyond_float_a_clear_error():
    points = scenes.corner(300, noise=0.01, seed=0).points
    assert pv.detect_planes(points, 0.05, seed=0, min_inliers=10 ** 20).n_planes == 0  # was numpy's TypeError
    with pytest.raises(ValueError, match='min_inliers must be'):
        pv.detect_planes(points, 0.05, seed=0, min_inliers=10 ** 400)  # was OverflowError


def test_seed_reproducible_and_none_draws_entropy():
    scene = scenes.room(5000, 0.02, outlier_fraction=0.2, seed=9)
    a = pv.detect_planes(scene.points, 0.03, seed=42)
    b = pv.detect_planes(scene.points, 0.03, seed=42)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.coefficients, b.coefficients)
    # Without a seed runs differ in the order or the exact fit of the planes at least once.
    runs = [pv.detect_planes(scene.points, 0.03, seed=None) for _ in range(5)]
    assert any(not np.array_equal(r.coefficients, runs[0].coefficients) for r in runs[1:])


def test_float32_input_gives_same_planes():
    scene = scenes.corner(3000, 1.0, seed=8)
    a = pv.detect_planes(scene.points, 2.0, seed=0)
    b = pv.detect_planes(scene.points.astype(np.float32), 2.0, seed=0)
    assert a.n_planes == b.n_planes == 3
    np.testing.assert_allclose(a.coefficients, b.coefficients, atol=1e-3)


def test_large_cloud_uses_subset_scoring():
    scene = scenes.boxes(100_000, seed=1)
    seg = pv.detect_planes(scene.points, 0.02, seed=0)
    assert seg.n_planes == 5
    assert label_accuracy(seg, scene) > 0.97


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), quat=st.lists(st.floats(-1, 1), min_size=4, max_size=4),
       shift=st.lists(st.floats(-50, 50), min_size=3, max_size=3))
def test_rigid_transform_moves_planes_and_keeps_labels(seed, quat, shift):
    if np.linalg.norm(quat) < 1e-3:
        quat = [0, 0, 0, 1]
    rot = Rotation.from_quat(quat)
    rng = np.random.default_rng(seed)
    # two random, clearly separated planes of different sizes
    normals = Rotation.random(random_state=seed).as_matrix()[:2]
    pts = []
    for normal, n in zip(normals, (1200, 700)):
        basis = np.linalg.svd(normal[None])[2][1:]
        pts.append(rng.uniform(-1, 1, (n, 2)) @ basis + 0.3 * normal + rng.uniform(-1e-3, 1e-3, (n, 1)) * normal)
    points = np.concatenate(pts)
    tol = 5e-3
    before = pv.detect_planes(points, tol, seed=seed)
    moved = rot.apply(points) + shift
    after = pv.detect_planes(moved, tol, seed=seed, viewpoint=shift)  # the sensor moves with the cloud
    assert before.n_planes == after.n_planes == 2
    np.testing.assert_array_equal(before.labels, after.labels)
    for p, q in zip(before.planes, after.planes):
        n_expected = rot.apply(p.normal)
        sign = np.sign(n_expected @ q.normal)
        np.testing.assert_allclose(sign * q.normal, n_expected, atol=1e-6)
        # the moved plane passes through the moved inliers
        assert np.abs(moved[q.inliers] @ q.normal + q.offset).max() <= tol


def test_labels_are_the_nearest_plane_within_tolerance():
    scene = scenes.cube(8000, 2.5, outlier_fraction=0.05, seed=6)
    t = 5.0
    seg = pv.detect_planes(scene.points, t, seed=1, connectivity=False)
    dist = np.abs(scene.points @ seg.coefficients[:, :3].T + seg.coefficients[:, 3])  # (n, k)
    assigned = seg.labels >= 0
    own = dist[np.flatnonzero(assigned), seg.labels[assigned]]
    assert np.all(own <= t)
    np.testing.assert_allclose(own, dist[assigned].min(axis=1))
    assert np.all(dist[~assigned].min(axis=1) > t)
    for k, plane in enumerate(seg.planes):
        np.testing.assert_array_equal(plane.inliers, np.flatnonzero(seg.labels == k))
        assert plane.rms == pytest.approx(np.sqrt(np.mean(dist[plane.inliers, k] ** 2)))


def test_ransac_sample_finds_the_same_planes_as_all_points():
    scene = scenes.boxes(120_000, seed=3)
    full = pv.detect_planes(scene.points, 0.02, seed=0, ransac_points=None, connectivity=False)
    sampled = pv.detect_planes(scene.points, 0.02, seed=0, ransac_points=10_000, connectivity=False)
    assert full.n_planes == sampled.n_planes == 5
    mapping = match_planes(sampled.coefficients, full.coefficients)  # extraction order may differ
    assert sorted(mapping) == list(range(5))
    for k in range(5):
        angle, offset = same_plane(sampled.coefficients[mapping[k]], full.coefficients[k])
        assert angle < 0.2 and offset < 2e-3
    relabelled = np.where(sampled.labels >= 0, np.argsort(mapping)[np.maximum(sampled.labels, 0)], -1)
    assert np.mean(full.labels == relabelled) > 0.995
    assert label_accuracy(sampled, scene) > 0.97


@pytest.mark.parametrize('bad', [0, 2, 2.5, -5])
def test_bad_ransac_points_raise(bad):
    with pytest.raises(ValueError, match='ransac_points'):
        pv.detect_planes(np.random.default_rng(0).random((50, 3)), 0.1, ransac_points=bad)


def test_far_away_coordinates_keep_their_precision():
    scene = scenes.corner(3000, 0.0, seed=2)
    shift = np.array([4.5e6, 5.2e6, 120.0])  # UTM-like coordinates
    near = pv.detect_planes(scene.points, 0.05, seed=0)
    far = pv.detect_planes(scene.points + shift, 0.05, seed=0)
    np.testing.assert_array_equal(near.labels, far.labels)
    for a, b in zip(near.planes, far.planes):
        assert angle_deg(a.normal, b.normal) < 1e-4
        assert b.rms < 1e-6


def test_a_far_small_plane_keeps_its_precision():
    # 1 m corner at the origin and a tilted 1 m patch 100 km away, 1 um noise, t = 5 um.
    rng = np.random.default_rng(0)
    rot = Rotation.from_euler('xyz', [0.3, 0.7, 1.1]).as_matrix()
    patch = np.column_stack([rng.random((6000, 2)), np.zeros(6000)]) @ rot.T + [1e5, 0, 0]
    pts = np.vstack([scenes.corner(20000, 0.0, side=1.0, seed=0).points, patch])
    pts += rng.normal(0, 1e-6, pts.shape)
    seg = pv.detect_planes(pts, 5e-6, seed=0, min_inliers=1000)
    far = seg.labels[20000:]
    assert np.bincount(far[far >= 0]).max() >= 5990


def test_planes_below_min_inliers_after_labelling_are_dropped():
    scene = scenes.boxes(100_000, seed=1)
    seg = pv.detect_planes(scene.points, 0.02, seed=0, min_inliers=2000, ransac_points=100)
    assert seg.n_planes >= 3
    assert all(len(p.inliers) >= 2000 for p in seg.planes)
    np.testing.assert_array_equal(np.unique(seg.labels[seg.labels >= 0]), np.arange(seg.n_planes))


def test_a_plane_through_the_viewpoint_keeps_its_normal_from_frame_to_frame():
    # the ground in base_link passes through the frame's origin: which side of it the origin is on was
    # noise, and the normal flipped between frames (3 of 10 down); now its largest component is positive
    rng = np.random.default_rng(0)
    normals = []
    for frame in range(8):
        floor = np.column_stack([rng.uniform(-5, 5, 3000), rng.uniform(-5, 5, 3000), rng.normal(0, 0.01, 3000)])
        for connectivity in (True, False):
            normals.append(pv.detect_planes(floor, 0.03, seed=frame, connectivity=connectivity).planes[0].normal)
    assert all(n[2] > 0.99 for n in normals)
    lifted = pv.detect_planes(floor + [0.0, 0.0, -1.0], 0.03, seed=0).planes[0]  # the sensor 1 m above it
    assert lifted.normal[2] < -0.99 and lifted.offset < 0  # away from the viewpoint, as for every other plane
    # base_link at axle height, 6 cm above the ground: away from it whatever t (a band of t around the
    # viewpoint flipped it at t = 6 cm: which side is noise only within the plane's own noise)
    for t in (0.03, 0.05, 0.07, 0.09):
        assert pv.detect_planes(floor + [0.0, 0.0, -0.06], t, seed=0).planes[0].normal[2] < -0.99


def test_a_segmentation_of_a_proxy_is_carried_to_the_points_it_stands_for():
    from plane_validation.core.geometry import voxel_downsample
    from plane_validation.core.ransac import carried, within_planes
    points = scenes.cube(6000, 1.0, seed=4).points
    points[::97] = np.nan
    valid = points[np.isfinite(points).all(axis=1)]
    centroids, voxel = voxel_downsample(valid, 5.0)
    seg = pv.detect_planes(centroids, 2.0, seed=0)
    out = carried(seg, points, voxel)
    assert len(out.labels) == len(points) and out.n_valid == len(valid) and out.n_planes == seg.n_planes
    assert np.all(out.labels[::97] == -1)
    np.testing.assert_array_equal(out.labels[np.isfinite(points).all(axis=1)],
                                  within_planes(valid, seg.labels[voxel], seg))
    for k, (plane, proxy) in enumerate(zip(out.planes, seg.planes)):
        np.testing.assert_array_equal(plane.inliers, np.flatnonzero(out.labels == k))
        np.testing.assert_array_equal(plane.coefficients, proxy.coefficients)
        distance = plane.distance(points[plane.inliers])
        assert distance.max() <= 2.0 and plane.rms == pytest.approx(np.sqrt(np.mean(distance ** 2)))
    # a point farther than t from its voxel's plane is left out
    assert 0 < np.count_nonzero((seg.labels[voxel] >= 0) & (out.labels[np.isfinite(points).all(axis=1)] < 0))


@pytest.mark.parametrize('connectivity', [True, False])
def test_a_search_stopped_by_max_planes_says_so(connectivity):
    points = scenes.cube(6000, 1.0, seed=4).points
    assert pv.detect_planes(points, 2.0, max_planes=2, seed=0, connectivity=connectivity).capped
    assert not pv.detect_planes(points, 2.0, max_planes=10, seed=0, connectivity=connectivity).capped
    # six planes for six faces: too few points are left for a seventh, so nothing was left out
    exact = pv.detect_planes(points, 2.0, max_planes=6, seed=0, connectivity=connectivity)
    assert exact.n_planes == 6 and not exact.capped



@pytest.mark.parametrize('make', [lambda: scenes.room(30000, 0.005, outlier_fraction=0.2, seed=2),
                                  lambda: scenes.boxes(20000, seed=4)])
@pytest.mark.parametrize('connectivity', [False, True])
def test_prescoring_keeps_the_best_hypotheses(make, connectivity, monkeypatch):
    """Dropping hypotheses after PRESCORE points (their count there cannot reach the best few) gives the same planes
    as scoring every hypothesis on the whole subset, and (numpy's scoring, the infinite planes: counted here) scores
    fewer distances. The connected search scores compiled (test_kernels_search_loop checks it against numpy's)."""
    scene = make()
    distances = hypotheses.plane_distances
    runs = []
    for prescore in (hypotheses.PRESCORE, 10**9):
        scored = []

        def spy(cols, normals, offsets, scored=scored):
            scored.append(cols.shape[1] * len(normals) if cols.dtype == np.float32 else 0)
            return distances(cols, normals, offsets)
        monkeypatch.setattr(hypotheses, 'PRESCORE', prescore)
        monkeypatch.setattr(hypotheses, 'plane_distances', spy)
        seg = pv.detect_planes(scene.points, 0.02, seed=5, max_planes=8, connectivity=connectivity)
        runs.append((seg.labels, seg.coefficients, sum(scored)))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    if not connectivity:
        assert runs[0][2] < 0.8 * runs[1][2], (runs[0][2], runs[1][2])
