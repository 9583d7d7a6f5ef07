"""Coplanar regions that do not touch: one surface where nothing is seen through it between them."""
import numpy as np

import plane_validation as pv
from plane_validation.core import scene_families
from plane_validation.core.scoring import segmentation_quality
from plane_validation.core.search import connected


def _rect(rng, n, x, y, z):
    """n points spread over the box x, y (ranges) at height z, 2 mm noise."""
    return np.column_stack([rng.uniform(*x, n), rng.uniform(*y, n), z + rng.normal(0, 0.002, n)])


def _tables(floor_between: bool) -> np.ndarray:
    """Two 1.5 x 2 m table tops 1 m below a sensor at the origin, 1 m apart, over a floor 2 m below, seen where
    the tables leave it in view (between them only with ``floor_between``)."""
    rng = np.random.default_rng(3)
    parts = [_rect(rng, 6000, (-2.0, -0.5), (-1, 1), -1.0), _rect(rng, 6000, (0.5, 2.0), (-1, 1), -1.0),
             _rect(rng, 6000, (-4.0, 4.0), (2.2, 4.0), -2.0), _rect(rng, 6000, (-4.0, 4.0), (-4.0, -2.2), -2.0)]
    if floor_between:
        parts.append(_rect(rng, 1500, (-0.3, 0.3), (-1.5, 1.5), -2.0))
    return np.concatenate(parts)


def _table_labels(points: np.ndarray, seg) -> set:
    """The labels of the two table tops' points (z about -1)."""
    top = np.abs(points[:, 2] + 1.0) < 0.05
    return {int(v) for v in np.unique(seg.labels[top]) if v >= 0}


def test_coplanar_tables_with_the_floor_seen_between_them_stay_two_planes():
    points = _tables(floor_between=True)
    seg = pv.detect_planes(points, 0.01, seed=0, max_planes=10)
    left, right = points[:, 0] < 0, points[:, 0] > 0
    top = np.abs(points[:, 2] + 1.0) < 0.05
    assert len(_table_labels(points, seg)) == 2
    assert set(np.unique(seg.labels[top & left])) != set(np.unique(seg.labels[top & right]))


def test_coplanar_tables_with_nothing_seen_between_them_are_one_surface(monkeypatch):
    # the same tables with the floor between them out of sight: nothing shows that they are apart
    points = _tables(floor_between=False)
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
