"""The per-frame pipeline shared by node and replay, without ROS: robustness and tuning set-up."""
import dataclasses
import re
import threading

import numpy as np
import pytest

from plane_validation import scenes
from plane_validation.app.pipeline import ERROR, OK, RETRY_AFTER_S, WARN, FramePipeline, PipelineConfig
from plane_validation.core.geometry import voxel_downsample

FIXED = PipelineConfig(auto_tune=False, tolerance=0.01, seed=1)


def corner(noise_cm: float = 0.5, n: int = 3000, seed: int = 1) -> np.ndarray:
    return scenes.corner(n, noise_cm, scale=0.01, seed=seed).points


@pytest.mark.parametrize('points, level, words', [
    (np.full((100, 3), np.nan), WARN, 'too few'),
    # three points do make a plane, but no evidence of one
    (np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]]), WARN, '1 plane(s) but plane 0 rests on 3 points'),
    (np.array([[1.0, 1, 1], [1, 1, 1], [2, 2, 2]]), WARN, 'collinear'),
    (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), WARN, 'too few valid points: 2'),  # (0, 0, 0): no return
    (np.zeros((500, 3)), WARN, 'too few valid points: 0 of 500 (need 3); 500 were left out as a driver'),
    (np.ones((10, 2)), ERROR, 'bad input'),
    (np.array([['a', 'b', 'c']]), ERROR, 'bad input'),
])
@pytest.mark.parametrize('auto', [False, True])
def test_bad_frames_give_a_result_not_an_exception(points, level, words, auto):
    pipe = FramePipeline(PipelineConfig(auto_tune=auto, tolerance=0.01))
    result = pipe.process(points, 0)
    assert result.level == level, result.message
    assert words in result.message


def test_a_bad_stamp_or_shape_is_bad_input_and_a_whole_float_stamp_is_a_stamp():
    """An outside probe: stamp_ns=1.5e9 raised TypeError, and shape=(-50, -60) (whose product is N) was reported as
    a numerical failure."""
    pts = corner()  # 3000 points
    floated = FramePipeline(FIXED).process(pts, 1.5e9)
    assert floated.level == OK, floated.message
    np.testing.assert_array_equal(floated.labels, FramePipeline(FIXED).process(pts, 1_500_000_000).labels)  # its seed
    assert FramePipeline(FIXED).process(pts, 2**63 - 1).level == OK  # int64's largest (np.isfinite refuses 2**70)
    for stamp in (2**63, 10**400, -2**63 - 1):  # 10**400 raised OverflowError (an outside review)
        result = FramePipeline(FIXED).process(pts, stamp)
        assert result.level == ERROR and result.message.startswith('bad input: stamp_ns must fit in 64 bits')
    for stamp in (1.5, np.nan, '1', None, True):
        result = FramePipeline(FIXED).process(pts, stamp)
        assert result.level == ERROR and result.message == f'bad input: stamp_ns must be an integer, got {stamp!r}'
    for shape in ((-50, -60), (50.5, 60), (1, 2, 3), 'ab'):
        result = FramePipeline(FIXED).process(pts, 0, shape=shape)
        assert result.level == ERROR and result.message.startswith('bad input: shape must be (H, W), two integers')


@pytest.mark.parametrize('auto, inline', [(False, True), (True, True), (True, False)])
def test_huge_coordinates_are_an_error_not_an_exception(auto, inline):
    pipe = FramePipeline(PipelineConfig(auto_tune=auto, tolerance=0.01))
    result = pipe.process(corner() * 1e200, 0, tune_inline=inline)  # the node's first frame: a quick estimate
    assert result.level == ERROR
    assert 'numerical failure' in result.message and 'a coordinate reaches 1e+200 m: beyond' in result.message
    # below MAX_COORDINATE but beyond what the float32 scoring holds: was WARN "no plane found" (an outside probe)
    result = FramePipeline(PipelineConfig(auto_tune=auto, tolerance=0.01)).process(corner() * 1e45, 0,
                                                                                   tune_inline=inline)
    assert result.level == ERROR and 'numerical failure' in result.message
    assert 'spread over' in result.message and 'beyond 1e+30 m' in result.message


def test_planes_on_a_handful_of_voxels_are_not_reliable():
    """A voxel grid coarser than the scene leaves a few centroids: a 'plane' through them is no evidence."""
    room = scenes.room(20000, 0.01, seed=1).points
    result = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.05, voxel_size=10.0)).process(room, 0)
    assert result.level == WARN and 'too few to tell a plane from chance' in result.message, result.message


def test_one_far_outlier_does_not_hide_the_planes():
    pts = corner()
    pts[0] = np.finfo(np.float32).max  # some drivers write FLT_MAX instead of NaN
    result = FramePipeline(FIXED).process(pts, 0)
    assert result.n_planes == 3, result.message


def test_integer_input_and_a_single_plane_work():
    plane = np.column_stack([np.arange(400) % 20, np.arange(400) // 20, np.zeros(400, int)])
    result = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.1)).process(plane, 0)
    assert result.level == OK and result.n_planes == 1


def test_voxel_grid_reports_counts_in_input_points():
    pts = corner(0.2, n=20000)
    result = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.01, voxel_size=0.03)).process(pts, 0)
    assert result.n_planes == 3
    assert len(result.labels) == len(pts)
    assert sum(result.plane_counts) == int(np.sum(result.labels >= 0))
    values = dict(result.values)
    assert int(values['plane_0_inliers']) == result.plane_counts[0]
    assert len(result.segmentation.planes[0].inliers) < result.plane_counts[0]  # detection ran on voxels


def test_with_a_voxel_grid_each_labelled_point_lies_within_t_of_its_plane():
    # a point took its voxel's label even 2 t from the plane (a voxel's points spread about its diagonal)
    pts = corner(0.5, n=20000)
    t = 0.01
    result = FramePipeline(PipelineConfig(auto_tune=False, tolerance=t, voxel_size=0.05)).process(pts, 0)
    labelled = result.labels >= 0
    plane = result.segmentation.coefficients[result.labels[labelled]]
    distance = np.abs(np.einsum('ij,ij->i', result.points[labelled], plane[:, :3]) + plane[:, 3])
    assert result.n_planes == 3 and distance.max() <= t and labelled.mean() > 0.6
    assert int(dict(result.values)['unassigned_points']) == int(np.sum(~labelled))


def test_voxel_downsample_centroids():
    pts = np.array([[0.01, 0.01, 0.01], [0.03, 0.03, 0.03], [0.26, 0.0, 0.0]])
    centroids, inverse = voxel_downsample(pts, 0.1)
    assert len(centroids) == 2
    np.testing.assert_allclose(centroids[inverse[0]], [0.02, 0.02, 0.02])
    assert inverse[0] == inverse[1] != inverse[2]
    # a far row (a driver's FLT_MAX) makes more voxels than an integer holds: still each its own
    far = np.vstack([pts, [1e150, 0.0, 0.0], [3e38, 3e38, 3e38]])
    centroids, inverse = voxel_downsample(far, 1e-6)
    assert len(centroids) == 5 and len(set(inverse.tolist())) == 5
    assert voxel_downsample(far, 0.1)[1].tolist()[:3] == [0, 0, 1]
    cloud = np.random.default_rng(0).random((1000, 3))
    for sentinel in (3.4e38, -3.4e38):  # on either side: the other voxels stay apart
        assert len(voxel_downsample(np.vstack([cloud, [sentinel, 0.5, 0.5]]), 0.05)[0]) == \
            len(voxel_downsample(cloud, 0.05)[0]) + 1


def test_tune_max_alone_bounds_the_candidates_and_tune_count_is_used():
    pipe = FramePipeline(PipelineConfig(tune_max=0.005, tune_count=5, seed=2))
    result = pipe.process(corner(1.0), 0)
    assert pipe.last_tuning is not None
    assert len(pipe.last_tuning.rows) == 5
    assert pipe.last_tuning.tolerances.max() == pytest.approx(0.005)
    assert result.tolerance <= 0.005


def test_parameter_change_during_a_retune_voids_it():
    pipe = FramePipeline(PipelineConfig(seed=3))
    started = threading.Event()
    real = pipe.retune

    def slow_retune(*args, **kwargs):
        started.set()
        return real(*args, **kwargs)
    results = []
    worker = threading.Thread(target=lambda: results.append(slow_retune(corner(1.0, n=20000), 1.0, 1_000_000_000)))
    worker.start()
    started.wait()
    pipe.reconfigure(PipelineConfig(seed=3, tune_min=0.001, tune_max=0.002, tune_count=3))
    worker.join()
    assert pipe.tolerance is None, 'a sweep for the old set-up was adopted after the change'
    assert results == [None]  # it stopped after its current candidate (an outside probe: it ran to its end)
    assert pipe.retune_due(2.0)


def test_same_frame_same_stamp_same_result_and_stamp_changes_the_seed():
    pts = corner(1.0)
    a = FramePipeline(FIXED).process(pts, 5)
    b = FramePipeline(FIXED).process(pts, 5)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert a.indices.gs_planes == b.indices.gs_planes


@pytest.mark.parametrize('bad', [dict(tolerance=0.0), dict(criterion='x'), dict(tune_min=0.2, tune_max=0.1),
                                 dict(probability=1.0), dict(voxel_size=-1.0), dict(tune_count=1),
                                 dict(ransac_points=500), dict(index_sample_size=20_001)])  # O(n^2): minutes
def test_invalid_config_is_rejected_with_a_reason(bad):
    with pytest.raises(ValueError) as info:
        PipelineConfig(**bad).validate()
    assert str(info.value)


def test_retune_is_due_after_the_period_and_when_header_time_runs_backwards():
    pipe = FramePipeline(PipelineConfig(retune_period=1.0, seed=4))
    assert pipe.retune_due(10.0)  # nothing tuned yet
    pipe.process(corner(1.0), 10_000_000_000)
    assert not pipe.retune_due(10.5)
    assert pipe.retune_due(11.0)
    assert pipe.retune_due(3.0)  # a looping bag starts over
    minute = FramePipeline(PipelineConfig(retune_period=60.0, seed=4))
    minute.process(corner(1.0), 123_000_000_000, tune_inline=True)
    clock = minute.process(corner(1.0), 183_000_000_000, tune_inline=False).clock  # 59.999999999999986 s later
    assert minute.retune_due(clock)  # float rounding of the stamps does not hold the period back a frame
    fixed = FramePipeline(PipelineConfig(retune_period=0.0, seed=4))
    fixed.process(corner(1.0), 10_000_000_000)
    assert not fixed.retune_due(1e6) and not fixed.retune_due(0.0)


def test_large_frames_sample_ransac_and_indices_unless_told_otherwise():
    pts = scenes.boxes(80_000, seed=2).points
    fast = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.02, seed=1)).process(pts, 7)
    exact = FramePipeline(PipelineConfig(auto_tune=False, tolerance=0.02, seed=1, ransac_points=0,
                                         exact_indices=True)).process(pts, 7)
    assert fast.n_planes == exact.n_planes == 5 and fast.level == exact.level == OK
    values, exact_values = dict(fast.values), dict(exact.values)
    assert values['dunn_db_points'] == values['index_sample_size'] != '80000'
    assert exact_values['dunn_db_points'] == '80000'
    assert sorted(fast.plane_counts) == pytest.approx(sorted(exact.plane_counts), rel=0.01)


def test_trailing_bytes_after_the_declared_data_are_reported_as_warn():
    from rosbags.typesys import Stores, get_typestore

    from plane_validation.formats.pointcloud2 import create_cloud, rosbags_types
    types = rosbags_types(get_typestore(Stores.ROS2_JAZZY))
    pts = scenes.corner(900, 0.0, scale=0.01, seed=2).points.astype(np.float32)
    header = types.Header(stamp=types.Time(sec=1, nanosec=0), frame_id='f')
    msg = create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]}, types=types)
    config = PipelineConfig(auto_tune=False, tolerance=0.01)
    clean = FramePipeline(config).process_cloud(msg)
    msg.data = np.concatenate([msg.data, np.zeros(7, np.uint8)])
    padded = FramePipeline(config).process_cloud(msg)
    assert clean.level == OK and padded.level == WARN
    assert '7 byte(s) beyond height*row_step' in padded.message
    assert padded.n_planes == clean.n_planes == 3 and np.array_equal(padded.labels, clean.labels)


@pytest.mark.parametrize('height', [1, 2, 480])
def test_an_empty_cloud_of_any_height_is_too_few_points(height):
    """An outside probe: 480 x 0 was ERROR 'bad input: shape must be (H, W)...' (the core's argument), 1 x 0 WARN."""
    from rosbags.typesys import Stores, get_typestore

    from plane_validation.formats.pointcloud2 import create_cloud, rosbags_types
    types = rosbags_types(get_typestore(Stores.ROS2_JAZZY))
    header = types.Header(stamp=types.Time(sec=1, nanosec=0), frame_id='f')
    msg = create_cloud(header, {name: np.zeros(0, np.float32) for name in 'xyz'}, types=types)
    msg.height = height
    result = FramePipeline(PipelineConfig()).process_cloud(msg)
    assert result.level == WARN and result.message == 'too few valid points: 0 of 0 (need 3)'


def test_a_failed_tune_detects_with_the_last_tuned_tolerance():
    import dataclasses
    points = scenes.corner(3000, 0.2, scale=0.01, seed=5).points
    pipeline = FramePipeline(PipelineConfig(seed=1))
    first = pipeline.process(points, 1)
    assert first.level == OK and first.tolerance_source.startswith('tuned')
    pipeline.reconfigure(dataclasses.replace(pipeline.config, tune_min=5.0))  # above the derived tune_max
    again = pipeline.process(points, 2)
    assert again.level == WARN and 'cannot tune' in again.message and 'tune_min' in again.message
    assert again.tolerance == first.tolerance and again.n_planes == 3
    assert dict(again.values)['tolerance_source'] == 'last tuned (tuning failed)'
    fresh = FramePipeline(PipelineConfig(seed=1, tune_min=5.0)).process(points, 3)  # nothing tuned yet
    assert fresh.level == WARN and fresh.tolerance == PipelineConfig().tolerance and fresh.n_planes == 3


def test_a_dead_sweep_worker_is_a_failed_tune_not_an_exception(monkeypatch):
    from plane_validation.app import pipeline as pipeline_module
    from plane_validation.core.workers import TuningWorkerError

    def dies(*args, **kwargs):
        raise TuningWorkerError('a tuning worker process died (killed)')
    monkeypatch.setattr(pipeline_module, 'tune_tolerance', dies)
    result = FramePipeline(PipelineConfig(seed=1, tune_jobs=2)).process(corner(), 1)
    assert result.level == WARN and 'cannot tune: a tuning worker process died' in result.message
    assert result.n_planes == 3


def test_tune_jobs_runs_the_sweep_in_worker_processes_with_the_same_result():
    cloud = corner()
    one = FramePipeline(PipelineConfig(seed=2)).process(cloud, 10**9)
    two = FramePipeline(PipelineConfig(seed=2, tune_jobs=2)).process(cloud, 10**9)
    assert two.tolerance == one.tolerance and two.tolerance_source == one.tolerance_source
    np.testing.assert_array_equal(two.labels, one.labels)
    untimed = [[kv for kv in r.diagnostic.values if not kv[0].endswith('_ms')] for r in (one, two)]
    assert untimed[0] == untimed[1] and len(untimed[0]) > 20


def test_frames_with_a_tuned_t_carry_the_sweeps_seed_agreement_into_their_verdict():
    """A sweep whose planes other RANSAC seeds do not find again makes the tuned frames WARN."""
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    cloud = corner()
    first = pipe.process(cloud, 10**9)
    values = dict(first.diagnostic.values)
    assert first.tolerance_source.startswith('tuned') and float(values['seed_agreement']) >= 0.9
    assert first.diagnostic.level == OK, first.diagnostic.message
    # the same frame, as if its sweep had found other planes under other seeds
    pipe.last_tuning = dataclasses.replace(pipe.last_tuning, seed_agreement=0.5)
    again = pipe.process(cloud, 2 * 10**9)
    assert again.diagnostic.level == WARN and 'seeds' in again.diagnostic.message
    values = dict(again.diagnostic.values)
    assert float(values['seed_agreement']) == 0.5 and values['verdict_failures'] == 'seeds_disagree'
    assert values['reliable'] == 'false' and dict(first.diagnostic.values)['verdict_failures'] == 'none'


def test_a_sweep_without_planes_is_not_adopted_and_is_tried_again():
    """A first frame without a plane (a line) tunes nothing; a later frame is swept again."""
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    line = pipe.process(np.outer(np.linspace(0.0, 100.0, 400), [1.0, 0.5, 0.25]), 10**9)  # collinear: no plane
    assert line.diagnostic.level == WARN and 'the sweep of the frame stamped 1.000 s found no plane' in line.message
    assert pipe.tolerance is None and 'seed_agreement' not in dict(line.diagnostic.values)
    corner = scenes.corner(3000, 0.0, seed=1).points
    assert not pipe.retune_due(1.0 + RETRY_AFTER_S / 2) and pipe.retune_due(1.0 + RETRY_AFTER_S)  # period 0
    planes = pipe.process(corner, 2 * 10**9)
    assert planes.tolerance_source.startswith('tuned') and planes.n_planes == 3
    assert planes.diagnostic.level == OK, planes.message


@pytest.mark.parametrize('first', [np.ones((500, 3)), np.outer(np.linspace(0, 1, 200), [1.0, 2.0, 3.0])],
                         ids=['identical', 'collinear'])
def test_the_node_recovers_from_a_degenerate_first_frame(first):
    """As the node runs it (sweeps in the background): a first frame without planes leaves neither
    a useless quick estimate nor a tuned t behind, and the sweep is tried again."""
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=7))
    assert pipe.process(first, 10**9, tune_inline=False).n_planes == 0
    with pytest.raises(ValueError):
        pipe.retune(first, 1.0)
    corner = scenes.corner(3000, 1.0, scale=0.01, seed=1).points
    good = pipe.process(corner, 2 * 10**9, tune_inline=False)  # the quick estimate of this frame
    assert good.n_planes == 3 and good.tolerance_source.startswith('quick estimate (tuning failed)'), good.message
    assert pipe.retune_due(2.0)
    assert pipe.retune(corner, 2.0).segmentation.n_planes == 3
    assert pipe.process(corner, 3 * 10**9, tune_inline=False).level == OK


def test_failed_sweeps_are_retried_ever_less_often():
    from plane_validation.app.pipeline import RETRY_MAX_S
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    line = np.outer(np.linspace(0.0, 1.0, 300), [1.0, 2.0, 3.0])
    stamp, waits = 1.0, []
    grid = np.arange(0.5, 200.0, 0.5)
    for _ in range(9):
        foreseen = next(w for w in grid if pipe.due_after_failed_sweep(stamp, stamp + w))  # while it runs
        with pytest.raises(ValueError, match='no plane'):
            pipe.retune(line, stamp)
        wait = next(w for w in grid if pipe.retune_due(stamp + w))
        assert foreseen == wait
        waits.append(float(wait))
        stamp += wait
    assert waits == [min(RETRY_AFTER_S * 2 ** k, RETRY_MAX_S) for k in range(9)] and waits[-1] == RETRY_MAX_S
    pipe.retune(scenes.corner(3000, 1.0, seed=1).points, stamp)  # a success: no more retries (period 0)
    assert pipe.failures == 0 and not pipe.retune_due(stamp + 1000.0)


def test_a_sweep_whose_verdict_is_not_reliable_is_used_and_tried_again_on_a_later_frame():
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    blob = np.random.default_rng(0).normal(0, 0.3, (3000, 3)) + [0, 0, 3]  # a first frame of clutter
    corner = scenes.corner(3000, 0.2, scale=0.01, seed=1).points + [0, 0, 1]  # then a 1 m corner, 2 mm noise
    first = pipe.process(blob, 10**9)
    assert first.n_planes > 0 and first.level == WARN, first.message
    assert first.tolerance_source == 'tuned at t=1.000s (its sweep was not reliable: tuned again on a later frame)'
    assert not pipe.retune_due(1.9) and pipe.retune_due(1.0 + RETRY_AFTER_S)  # as after a failed sweep
    later = pipe.process(corner, 2 * 10**9)
    assert later.level == OK and later.tolerance_source == 'tuned at t=2.000s', later.message
    assert later.tolerance < 0.5 * first.tolerance and later.n_planes == 3
    assert pipe.failures == 0 and not pipe.retune_due(1000.0)  # reliable: kept (retune_period 0)


def test_a_sweep_asked_to_stop_adopts_nothing():
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    asked = []
    result = pipe.retune(scenes.corner(3000, 1.0, seed=1).points, 1.0, stop=lambda: asked.append(1) or True)
    assert result is None and len(asked) == 1 and pipe.tolerance is None and pipe.tune_error is None


def test_a_sweep_range_too_small_for_the_noise_is_named_in_the_message():
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0, tune_max=0.0001))
    noisy = scenes.corner(3000, 1.0, scale=0.01, seed=1).points  # a 1 m corner, noise 1 cm
    frame = pipe.process(noisy, 10**9)
    assert frame.diagnostic.level == WARN and pipe.tolerance is None
    assert re.search(r'stamped 1.000 s found no plane at any t from [\d.e-]+ to 0\.0001 m .*; tune_max set that range',
                     frame.message), frame.message


@pytest.mark.parametrize('organized', [False, True])
def test_points_at_the_origin_are_no_returns_not_a_plane(organized):
    # some drivers (ouster-ros, for one) mark a pixel without a return as (0, 0, 0): thousands of copies
    # of one point, which every plane through the origin would take as inliers
    scene = scenes.depth_camera('table', width=160, height=120, seed=0)
    pts = scene.points.copy()
    pts[:1800] = 0.0  # the top 15 rows
    shape = scene.shape if organized else None
    rows = pts if organized else pts[np.isfinite(pts).all(axis=1)]
    n_zero = int(np.count_nonzero((rows == 0).all(axis=1)))
    assert n_zero > 1000
    config = dataclasses.replace(FIXED, min_inliers=50.0)
    result = FramePipeline(config).process(rows, 0, shape=shape)
    values = dict(result.values)
    assert values['no_return_points'] == str(n_zero)
    assert int(values['valid_points']) == np.isfinite(rows).all(axis=1).sum() - n_zero
    assert not (result.points == 0).all(axis=1).any()
    assert all(plane.rms > 0 for plane in result.segmentation.planes)
    kept = FramePipeline(dataclasses.replace(config, zero_is_no_return=False)).process(rows, 0, shape=shape)
    assert dict(kept.values)['no_return_points'] == '0'
    assert (kept.points == 0).all(axis=1).sum() == n_zero  # points like any other when told so


def test_the_quick_estimate_finds_the_walls_of_an_unorganized_lidar_scan():
    # the 16 nearest points of a return lie on its ring, flat to 0.05 mm: 6 such thicknesses (0.3 mm)
    # found no plane, and the node answered "no plane found" until its first sweep ended
    scan = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    first = pipe.process(scan.points, 10**9, tune_inline=False)
    assert first.tolerance_source.startswith('quick estimate') and first.tolerance > 0.01
    assert first.n_planes >= 4, first.message


def test_the_viewpoint_parameters_give_a_lidar_scan_in_base_link_its_sensor_frame_planes():
    scan = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    fixed = dict(auto_tune=False, tolerance=0.05, max_planes=14, min_inliers=23.0, seed=0)
    own = FramePipeline(PipelineConfig(**fixed)).process(scan.points, 10**9)
    lifted = scan.points + [0.0, 0.0, 1.8]
    moved = FramePipeline(PipelineConfig(**fixed, viewpoint_z=1.8)).process(lifted, 10**9)
    blind = FramePipeline(PipelineConfig(**fixed)).process(lifted, 10**9)
    assert np.array_equal(moved.labels, own.labels) and own.n_planes >= 5
    assert not np.array_equal(blind.labels, own.labels)
    np.testing.assert_allclose(moved.points, lifted)


def test_with_a_viewpoint_the_no_return_mark_moved_with_the_cloud_is_left_out():
    # a driver's (0, 0, 0) rows, transformed to base_link with the scan (float32), sit at the viewpoint
    scan = scenes.lidar(**scenes.VLP16_ROOM, seed=1)
    marked = scan.points.copy()
    marked[::10] = 0.0
    sensor = np.array([3.0, 0.0, 1.8])  # the frame's origin behind a wall, seen from the sensor
    lifted = (marked + sensor).astype(np.float32)
    fixed = dict(auto_tune=False, tolerance=0.05, max_planes=14, min_inliers=23.0, seed=0)
    own = FramePipeline(PipelineConfig(**fixed)).process(marked.astype(np.float32), 10**9)
    moved = FramePipeline(PipelineConfig(**fixed, viewpoint_x=3.0, viewpoint_z=1.8)).process(lifted, 10**9)
    assert dict(moved.values)['no_return_points'] == dict(own.values)['no_return_points'] == str(len(marked[::10]))
    assert dict(moved.values)['viewpoint'] == '3 0 1.8' and 'viewpoint' not in dict(own.values)
    assert sorted(moved.plane_counts) == pytest.approx(sorted(own.plane_counts), abs=10)  # float32 rounding moved
    assert all(p.normal @ sensor + p.offset < 0 for p in moved.segmentation.planes)  # normals away from the sensor


def test_an_unorganized_lidar_scan_with_a_ring_field_is_searched_on_its_ring_image():
    # velodyne_pointcloud without organize_cloud: a height-1 cloud with a ring field; shuffled as a driver
    # may order it. Laid out by its rings (organize_rings), it is searched as an organized cloud (5-6 times
    # faster than the neighbourhood graph), its planes nearly as good
    from rosbags.typesys import Stores, get_typestore

    from plane_validation.core.scoring import segmentation_quality
    from plane_validation.formats.pointcloud2 import create_cloud, rosbags_types
    types = rosbags_types(get_typestore(Stores.ROS2_JAZZY))
    scan = scenes.lidar(rings=16, seed=1)
    order = np.random.default_rng(0).permutation(len(scan.points))
    pts, rings, truth = scan.points[order].astype(np.float32), scan.rings[order].astype(np.uint16), scan.labels[order]
    header = types.Header(stamp=types.Time(sec=1, nanosec=0), frame_id='velodyne')
    msg = create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2], 'ring': rings}, types=types)
    fixed = dict(auto_tune=False, tolerance=0.05, max_planes=10, seed=0)
    laid = FramePipeline(PipelineConfig(**fixed)).process_cloud(msg)  # the default
    graph = FramePipeline(PipelineConfig(**fixed, organize_rings=False)).process_cloud(msg)
    assert dict(laid.values)['ring_image'] == '16x1800' and 'ring_image' not in dict(graph.values)
    assert laid.sweep_cloud[1] == (16, 1800) and graph.sweep_cloud[1] is None  # what a retune sweeps
    q, q_graph = segmentation_quality(laid.labels, truth), segmentation_quality(graph.labels, truth)
    assert q.correct >= 5 and q.f1 > 0.97 and q_graph.correct == 6, (q, q_graph)  # the graph: F1 0.999
    assert laid.level == OK and len(laid.labels) == len(pts)
    tuned = FramePipeline(PipelineConfig(seed=0)).process_cloud(msg)  # the first frame's sweep, on the image
    assert tuned.tolerance_source.startswith('tuned') and tuned.level == OK, tuned.message
    # thinned at random, the ring field kept: no image; the graph, and the diagnostics say why
    kept = np.random.default_rng(1).random(len(pts)) < 0.3
    thinned = FramePipeline(PipelineConfig(**fixed)).process(pts[kept], 10**9, ring=rings[kept])
    assert dict(thinned.values)['ring_image'].startswith('not used: only ') and thinned.level == OK
    assert segmentation_quality(thinned.labels, truth[kept]).correct >= 5
    # a float32 ring field (some drivers write it so): whole numbers are beams; other values are not, and it says so
    as_floats = create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2], 'ring': rings.astype(np.float32)},
                             types=types)
    floated = FramePipeline(PipelineConfig(**fixed)).process_cloud(as_floats)
    assert dict(floated.values)['ring_image'] == '16x1800' and np.array_equal(floated.labels, laid.labels)
    halves = create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2],
                                   'ring': rings.astype(np.float32) + np.float32(0.5)}, types=types)
    halved = FramePipeline(PipelineConfig(**fixed)).process_cloud(halves)
    assert 'not whole numbers' in dict(halved.values)['ring_image'] and halved.level == OK
    assert np.array_equal(halved.labels, graph.labels)  # searched on the graph, as without a ring field
    given = FramePipeline(PipelineConfig(**fixed)).process(pts, 10**9, ring=rings.astype(np.float32))  # the API too
    assert dict(given.values)['ring_image'] == '16x1800' and np.array_equal(given.labels, laid.labels)


def test_a_stream_whose_stamps_do_not_advance_still_retries_a_failed_sweep():
    """Header stamps left at 0 (a driver or simulator): each frame repeating the last stamp counts as
    FROZEN_FRAME_S of header time, so the failed sweep of a first frame without planes is retried, and
    the diagnostics say why the timing is in frames."""
    from plane_validation.app.pipeline import FROZEN_FRAME_S
    pipe = FramePipeline(PipelineConfig(auto_tune=True, seed=0))
    line = pipe.process(np.outer(np.linspace(0.0, 100.0, 400), [1.0, 0.5, 0.25]), 0)
    assert line.level == WARN and 'the sweep of the frame stamped 0.000 s found no plane' in line.message
    retry = round(RETRY_AFTER_S / FROZEN_FRAME_S)
    results = [pipe.process(corner(), 0) for _ in range(retry)]
    assert all('cannot tune' in r.message for r in results[:-1])
    assert all('not advancing' in dict(r.values)['header_time'] for r in results)
    assert results[-1].level == OK and results[-1].tolerance_source.startswith('tuned'), results[-1].message
    assert results[-1].clock == pytest.approx(retry * FROZEN_FRAME_S)
    advancing = FramePipeline(PipelineConfig(auto_tune=True, seed=0)).process(corner(), 10**9)
    assert 'header_time' not in dict(advancing.values) and advancing.clock == 1.0


def test_retune_period_counts_frames_whose_stamps_do_not_advance():
    from plane_validation.app.pipeline import FROZEN_FRAME_S
    pipe = FramePipeline(PipelineConfig(retune_period=0.5, seed=4))
    sweeps = []
    for _ in range(8):
        frame = pipe.process(corner(1.0), 7 * 10**9)
        sweeps.append(pipe.tuned_at)
        assert frame.tolerance_source == 'tuned at t=7.000s'  # the header stamp of the frame swept
    period = round(0.5 / FROZEN_FRAME_S)
    assert sweeps == [7.0] * period + [7.5] * (8 - period)  # retuned on the frame 0.5 s of frames later
    assert pipe.process(corner(1.0), 3 * 10**9).tolerance_source == 'tuned at t=3.000s'  # time ran backwards
    assert pipe.tuned_at == 3.0


def test_planes_put_in_id_order_alike_on_an_organized_frame_and_on_points():
    """The renumbering by track id: an organized frame's rows and valid points in one compiled pass give what an index
    by rank gives each of them, as the other inputs' renumbering does."""
    from plane_validation.app.frame_result import by_track_id
    from plane_validation.core.scenes import depth_camera
    scene = depth_camera('table', width=64, height=48, seed=0)
    result = FramePipeline(dataclasses.replace(FIXED, tolerance=0.02, max_planes=4)).process(scene.points, 10**9,
                                                                                                shape=scene.shape)
    seg = result.segmentation
    assert seg.n_planes >= 3
    finite = np.isfinite(result.organized).all(axis=1)
    labels = np.compress(finite, seg.labels)
    ids = tuple(10 * (seg.n_planes - k) for k in range(seg.n_planes))  # the reverse order
    rank = np.append(np.arange(seg.n_planes)[::-1], -1).astype(np.int32)
    for got_seg, got_labels, got_ids in (by_track_id(seg, labels, ids, finite), by_track_id(seg, labels, ids)):
        np.testing.assert_array_equal(got_seg.labels, rank[seg.labels])
        np.testing.assert_array_equal(got_labels, rank[labels])
        assert got_seg.labels.dtype == got_labels.dtype == np.int32
        assert got_ids == tuple(sorted(ids)) and got_seg.planes == seg.planes[::-1]
    assert by_track_id(seg, labels, tuple(range(seg.n_planes)), finite)[0] is seg  # in order already: as it is
