"""The frame's outputs from its one pass over the rows (ros/messages.py with kernels.frame_pass) against their
references: the generic cloud writer (create_cloud) and the outlines computed per plane in numpy."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from plane_validation.app.pipeline import FramePipeline, PipelineConfig
from plane_validation.core.geometry import _plane_outlines_numpy
from plane_validation.core.scenes import depth_camera

sensor_msgs = pytest.importorskip('sensor_msgs.msg')
std_msgs = pytest.importorskip('std_msgs.msg')
from plane_validation.ros import messages  # noqa: E402  (needs the ROS message packages)

SETTINGS = dict(auto_tune=False, tolerance=0.02, max_planes=4)


@functools.cache
def _results() -> tuple:
    """A depth camera's frame (an inf row, a row with one NaN coordinate) organized and as its valid points, with
    regions, with infinite planes and through a voxel grid, and one with the ground left out of the obstacles."""
    scene = depth_camera('table', width=64, height=48, seed=0)
    points = scene.points.copy()
    points[5] = np.inf
    points[9, 1] = np.nan
    valid = points[np.isfinite(points).all(axis=1)]
    out = []
    for extra in ({}, {'connectivity': False}, {'voxel_size': 0.05}, {'ground_margin': 0.05}):
        pipeline = FramePipeline(PipelineConfig(**SETTINGS, **extra))
        for pts, shape in ((points, scene.shape), (valid, None)):
            out.append((extra, pipeline.process(pts, 10**9, shape=shape)))
    return tuple(out)


@pytest.mark.parametrize('case', range(8))
def test_the_clouds_and_outlines_of_one_pass_match_their_references(case):
    extra, result = _results()[case]
    assert result.n_planes > 0 and 0 < result.obstacles.sum() < len(result.points)
    header = std_msgs.Header(frame_id='camera')
    frame = messages._frame_pass(header, result)
    labels = result.labels.astype(np.int32)
    ids = np.array([*result.plane_ids, -1], np.int32)
    palette = np.vstack([messages._colors(result), np.array([messages.UNASSIGNED_RGB], np.uint8)])
    packed = messages.pack_rgb(palette[:, 0], palette[:, 1], palette[:, 2])
    mask = result.obstacles
    references = {'segmented': messages._cloud(header, result, {'plane_id': ids[labels], 'rgb': packed[labels]},
                                               {'plane_id': -1, 'rgb': packed[-1]}),
                  'obstacles': messages._cloud(header, result, {}, {}, rows=mask) if result.image_shape is None else
                  messages._cloud(header, result, {}, {}, hide=~mask)}
    for name, reference in references.items():
        got = getattr(frame, name)
        assert isinstance(got, sensor_msgs.PointCloud2)
        assert (got.height, got.width, got.point_step, got.row_step, got.is_dense) == \
            (reference.height, reference.width, reference.point_step, reference.row_step, reference.is_dense), name
        assert [(f.name, f.offset, f.datatype) for f in got.fields] == \
            [(f.name, f.offset, f.datatype) for f in reference.fields], name
        assert bytes(got.data) == bytes(reference.data), name
    want = _plane_outlines_numpy(result.points, result.labels, result.segmentation)
    assert len(frame.outlines) == len(want) == result.n_planes
    for got, ref in zip(frame.outlines, want):
        np.testing.assert_allclose(got.centroid, ref.centroid, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(got.rotation, ref.rotation)
        np.testing.assert_allclose(got.corners, ref.corners, rtol=0, atol=1e-12)
        assert got.extent == pytest.approx(ref.extent, abs=1e-12)
    if result.image_shape is not None:  # the organized rows' labels are the valid points'
        finite = np.isfinite(result.organized).all(axis=1)
        np.testing.assert_array_equal(result.image_labels[finite], result.labels)
        np.testing.assert_array_equal(result.image_labels[~finite], -1)


def test_far_coordinates_fall_back_to_float64_for_both_clouds():
    scene = depth_camera('table', width=32, height=24, seed=0)
    result = FramePipeline(PipelineConfig(**SETTINGS)).process(scene.points + 4_012_345.6789, 10**9,
                                                               shape=scene.shape)
    frame = messages._frame_pass(std_msgs.Header(frame_id='utm'), result)
    for cloud in (frame.segmented, frame.obstacles):
        assert [f.datatype for f in cloud.fields[:3]] == [sensor_msgs.PointField.FLOAT64] * 3
        assert (cloud.height, cloud.width) == scene.shape


def test_markers_copied_from_one_base_are_whole_messages_of_their_own():
    """plane_markers copies one base marker per marker: each must equal a Marker built by its constructor from the
    fields it sets (the rest at their defaults), own its lists, and survive a round trip through serialization."""
    serialization = pytest.importorskip('rclpy.serialization')
    marker_msgs = pytest.importorskip('visualization_msgs.msg')
    _, result = _results()[0]
    header = std_msgs.Header(frame_id='camera')
    markers = messages.plane_markers(header, result).markers
    assert len(markers) == 1 + 3 * result.n_planes
    set_fields = ('header', 'ns', 'id', 'type', 'action', 'pose', 'scale', 'color', 'points', 'text')
    for marker in markers:
        built = marker_msgs.Marker(**{name: getattr(marker, name) for name in set_fields})
        assert marker == built
        back = [serialization.deserialize_message(serialization.serialize_message(m), marker_msgs.Marker)
                for m in (marker, built)]  # (compared as messages: padding bytes are left uninitialised)
        assert back[0] == back[1]
    hull, arrow = markers[1], markers[2]
    hull.colors.append(std_msgs.ColorRGBA(r=1.0))
    hull.uv_coordinates.append(marker_msgs.UVCoordinate())
    assert (len(arrow.colors), len(arrow.uv_coordinates)) == (0, 0)
    assert hull.points is not arrow.points and arrow.points is not markers[3].points


@pytest.mark.parametrize('case', range(8))
@pytest.mark.parametrize('keys', [('planes',), ('plane_poses', 'diagnostics'), ('obstacles', 'plane_coefficients'),
                                  ('diagnostics', 'segmented', 'planes')])
def test_outputs_asked_for_alone_are_the_messages_of_all_outputs(keys, case):
    """Without the clouds, the outlines come from their own pass: the same sums in the same order."""
    _, result = _results()[case]
    header = std_msgs.Header(frame_id='camera')
    every = messages.frame_messages(header, result, 'pv', (('extra', '1'),))
    some = messages.frame_messages(header, result, 'pv', (('extra', '1'),), keys)
    assert list(some) == [key for key in messages.OUTPUTS if key in keys]  # in OUTPUTS order, nothing else
    for key, msg in some.items():
        assert msg == every[key], key  # field by field (CDR's padding bytes are not set: no byte comparison)


def test_an_output_the_node_does_not_have_is_refused_by_name():
    _, result = _results()[0]
    with pytest.raises(ValueError, match='no output plane_normals'):
        messages.frame_messages(std_msgs.Header(), result, 'pv', keys=('planes', 'plane_normals'))


def test_a_serialized_cloud_reads_as_the_cloud_it_was_and_other_bytes_are_refused():
    from rclpy.serialization import serialize_message

    from plane_validation.formats.pointcloud2 import xyz_array, xyz_words

    _, result = _results()[0]
    sent = messages.frame_messages(std_msgs.Header(frame_id='camera'), result, 'pv', keys=('segmented',))['segmented']
    sent.header.stamp.sec, sent.header.stamp.nanosec = 17, 42
    cloud, header = messages.cloud_from_cdr(serialize_message(sent))
    assert header == sent.header
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step, cloud.is_dense) == \
        (sent.height, sent.width, sent.point_step, sent.row_step, sent.is_dense)
    fields = [[(f.name, f.offset, f.datatype) for f in m.fields] for m in (cloud, sent)]
    assert fields[0] == fields[1]
    np.testing.assert_array_equal(xyz_array(cloud), xyz_array(sent))
    assert xyz_words(cloud) is not None  # writable, aligned words: the compiled reader's, not the numpy fallback
    for raw in (b'', bytes(range(7, 250)), serialize_message(sent)[:100]):
        with pytest.raises(ValueError, match='not a serialized sensor_msgs/PointCloud2'):
            messages.cloud_from_cdr(raw)


def test_the_clouds_reader_has_jazzys_fields_of_its_messages():
    from plane_validation.formats.bags import typestore

    jazzy = typestore()
    for name in messages.CLOUD_DEFINITIONS:
        assert messages.cloud_types().fielddefs[name][1] == jazzy.fielddefs[name][1], name  # constants aside
