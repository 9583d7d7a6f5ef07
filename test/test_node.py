"""The ROS 2 node over real DDS (rclpy, Fast DDS, isolated domain): outputs, bad input, parameters, load."""
from __future__ import annotations

import array
import gc
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
import sensor_msgs.msg  # noqa: E402
from processes import session_ended  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from ros_harness import Harness, diag_values, make_header, xyz_cloud  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402

from plane_validation import scenes  # noqa: E402
from plane_validation.app.pipeline import FramePipeline, PipelineConfig  # noqa: E402
from plane_validation.formats.pointcloud2 import create_cloud, structured_array, xyz_array  # noqa: E402
from plane_validation.ros.messages import OUTPUTS  # noqa: E402
from plane_validation.ros.node import PlaneValidationNode  # noqa: E402

pytestmark = pytest.mark.ros  # rclpy and the ROS message packages (and DDS for node tests)

FIXED = {'auto_tune': False, 'tolerance': 0.01, 'seed': 7}


@pytest.fixture(scope='module')
def ros():
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture
def harness(ros):
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in FIXED.items()])
    h = Harness(node)
    yield h
    h.close()


def corner_points(noise: float = 0.0, seed: int = 1, n: int = 3000) -> np.ndarray:
    return scenes.corner(n, noise, scale=0.01, seed=seed).points  # a 1 m corner in meters; noise in cm


def test_help_prints_the_topics_and_parameters_instead_of_starting_the_node(capsys):
    # an outside probe: --help was left to rclpy, which ignores it, and the node started silently
    from plane_validation.app.config import PARAMETERS
    from plane_validation.ros.node import main
    assert main(['--help']) == 0 and main(['-h', '--ros-args', '-p', 'tolerance:=0.05']) == 0
    assert main(['--ros-args', '-p', 'tolerance:=0.05', '--', '--help']) == 0
    text = capsys.readouterr().out
    assert text.startswith('usage: plane_validation_node') and '~/segmented' in text
    assert all(f'  {name} (default ' in text for name in (*PARAMETERS, 'reliability'))
    assert not rclpy.ok()  # rclpy was not started


def test_georeferenced_points_go_out_as_float64_and_sensor_frames_as_float32():
    from plane_validation.ros.messages import segmented_cloud
    pipe = FramePipeline(PipelineConfig(**FIXED))
    for offset, datatype in ((0.0, PointField.FLOAT32), (4_012_345.6789, PointField.FLOAT64)):
        points = corner_points(0.002) + offset
        result = pipe.process(points, 1)
        msg = segmented_cloud(make_header(1), result)
        assert [f.datatype for f in msg.fields[:3]] == [datatype] * 3
        np.testing.assert_allclose(xyz_array(msg), result.points, rtol=0, atol=1e-4)


def test_corner_frame_publishes_every_output_matching_the_core(harness):
    points = corner_points(0.002)
    stamp = 1_000_000_000_123
    out = harness.send(xyz_cloud(points, stamp), outputs=('diagnostics', 'segmented', 'planes', 'plane_poses'))
    # The same pipeline run in-process, same config, cloud and stamp: the node must agree exactly.
    expected = FramePipeline(PipelineConfig(**FIXED)).process(xyz_array(xyz_cloud(points, stamp)), stamp)
    assert expected.n_planes == 3

    seg = structured_array(out['segmented'])
    assert out['segmented'].header.frame_id == 'sensor'
    assert out['segmented'].header.stamp.sec == stamp // 10**9
    np.testing.assert_array_equal(seg['plane_id'], expected.labels)
    assert set(np.unique(seg['plane_id'])) <= {-1, 0, 1, 2}
    assert [f.name for f in out['segmented'].fields] == ['x', 'y', 'z', 'plane_id', 'rgb']

    values = diag_values(out['diagnostics'])
    status = out['diagnostics'].status[0]
    assert status.level == b'\x00', status.message
    assert values['planes'] == '3'
    assert values['tolerance_source'] == 'fixed'
    for key in ('dunn', 'davies_bouldin', 'gs', 'gs_planes', 'silhouette', 'silhouette_se', 'noise_estimate',
                'processing_ms', 'outputs_ms', 'frames_dropped', 'valid_points', 'unassigned_points', 'plane_0_inliers',
                'plane_2_rms'):
        assert key in values, key
    for key in ('dunn', 'davies_bouldin', 'gs', 'gs_planes', 'silhouette'):
        assert float(values[key]) == pytest.approx(getattr(expected.indices, key), rel=1e-5, abs=1e-12)

    markers = out['planes'].markers
    assert markers[0].action == markers[0].DELETEALL
    assert len(markers) == 1 + 3 * 3
    assert {m.type for m in markers[1:]} == {markers[0].TRIANGLE_LIST, markers[0].ARROW,
                                               markers[0].TEXT_VIEW_FACING}
    poses = out['plane_poses'].poses
    assert len(poses) == 3
    for pose, plane in zip(poses, expected.segmentation.planes):
        q = np.array([pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w])
        x, y, z, w = q
        z_axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
        np.testing.assert_allclose(z_axis, plane.normal, atol=1e-6)
        centroid = np.array([pose.position.x, pose.position.y, pose.position.z])
        assert abs(centroid @ plane.normal + plane.offset) < 1e-3

    coeffs = list(harness.received['plane_coefficients'].values())[-1]
    assert [d.label for d in coeffs.layout.dim] == ['planes', 'coefficients']
    assert coeffs.layout.dim[0].size == 3
    np.testing.assert_allclose(np.reshape(coeffs.data, (3, 4)), expected.segmentation.coefficients)


def test_only_the_outputs_someone_subscribes_to_are_built_and_a_later_subscriber_gets_its_own(ros):
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in FIXED.items()])
    h = Harness(node, outputs=('planes',))
    built: list[set[str]] = []
    publish = node.worker.publish
    node.worker.publish = lambda key, msg: (built[-1].add(key) if built and key != 'diagnostics' else None,
                                            publish(key, msg))
    try:
        points = corner_points(0.002)
        built.append(set())
        out = h.send(xyz_cloud(points, 2_000_000_000_001), outputs=('diagnostics', 'planes'))
        assert diag_values(out['diagnostics'])['planes'] == '3'
        assert len(out['planes'].markers) == 1 + 3 * 3
        assert built[-1] == {'planes'}
        assert float(diag_values(out['diagnostics'])['outputs_ms']) >= 0

        h.listen('segmented')
        end = time.monotonic() + 10
        while not node.worker.listened('segmented') and time.monotonic() < end:
            time.sleep(0.02)
        assert node.worker.listened('segmented')
        built.append(set())
        out = h.send(xyz_cloud(points, 2_000_000_000_002), outputs=('diagnostics', 'planes', 'segmented'))
        assert built[-1] == {'planes', 'segmented'}
        assert set(np.unique(structured_array(out['segmented'])['plane_id'])) <= {-1, 0, 1, 2}
    finally:
        h.close()


def _custom_cloud(points: np.ndarray, stamp: int, *, height: int = 1, dtype=np.float32, bigendian: bool = False,
                  pad: int = 0, row_pad: int = 0) -> PointCloud2:
    """Cloud with x, y, z of ``dtype``, an intensity field, ``pad`` bytes per point, ``row_pad`` per row."""
    n = len(points)
    width = n // height
    item = np.dtype(dtype).itemsize
    order = '>' if bigendian else '<'
    fmt = np.dtype(dtype).newbyteorder(order)
    layout = np.dtype({'names': ['intensity', 'x', 'y', 'z'],
                       'formats': [np.dtype('f4').newbyteorder(order), fmt, fmt, fmt],
                       'offsets': [0, 4, 4 + item, 4 + 2 * item], 'itemsize': 4 + 3 * item + pad})
    records = np.zeros(n, layout)
    records['x'], records['y'], records['z'] = points.T
    records['intensity'] = np.arange(n)
    row_step = width * layout.itemsize + row_pad
    rows = records.tobytes()
    data = b''.join(rows[r * width * layout.itemsize:(r + 1) * width * layout.itemsize] + b'\xab' * row_pad
                    for r in range(height))
    code = PointField.FLOAT64 if item == 8 else PointField.FLOAT32
    msg = PointCloud2(header=make_header(stamp), height=height, width=width, is_bigendian=bigendian,
                      point_step=layout.itemsize, row_step=row_step, is_dense=not np.isnan(points).any(),
                      fields=[PointField(name='intensity', offset=0, datatype=PointField.FLOAT32, count=1)] +
                      [PointField(name=a, offset=4 + i * item, datatype=code, count=1) for i, a in enumerate('xyz')])
    msg.data = array.array('B', data)
    return msg


def test_layout_variants_decode_to_the_same_points_and_unorganized_ones_to_the_same_planes(harness):
    points = corner_points(0.002, seed=3, n=2400)
    holes = points.copy()
    holes[np.random.default_rng(0).choice(len(points), 300, replace=False)] = np.nan
    stamp = 2_000_000_000_000
    plain = harness.send(xyz_cloud(holes, stamp), outputs=('diagnostics', 'segmented'))
    ref = structured_array(plain['segmented'])
    variants = [dict(height=40), dict(dtype=np.float64), dict(bigendian=True), dict(pad=6, row_pad=10, height=20),
                dict(height=30, dtype=np.float64, bigendian=True, pad=3)]
    for variant in variants:
        out = harness.send(_custom_cloud(holes, stamp, **variant), outputs=('diagnostics', 'segmented'))
        # the same valid points in the same order; with the same stamp (seed) and layout, identical planes
        values = diag_values(out['diagnostics'])
        assert values['valid_points'] == str(len(points) - 300), variant
        segmented = structured_array(out['segmented']).ravel()
        height = variant.get('height', 1)
        if height > 1:  # an organized input comes back organized: its pixels, NaN and plane_id -1 at the holes
            assert (out['segmented'].height, out['segmented'].width) == (height, len(points) // height)
            hole = np.isnan(holes).any(axis=1)
            assert np.isnan(segmented['x'][hole]).all() and (segmented['plane_id'][hole] == -1).all()
            segmented = segmented[~hole]
        for axis in 'xyz':
            np.testing.assert_array_equal(segmented[axis], ref[axis], err_msg=str(variant))
        if height == 1:  # a taller cloud is searched as an image, and these rows are none
            assert values['planes'] == '3' and out['diagnostics'].status[0].level == b'\x00', variant
            np.testing.assert_array_equal(segmented['plane_id'], ref['plane_id'], err_msg=str(variant))


def test_rows_with_an_infinite_coordinate_are_left_out_and_counted(harness):
    """+inf and -inf (REP 117's marks of a return out of range or too close) are no points, as NaN: the frame
    is answered from the others and says how many rows had one; a finite coordinate out of numeric range is
    ERROR (test_bad_input...)."""
    points = corner_points(0.002, seed=3, n=2400)
    marked = points.copy()
    marked[:2088, 0] = np.inf  # 87 % of the rows
    marked[:50, 2] = -np.inf
    out = harness.send(xyz_cloud(marked, 2_100_000_000_000))
    status = out['diagnostics'].status[0]
    values = diag_values(out['diagnostics'])
    assert status.level == b'\x00' and values['planes'] != '0', status.message
    assert (values['infinite_points'], values['valid_points'], values['input_points']) == ('2088', '312', '2400')
    few = harness.send(xyz_cloud(np.full((40, 3), -np.inf), 2_200_000_000_000))['diagnostics'].status[0]
    assert few.level == b'\x01' and 'too few valid points: 0 of 40' in few.message \
        and '40 had an infinite' in few.message, few.message


def test_a_byte_order_that_does_not_match_the_data_is_error_without_a_raw_numpy_warning(harness):
    import warnings
    msg = xyz_cloud(corner_points(0.002, seed=3, n=2400), 2_300_000_000_000)
    msg.is_bigendian = True  # the bytes are little-endian: read the other way, many are signalling NaNs
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        status = harness.send(msg)['diagnostics'].status[0]
    assert status.level == b'\x02', status.message
    assert not [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]


def test_an_organized_cloud_gives_organized_segmented_and_obstacle_clouds(harness):
    scene = scenes.depth_camera('room', width=80, height=60, seed=2)
    msg = create_cloud(make_header(2_500_000_000_000), {a: scene.points[:, i].astype(np.float32)
                                                        for i, a in enumerate('xyz')}, types=sensor_msgs.msg,
                       shape=scene.shape)
    out = harness.send(msg, outputs=('diagnostics', 'segmented', 'obstacles'))
    seg, obs = out['segmented'], out['obstacles']
    assert (seg.height, seg.width) == (obs.height, obs.width) == (60, 80)
    seg, obs = structured_array(seg).ravel(), structured_array(obs).ravel()
    hole = np.isnan(scene.points).any(axis=1)
    assert np.isnan(seg['x'][hole]).all() and (seg['plane_id'][hole] == -1).all()
    on_no_plane = ~hole & (seg['plane_id'] == -1)
    assert on_no_plane.any() and (seg['plane_id'][~hole] >= 0).any()
    # an obstacle pixel is a valid pixel on no plane, with its coordinates; every other pixel is NaN
    np.testing.assert_array_equal(np.isfinite(obs['x']), on_no_plane)
    np.testing.assert_array_equal(obs['z'][on_no_plane], seg['z'][on_no_plane])
    assert diag_values(out['diagnostics'])['obstacle_points'] == str(int(on_no_plane.sum()))


def _bad_clouds(stamp: int):
    no_z = xyz_cloud(corner_points(), stamp)
    no_z.fields = list(no_z.fields)[:2]
    short = xyz_cloud(corner_points(), stamp)
    short.data = array.array('B', bytes(short.data)[:-5])
    wrong_type = xyz_cloud(corner_points(), stamp)
    wrong_type.fields[2].datatype = 42
    return [('missing z', no_z, b'\x02', 'z'), ('data too short', short, b'\x02', 'bytes'),
            ('bad datatype', wrong_type, b'\x02', 'datatype'),
            ('empty', xyz_cloud(np.empty((0, 3)), stamp), b'\x01', 'too few'),
            ('all NaN', xyz_cloud(np.full((100, 3), np.nan), stamp), b'\x01', 'too few'),
            ('two points', xyz_cloud(np.array([[0, 0, 0], [1, 1, 1.0]]), stamp), b'\x01', 'too few'),
            ('collinear', xyz_cloud(np.outer(np.linspace(0, 1, 200), [1, 2, 3]), stamp), b'\x01', 'collinear'),
            ('identical', xyz_cloud(np.ones((200, 3)), stamp), b'\x01', 'identical')]


def test_bad_input_is_reported_and_the_next_frame_works(harness):
    stamp = 3_000_000_000_000
    for i, (what, msg, level, word) in enumerate(_bad_clouds(stamp)):
        msg.header = make_header(stamp + 2 * i)
        out = harness.send(msg)
        status = out['diagnostics'].status[0]
        assert status.level == level, (what, status.message)
        assert word in status.message, (what, status.message)
        good = harness.send(xyz_cloud(corner_points(), stamp + 2 * i + 1))
        assert diag_values(good['diagnostics'])['planes'] == '3', what


def test_bytes_that_are_no_pointcloud2_are_an_error_with_a_reason_and_the_next_frame_works(harness):
    """A publisher can send any bytes as a serialized PointCloud2 (the node reads them itself): the answer is ERROR,
    stamped 0 (there is no header to copy)."""
    out = harness.send(_Serialized(bytes(range(7, 250))))
    status = out['diagnostics'].status[0]
    assert status.level == b'\x02' and 'malformed PointCloud2: not a serialized sensor_msgs/PointCloud2' in \
        status.message, status.message
    good = harness.send(xyz_cloud(corner_points(), 3_100_000_000_000))
    assert diag_values(good['diagnostics'])['planes'] == '3'


class _Serialized(bytes):
    """Bytes published as they are (rclpy sends a bytes message serialized), with the header ``Harness.send`` keys
    the answer by: none, stamp 0."""

    header = make_header(0)


def test_parameter_change_applies_to_next_frame_and_invalid_is_rejected(harness):
    node = harness.node
    results = node.set_parameters([Parameter('tolerance', value=0.004)])
    assert results[0].successful
    out = harness.send(xyz_cloud(corner_points(0.001), 4_000_000_000_000))
    assert float(diag_values(out['diagnostics'])['tolerance']) == pytest.approx(0.004)

    for bad, why in [(Parameter('tolerance', value=-1.0), ''), (Parameter('criterion', value='entropy'), 'criterion'),
                     (Parameter('probability', value=1.5), ''), (Parameter('max_planes', value=0), ''),
                     (Parameter('tune_max', value=0.001), 'tune_max')]:
        if bad.name == 'tune_max':
            assert node.set_parameters([Parameter('tune_min', value=0.01)])[0].successful
        result = node.set_parameters([bad])[0]
        assert not result.successful, bad.name
        assert result.reason, bad.name
        assert why in result.reason
    assert node.get_parameter('tolerance').value == 0.004
    assert node.get_parameter('criterion').value == PipelineConfig().criterion
    assert node.pipeline.config.tolerance == 0.004
    out = harness.send(xyz_cloud(corner_points(0.001), 4_000_000_000_001))
    assert float(diag_values(out['diagnostics'])['tolerance']) == pytest.approx(0.004)

    # switching auto-tuning on at run time answers at once with a quick estimate and tunes in
    # the background; the next frame after the sweep uses the tuned t
    assert node.set_parameters([Parameter('auto_tune', value=True), Parameter('tune_min', value=0.0)])[0].successful
    out = harness.send(xyz_cloud(corner_points(1.0), 4_000_000_000_002))  # e = 1 cm
    assert diag_values(out['diagnostics'])['tolerance_source'] == 'quick estimate (sweep pending)'
    assert node.wait_for_sweep(timeout=30)
    out = harness.send(xyz_cloud(corner_points(1.0), 4_000_000_000_003))
    values = diag_values(out['diagnostics'])
    assert values['tolerance_source'].startswith('tuned at')
    assert 0.01 <= float(values['tolerance']) <= 0.03


def _rss_mb() -> float:
    with open('/proc/self/statm') as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def test_flood_drops_old_frames_keeps_memory_flat_and_stays_responsive(harness):
    big = scenes.boxes(8_000, seed=2).points.astype(np.float32)
    msgs = [xyz_cloud(big, 5_000_000_000_000 + i) for i in range(250)]
    for m in msgs[:50]:  # ~500 Hz: far faster than the node can process, slow enough for DDS to deliver
        harness.pub.publish(m)
        time.sleep(0.002)
    time.sleep(2.0)
    gc.collect()
    before = _rss_mb()
    for m in msgs[50:]:
        harness.pub.publish(m)
        time.sleep(0.002)
    time.sleep(2.0)
    gc.collect()
    after = _rss_mb()
    # still responsive: a fresh frame is processed promptly after the flood
    out = harness.send(xyz_cloud(corner_points(), 5_100_000_000_000), timeout=30)
    values = diag_values(out['diagnostics'])
    assert values['planes'] == '3'
    dropped = int(values["frames_dropped"])
    processed = int(values['frames_processed'])
    assert dropped > 0
    with harness.lock:
        answered = sorted((k, diag_values(d), d.status[0]) for k, d in harness.received['diagnostics'].items()
                          if 5_000_000_000_000 <= k < 5_100_000_000_000)
    # a drop does not change a frame's level: the level says what its planes and its input are like
    assert not any('dropped' in st.message or 'rate' in st.message for _, _, st in answered)
    # each drop is reported once, with a newer frame than the dropped one: by any answered frame, no more
    # drops were reported than clouds sent before it went unanswered (stamps count the clouds sent)
    so_far = 0
    for position, (stamp, vals, _) in enumerate(answered):
        so_far += int(vals['frames_dropped_since_last'])
        assert so_far <= stamp - 5_000_000_000_000 - position, (stamp, vals)
    assert so_far == dropped and int(values['frames_dropped_since_last']) == 0
    # the rates say what happened: during the flood clouds came in faster than the node answered them
    rates = [(float(v['input_rate_hz']), float(v['output_rate_hz'])) for _, v, _ in answered]
    assert any(i > 2 * o > 0 for i, o in rates), rates
    assert values['planes'] == '3' and out['diagnostics'].status[0].level == b'\x00'
    # (DDS itself may also discard frames for the best-effort subscription, so no lower bound on the sum)
    assert processed + dropped <= 251
    assert after - before < 60, f'RSS grew from {before:.0f} MB to {after:.0f} MB'


def test_a_frame_is_warn_only_while_the_output_rate_is_below_min_output_rate_hz(harness):
    node = harness.node
    assert not node.set_parameters([Parameter('min_output_rate_hz', value=-1.0)])[0].successful
    stamp = 5_200_000_000_000
    for k in range(4):  # about 10 Hz: well below 1000 Hz
        out = harness.send(xyz_cloud(corner_points(), stamp + k))['diagnostics']
        time.sleep(0.1)
    assert float(diag_values(out)['output_rate_hz']) < 1000
    assert node.set_parameters([Parameter('min_output_rate_hz', value=1000.0)])[0].successful
    out = harness.send(xyz_cloud(corner_points(), stamp + 10))['diagnostics']
    status = out.status[0]
    assert status.level == b'\x01' and 'below min_output_rate_hz 1000' in status.message, status.message
    assert diag_values(out)['planes'] == '3'  # the planes are the same: only the rate is wrong
    assert node.set_parameters([Parameter('min_output_rate_hz', value=0.0)])[0].successful
    assert harness.send(xyz_cloud(corner_points(), stamp + 11))['diagnostics'].status[0].level == b'\x00'
    assert node.set_parameters([Parameter('min_output_rate_hz', value=0.5)])[0].successful  # met
    assert harness.send(xyz_cloud(corner_points(), stamp + 12))['diagnostics'].status[0].level == b'\x00'


def test_periodic_retune_runs_in_the_background_while_frames_flow(ros):
    params = {'auto_tune': True, 'retune_period': 0.5, 'seed': 3, 'tune_count': 12, 'tune_points': 30000}
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    h = Harness(node)
    try:
        cloud = scenes.corner(30000, 1.0, scale=0.01, seed=4).points  # e = 1 cm
        first = h.send(xyz_cloud(cloud, 6_000_000_000_000), timeout=60)  # answered before any sweep
        assert diag_values(first['diagnostics'])['tolerance_source'] == 'quick estimate (sweep pending)'
        assert node.wait_for_sweep(timeout=60)
        seen_running = []
        for k in range(1, 150):  # header time advances 0.1 s per frame: a retune is due after 0.5 s
            out = h.send(xyz_cloud(cloud, 6_000_000_000_000 + k * 100_000_000), timeout=60)
            values = diag_values(out['diagnostics'])
            assert values['planes'] == '3'
            seen_running.append(values['retune_running'] == 'true')
            if values['tolerance_source'] != 'tuned at t=6000.000s':
                break
        assert any(seen_running), 'no frame was processed while a retune was running'
        assert values['tolerance_source'].startswith('tuned at t=600')
        assert values['tolerance_source'] != 'tuned at t=6000.000s', 'the periodic retune never landed'
    finally:
        h.close()


def _set_parameters(harness, service: str, params: dict) -> list:
    """Call the node's ``service`` (set_parameters or set_parameters_atomically) over DDS; its results."""
    from rcl_interfaces.srv import SetParameters, SetParametersAtomically
    kind = SetParameters if service == 'set_parameters' else SetParametersAtomically
    client = harness.probe.create_client(kind, f'/plane_validation/{service}')
    try:
        assert client.wait_for_service(timeout_sec=10)
        request = kind.Request(parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in params.items()])
        future = client.call_async(request)
        deadline = time.monotonic() + 10
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.01)
        response = future.result()
        return list(response.results) if kind is SetParameters else [response.result]
    finally:
        harness.probe.destroy_client(client)


@pytest.mark.parametrize('service', ['set_parameters', 'set_parameters_atomically'])
def test_parameters_set_together_that_conflict_are_all_refused_over_dds(harness, service):
    """tune_min above tune_max in one request: neither is applied (plain SetParameters included, which rclpy
    would apply one by one: tune_min, then a refused tune_max, leaving every later sweep to fail)."""
    config = harness.node.pipeline.config
    results = _set_parameters(harness, service, {'tune_min': 0.5, 'tune_max': 0.1})
    assert results and not any(r.successful for r in results), results
    assert all('tune_max must be greater than tune_min' in r.reason for r in results), results
    assert harness.node.pipeline.config == config
    assert (harness.node.get_parameter('tune_min').value, harness.node.get_parameter('tune_max').value) == \
        (config.tune_min, config.tune_max)
    # a request valid as a whole is applied whole, whatever the order (tune_min alone would conflict with 0.2)
    assert all(r.successful for r in _set_parameters(harness, service, {'tune_max': 0.2}))
    results = _set_parameters(harness, service, {'tune_min': 0.3, 'tune_max': 0.6})
    assert all(r.successful for r in results), results
    assert (harness.node.pipeline.config.tune_min, harness.node.pipeline.config.tune_max) == (0.3, 0.6)
    # one that conflicts with the current value of another is refused on its own
    alone = _set_parameters(harness, service, {'tune_max': 0.25})
    assert not alone[0].successful and harness.node.pipeline.config.tune_max == 0.6


@pytest.mark.parametrize('service', ['set_parameters', 'set_parameters_atomically'])
def test_a_misspelt_parameter_set_over_dds_is_refused_naming_it(harness, service):
    """rclpy's own reason names no parameter ('Invalid access to undeclared parameter(s): []'): what
    `ros2 param set /plane_validation tolerence 0.01` printed. The whole request is refused, its valid part too."""
    config = harness.node.pipeline.config
    results = _set_parameters(harness, service, {'tolerence': 0.01, 'max_planes': config.max_planes + 1})
    assert results and not any(r.successful for r in results), results
    assert all(r.reason == 'tolerence: not a parameter of this node (--help lists them)' for r in results), results
    assert harness.node.pipeline.config == config


@pytest.mark.parametrize('sig', ['SIGINT', 'SIGTERM', 'SIGHUP', 'nohup'])
def test_node_process_stops_cleanly_on_signal(ros, sig):
    """The node ends with status 0 on SIGINT, SIGTERM and SIGHUP; started under nohup (SIGHUP ignored from the
    start) a hangup leaves it running, and SIGTERM ends it."""
    import os
    import signal
    import subprocess
    import sys
    ignore = (lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN)) if sig == 'nohup' else None
    proc = subprocess.Popen([sys.executable, '-m', 'plane_validation.ros.node'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ), start_new_session=True,
                            preexec_fn=ignore)
    probe = rclpy.create_node('signal_probe')
    try:
        # the signal once the node is up (rclpy handles it from then on), however slow the start on a busy
        # machine: its outputs are advertised at the end of its constructor
        deadline = time.monotonic() + 60
        while not all(probe.count_publishers(f'/plane_validation/{key}') for key in OUTPUTS if key != 'diagnostics') \
                and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.5)
        assert proc.poll() is None, proc.communicate()
        if sig == 'nohup':
            proc.send_signal(signal.SIGHUP)
            time.sleep(3.0)  # a node that takes it for SIGTERM has ended by then
            assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGTERM if sig == 'nohup' else getattr(signal, sig))
        out, err = proc.communicate(timeout=15)
    finally:
        probe.destroy_node()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0, (proc.returncode, err)
    assert 'Traceback' not in err + out


def test_a_starting_node_imports_what_its_frames_would_import_on_first_use():
    """The tracker imports scipy.optimize on a node's second frame and the search scipy.ndimage on some frame: the
    warm-up imports them, so that no frame after the first pays 0.1-0.2 s for it."""
    import subprocess
    import sys

    from plane_validation.app.pipeline import FIRST_USE_MODULES
    names = (*FIRST_USE_MODULES, 'rosbags.typesys')  # the serialized clouds' reader too
    code = ('import logging, sys; from plane_validation.ros.worker import warm_kernels; '
            f'names = {names!r}; before = [n in sys.modules for n in names]; '
            "warm_kernels(logging.getLogger('probe')); print(before, [n in sys.modules for n in names])")
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split('\n')[-2] == f'{[False] * len(names)} {[True] * len(names)}', run.stdout


def test_a_node_started_as_ros2_run_starts_it_says_its_kernels_are_ready_before_its_first_answer(ros, tmp_path):
    """Through the entry point (plane_validation.ros:main) and this process's warm kernel cache, the node loads the
    kernels once its subscription exists, says how long that took, and only then answers a frame."""
    import os
    import signal
    import subprocess
    import sys

    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import qos_profile_sensor_data
    log = tmp_path / 'node.log'
    with open(log, 'w') as out:
        proc = subprocess.Popen([sys.executable, '-c', 'import sys; from plane_validation.ros import main; '
                                 'sys.exit(main())', '--ros-args', '-p', 'auto_tune:=false'], stdout=out,
                                stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONUNBUFFERED='1'),
                                start_new_session=True)
    probe = rclpy.create_node('start_probe')
    answers: list[str] = []  # the log as it was when each answer came
    probe.create_subscription(DiagnosticArray, '/diagnostics', lambda msg: answers.append(log.read_text()), 10)
    pub = probe.create_publisher(PointCloud2, '/cloud', qos_profile_sensor_data)
    try:
        deadline, stamp = time.monotonic() + 90, 10**12
        while not answers and proc.poll() is None and time.monotonic() < deadline:
            stamp += 100_000_000
            pub.publish(xyz_cloud(corner_points(0.1), stamp))
            rclpy.spin_once(probe, timeout_sec=0.1)
    finally:
        probe.destroy_node()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=15)
    assert answers, log.read_text()
    assert 'compiled kernels ready in' in answers[0] and '(loaded from the cache)' in answers[0], answers[0]


def test_the_collector_the_entry_point_turns_off_comes_back_on_with_the_start_frozen():
    from plane_validation.ros.node import _collect_from_now
    gc.disable()
    try:
        _collect_from_now()
        assert gc.isenabled() and gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()
        gc.enable()
    _collect_from_now()  # an in-process node's (the collector on): nothing frozen
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_the_node_module_loads_without_the_scipy_parts_a_first_frame_does_not_use():
    """scipy.optimize and scipy.ndimage (0.1-0.2 s each to import) load when a sweep, the tracker or a search needs
    them, not when the node starts."""
    import subprocess
    import sys
    script = ('import sys; import plane_validation.ros.node; '
              'print(sorted(m for m in ("scipy.optimize", "scipy.ndimage") if m in sys.modules))')
    run = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == '[]'


def test_spin_ends_when_the_context_shuts_down_without_waking_the_executor():
    """An outside probe: about 1 in 6 SIGTERMs during a parallel sweep shut the context down but left rclpy.spin
    waiting forever (no wake-up reached its wait); spin looks at the context every SPIN_CHECK_S."""
    import threading

    from rclpy.context import Context
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from plane_validation.ros.node import SPIN_CHECK_S, spin

    class Deaf(SingleThreadedExecutor):
        def wake(self) -> None:  # the shutdown's wake-up is lost
            pass

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node('deaf_spin', context=context)
    timer = threading.Timer(0.3, context.try_shutdown)
    timer.start()
    start = time.monotonic()
    try:
        spin(node, Deaf(context=context))
    except ExternalShutdownException:
        pass
    finally:
        timer.cancel()
        node.destroy_node()
        context.try_shutdown()
    assert time.monotonic() - start < 0.3 + 3 * SPIN_CHECK_S


def test_node_with_invalid_startup_parameters_exits_with_a_reason():
    import os
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-m', 'plane_validation.ros.node', '--ros-args', '-p', 'tune_min:=0.5',
                           '-p', 'tune_max:=0.1'], capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2
    assert 'tune_max must be greater than tune_min' in proc.stderr
    assert 'Traceback' not in proc.stderr
    proc = subprocess.run([sys.executable, '-m', 'plane_validation.ros.node', '--ros-args', '--params-file',
                           '/nonexistent/params.yaml'], capture_output=True, text=True, timeout=60,
                          env=dict(os.environ))
    assert proc.returncode == 2 and 'cannot start' in proc.stderr and 'Traceback' not in proc.stderr
    # a parameter without its -p: rclpy said only "cannot start: ['tolerance:=0.01']"
    proc = subprocess.run([sys.executable, '-m', 'plane_validation.ros.node', '--ros-args', 'tolerance:=0.01'],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr
    assert "not ROS arguments after --ros-args: ['tolerance:=0.01'] (a parameter is -p NAME:=VALUE" in proc.stderr


def test_whole_numbers_are_taken_for_float_parameters_and_other_types_are_not(ros):
    overrides = {'min_inliers': 500, 'tolerance': 1, 'auto_tune': False}
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    try:
        config = node.pipeline.config
        assert (config.min_inliers, config.tolerance) == (500.0, 1.0) and isinstance(config.tolerance, float)
        assert node.set_parameters([Parameter('tolerance', value=2)])[0].successful
        assert node.pipeline.config.tolerance == 2.0 and isinstance(node.pipeline.config.tolerance, float)
        for bad, why in ((Parameter('tolerance', value='abc'), 'tolerance must be a float'),
                         (Parameter('tolerance', value=10_000), 'tolerance must be in'),
                         (Parameter('max_planes', value=2.5), 'INTEGER'),
                         (Parameter('tolerance', value=True), 'float')):
            result = node.set_parameters([bad])[0]
            assert not result.successful and why in result.reason, (bad.value, result.reason)
        assert node.pipeline.config.tolerance == 2.0
    finally:
        node.destroy_node()


def test_error_and_warn_log_lines_both_appear_throttled_per_level(harness, capfd):
    """rclpy ties a throttled call site to one severity: an ERROR frame, then a WARN frame, then an
    ERROR frame must give one ERROR and one WARN line (the third is throttled), not a ValueError
    logged as 'frame failed unexpectedly'."""
    stamp = 9_000_000_000_000
    no_z = xyz_cloud(corner_points(), stamp)
    no_z.fields = list(no_z.fields)[:2]
    two_points = xyz_cloud(np.array([[0, 0, 0], [1, 1, 1.0]]), stamp + 1)
    no_z_again = xyz_cloud(corner_points(), stamp + 2)
    no_z_again.fields = list(no_z_again.fields)[:2]
    answers = [harness.send(msg)['diagnostics'] for msg in (no_z, two_points, no_z_again)]
    assert [a.status[0].level for a in answers] == [b'\x02', b'\x01', b'\x02']
    assert diag_values(answers[0])['input_points'] == str(len(corner_points()))  # as the message declares
    time.sleep(0.2)
    err = capfd.readouterr().err
    assert 'failed unexpectedly' not in err
    assert err.count('ERROR: malformed PointCloud2') == 1, err
    assert err.count('WARN: too few valid points') == 1, err


def test_a_sweep_whose_planes_are_not_reliable_is_logged_as_a_warning(ros, capfd):
    """An outside probe: the log said INFO 'retuned: ...' while every frame said WARN 'no reliable planes'."""
    for points, level, other in ((corner_points(0.002), 'INFO', 'WARN'),
                                 (np.random.default_rng(0).random((3000, 3)), 'WARN', 'INFO')):
        node = PlaneValidationNode(parameter_overrides=[Parameter('seed', value=3)])
        harness = Harness(node)
        try:
            harness.send(xyz_cloud(points, 11_000_000_000_000))  # the first frame starts a sweep
            assert harness.node.wait_for_sweep(timeout=30)
            time.sleep(0.2)
        finally:
            harness.close()
        lines = [line for line in capfd.readouterr().err.splitlines() if 'retuned: t = ' in line]
        assert len(lines) == 1 and level in lines[0] and other not in lines[0], lines
        assert ('plane(s) but' in lines[0]) == (level == 'WARN')  # the verdict says why


def test_a_tuning_range_the_cloud_cannot_honour_keeps_the_last_tuned_tolerance(ros):
    node = PlaneValidationNode(parameter_overrides=[Parameter('seed', value=3)])
    harness = Harness(node)
    try:
        quick = diag_values(harness.send(xyz_cloud(corner_points(0.002), 10_000_000_000_000))['diagnostics'])
        assert quick['tolerance_source'] == 'quick estimate (sweep pending)'  # answered at once
        assert harness.node.wait_for_sweep(timeout=30)
        first = diag_values(harness.send(xyz_cloud(corner_points(0.002), 10_000_000_000_001))['diagnostics'])
        assert first['tolerance_source'].startswith('tuned') and first['planes'] == '3'
        assert node.set_parameters([Parameter('tune_min', value=5.0)])[0].successful  # tune_max 0: derived
        harness.send(xyz_cloud(corner_points(0.002), 10_000_000_000_002))  # the background sweep fails
        assert harness.node.wait_for_sweep(timeout=30)
        out = harness.send(xyz_cloud(corner_points(0.002), 10_000_000_000_003))['diagnostics']
        values, status = diag_values(out), out.status[0]
        assert status.level == b'\x01' and 'cannot tune' in status.message and 'tune_min' in status.message
        assert values['tolerance'] == first['tolerance'] and values['tolerance_source'] == 'last tuned (tuning failed)'
        assert values['planes'] == '3'
    finally:
        harness.close()


def test_a_node_stopped_during_a_sweep_stops_it_after_the_current_candidate(ros):
    """Shutdown (Ctrl-C, ros2 launch's SIGTERM) does not wait for a whole sweep."""
    from plane_validation.ros.node import SWEEP_STOP_S
    params = {'auto_tune': True, 'seed': 3, 'tune_count': 100, 'tune_points': 60000}
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    h = Harness(node)
    stopped = False
    try:
        first = h.send(xyz_cloud(scenes.room(60000, 0.01, seed=2).points, 7_000_000_000_000), timeout=60)
        assert diag_values(first['diagnostics'])['tolerance_source'] == 'quick estimate (sweep pending)'
        assert not node.wait_for_sweep(timeout=0.5)  # 100 candidates on 60,000 points: still running
        start = time.perf_counter()
        h.close()
        stopped = True
        assert time.perf_counter() - start < SWEEP_STOP_S + 5.0
        assert node.wait_for_sweep(timeout=SWEEP_STOP_S)  # the sweep ended instead of running on
        assert node.pipeline.tolerance is None  # and adopted nothing
    finally:
        if not stopped:
            h.close()


@pytest.mark.parametrize('step_ns', [100_000_000, 0], ids=['10Hz', 'frozen'])
def test_live_sweeps_the_frames_offline_sweeps_after_a_first_frame_without_planes(ros, step_ns):
    """A first frame without planes fails its sweep; the retry 1 s later (header time, or frames of
    FROZEN_FRAME_S where the stamps do not advance) runs on the same frame live as offline, even when
    the failed sweep is still running at that frame."""
    from plane_validation.app.pipeline import FROZEN_FRAME_S, RETRY_AFTER_S
    params = {'auto_tune': True, 'seed': 5}
    frames = [np.outer(np.linspace(0.0, 3.0, 20000), [1.0, 0.5, 0.2])]  # a line: no plane
    retry = round(RETRY_AFTER_S / FROZEN_FRAME_S)  # the frame RETRY_AFTER_S after the first, at 10 Hz
    frames += [scenes.room(20000, 0.01, seed=k).points for k in range(1, retry + 4)]  # a few past the retry
    frames = [f.astype(np.float32).astype(np.float64) for f in frames]  # as the node receives them
    stamps = [8_000_000_000_000 + k * step_ns for k in range(len(frames))]  # 10 Hz header time, or frozen
    offline = FramePipeline(PipelineConfig(**params))
    for points, stamp_ns in zip(frames, stamps):
        result = offline.process(points, stamp_ns, tune_inline=False)
        if result.segmentation is not None and offline.retune_due(result.clock):
            try:
                offline.retune(result.points, result.clock, stamp_ns)
            except ValueError:
                pass
    assert offline.tuned_at == pytest.approx(stamps[0] * 1e-9 + retry * FROZEN_FRAME_S)
    node = PlaneValidationNode(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    kept = []  # whether a sweep ended with a frame kept for the next one
    worker = node.worker
    ended = worker._sweep_ended
    worker._sweep_ended = lambda: kept.append(worker._next_sweep is not None) or ended()
    retune = node.pipeline.retune

    def first_sweep_outlasts_the_retry_frame(*args, **kwargs):  # however fast the sweep of the line is
        deadline = time.monotonic() + 60
        while not kept and worker.frames_processed <= retry + 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        return retune(*args, **kwargs)
    node.pipeline.retune = first_sweep_outlasts_the_retry_frame
    h = Harness(node)
    try:
        for points, stamp_ns in zip(frames, stamps):
            h.send(xyz_cloud(points, stamp_ns), timeout=60)
        assert node.wait_for_sweep(timeout=120)
        assert kept[0], 'the retry did not come due while the failed sweep ran: the kept frame was not tested'
        assert node.pipeline.tuned_at == offline.tuned_at and node.pipeline.tolerance == offline.tolerance
    finally:
        h.close()


def test_a_lidar_scan_with_a_ring_field_is_answered_on_its_ring_image_and_swept_there(ros):
    # velodyne_pointcloud without organize_cloud; the first frame answers with the quick estimate while the
    # background sweep runs on the ring image (its 8 x 900 sub-grid, not 20,000 points of the scan), whose t
    # the next frame uses
    import sensor_msgs.msg

    from plane_validation.formats.pointcloud2 import create_cloud
    node = PlaneValidationNode(parameter_overrides=[Parameter('seed', value=0)])
    h = Harness(node)
    try:
        scan = scenes.lidar(rings=16, seed=1)
        pts = scan.points.astype(np.float32)
        columns = {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2], 'ring': scan.rings.astype(np.uint16)}

        def frame(stamp_ns: int) -> dict[str, str]:
            msg = create_cloud(make_header(stamp_ns), columns, types=sensor_msgs.msg)
            return diag_values(h.send(msg, timeout=60)['diagnostics'])
        first = frame(7_000_000_000_000)
        assert first['ring_image'] == '16x1800' and first['tolerance_source'] == 'quick estimate (sweep pending)'
        assert node.wait_for_sweep(timeout=60)
        assert node.pipeline.last_tuning.sweep_points <= 8 * 900
        second = frame(7_000_100_000_000)
        assert second['tolerance_source'] == 'tuned at t=7000.000s' and second['planes'] == '6', second
    finally:
        h.close()


def test_orientation_constraint_parameters_over_dds(harness):
    """axis_mode needs an axis (refused on its own, with the reason), and then only planes within axis_angle of it
    come out; an axis of zero length is refused while a mode is set."""
    node = harness.node
    assert node.set_parameters([Parameter('auto_tune', value=False), Parameter('tolerance', value=0.01)])[0].successful
    refused = node.set_parameters([Parameter('axis_mode', value='parallel')])[0]
    assert not refused.successful and 'normal_axis is (0, 0, 0)' in refused.reason
    assert node.set_parameters([Parameter('normal_axis_z', value=1.0)])[0].successful
    assert node.set_parameters([Parameter('axis_mode', value='parallel')])[0].successful
    out = harness.send(xyz_cloud(corner_points(0.1), 5_000_000_000_000), outputs=('diagnostics', 'plane_poses'))
    assert diag_values(out['diagnostics'])['planes'] == '1'
    (pose,) = out['plane_poses'].poses
    q = pose.orientation  # the pose's z axis is the plane's normal
    assert abs(1 - 2 * (q.x ** 2 + q.y ** 2)) > np.cos(np.radians(10))
    zero = node.set_parameters([Parameter('normal_axis_z', value=0.0)])[0]
    assert not zero.successful and 'normal_axis' in zero.reason
    assert node.set_parameters([Parameter('axis_mode', value='none')])[0].successful
    out = harness.send(xyz_cloud(corner_points(0.1), 5_000_000_000_001))
    assert diag_values(out['diagnostics'])['planes'] == '3'


def test_a_signal_during_the_first_compile_stops_the_node_cleanly(tmp_path):
    """The kernels compile before the node starts (a cold cache: a new NUMBA_CACHE_DIR), for minutes on a new
    machine: a Ctrl-C then ends the node at once, quietly (status 0), its compiling workers with it, and what was
    compiled stays cached."""
    import os
    import shutil
    import signal
    import subprocess
    import sys
    from pathlib import Path

    from plane_validation.core import kernels
    cache = tmp_path / 'cache'
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONUNBUFFERED='1')
    # every kernel but the five named below comes from this process's cache, so the node compiles only those (a
    # whole cold compile takes over a minute); marked_rows is in warm()'s first step, so the cache looks cold and
    # the others compile in worker processes, which leave the signal to the node
    kernels.warm()
    subprocess.run([sys.executable, '-c', 'import numpy as np; from plane_validation.core import kernels; '
                    'kernels.finite_mask(np.zeros((2, 3)))'], env=env, check=True, timeout=120)
    folder = next(cache.glob('*'))  # where numba keeps this module's cache under NUMBA_CACHE_DIR
    recompiled = tuple(f'kernels.{name}-' for name in ('marked_rows', 'voxel_grid', 'voxel_knn', 'principal_axes',
                                                           'pair_graph'))
    # this process's cache: __pycache__ beside the module, or under its own NUMBA_CACHE_DIR when one is set
    for path in Path(kernels.finite_mask._cache._cache_path).glob('kernels.*.nb*'):
        if not path.name.startswith(recompiled):
            shutil.copy(path, folder / path.name)
    copied = set(folder.glob('*.nbi'))
    proc = subprocess.Popen([sys.executable, '-m', 'plane_validation.ros.node'], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=env, start_new_session=True)
    try:
        deadline = time.monotonic() + 60

        def in_workers() -> bool:  # a kernel the workers compile was cached: the others are compiling
            return any(not path.name.startswith(recompiled[0]) for path in set(folder.glob('*.nbi')) - copied)

        while not in_workers() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.02)
        assert in_workers(), 'the workers did not start compiling'
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the node and its workers
        sent = time.monotonic()
        out, _ = proc.communicate(timeout=120)
        took = time.monotonic() - sent
        assert session_ended(proc.pid), 'a compiling worker outlived the node'
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 0 and took < 10, (took, out)
    assert 'stopped while compiling the kernels' in out and 'Traceback' not in out, out
    assert any(not path.name.startswith(recompiled[0]) for path in set(folder.glob('*.nbi')) - copied)  # kept
