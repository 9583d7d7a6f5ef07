"""Coplanar regions that do not touch: one surface where nothing is seen through it between them."""
import numpy as np

import plane_validation as pv
from plane_validation.core import scene_families
from plane_validation.core.scoring import segmentation_quality
from plane_validation.core.search import connected, occluded


def _rect(rng, n, x, y, z):
    """n points spread over the box x, y (ranges) at height z, 2 mm noise."""
    return np.column_stack([rng.uniform(*x, n), rng.uniform(*y, n), z + rng.normal(0, 0.002, n)])


def _tables(between: str) -> np.ndarray:
    """Two 1.5 x 2 m table tops 1 m below a sensor at the origin, 1 m apart, over a floor 2 m below, seen where
    the tables leave it in view; between the tables: the floor (``between='floor'``), a plank half way up that
    hides that part of the floor and of the tables' plane (``'plank'``) or nothing, as if cropped (``'nothing'``)."""
    rng = np.random.default_rng(3)
    parts = [_rect(rng, 6000, (-2.0, -0.5), (-1, 1), -1.0), _rect(rng, 6000, (0.5, 2.0), (-1, 1), -1.0),
             _rect(rng, 6000, (-4.0, 4.0), (2.2, 4.0), -2.0), _rect(rng, 6000, (-4.0, 4.0), (-4.0, -2.2), -2.0)]
    if between == 'floor':
        parts.append(_rect(rng, 1500, (-0.3, 0.3), (-1.5, 1.5), -2.0))
    elif between == 'plank':
        parts.append(_rect(rng, 1500, (-0.3, 0.3), (-0.6, 0.6), -0.5))
    return np.concatenate(parts)


def _table_labels(points: np.ndarray, seg) -> set:
    """The labels of the two table tops' points (z about -1)."""
    top = np.abs(points[:, 2] + 1.0) < 0.05
    return {int(v) for v in np.unique(seg.labels[top]) if v >= 0}


def test_coplanar_tables_with_the_floor_seen_between_them_stay_two_planes():
    points = _tables('floor')
    seg = pv.detect_planes(points, 0.01, seed=0, max_planes=10)
    assert len(_table_labels(points, seg)) == 2


def test_coplanar_tables_with_nothing_to_tell_what_lies_between_them_stay_two_planes():
    # nothing seen there, nothing hiding it, in the sensor's view: a cropped cloud tells nothing
    points = _tables('nothing')
    seg = pv.detect_planes(points, 0.01, seed=0, max_planes=10)
    assert len(_table_labels(points, seg)) == 2


def test_coplanar_tables_whose_gap_something_before_them_hides_are_one_surface(monkeypatch):
    points = _tables('plank')
    seg = pv.detect_planes(points, 0.01, seed=0, max_planes=10)
    assert len(_table_labels(points, seg)) == 1
    monkeypatch.setattr(connected, 'merge_occluded', lambda search, region, found, *args: (region, found))
    seg = pv.detect_planes(points, 0.01, seed=0, max_planes=10)
    assert len(_table_labels(points, seg)) == 2  # the merge is what joins them


def test_a_lidar_corridor_floor_cut_by_the_walls_that_hide_it_is_one_plane():
    # a spinning lidar sees the floor ahead of and behind it, never beside it under the near walls
    scene = scene_families.lidar_scan(3)
    seg = pv.detect_planes(scene.points, 0.026, seed=0, shape=scene.shape, max_planes=14,
                           min_inliers=max(5, int(0.01 * len(scene.points))))
    floor = scene.labels == int(np.argmax(scene.planes[:, 2]))  # the true plane facing up
    values, counts = np.unique(seg.labels[floor], return_counts=True)
    assert counts[values >= 0].max() >= 0.95 * np.count_nonzero(floor)
    assert segmentation_quality(seg.labels, scene.labels).correct >= 5


def test_the_corridor_floor_is_one_plane_also_with_a_tolerance_growing_with_range():
    # the tolerance at the regions' far points (meters at 10 m) must not read as the sensor lying on the plane
    scene = scene_families.lidar_scan(3)
    seg = pv.detect_planes(scene.points, 0.001, seed=0, shape=scene.shape, max_planes=14, noise_model='depth_quadratic',
                           min_inliers=max(5, int(0.01 * len(scene.points))))
    floor = scene.labels == int(np.argmax(scene.planes[:, 2]))
    values, counts = np.unique(seg.labels[floor], return_counts=True)
    assert counts[values >= 0].max() >= 0.9 * np.count_nonzero(floor)


def test_a_large_tolerance_at_far_points_does_not_read_as_the_sensor_on_the_plane():
    rng = np.random.default_rng(5)
    a, b = _rect(rng, 3000, (1.0, 3.0), (-1, 1), -1.0), _rect(rng, 3000, (-3.0, -1.0), (-1, 1), -1.0)
    plank = _rect(rng, 1500, (-0.5, 0.5), (-0.5, 0.5), -0.5)  # hides the floor between a and b from the origin
    search = np.ascontiguousarray(np.concatenate([a, b, plank]).T)
    region = np.repeat([0, 1, -1], [3000, 3000, 1500])
    tolerance = np.full(7500, 0.01)
    tolerance[:5] = 2.0  # a range-grown t at a few far points: beyond the sensor's 1 m from the plane
    found = [(np.array([0.0, 0.0, 1.0]), 1.0)] * 2
    merged, planes = occluded.merge_occluded(search, region.copy(), found, tolerance, np.zeros(3), 0.95, 1.5)
    assert len(planes) == 1 and (merged[:6000] == 0).all()


def test_a_far_floor_between_a_lidars_rings_is_out_of_its_view():
    # the floor ahead of and behind a spinning lidar, seen at a t of two sigmas: far out, its rings are strips metres
    # apart, and between them no ray points at the floor; that gap is not missing floor but unseen
    scene = scene_families.lidar_scan(15)
    assert scene.name.startswith('lidar_scan_corridor')
    seg = pv.detect_planes(scene.points, 0.0383, seed=0, max_planes=17, min_inliers=160)
    floor = scene.labels == int(np.argmax(np.abs(scene.planes[:, 2])))  # the true plane facing up
    values, counts = np.unique(seg.labels[floor], return_counts=True)
    assert counts[values >= 0].max() >= 0.95 * np.count_nonzero(floor)
    view = occluded._view(np.array([[5.0, 5.0], [0.0, 0.0], [0.0, -1.0]]), np.zeros(3))  # rays at 0 and -11.3 deg
    unseen = occluded._unseen(np.radians([0.0, -5.0, -11.3, -40.0]), np.radians([0.5, 0.5, 0.5, 0.5]), view)
    assert unseen.tolist() == [False, True, False, True]


def test_the_median_test_is_numpys_on_any_values():
    rng = np.random.default_rng(5)
    cases = [np.array([]), np.array([0.0]), np.array([-1.0, 1.0]), np.array([-1.0, 2.0]), np.array([-2.0, 1.0]),
             np.array([np.nan, -1.0, -2.0]), np.array([-0.0, 0.0]), np.array([-5e-324, 5e-324]),
             np.array([5e-324, 5e-324, -5e-324, 0.0])]
    cases += [rng.normal(size=int(rng.integers(1, 130))).round(int(rng.integers(0, 3))) for _ in range(500)]
    for values in cases:
        with np.errstate(invalid='ignore'):
            want = bool(np.median(values) <= 0) if len(values) else False
        assert occluded._median_at_most_zero(values) == want, values
