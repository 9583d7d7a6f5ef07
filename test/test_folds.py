"""Regions holding the two sides of a shallow ridge are split at its line (core/search/folds.py)."""
import numpy as np
import pytest

import plane_validation as pv
from plane_validation.core.search.folds import split_folds


def _gable(seed: int, degrees: float = 2.0, noise: float = 0.02, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """A gable roof 8 x 10 m at 10 m height, its two faces meeting along y at x = 0; (points, side of each point)."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-4, 4, n), rng.uniform(-5, 5, n)
    z = 10 - np.tan(np.radians(degrees)) * np.abs(x) + rng.normal(0, noise, n)
    return np.column_stack([x, y, z]), (x > 0).astype(int)


@pytest.mark.parametrize('seed', range(4))
def test_a_shallow_gable_within_t_of_one_plane_comes_out_as_its_two_faces(seed):
    points, side = _gable(seed)
    seg = pv.detect_planes(points, 0.1, max_planes=4, min_inliers=50, seed=seed)
    assert seg.n_planes == 2 and 'split 1 region(s) at a ridge' in seg.reason
    for k in range(2):
        faces = np.bincount(side[seg.labels == k], minlength=2)
        assert faces.max() >= 0.9 * faces.sum()  # each plane on one face (near the ridge the noise hides the side)
    normals = seg.coefficients[:, :3]
    assert 3.0 < np.degrees(np.arccos(abs(normals[0] @ normals[1]))) < 5.0  # the faces are 4 degrees apart


def test_the_split_keeps_to_max_planes_and_infinite_planes_do_not_split():
    points, _ = _gable(0)
    assert pv.detect_planes(points, 0.1, max_planes=1, min_inliers=50, seed=0).n_planes == 1
    assert pv.detect_planes(points, 0.1, max_planes=4, min_inliers=50, seed=0, connectivity=False).n_planes == 1


@pytest.mark.parametrize('seed', range(4))
def test_a_flat_noisy_roof_is_not_split(seed):
    points, _ = _gable(seed, degrees=0.0)
    seg = pv.detect_planes(points, 0.1, max_planes=4, min_inliers=50, seed=seed)
    assert seg.n_planes == 1 and 'split' not in seg.reason


def _one_region(points: np.ndarray):
    search = np.ascontiguousarray((points - points.mean(axis=0)).T)
    return search, np.zeros(len(points), dtype=np.int64), [(np.array([0.0, 0.0, 1.0]), 0.0)]


def test_split_folds_splits_a_ridge_unless_a_side_is_too_small_or_its_plane_not_allowed():
    points, side = _gable(1)
    search, region, found = _one_region(points)
    got, planes = split_folds(search, region, found, 0.1, 4, 50)
    assert len(planes) == 2 and set(np.unique(got)) == {0, 1}
    assert max(np.mean(got[side == 0] == 0), np.mean(got[side == 0] == 1)) > 0.95
    assert region.max() == 0 and len(found) == 1  # the inputs are left as they were
    kept, same = split_folds(search, region, found, 0.1, 4, 1500)  # a side would hold fewer than min_count
    assert len(same) == 1 and np.array_equal(kept, region)
    level_only = lambda normals: np.abs(normals[:, 2]) > 0.99999  # noqa: E731 (no 2-degree face is level)
    kept, same = split_folds(search, region, found, 0.1, 4, 50, level_only)
    assert len(same) == 1 and np.array_equal(kept, region)
