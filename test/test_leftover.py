"""The leftover plane (core/leftover.py): a surface among the points no plane covers, and the verdict's test on it."""
from __future__ import annotations

import numpy as np
import pytest

import plane_validation as pv
from plane_validation.core import leftover, scenes
from plane_validation.core.failures import FailureKind
from plane_validation.core.leftover import leftover_plane
from plane_validation.core.verdict import LEFTOVER_SHARE, judge


def _room(max_planes: int):
    room = scenes.room(12000, 0.004, seed=0)
    seg = pv.detect_planes(room.points, 0.015, seed=0, max_planes=max_planes, min_inliers=100)
    return room.points, seg, judge(room.points, seg, pv.validity_indices(room.points, seg.labels, seed=0))


def test_a_wall_the_search_left_behind_fails_the_verdict():
    """A room whose search stopped at max_planes before its last faces: each plane found is sound, but a whole face
    lies among the points in no plane."""
    points, seg, verdict = _room(4)
    left = [f for f in verdict.failures if f.kind is FailureKind.LEFTOVER_PLANE]
    assert len(left) == 1 and left[0].value >= LEFTOVER_SHARE and left[0].limit == LEFTOVER_SHARE, verdict
    assert not verdict.reliable and 'the search did not find' in str(verdict)
    free = np.count_nonzero(seg.labels < 0) / seg.n_valid
    assert left[0].other == pytest.approx(free, abs=0.02)  # the sampled share of the points in no plane
    # the plane it found is one of the faces left: most of its points lie on one true plane the search did not take
    found = leftover_plane(points, seg)
    room = scenes.room(12000, 0.004, seed=0)
    on = np.abs(points @ found.normal + found.offset) <= seg.tolerance
    truth = room.labels[on & (seg.labels < 0)]
    assert np.bincount(truth[truth >= 0]).max() >= 0.9 * np.count_nonzero(on & (seg.labels < 0))


def test_the_same_room_with_every_face_found_passes():
    points, seg, verdict = _room(10)
    assert seg.n_planes == 6 and FailureKind.LEFTOVER_PLANE not in verdict.kinds, verdict
    assert leftover_plane(points, seg).share < LEFTOVER_SHARE / 4


def test_the_tails_of_a_planes_noise_are_not_a_plane_left_behind(monkeypatch):
    """Points just beyond t of a noisy plane (t = 1.5 sigma: 13 % of them) lie in no plane but on its surface: its
    cover of COVER t spares them, without which one side's tail would be a plane of the verdict's size."""
    rng = np.random.default_rng(3)
    sigma = 0.01
    points = np.column_stack([rng.uniform(0, 4, 20000), rng.uniform(0, 3, 20000), rng.normal(0, sigma, 20000)])
    seg = pv.detect_planes(points, 1.5 * sigma, seed=0, max_planes=1)
    assert np.count_nonzero(seg.labels < 0) > 0.1 * len(points)
    assert leftover_plane(points, seg).share < LEFTOVER_SHARE / 4
    monkeypatch.setattr(leftover, 'COVER', 0.0)
    assert leftover_plane(points, seg).share >= LEFTOVER_SHARE


def test_no_points_left_and_a_cloud_of_nan_rows_give_no_plane():
    points = np.full((50, 3), np.nan)
    seg = pv.detect_planes(points, 0.01, seed=0)
    out = leftover_plane(points, seg)
    assert out.share == 0.0 and out.free == 0.0 and np.isnan(out.offset)


def test_a_segmentation_of_other_points_is_refused():
    points, seg, _ = _room(10)
    with pytest.raises(ValueError, match='judge a segmentation with the points it was found on'):
        leftover_plane(points[:-1], seg)
