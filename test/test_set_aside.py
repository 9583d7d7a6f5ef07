"""A surface whose points within t hold no region because its noise scatters their normals does not end the search:
its largest connected piece becomes the plane, or it is set aside (sequential.SET_ASIDE, SCATTERED_AGREE)."""
import numpy as np
import pytest

import plane_validation as pv
from plane_validation.core.search import sequential

TILT = np.array([0.0, -0.9, -0.436]) / np.linalg.norm([0.0, -0.9, -0.436])


def _noisy_wall_and_near_patch(seed: int = 0, h: int = 120, w: int = 160):
    """An organized (h * w, 3) frame: a wall 4 m away with 5 cm depth noise (its normals scatter) and, nearer, a
    tilted patch of 17 % of the pixels with 1 mm noise; labels (h * w,) 0 wall, 1 patch."""
    rng = np.random.default_rng(seed)
    f = w / (2 * np.tan(np.radians(29)))
    v, u = np.mgrid[0:h, 0:w]
    rays = np.stack([(u - w / 2) / f, (v - h / 2) / f, np.ones((h, w))], -1).reshape(-1, 3)
    patch = (np.abs(rays[:, 0]) < 0.25) & (rays[:, 1] > 0.1)
    depth = np.where(patch, 1.5 * TILT[2] / (rays @ TILT), 4.0)
    depth = depth + rng.normal(0.0, 1.0, h * w) * np.where(patch, 0.001, 0.05)
    return rays * depth[:, None], patch.astype(int), (h, w)


def _shares(seg, labels):
    """(share of the patch in a plane whose normal is the patch's, share of the wall in its largest plane)."""
    out = []
    for g in (1, 0):
        got = seg.labels[labels == g]
        if not (got >= 0).any():
            out.append(0.0)
            continue
        plane = int(np.bincount(got[got >= 0]).argmax())
        out.append(float(np.mean(got == plane)))
        if g == 1:
            assert abs(seg.planes[plane].normal @ TILT) > 0.999
    return tuple(out)


@pytest.mark.parametrize('t', [0.08, 0.12])
def test_a_scattered_wall_becomes_a_plane_and_the_patch_before_it_is_found(t):
    points, labels, shape = _noisy_wall_and_near_patch()
    seg = pv.detect_planes(points, t, shape=shape, seed=0, max_planes=5, min_inliers=0.02)
    patch, wall = _shares(seg, labels)
    assert patch > 0.95 and wall > 0.85
    assert sum(abs(p.normal[2]) > 0.99 for p in seg.planes) == 1  # the wall is one plane, facing the camera


def test_a_scattered_wall_without_a_piece_of_min_inliers_is_set_aside(monkeypatch):
    points, labels, shape = _noisy_wall_and_near_patch()
    monkeypatch.setattr(sequential, '_joined', lambda *args: None)
    seg = pv.detect_planes(points, 0.08, shape=shape, seed=0, max_planes=5, min_inliers=0.02)
    patch, wall = _shares(seg, labels)
    assert patch > 0.95 and wall < 0.5
    assert 'set aside' in seg.reason


def test_without_setting_aside_the_search_stops_at_the_wall(monkeypatch):
    points, labels, shape = _noisy_wall_and_near_patch()
    monkeypatch.setattr(sequential, 'SET_ASIDE', 0)
    seg = pv.detect_planes(points, 0.08, shape=shape, seed=0, max_planes=5, min_inliers=0.02)
    assert (seg.labels[labels == 1] >= 0).mean() < 0.05
    assert 'set aside' not in seg.reason


def test_a_surface_whose_normals_agree_is_not_set_aside(monkeypatch):
    points, labels, shape = _noisy_wall_and_near_patch()
    monkeypatch.setattr(sequential, 'SCATTERED_AGREE', 0.0)  # as if every scattered wall's normals agreed
    seg = pv.detect_planes(points, 0.08, shape=shape, seed=0, max_planes=5, min_inliers=0.02)
    assert 'set aside' not in seg.reason and (seg.labels[labels == 1] >= 0).mean() < 0.05


def test_infinite_planes_never_set_aside():
    points, _, shape = _noisy_wall_and_near_patch()
    seg = pv.detect_planes(points, 0.08, shape=shape, seed=0, max_planes=5, min_inliers=0.02, connectivity=False)
    assert 'set aside' not in seg.reason


def test_setting_aside_stops_after_set_aside_times(monkeypatch):
    points, _, shape = _noisy_wall_and_near_patch()
    monkeypatch.setattr(sequential, '_joined', lambda *args: None)
    monkeypatch.setattr(sequential, 'SET_ASIDE', 1)
    seg = pv.detect_planes(points, 0.06, shape=shape, seed=0, max_planes=5, min_inliers=0.02)
    assert 'set aside 1 surface' in seg.reason


def _layered_wall(seed: int = 0, h: int = 120, w: int = 160, step: float = 0.07):
    """An organized (h * w, 3) frame of a wall 5 m away facing the camera, its depth with 8 cm noise in steps of
    ``step`` meters: layers of exactly equal depth, their normals scattered."""
    rng = np.random.default_rng(seed)
    f = w / (2 * np.tan(np.radians(29)))
    v, u = np.mgrid[0:h, 0:w]
    rays = np.stack([(u - w / 2) / f, (v - h / 2) / f, np.ones((h, w))], -1).reshape(-1, 3)
    depth = np.round((5.0 + rng.normal(0.0, 0.08, h * w)) / step) * step
    return rays * depth[:, None], (h, w)


def test_layers_of_a_stepped_depth_are_not_a_scattered_surface(monkeypatch):
    """At t below the depth step each layer lies exactly on a plane (no spread over the band within t): neither
    joined nor set aside, the search ends there."""
    points, shape = _layered_wall()
    seg = pv.detect_planes(points, 0.01, shape=shape, seed=0, max_planes=8, min_inliers=0.02)
    assert 'set aside' not in seg.reason and not seg.planes
    monkeypatch.setattr(sequential, 'SCATTERED_SPREAD', 0.0)
    seg = pv.detect_planes(points, 0.01, shape=shape, seed=0, max_planes=8, min_inliers=0.02)
    assert 'set aside' in seg.reason


def test_a_search_whose_regions_merged_goes_on_for_the_planes_it_had_no_room_for(monkeypatch):
    # a room whose far walls' noise (3 cm at 3.5 m) cuts them into pieces: the pieces take the max_planes, merge into
    # their walls afterwards, and the boxes in front were never searched
    from plane_validation.core import scene_families
    from plane_validation.core.scoring import segmentation_quality
    from plane_validation.core.search import connected
    scene = scene_families.indoor_depth(13)
    truth = scene.labels.astype(np.int64)

    def run():
        seg = pv.detect_planes(scene.points, 0.0087, seed=0, shape=scene.shape, noise_model='depth_quadratic',
                               max_planes=18, min_inliers=211)
        return seg, segmentation_quality(seg.labels, truth, points=scene.points, pred_planes=seg.coefficients)

    seg, quality = run()
    monkeypatch.setattr(connected, 'RESUME_ROUNDS', 0)
    stopped, before = run()
    assert stopped.reason.startswith('reached max_planes=18') and stopped.n_planes <= 6
    assert seg.n_planes > stopped.n_planes and seg.n_planes <= 18
    assert quality.correct >= before.correct + 3 and quality.f1 > before.f1
    assert 'merged' in seg.reason and not seg.reason.startswith('reached max_planes')
