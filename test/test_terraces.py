"""A shallow roof cut into slabs across its faces comes back as its faces (core/search/folds.py split_terraces), and
the ridge and tent tests judge a region on its points within t of its plane."""
import numpy as np
import pytest

import plane_validation as pv
from plane_validation.core.search import connected, folds
from plane_validation.core.search.fit import fit_columns


def _hip(seed: int, degrees: float, noise: float, n: int = 2500) -> tuple[np.ndarray, np.ndarray]:
    """A hip roof on a 12 x 8 m footprint, its four faces rising evenly from the eaves; (points (n, 3) m, the face of
    each point (n,))."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-6, 6, n), rng.uniform(-4, 4, n)
    edge = np.column_stack([y + 4, 4 - y, x + 6, 6 - x])  # distance to each eave
    z = np.tan(np.radians(degrees)) * edge.min(axis=1) + rng.normal(0, noise, n)
    return np.column_stack([x, y, z]), np.argmin(edge, axis=1)


def _purity(seg, truth: np.ndarray) -> float:
    """The smallest share of a plane's points on its main face (0 without planes)."""
    return min((np.bincount(truth[p.inliers]).max() / len(p.inliers) for p in seg.planes), default=0.0)


def _without_terraces(monkeypatch):
    monkeypatch.setattr(connected, 'split_terraces', lambda search, region, found, *args: (region, found, 0))


@pytest.mark.parametrize('seed', range(4))
def test_a_shallow_hip_cut_into_slabs_comes_out_as_its_four_faces(seed, monkeypatch):
    points, face = _hip(seed, 2.0, 0.03)
    # at 2.5 noise sigmas a level slab 2 t thick holds more of a 2-degree hip than any face
    seg = pv.detect_planes(points, 0.075, max_planes=8, min_inliers=50, seed=seed)
    assert seg.n_planes == 4 and _purity(seg, face) > 0.9
    assert 'cut across a fold or tent' in seg.reason
    _without_terraces(monkeypatch)
    before = pv.detect_planes(points, 0.075, max_planes=8, min_inliers=50, seed=seed)
    assert _purity(before, face) < 0.6  # slabs across the faces


def _search(points: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray((points - points.mean(axis=0)).T)


def test_split_terraces_gives_level_slabs_of_a_hip_its_faces_and_keeps_to_max_planes():
    points, face = _hip(0, 3.0, 0.03)
    search = _search(points)
    slab = np.digitize(search[2], np.quantile(search[2], [0.33, 0.67]))  # three level slabs across every face
    up = np.array([0.0, 0.0, 1.0])
    found = [(up, -float(np.mean(search[2, slab == k]))) for k in range(3)]
    region, planes, split = folds.split_terraces(search, slab, found, 0.1, 8, 50)
    assert split == 1 and len(planes) == 4
    for k in range(4):  # each label on one face, with a plane tilted 3 degrees
        assert np.bincount(face[region == k]).max() > 0.9 * np.count_nonzero(region == k)
        assert 2.5 < np.degrees(np.arccos(abs(planes[k][0][2]))) < 3.5
    assert len(found) == 3 and slab.max() == 2  # the inputs are left as they were
    kept, same, split = folds.split_terraces(search, slab, found, 0.1, 3, 50)  # four faces would exceed max_planes
    assert split == 0 and len(same) == 3 and np.array_equal(kept, slab)


def test_two_level_surfaces_side_by_side_and_a_steep_roof_are_left_as_they_were(monkeypatch):
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-5, 5, 3000), rng.uniform(-4, 4, 3000)
    step = np.column_stack([x, y, np.where(x > 0, 0.12, 0.0) + rng.normal(0, 0.02, 3000)])  # 2.4 t apart
    steep, _ = _hip(1, 25.0, 0.03)
    for points, t in ((step, 0.05), (steep, 0.08)):
        seg = pv.detect_planes(points, t, max_planes=8, min_inliers=50, seed=0)
        assert 'cut across' not in seg.reason
        with monkeypatch.context() as m:
            _without_terraces(m)
            same = pv.detect_planes(points, t, max_planes=8, min_inliers=50, seed=0)
        assert np.array_equal(seg.labels, same.labels)
    search = _search(step)
    side = (step[:, 0] > 0).astype(np.int64)
    found = [(np.array([0.0, 0.0, 1.0]), -float(np.mean(search[2, side == k]))) for k in range(2)]
    region, planes, split = folds.split_terraces(search, side, found, 0.05, 8, 50)
    assert split == 0 and np.array_equal(region, side)  # no ridge or tent explains a step


def test_a_shallow_gable_found_as_its_two_faces_is_left_as_it_was(monkeypatch):
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-4, 4, 2000), rng.uniform(-5, 5, 2000)
    points = np.column_stack([x, y, -np.tan(np.radians(3.0)) * np.abs(x) + rng.normal(0, 0.02, 2000)])
    search = _search(points)
    side = (x > 0).astype(np.int64)
    found = [fit_columns(np.ascontiguousarray(search[:, side == k])) for k in range(2)]
    assert folds._terrace_groups(search, side, found, 0.1, 100) == [[0, 1]]  # one group of terraces
    region, planes, split = folds.split_terraces(search, side, found, 0.1, 8, 50)
    assert split == 0 and np.array_equal(region, side) and planes == found
    monkeypatch.setattr(folds, '_same_regions', lambda *args: False)  # the ridge's sides, found again
    region, planes, split = folds.split_terraces(search, side, found, 0.1, 8, 50)
    assert split == 1 and not np.array_equal(region, side)


def test_a_clutter_blob_within_t_of_a_merged_hip_does_not_stop_its_tent_split(monkeypatch):
    points, face = _hip(2, 3.0, 0.035)
    rng = np.random.default_rng(2)
    blob = np.array([1.0, 1.0, 0.4]) + rng.normal(0, 0.2, (80, 3))  # a chimney-sized blob above the roof
    cloud = np.vstack([points, blob])
    seg = pv.detect_planes(cloud, 0.17, max_planes=8, min_inliers=40, seed=0)  # one region holds the whole roof
    assert 'tent into its faces' in seg.reason
    assert _purity(seg, np.concatenate([face, np.full(len(blob), 4)])) > 0.9
    monkeypatch.setattr(folds, '_within', lambda search, rows, *args: rows)  # the region's points as searched
    before = pv.detect_planes(cloud, 0.17, max_planes=8, min_inliers=40, seed=0)
    assert 'tent into its faces' not in before.reason
