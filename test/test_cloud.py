"""PointCloud2 <-> numpy on real rclpy and rosbags messages: layouts, errors, round trips."""
from __future__ import annotations

import array
import os
import subprocess
import sys
from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from plane_validation.formats.pointcloud2 import (
    create_cloud,
    pack_rgb,
    ring_array,
    rosbags_types,
    structured_array,
    unpack_rgb,
    xyz_array,
)

sensor_msgs_msg = pytest.importorskip('sensor_msgs.msg')
std_msgs_msg = pytest.importorskip('std_msgs.msg')
builtin_interfaces_msg = pytest.importorskip('builtin_interfaces.msg')
typesys = pytest.importorskip('rosbags.typesys')
pytestmark = pytest.mark.ros  # rclpy and the ROS message packages

TYPESTORE = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
RB = rosbags_types(TYPESTORE)
FAMILIES = ['rclpy', 'rosbags']
CODES = {np.dtype(t): c for c, t in {1: np.int8, 2: np.uint8, 3: np.int16, 4: np.uint16,
                                      5: np.int32, 6: np.uint32, 7: np.float32,
                                      8: np.float64}.items()}
F32, F64 = 7, 8


def header(family: str, frame_id: str = 'lidar', sec: int = 12, nanosec: int = 345):
    if family == 'rclpy':
        return std_msgs_msg.Header(stamp=builtin_interfaces_msg.Time(sec=sec, nanosec=nanosec),
                                   frame_id=frame_id)
    return RB.Header(stamp=RB.Time(sec=sec, nanosec=nanosec), frame_id=frame_id)


def types_of(family: str):
    return sensor_msgs_msg if family == 'rclpy' else RB


@dataclass
class Field:
    """One field of a test layout: values has shape (height*width,) or (height*width, count)."""

    name: str
    dtype: np.dtype
    offset: int
    values: np.ndarray
    count: int = 1
    datatype: int | None = None  # override the code (malformed messages)


@dataclass
class Layout:
    height: int
    width: int
    point_step: int
    row_step: int
    fields: list[Field]
    bigendian: bool = False
    is_dense: bool = True
    extra_fields: list[tuple[str, int, int, int]] = field(default_factory=list)


def write_bytes(layout: Layout, seed: int = 0) -> bytes:
    """Lay out the values byte by byte (independently of cloud.py); padding gets garbage."""
    rng = np.random.default_rng(seed)
    buf = rng.integers(0, 256, layout.height * layout.row_step, dtype=np.uint8)
    rows, cols = np.divmod(np.arange(layout.height * layout.width), max(layout.width, 1))
    starts = rows * layout.row_step + cols * layout.point_step
    order = '>' if layout.bigendian else '<'
    for f in layout.fields:
        raw = np.ascontiguousarray(f.values, dtype=f.dtype.newbyteorder(order)).view(np.uint8)
        size = f.dtype.itemsize * f.count
        idx = starts[:, None] + f.offset + np.arange(size)
        buf[idx] = raw.reshape(len(starts), size)
    return buf.tobytes()


def make_msg(family: str, layout: Layout, data: bytes | None = None, hdr=None):
    """A real PointCloud2 of the given family holding `layout` (or raw `data`)."""
    data = write_bytes(layout) if data is None else data
    types = types_of(family)
    specs = [(f.name, f.offset, CODES[f.dtype] if f.datatype is None else f.datatype, f.count)
             for f in layout.fields] + layout.extra_fields
    fields = [types.PointField(name=n, offset=o, datatype=d, count=c) for n, o, d, c in specs]
    kwargs = dict(header=header(family) if hdr is None else hdr, height=layout.height,
                  width=layout.width, fields=fields, is_bigendian=layout.bigendian,
                  point_step=layout.point_step, row_step=layout.row_step,
                  is_dense=layout.is_dense)
    if family == 'rclpy':
        return types.PointCloud2(data=array.array('B', data), **kwargs)
    return types.PointCloud2(data=np.frombuffer(data, np.uint8).copy(), **kwargs)


def packed_layout(specs: list[tuple[str, str, int]], n: int, *, height: int = 1, pad: int = 0,
                  row_pad: int = 0, seed: int = 1, bigendian: bool = False) -> Layout:
    """Fields (name, dtype, gap before it) in order, point_step padding `pad`, row padding."""
    rng = np.random.default_rng(seed)
    fields, offset = [], 0
    for name, dt, gap in specs:
        dt = np.dtype(dt)
        offset += gap
        if dt.kind == 'f':
            values = rng.normal(0, 10, n).astype(dt)
        else:
            info = np.iinfo(dt)
            values = rng.integers(info.min, info.max, n, dtype=dt, endpoint=True)
        fields.append(Field(name, dt, offset, values))
        offset += dt.itemsize
    width = n // height
    step = offset + pad
    return Layout(height, width, step, width * step + row_pad, fields, bigendian)


def expected_xyz(layout: Layout) -> np.ndarray:
    by = {f.name: f.values for f in layout.fields}
    return np.stack([by['x'], by['y'], by['z']], axis=1).astype(np.float64)


def buffer_of(msg) -> np.ndarray:
    return msg.data if isinstance(msg.data, np.ndarray) else np.frombuffer(msg.data, np.uint8)


# ---------------------------------------------------------------- layouts that decode


XYZ32 = [('x', 'f4', 0), ('y', 'f4', 0), ('z', 'f4', 0)]


@pytest.mark.parametrize('family', FAMILIES)
@pytest.mark.parametrize('specs', [
    XYZ32,
    [('x', 'f8', 0), ('y', 'f8', 0), ('z', 'f8', 0)],
    [('x', 'f4', 0), ('y', 'f8', 0), ('z', 'f4', 0)],
    [('rgb', 'f4', 0), ('x', 'f4', 0), ('y', 'f4', 0), ('z', 'f4', 0)],                # before
    [('x', 'f4', 0), ('intensity', 'f4', 0), ('y', 'f4', 0), ('ring', 'u2', 0),
     ('z', 'f4', 0)],                                                                 # between
    [('x', 'f4', 0), ('y', 'f4', 0), ('z', 'f4', 4), ('intensity', 'f4', 0),
     ('ring', 'u2', 0), ('t', 'u4', 2), ('label', 'i1', 0)],                           # after, gaps
    [('z', 'f8', 0), ('ring', 'u2', 0), ('y', 'f8', 0), ('x', 'f8', 1)],               # reordered
], ids=['f32', 'f64', 'mixed', 'before', 'between', 'after', 'reordered'])
@pytest.mark.parametrize('pad', [0, 3])
def test_xyz_with_extra_fields_and_padding(family, specs, pad):
    layout = packed_layout(specs, 20, pad=pad)
    msg = make_msg(family, layout)
    xyz = xyz_array(msg)
    assert xyz.shape == (20, 3) and xyz.dtype == np.float64 and xyz.flags.c_contiguous
    np.testing.assert_array_equal(xyz, expected_xyz(layout))
    rec = structured_array(msg)
    assert rec.shape == (20,) and rec.dtype.itemsize == layout.point_step
    for f in layout.fields:
        np.testing.assert_array_equal(rec[f.name], f.values)
    np.testing.assert_array_equal(xyz_array(msg, dtype=np.float32),
                                  expected_xyz(layout).astype(np.float32))


@pytest.mark.parametrize('family', FAMILIES)
def test_bigendian_gives_same_values(family):
    specs = [('x', 'f4', 0), ('ring', 'u2', 0), ('y', 'f8', 0), ('z', 'f4', 0), ('rgb', 'f4', 0)]
    little = packed_layout(specs, 12, height=3, row_pad=5, seed=4)
    big = packed_layout(specs, 12, height=3, row_pad=5, seed=4, bigendian=True)
    msg_l, msg_b = make_msg(family, little), make_msg(family, big)
    assert bytes(buffer_of(msg_l)) != bytes(buffer_of(msg_b))
    np.testing.assert_array_equal(xyz_array(msg_b), xyz_array(msg_l))
    rec_l, rec_b = structured_array(msg_l), structured_array(msg_b)
    for name in ('x', 'ring', 'y', 'z', 'rgb'):
        np.testing.assert_array_equal(rec_b[name], rec_l[name])
    assert rec_b.dtype['y'].byteorder == '>'


@pytest.mark.parametrize('family', FAMILIES)
@pytest.mark.parametrize('row_pad', [0, 7])
def test_organized_cloud_with_nan_holes(family, row_pad):
    height, width = 4, 5
    layout = packed_layout(XYZ32 + [('rgb', 'f4', 0)], height * width, height=height,
                           row_pad=row_pad, pad=4)
    holes = [(0, 0), (1, 3), (3, 4), (2, 2)]
    for r, c in holes:
        for f in layout.fields[:3]:
            f.values[r * width + c] = np.nan
    layout.is_dense = False
    msg = make_msg(family, layout)
    assert msg.is_dense is False
    xyz = xyz_array(msg)
    assert xyz.shape == (height * width, 3)
    np.testing.assert_array_equal(xyz, expected_xyz(layout))  # NaN-aware, row-major
    nan_rows = set(np.flatnonzero(np.isnan(xyz).any(axis=1)))
    assert nan_rows == {r * width + c for r, c in holes}
    # Row order: pixel (r, c) is index r*width + c.
    np.testing.assert_array_equal(xyz.reshape(height, width, 3)[2, 1],
                                  expected_xyz(layout)[2 * width + 1])


@pytest.mark.parametrize('family', FAMILIES)
def test_zero_copy_for_contiguous_cloud(family):
    layout = packed_layout(XYZ32 + [('rgb', 'f4', 0)], 24, height=4)
    msg = make_msg(family, layout)
    rec = structured_array(msg)
    assert np.shares_memory(rec, buffer_of(msg))
    assert np.shares_memory(rec['x'], buffer_of(msg))
    xyz = xyz_array(msg)  # always a fresh array
    assert not np.shares_memory(xyz, buffer_of(msg))
    if family == 'rclpy':  # array.array is writable, so the view is too
        rec['x'][0] = 42.0
        assert np.frombuffer(msg.data, '<f4', count=1)[0] == 42.0
        del rec
        msg.data.append(0)  # the export is released with the view


@pytest.mark.parametrize('family', FAMILIES)
def test_row_padding_is_copied_single_row_is_not(family):
    organized = make_msg(family, packed_layout(XYZ32, 12, height=3, row_pad=8))
    rec = structured_array(organized)
    assert not np.shares_memory(rec, buffer_of(organized))
    single = make_msg(family, packed_layout(XYZ32, 12, height=1, row_pad=8))
    assert np.shares_memory(structured_array(single), buffer_of(single))


@pytest.mark.parametrize('family', FAMILIES)
def test_data_longer_than_needed_is_fine(family):
    layout = packed_layout(XYZ32, 6)
    msg = make_msg(family, layout, data=write_bytes(layout) + b'\x01\x02\x03')
    np.testing.assert_array_equal(xyz_array(msg), expected_xyz(layout))


@pytest.mark.parametrize('height', [1, 3])
def test_a_strided_data_array_is_copied(height):
    """An outside probe: a non-contiguous uint8 array as data was refused as malformed, with numpy's "the last axis
    must be contiguous"."""
    layout = packed_layout(XYZ32, 24, height=height)
    msg = make_msg('rosbags', layout)
    every_other = np.zeros(2 * len(msg.data), np.uint8)
    every_other[::2] = msg.data
    msg.data = every_other[::2]  # the same bytes, 2 apart
    np.testing.assert_array_equal(xyz_array(msg), expected_xyz(layout))
    assert structured_array(msg).shape == (24,)


@pytest.mark.parametrize('family', FAMILIES)
@pytest.mark.parametrize('height, width', [(0, 0), (1, 0), (0, 7), (3, 0)])
def test_empty_clouds(family, height, width):
    layout = Layout(height, width, 12, width * 12, [
        Field(n, np.dtype('f4'), 4 * i, np.zeros(0, 'f4')) for i, n in enumerate('xyz')])
    msg = make_msg(family, layout, data=b'')
    xyz = xyz_array(msg)
    assert xyz.shape == (0, 3) and xyz.dtype == np.float64
    assert structured_array(msg).shape == (0,)
    assert xyz_array(msg, dtype=np.float32).dtype == np.float32


def test_default_rclpy_message_is_empty():
    assert xyz_array(sensor_msgs_msg.PointCloud2()).shape == (0, 3)
    assert structured_array(sensor_msgs_msg.PointCloud2()).shape == (0,)


@pytest.mark.parametrize('family', FAMILIES)
def test_padding_named_fields_and_count_gt_1(family):
    layout = packed_layout(XYZ32, 5, pad=0)
    normals = np.arange(15, dtype='f4').reshape(5, 3)
    layout.fields.append(Field('normal', np.dtype('f4'), 12, normals, count=3))
    layout.point_step = 28
    layout.row_step = 5 * 28
    layout.extra_fields = [('_', 24, 2, 4)]  # explicit padding entry, as some writers emit
    msg = make_msg(family, layout)
    rec = structured_array(msg)
    assert rec.dtype.names == ('x', 'y', 'z', 'normal')
    np.testing.assert_array_equal(rec['normal'], layout.fields[3].values)
    np.testing.assert_array_equal(xyz_array(msg), expected_xyz(layout))


# ---------------------------------------------------------------- malformed messages


def base_layout() -> Layout:
    return packed_layout(XYZ32 + [('intensity', 'f4', 0)], 6, height=2)


def malformed(kind: str) -> tuple[Layout, bytes | None]:
    lay = base_layout()
    data = None
    if kind == 'missing_z':
        lay.fields = [f for f in lay.fields if f.name != 'z']
    elif kind == 'short_data':
        data = write_bytes(lay)[:-1]
    elif kind == 'bad_datatype':
        lay.fields[3].datatype = 9
    elif kind == 'bad_datatype_x':
        lay.fields[0].datatype = 0
    elif kind == 'count_x':
        lay.fields[0].count = 2
        lay.fields[0].values = np.repeat(lay.fields[0].values[:, None], 2, axis=1)
        lay.fields = [lay.fields[0]]
        lay.extra_fields = [('y', 8, F32, 1), ('z', 12, F32, 1)]
    elif kind == 'count_zero_z':
        lay.fields[2].count = 0
        lay.fields[2].values = np.zeros((6, 0), 'f4')
    elif kind == 'point_step_small':
        lay.point_step, lay.row_step = 12, 36
        data = bytes(2 * 36)
    elif kind == 'field_beyond_step':
        lay.extra_fields = [('rgb', 14, F32, 1)]
    elif kind == 'row_step_small':
        lay.row_step = lay.width * lay.point_step - 1
        data = bytes(2 * lay.row_step)
    elif kind == 'zero_point_step':
        lay.point_step, lay.row_step = 0, 0
        data = b''
    elif kind == 'xyz_overlap':
        lay.fields[1].offset = 2
        data = bytes(2 * lay.row_step)
    elif kind == 'integer_x':
        lay.fields[0].datatype = 5
    elif kind == 'duplicate':
        lay.extra_fields = [('intensity', 0, F32, 1)]
    elif kind == 'duplicate_x':  # a second 'x' where 'y' is: it was reported as x and y overlapping
        lay.extra_fields = [('x', 4, F32, 1)]
    elif kind == 'huge_offset':
        lay.fields[3].offset = 2**31
        data = bytes(2 * lay.row_step)
    return lay, data


MALFORMED = [
    ('missing_z', r'missing field\(s\) z'),
    ('short_data', r'too short: expected .*= 96 bytes, got 95'),
    ('bad_datatype', r"'intensity' has unsupported datatype code 9"),
    ('bad_datatype_x', r"'x' has unsupported datatype code 0"),
    ('count_x', r"'x' has count 2"),
    ('count_zero_z', r"'z' has count 0"),
    ('point_step_small',
     r"point_step 12 is smaller than the fields need \(16 bytes\).*'intensity'"),
    ('field_beyond_step', r"point_step 16 is smaller .*'rgb' at offset 14"),
    ('row_step_small', r'row_step 47 is smaller than width\*point_step'),
    ('zero_point_step', r'point_step is 0 but width is 3'),
    ('xyz_overlap', r"'x' and 'y' overlap"),
    ('integer_x', r"'x' has datatype INT32; xyz must be FLOAT32 or FLOAT64"),
    ('duplicate', r"'intensity' appears more than once"),
    ('duplicate_x', r"'x' appears more than once"),
    ('huge_offset', r"'intensity' \(offset 2147483648, count 1\) ends 2 GiB or more into the point"),
]


@pytest.mark.parametrize('family', FAMILIES)
@pytest.mark.parametrize('kind, match', MALFORMED, ids=[k for k, _ in MALFORMED])
def test_malformed_raises_value_error(family, kind, match):
    layout, data = malformed(kind)
    msg = make_msg(family, layout, data=data)
    with pytest.raises(ValueError, match=match):
        xyz_array(msg)


@pytest.mark.parametrize('family', FAMILIES)
@pytest.mark.parametrize('kind', ['short_data', 'bad_datatype', 'point_step_small',
                                  'field_beyond_step', 'row_step_small', 'zero_point_step',
                                  'duplicate'])
def test_malformed_layout_also_rejected_by_structured_array(family, kind):
    layout, data = malformed(kind)
    with pytest.raises(ValueError):
        structured_array(make_msg(family, layout, data=data))


def test_missing_xyz_is_fine_for_structured_array():
    layout, _ = malformed('missing_z')
    rec = structured_array(make_msg('rosbags', layout))
    assert rec.dtype.names == ('x', 'y', 'intensity')


@pytest.mark.parametrize('bad', [np.int32, 'i8'])
def test_xyz_array_rejects_non_float_output(bad):
    with pytest.raises(ValueError, match='floating dtype'):
        xyz_array(make_msg('rosbags', base_layout()), dtype=bad)


# ---------------------------------------------------------------- create_cloud


def sample_columns(n: int = 50, seed: int = 3) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    xyz = rng.normal(0, 5, (n, 3))
    colours = rng.integers(0, 256, (3, n), dtype=np.uint8)
    return {
        'x': xyz[:, 0].astype(np.float32), 'y': xyz[:, 1].astype(np.float32),
        'z': xyz[:, 2].astype(np.float32),
        'plane_id': rng.integers(-1, 6, n).astype(np.int32),
        'rgb': pack_rgb(*colours),
        'intensity': rng.random(n),                       # float64
        'ring': rng.integers(0, 128, n).astype(np.uint16),
        'flag': rng.integers(-128, 128, n).astype(np.int8),
        'mask': rng.integers(0, 256, n).astype(np.uint8),
        'label': rng.integers(-9, 9, n).astype(np.int16),
        'count': rng.integers(0, 2**32, n).astype(np.uint32),
    }


@pytest.mark.parametrize('family', FAMILIES)
def test_create_cloud_round_trip(family):
    cols = sample_columns()
    hdr = header(family, 'map', 7, 8)
    msg = create_cloud(hdr, cols, types=types_of(family))
    assert isinstance(msg, types_of(family).PointCloud2)
    assert msg.header is hdr
    assert (msg.height, msg.width, msg.is_bigendian, msg.is_dense) == (1, 50, False, True)
    assert msg.point_step == 4 * 3 + 4 + 4 + 8 + 2 + 1 + 1 + 2 + 4
    assert msg.row_step == 50 * msg.point_step and len(msg.data) == msg.row_step
    assert [(f.name, f.datatype, f.count) for f in msg.fields][:5] == [
        ('x', F32, 1), ('y', F32, 1), ('z', F32, 1), ('plane_id', 5, 1), ('rgb', F32, 1)]
    if family == 'rclpy':
        assert isinstance(msg.data, array.array) and msg.data.typecode == 'B'
    else:
        assert isinstance(msg.data, np.ndarray) and msg.data.dtype == np.uint8
    np.testing.assert_array_equal(
        xyz_array(msg), np.stack([cols['x'], cols['y'], cols['z']], 1).astype(np.float64))
    rec = structured_array(msg)
    for name, col in cols.items():
        assert rec[name].dtype.newbyteorder('=') == col.dtype.newbyteorder('=')
        np.testing.assert_array_equal(rec[name].view(col.dtype.str[1:]) if name == 'rgb'
                                      else rec[name], col)
    np.testing.assert_array_equal(rec['rgb'].view('<u4'), cols['rgb'].view(np.uint32))


@pytest.mark.parametrize('family', FAMILIES)
def test_the_ring_field_of_a_lidar_scan(family):
    xyz = {a: np.arange(4, dtype=np.float32) for a in 'xyz'}
    hdr = header(family, 'velodyne', 1, 0)
    for dtype in (np.uint16, np.uint8, np.int32):
        msg = create_cloud(hdr, {**xyz, 'ring': np.array([3, 0, 1, 2], dtype)}, types=types_of(family))
        assert ring_array(msg).tolist() == [3, 0, 1, 2] and ring_array(msg).dtype == np.int64
    assert ring_array(create_cloud(hdr, xyz, types=types_of(family))) is None  # no ring field
    floats = create_cloud(hdr, {**xyz, 'ring': np.array([3, 0, 1, 2], np.float32)}, types=types_of(family))
    assert ring_array(floats).tolist() == [3, 0, 1, 2] and ring_array(floats).dtype == np.int64  # whole numbers
    halves = create_cloud(hdr, {**xyz, 'ring': np.array([3, 0, 1, 2.5])}, types=types_of(family))
    assert ring_array(halves).dtype == np.float64  # left for ring_image to refuse with its reason


@pytest.mark.parametrize('family', FAMILIES)
def test_create_cloud_nan_and_empty(family):
    cols = sample_columns(10)
    cols['y'][4] = np.nan
    msg = create_cloud(header(family), cols, types=types_of(family))
    assert msg.is_dense is False
    np.testing.assert_array_equal(xyz_array(msg)[4, 1], np.nan)
    empty = create_cloud(header(family), {k: v[:0] for k, v in cols.items()},
                         types=types_of(family))
    assert (empty.width, len(empty.data), empty.is_dense) == (0, 0, True)
    assert xyz_array(empty).shape == (0, 3)


@pytest.mark.parametrize('columns, match', [
    ({}, 'at least one column'),
    ({'x': np.zeros(3, 'f4'), 'y': np.zeros(4, 'f4')}, 'equal length'),
    ({'x': np.zeros(3, np.int64)}, "'x' has unsupported dtype int64"),
    ({'x': np.zeros(3, bool)}, 'unsupported dtype bool'),
    ({'x': np.zeros((3, 1), 'f4')}, 'must be 1-D'),
])
def test_create_cloud_rejects_bad_columns(columns, match):
    with pytest.raises(ValueError, match=match):
        create_cloud(header('rosbags'), columns, types=RB)


def test_create_cloud_accepts_big_endian_columns():
    cols = {'x': np.arange(4, dtype='>f8'), 'y': np.ones(4, '>f4'), 'z': np.zeros(4, '<f4'),
            'id': np.arange(4, dtype='>i4')}
    msg = create_cloud(header('rosbags'), cols, types=RB)
    assert [f.datatype for f in msg.fields] == [F64, F32, F32, 5]
    np.testing.assert_array_equal(structured_array(msg)['id'], np.arange(4))
    np.testing.assert_array_equal(xyz_array(msg)[:, 0], np.arange(4))


def test_serialization_round_trips_and_cross_family():
    """rclpy CDR <-> rosbags CDR (what a bag replayer does) keeps everything."""
    from rclpy.serialization import deserialize_message, serialize_message
    cols = sample_columns(30)
    cols['x'][[3, 7]] = np.nan
    rcl = create_cloud(header('rclpy'), cols, types=sensor_msgs_msg)
    raw = serialize_message(rcl)
    back = deserialize_message(raw, sensor_msgs_msg.PointCloud2)
    from_bag = TYPESTORE.deserialize_cdr(raw, 'sensor_msgs/msg/PointCloud2')
    rb = create_cloud(header('rosbags'), cols, types=RB)
    rb_raw = TYPESTORE.serialize_cdr(rb, 'sensor_msgs/msg/PointCloud2')
    assert len(rb_raw) == len(raw)  # same CDR layout (alignment padding bytes may differ)
    into_rcl = deserialize_message(bytes(rb_raw), sensor_msgs_msg.PointCloud2)
    ref = xyz_array(rcl)
    for msg in (back, from_bag, into_rcl):
        np.testing.assert_array_equal(xyz_array(msg), ref)
        np.testing.assert_array_equal(structured_array(msg)['plane_id'], cols['plane_id'])
        assert msg.is_dense is False and msg.header.frame_id == 'lidar'
    assert np.shares_memory(structured_array(from_bag), from_bag.data)


def test_strict_rclpy_field_checks():
    """With ROS_PYTHON_CHECK_FIELDS=1 the rclpy setters assert types: create_cloud must pass."""
    code = (
        'import array, numpy as np\n'
        'from sensor_msgs import msg as m\n'
        'from std_msgs.msg import Header\n'
        'from plane_validation.formats.pointcloud2 import create_cloud, xyz_array\n'
        'x = np.arange(5, dtype=np.float32)\n'
        'c = create_cloud(Header(frame_id="f"), {"x": x, "y": x, "z": x, "i": x.astype(np.uint8)},'
        ' types=m)\n'
        'assert c._check_fields and isinstance(c.data, array.array)\n'
        'assert xyz_array(c).shape == (5, 3)\n'
    )
    env = dict(os.environ, ROS_PYTHON_CHECK_FIELDS='1')
    result = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                            timeout=60, cwd=os.path.dirname(os.path.dirname(__file__)))
    assert result.returncode == 0, result.stderr


def test_pack_rgb():
    rgb = pack_rgb(np.array([255, 0, 1], np.uint8), np.array([0, 255, 2], np.uint8),
                   np.array([0, 0, 3], np.uint8))
    assert rgb.dtype == np.float32
    assert list(rgb.view(np.uint32)) == [0xFF0000, 0x00FF00, 0x010203]
    r, g, b = unpack_rgb(rgb)
    assert [r.tolist(), g.tolist(), b.tolist()] == [[255, 0, 1], [0, 255, 2], [0, 0, 3]]
    assert pack_rgb(255, 255, 255).view(np.uint32) == 0xFFFFFF
    assert not np.isnan(pack_rgb(*np.full((3, 256), np.arange(256), np.uint8))).any()
    with pytest.raises(ValueError, match='outside'):
        pack_rgb(np.array([256]), 0, 0)
    with pytest.raises(ValueError, match='integers'):
        pack_rgb(np.array([0.5]), 0, 0)
    r, g, b = unpack_rgb(rgb.astype('>f4'))  # e.g. the rgb column of a big-endian cloud
    assert [r.tolist(), g.tolist(), b.tolist()] == [[255, 0, 1], [0, 255, 2], [0, 0, 3]]


def test_create_cloud_rejects_padding_column_name():
    with pytest.raises(ValueError, match='invalid column name'):
        create_cloud(header('rosbags'), {'x': np.zeros(2, 'f4'), '_': np.zeros(2, 'u1')}, types=RB)


# ---------------------------------------------------------------- property test

ALL_DTYPES = ['i1', 'u1', 'i2', 'u2', 'i4', 'u4', 'f4', 'f8']


@st.composite
def random_layouts(draw) -> tuple[Layout, int]:
    """x/y/z (float32/64) shuffled among 0-4 extra fields, with random gaps, padding, order."""
    specs = [(n, draw(st.sampled_from(['f4', 'f8'])), 1) for n in 'xyz']
    n_extra = draw(st.integers(0, 4))
    specs += [(f'extra{i}', draw(st.sampled_from(ALL_DTYPES)), draw(st.integers(1, 3)))
              for i in range(n_extra)]
    specs = draw(st.permutations(specs))
    height, width = draw(st.integers(0, 5)), draw(st.integers(0, 7))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    n = height * width
    fields, offset = [], 0
    for name, dt, count in specs:
        dt = np.dtype(dt)
        offset += draw(st.integers(0, 3))
        shape = (n,) if count == 1 else (n, count)
        if dt.kind == 'f':
            values = rng.normal(0, 100, shape).astype(dt)
            values[rng.random(shape) < 0.15] = np.nan
            values[rng.random(shape) < 0.05] = np.inf
        else:
            info = np.iinfo(dt)
            values = rng.integers(info.min, info.max, shape, dtype=dt, endpoint=True)
        fields.append(Field(name, dt, offset, values, count))
        offset += dt.itemsize * count
    point_step = offset + draw(st.integers(0, 9))
    row_step = width * point_step + draw(st.integers(0, 17))
    layout = Layout(height, width, point_step, row_step, fields,
                    bigendian=draw(st.booleans()))
    return layout, seed


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_layouts(), st.sampled_from(FAMILIES))
def test_property_random_layouts_decode_exactly(layout_seed, family):
    layout, seed = layout_seed
    msg = make_msg(family, layout, data=write_bytes(layout, seed))
    xyz = xyz_array(msg)
    n = layout.height * layout.width
    assert xyz.shape == (n, 3)
    if n == 0:
        return
    np.testing.assert_array_equal(xyz, expected_xyz(layout))  # NaN-aware, exact
    rec = structured_array(msg)
    assert rec.shape == (n,)
    for f in layout.fields:
        np.testing.assert_array_equal(rec[f.name], f.values)
    # A flat view exists unless row padding separates several multi-point rows.
    contiguous = (layout.height == 1 or layout.width == 1
                  or layout.row_step == layout.width * layout.point_step)
    assert np.shares_memory(rec, buffer_of(msg)) == contiguous


def test_a_message_without_a_field_list_is_a_clear_error():
    from types import SimpleNamespace  # a hand-made message (an outside probe: it raised a TypeError)
    msg = SimpleNamespace(height=1, width=1, fields=None, is_bigendian=False, point_step=12, row_step=12,
                          data=bytes(12), is_dense=True)
    with pytest.raises(ValueError, match='PointCloud2.fields must be a list of PointField'):
        xyz_array(msg)
    assert ring_array(SimpleNamespace(fields=[])) is None
