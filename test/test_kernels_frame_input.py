"""The frame's input pass and its hulls against their references: kernels.read_rows (``# --- frame input and
outlines ---``) against numpy's widening, no_returns_as_nan and valid rows, on random inputs; the pipeline reading a
PointCloud2 through it against reading the same points as an array; geometry.hull_vertices against ConvexHull."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull, QhullError

from plane_validation.app.frame_rows import valid_rows_numpy
from plane_validation.app.pipeline import FramePipeline, PipelineConfig
from plane_validation.core import geometry, kernels
from plane_validation.core.ransac import AT_VIEWPOINT, no_returns_as_nan
from plane_validation.core.scenes import depth_camera
from plane_validation.formats.pointcloud2 import create_cloud, pack_rgb, xyz_array, xyz_words

SETTINGS = settings(max_examples=60, deadline=None)


def _words(seed: int, n: int, width: int, view: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """n records of ``width`` float32 words with x, y, z at three random columns: random rows, some NaN, some with
    an inf coordinate, some at the origin, some within AT_VIEWPOINT of ``view`` and some just beyond it; the first row
    (if any) exactly at ``view``."""
    rng = np.random.default_rng(seed)
    words = rng.normal(scale=10, size=(n, width)).astype(np.float32)
    columns = rng.permutation(width)[:3].astype(np.int64)
    kind = rng.random(n)
    xyz = words[:, columns]
    xyz[kind < 0.1] = np.nan
    xyz[(kind >= 0.1) & (kind < 0.15), rng.integers(0, 3)] = rng.choice([np.inf, -np.inf])
    xyz[(kind >= 0.15) & (kind < 0.2)] = 0.0
    near = (kind >= 0.2) & (kind < 0.25)  # within half the reach: float32 rounding keeps them within it
    xyz[near] = view + rng.uniform(-0.5, 0.5, (int(near.sum()), 3)) * AT_VIEWPOINT
    xyz[(kind >= 0.25) & (kind < 0.3)] = view + 3 * AT_VIEWPOINT
    xyz[(kind >= 0.3) & (kind < 0.32), 1] = 0.0  # one coordinate at the mark only
    xyz[:1] = view  # at least one row at the mark, whatever the draw
    words[:, columns] = xyz
    return words, columns


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.integers(3, 6), st.booleans(), st.booleans())
def test_read_rows_matches_numpy(seed, n, width, marks, at_origin):
    view = np.zeros(3) if at_origin else np.array([0.5, -1.25, 2.0])
    words, columns = _words(seed, n, width, view)
    points, finite, valid, infinite, marked, largest = kernels.read_rows(words, columns, view, AT_VIEWPOINT,
                                                                          marks)

    wide = words[:, columns].astype(np.float64)
    ref_points, ref_marked = no_returns_as_nan(wide, view) if marks else (wide, 0)
    ref_finite, ref_valid, ref_infinite = valid_rows_numpy(ref_points)
    np.testing.assert_array_equal(points, ref_points)  # NaN in the same places
    np.testing.assert_array_equal(finite, ref_finite)
    np.testing.assert_array_equal(valid, ref_valid)
    assert (infinite, marked) == (ref_infinite, ref_marked)
    magnitudes = np.abs(ref_points[~np.isnan(ref_points)])  # inf counts, NaN does not
    if len(magnitudes):
        assert largest == magnitudes.max()
    else:
        assert np.isnan(largest)
    if marks and n:
        assert marked > 0  # the first row is at the mark


def _message(points: np.ndarray, shape: tuple[int, int]):
    import sensor_msgs.msg
    from std_msgs.msg import Header

    pts = points.astype(np.float32)
    zero = np.zeros(len(pts), np.uint8)
    return create_cloud(Header(frame_id='camera'), {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2],
                                                    'rgb': pack_rgb(zero, zero, zero)},
                        types=sensor_msgs.msg, shape=shape)


@pytest.mark.parametrize('extra, marks', [({}, 3), ({'viewpoint_x': 0.5}, 1), ({'zero_is_no_return': False}, 0)])
def test_a_message_read_in_one_pass_gives_the_frame_its_array_gives(extra, marks):
    pytest.importorskip('sensor_msgs.msg')
    scene = depth_camera('table', width=64, height=48, seed=0)
    points = scene.points.copy()
    points[5] = np.inf
    points[9, 1] = np.nan
    points[11:14] = 0.0  # the driver's "no return" mark
    points[20] = (0.5, 0.0, 0.0)
    msg = _message(points, scene.shape)
    assert xyz_words(msg) is not None  # the usual layout: read by the compiled pass
    config = PipelineConfig(auto_tune=False, tolerance=0.02, max_planes=4, **extra)
    got = FramePipeline(config).process_cloud(msg)
    want = FramePipeline(config).process(xyz_array(msg), 0, shape=scene.shape)
    assert got.n_planes == want.n_planes > 0
    for name in ('points', 'labels', 'organized', 'image_labels', 'obstacles'):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    timing = {'processing_ms'}
    assert [kv for kv in got.values if kv[0] not in timing] == [kv for kv in want.values if kv[0] not in timing]
    assert dict(got.values)['no_return_points'] == str(marks)


def test_layouts_the_pass_does_not_read_are_read_as_before():
    pytest.importorskip('sensor_msgs.msg')
    scene = depth_camera('table', width=32, height=24, seed=0)
    msg = _message(scene.points, scene.shape)
    msg.is_bigendian = True  # x, y, z no longer in this machine's byte order
    assert xyz_words(msg) is None
    config = PipelineConfig(auto_tune=False, tolerance=0.02)
    got = FramePipeline(config).process_cloud(msg)
    want = FramePipeline(config).process(xyz_array(msg), 0, shape=scene.shape)  # as its declared layout reads
    assert dict(got.values)['input_points'] == str(32 * 24)
    for name in ('points', 'labels'):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)


def _hull_points(seed: int, m: int, kind: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if kind == 0:
        return rng.normal(size=(m, 2))
    if kind == 1:  # a long thin strip
        return rng.random((m, 2)) * [30.0, 0.01]
    if kind == 2:  # on a coarse grid: repeated points and collinear runs on the hull
        return np.round(rng.random((m, 2)) * 6) / 6
    return np.outer(rng.random(m), [1.0, 2.0]) + 3.0  # collinear: Qhull refuses them


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(3, 400), st.integers(0, 3))
def test_hull_vertices_are_convex_hulls_vertices(seed, m, kind):
    points = _hull_points(seed, m, kind)
    try:
        want = ConvexHull(points).vertices
    except QhullError:
        with pytest.raises(QhullError):
            geometry.hull_vertices(points)
        return
    got = geometry.hull_vertices(points)
    np.testing.assert_array_equal(got, want)  # the same vertices from the same start, in the same order


def test_hull_vertices_use_the_wrapper_and_fall_back_to_convex_hull(monkeypatch):
    assert geometry._QHULL is not None  # this scipy's wrapper has what ConvexHull calls
    points = _hull_points(1, 200, 0)
    monkeypatch.setattr(geometry, '_QHULL', None)
    np.testing.assert_array_equal(geometry.hull_vertices(points), ConvexHull(points).vertices)
    with pytest.raises(ValueError):
        geometry.hull_vertices(np.full((5, 2), np.nan))


@SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 400), st.integers(0, 3), st.sampled_from([0.0, 1e-9, 1e-3]),
       st.booleans())
def test_outside_polygon_matches_numpy(seed, m, kind, margin, octagon):
    """The outlines' 8 directions, or a few random ones in any order (a polygon that need not be convex)."""
    local = np.ascontiguousarray(_hull_points(seed, m, kind).T)
    directions = geometry._DIRECTIONS if octagon else np.random.default_rng(seed).normal(size=(seed % 7 + 1, 2))
    np.testing.assert_array_equal(kernels.outside_polygon(local, directions, margin),
                                  geometry.outside_polygon_numpy(local, directions, margin))


@pytest.mark.parametrize('kind', range(4))
def test_hulls_of_the_points_outside_the_extremes_polygon_have_the_whole_sets_corners(kind, monkeypatch):
    """The outlines' hulls without the points inside the polygon of their extremes: the same corners from the same
    start, as Qhull gives them on every point (grids repeat points: the same coordinates, maybe another copy's index);
    and the filter does leave points out."""
    cases = [(seed, m) for seed in range(60) for m in (65, 300, 2056)]
    filtered = {}
    for seed, m in cases:
        local = np.ascontiguousarray(_hull_points(seed, m, kind).T)
        filtered[seed, m] = local[:, geometry._hull(local)], len(geometry._outer(local))
    monkeypatch.setattr(geometry, 'HULL_FILTER', 10**9)
    for seed, m in cases:
        local = np.ascontiguousarray(_hull_points(seed, m, kind).T)
        np.testing.assert_array_equal(filtered[seed, m][0], local[:, geometry._hull(local)])
    if kind == 0:  # a round blob: most points lie inside its extremes (a strip's or a line's need not)
        assert all(filtered[case][1] < case[1] // 2 for case in cases if case[1] == 2056)
