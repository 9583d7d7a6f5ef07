"""Points near a shallow fold settled on their side of it, and shallow hip roofs split into their faces
(core/search/folds.py settle_folds, core/search/tents.py)."""
import numpy as np
import pytest

import plane_validation as pv
from plane_validation.core.search import connected, folds
from plane_validation.core.search.fit import fit_columns
from plane_validation.core.search.graph import search_graph
from plane_validation.core.search.tents import tent_faces


def _gable(seed: int, degrees: float, noise: float, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """A gable roof 8 x 10 m, its ridge along y at x = 0; (points (n, 3) m, the face of each point (n,))."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-4, 4, n), rng.uniform(-5, 5, n)
    z = 10 - np.tan(np.radians(degrees)) * np.abs(x) + rng.normal(0, noise, n)
    return np.column_stack([x, y, z]), (x > 0).astype(int)


def _hip(seed: int, degrees: float, noise: float, n: int = 2500) -> tuple[np.ndarray, np.ndarray]:
    """A hip roof on a 12 x 8 m footprint, its four faces rising evenly from the eaves; (points, face (n,): 0/1 the
    long sides at y < 0 / y > 0, 2/3 the ends at x < 0 / x > 0)."""
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-6, 6, n), rng.uniform(-4, 4, n)
    edge = np.column_stack([y + 4, 4 - y, x + 6, 6 - x])  # distance to each eave
    z = np.tan(np.radians(degrees)) * edge.min(axis=1) + rng.normal(0, noise, n)
    return np.column_stack([x, y, z]), np.argmin(edge, axis=1)


def _purity(labels: np.ndarray, truth: np.ndarray, k: int) -> float:
    """The smallest share of a plane's points on its main face, over the ``k`` planes."""
    return min(np.bincount(truth[labels == j]).max() / np.count_nonzero(labels == j) for j in range(k))


def _without_settling(monkeypatch):
    monkeypatch.setattr(connected, 'settle_folds', lambda search, region, found, *args: (region, found))


@pytest.mark.parametrize('seed', range(3))
def test_the_band_along_a_shallow_ridge_goes_to_the_side_each_point_lies_on(seed, monkeypatch):
    points, face = _gable(seed, 6.0, 0.03)
    seg = pv.detect_planes(points, 0.065, max_planes=4, min_inliers=50, seed=seed)  # each face found by RANSAC
    assert seg.n_planes == 2 and 'ridge' not in seg.reason
    assert _purity(seg.labels, face, 2) > 0.99
    _without_settling(monkeypatch)  # the nearer plane, which the noise picks within 0.3 m of the ridge
    before = pv.detect_planes(points, 0.065, max_planes=4, min_inliers=50, seed=seed)
    assert before.n_planes == 2 and _purity(before.labels, face, 2) < 0.975


def test_settle_folds_moves_the_band_and_refits_both_planes():
    points, face = _gable(0, 6.0, 0.03)
    search = np.ascontiguousarray((points - points.mean(axis=0)).T)
    graph = search_graph(points, ransac_points=None)
    assert np.array_equal(graph.search_idx, np.arange(len(points)))
    planes = [fit_columns(np.ascontiguousarray(search[:, face == k])) for k in (0, 1)]
    distance = np.abs(np.array([n @ search + d for n, d in planes]))
    nearer = np.argmin(distance, axis=0)  # the band split by the noise
    region, found = folds.settle_folds(search, nearer, planes, 0.065, graph.neighbours)
    assert np.mean(nearer != face) > 0.015 and np.mean(region != face) < 0.005
    for k in (0, 1):  # each plane refitted to its points
        normal, offset = fit_columns(np.ascontiguousarray(search[:, region == k]))
        assert np.allclose(abs(normal @ found[k][0]), 1.0) and abs(abs(offset) - abs(found[k][1])) < 1e-9
    assert np.array_equal(nearer, np.argmin(distance, axis=0))  # the input left as it was


def test_two_pieces_of_one_plane_and_a_steep_corner_are_no_fold():
    rng = np.random.default_rng(0)
    flat = np.column_stack([rng.uniform(-4, 4, 2000), rng.uniform(-5, 5, 2000), rng.normal(0, 0.03, 2000)])
    search = np.ascontiguousarray(flat.T)
    half = (flat[:, 0] > 0).astype(np.int64)
    planes = [fit_columns(np.ascontiguousarray(search[:, half == k])) for k in (0, 1)]
    contact = np.flatnonzero(np.abs(flat[:, 0]) < 0.2)
    a, b = np.flatnonzero(half == 0), np.flatnonzero(half == 1)
    assert folds._fold_moves(search, a, b, planes[0], planes[1], 0.08, contact) is None
    tilted = [planes[0], (np.array([np.sin(0.6), 0.0, np.cos(0.6)]), 0.0)]  # 34 degrees: border settling's
    assert folds._fold_moves(search, a, b, tilted[0], tilted[1], 0.08, contact) is None


@pytest.mark.parametrize('seed', range(3))
def test_a_shallow_hip_roof_within_t_of_one_plane_comes_out_as_its_four_faces(seed, monkeypatch):
    points, face = _hip(seed, 3.0, 0.02)
    seg = pv.detect_planes(points, 0.15, max_planes=8, min_inliers=50, seed=seed)
    assert seg.n_planes == 4 and 'tent' in seg.reason
    assert _purity(seg.labels, face, 4) > 0.9
    monkeypatch.setattr(folds, 'tent_faces', lambda *args: None)  # without the faces: one plane, or a fold
    assert pv.detect_planes(points, 0.15, max_planes=8, min_inliers=50, seed=seed).n_planes < 4


def test_a_flat_or_gently_curved_roof_is_no_tent():
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-6, 6, 2500), rng.uniform(-4, 4, 2500)
    flat = np.column_stack([x, y, rng.normal(0, 0.02, 2500)])
    dome = np.column_stack([x, y, -0.01 * (x ** 2 + y ** 2) + rng.normal(0, 0.02, 2500)])
    for points in (flat, dome):
        seg = pv.detect_planes(points, 0.3, max_planes=8, min_inliers=50, seed=0)
        assert 'tent' not in seg.reason


def test_tent_faces_refuse_too_few_points_or_a_normal_not_allowed():
    from plane_validation.core import plane_shape
    points, face = _hip(0, 3.0, 0.02)
    cols = np.ascontiguousarray((points - points.mean(axis=0)).T)
    pca = plane_shape.principal_frame(np.ascontiguousarray(cols.T[plane_shape.sample_rows(np.arange(cols.shape[1]))]))
    local = plane_shape.patch_noise(pca, 0.15)
    got = tent_faces(cols, pca, local, 50)
    assert got is not None and len(got[1]) == 4
    assert np.mean(got[0] == np.array([np.bincount(got[0][face == k]).argmax() for k in range(4)])[face]) > 0.95
    assert tent_faces(cols, pca, local, 1000) is None  # no face holds 1,000 of the 2,500 points
    level_only = lambda normals: np.abs(normals[:, 2]) > 0.99999  # noqa: E731 (no 3-degree face is level)
    assert tent_faces(cols, pca, local, 50, level_only) is None
