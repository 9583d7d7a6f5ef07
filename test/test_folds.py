"""Regions holding the two sides of a shallow ridge are split at its line (core/search/folds.py)."""
import numpy as np
import pytest

import plane_validation as pv
from plane_validation.core.search.folds import split_folds


def _gable(seed: int, degrees: float = 2.0, noise: float = 0.02, n: int = 2000, ridge: float = 0.0
           ) -> tuple[np.ndarray, np.ndarray]:
    """A gable roof 8 x 10 m at 10 m height, its two faces meeting along y at x = ``ridge`` (m); (points, side of
    each point)."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-4, 4, n), rng.uniform(-5, 5, n)
    z = 10 - np.tan(np.radians(degrees)) * np.abs(x - ridge) + rng.normal(0, noise, n)
    return np.column_stack([x, y, z]), (x > ridge).astype(int)


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
    points, side = _gable(1, ridge=1.0)  # sides of about 1,250 and 750 points
    search, region, found = _one_region(points)
    got, planes, _ = split_folds(search, region, found, 0.1, 4, 50)
    assert len(planes) == 2 and set(np.unique(got)) == {0, 1}
    for j, (normal, offset) in enumerate(planes):  # each label goes with its own plane
        assert np.sqrt(np.mean((normal @ search[:, got == j] + offset) ** 2)) < 0.03
        assert np.bincount(side[got == j], minlength=2).max() > 0.9 * np.count_nonzero(got == j)
    assert region.max() == 0 and len(found) == 1  # the inputs are left as they were
    kept, same, _ = split_folds(search, region, found, 0.1, 4, 800)  # the smaller side would keep under 800
    assert len(same) == 1 and np.array_equal(kept, region)
    level_only = lambda normals: np.abs(normals[:, 2]) > 0.99999  # noqa: E731 (no 2-degree face is level)
    kept, same, _ = split_folds(search, region, found, 0.1, 4, 50, level_only)
    assert len(same) == 1 and np.array_equal(kept, region)
    kept, same, _ = split_folds(search, region, found, 0.1, 1, 50)  # at max_planes already
    assert len(same) == 1 and np.array_equal(kept, region)


def _tilts(seg, points: np.ndarray, side: np.ndarray) -> list[tuple[int, float, float]]:
    """Per plane: the face most of its points lie on, its slope dz/dx and the RMS distance (m) of its points."""
    out = []
    for plane in seg.planes:
        face = int(np.bincount(side[plane.inliers], minlength=2).argmax())
        distance = points[plane.inliers] @ plane.normal + plane.offset
        out.append((face, -plane.normal[0] / plane.normal[2], float(np.sqrt(np.mean(distance ** 2)))))
    return out


@pytest.mark.parametrize('seed', range(3))
def test_each_face_gets_its_own_plane(seed):
    points, side = _gable(seed)
    seg = pv.detect_planes(points, 0.1, max_planes=4, min_inliers=50, seed=seed)
    tilts = _tilts(seg, points, side)
    assert sorted(face for face, _, _ in tilts) == [0, 1]
    slope = np.tan(np.radians(2.0))
    for face, dz_dx, rms in tilts:  # face 1 (x > 0) falls with x, face 0 rises
        assert abs(dz_dx - (-slope if face else slope)) < 0.2 * slope
        assert rms < 0.03  # its points lie on it, within the noise (0.02 m)


def test_a_ridge_near_the_edge_or_a_curved_trough_is_not_split():
    rng = np.random.default_rng(5)
    x, y = rng.uniform(-4, 4, 2000), rng.uniform(-5, 5, 2000)
    lip = np.column_stack([x, y, 10 - 0.06 * np.abs(x - 3.2) + rng.normal(0, 0.02, 2000)])  # 10 % beyond the ridge
    trough = np.column_stack([x, y, 10 + 0.012 * x ** 2 + rng.normal(0, 0.02, 2000)])  # a quadric, no V
    for points in (lip, trough):
        seg = pv.detect_planes(points, 0.15, max_planes=4, min_inliers=50, seed=0)
        assert 'ridge' not in seg.reason


def test_under_depth_quadratic_each_region_is_judged_at_its_own_range():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-0.5, 0.5, 1500), rng.uniform(-0.6, 0.6, 1500)
    gable = np.column_stack([x, y, 1.0 + np.tan(np.radians(2.0)) * np.abs(x) + rng.normal(0, 0.001, 1500)])
    wall = np.column_stack([rng.uniform(-2, 2, 3000), rng.uniform(-2, 2, 3000), 4.0 + rng.normal(0, 0.005, 3000)])
    points = np.concatenate([gable, wall])  # the gable 1 m from the sensor, nearer than most points
    seg = pv.detect_planes(points, 0.01, max_planes=6, min_inliers=100, seed=0, noise_model='depth_quadratic')
    on_gable = [p for p in seg.planes if np.mean(p.inliers < 1500) > 0.9]
    assert len(on_gable) == 2 and 'split 1 region(s) at a ridge' in seg.reason
    assert {int(np.sign(np.median(x[p.inliers]))) for p in on_gable} == {-1, 1}
