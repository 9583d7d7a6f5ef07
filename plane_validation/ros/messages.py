"""ROS 2 messages for one processed frame: segmented cloud, markers, poses, coefficients, diagnostics.

Used by the node and by bag replay (which records them serialized by rosbags, see ros/recorder.py), so
both publish the same messages for the same frame. Needs the ROS message packages, not rclpy.
"""
from __future__ import annotations

import copy
import functools
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
import sensor_msgs.msg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion, Vector3
from std_msgs.msg import ColorRGBA, Float64MultiArray, MultiArrayDimension
from visualization_msgs.msg import Marker, MarkerArray

from ..app.diagnostics import Diagnostic, Level
from ..app.frame_result import FrameResult
from ..core.geometry import (
    UNASSIGNED_RGB,
    PlaneOutline,
    id_colors,
    outline_directions,
    outlines_from,
    plane_bases,
    plane_outlines,
    plane_rows,
)
from ..core.kernels import c_array, frame_pass
from ..formats.files import FLOAT32_FINE, coordinate_dtype
from ..formats.pointcloud2 import cloud_buffer, cloud_message, create_cloud, pack_rgb, record_layout

__all__ = ['OUTPUTS', 'msgtype', 'status_name', 'node_values', 'segmented_cloud', 'obstacle_cloud', 'plane_markers',
           'plane_poses', 'plane_coefficients', 'diagnostics', 'diagnostic_from_status', 'frame_messages',
           'cloud_from_cdr', 'to_rclpy_cloud']

#: The node's outputs: key -> message class. All but the last are published under ~/<key>, the
#: diagnostics on /diagnostics.
OUTPUTS = {'segmented': sensor_msgs.msg.PointCloud2, 'obstacles': sensor_msgs.msg.PointCloud2,
           'planes': MarkerArray, 'plane_poses': PoseArray,
           'plane_coefficients': Float64MultiArray, 'diagnostics': DiagnosticArray}


def msgtype(cls) -> str:
    """'pkg/msg/Name' of an rclpy message class (the name bags and rosbags use)."""
    return f'{cls.__module__.split(".")[0]}/msg/{cls.__name__}'


def status_name(node_name: str) -> str:
    """The name of the node's DiagnosticStatus."""
    return f'{node_name}: plane detection'


def node_values(processed: int, dropped: int, sweep_running: bool, dropped_now: int = 0) -> tuple[tuple[str, str], ...]:
    """The node's own diagnostic key-values, added to each frame's: frames processed and dropped since
    it started, and dropped since its last answer (older than this frame)."""
    return (('frames_processed', str(processed)), ('frames_dropped', str(dropped)),
            ('frames_dropped_since_last', str(dropped_now)), ('retune_running', str(sweep_running).lower()))


def segmented_cloud(header, result: FrameResult) -> sensor_msgs.msg.PointCloud2:
    """x, y, z (float32; float64 where float32 would lose precision: :func:`coordinate_dtype`), plane_id
    (int32: the plane's track id, -1 unassigned) and packed rgb of the valid points; of an organized input,
    its H x W pixels with NaN x, y, z and plane_id -1 where a pixel had no valid point."""
    return _frame_pass(header, result).segmented


def obstacle_cloud(header, result: FrameResult) -> sensor_msgs.msg.PointCloud2:
    """x, y, z of the valid points on no plane (without those near the ground with ``ground_margin``); of an
    organized input, its H x W pixels with NaN where a pixel is not an obstacle."""
    return _frame_pass(header, result).obstacles


#: The records of the segmented and the obstacle cloud (built once: a dtype takes a tenth of a millisecond).
_SEGMENTED_LAYOUT = record_layout({'x': np.float32, 'y': np.float32, 'z': np.float32, 'plane_id': np.int32,
                                   'rgb': np.float32})
_OBSTACLE_LAYOUT = record_layout({'x': np.float32, 'y': np.float32, 'z': np.float32})


@dataclass(frozen=True, eq=False)
class _FramePass:
    """What the one compiled pass over a frame's rows gives: both output clouds and the planes' outlines."""

    segmented: sensor_msgs.msg.PointCloud2
    obstacles: sensor_msgs.msg.PointCloud2
    outlines: tuple[PlaneOutline, ...]


def _frame_pass(header, result: FrameResult) -> _FramePass:
    """The output clouds and outlines of a frame from one pass over its rows (:func:`.kernels.frame_pass`): the
    organized input's H x W rows, else the valid points."""
    seg, image = result.segmentation, result.image_labels is not None
    if image:
        rows, labels, shape = result.organized, result.image_labels, result.image_shape
    else:
        rows, labels, shape = result.points, result.labels, (1, len(result.labels))
    keep = np.zeros(len(result.points), bool) if result.obstacles is None else result.obstacles  # per valid point
    members = None if seg is None else plane_rows(labels, seg)  # before c_array: it knows seg's own labels
    rows, labels, keep = c_array(rows, np.float64), c_array(labels, np.int32), c_array(keep, bool)
    ids = np.array([*result.plane_ids, -1], np.int32)  # label -1 indexes the last entry: -1
    palette = np.vstack([_colors(result), np.array([UNASSIGNED_RGB], np.uint8)])
    packed = pack_rgb(palette[:, 0], palette[:, 1], palette[:, 2])
    rotations = [] if seg is None else plane_bases(seg)
    kept = len(rows) if image else int(np.count_nonzero(keep))
    seg_layout, obs_layout = _SEGMENTED_LAYOUT, _OBSTACLE_LAYOUT
    seg_data = cloud_buffer(len(rows) * seg_layout.itemsize, sensor_msgs.msg)
    obs_data = cloud_buffer(kept * obs_layout.itemsize, sensor_msgs.msg)
    _, centroids, extremes, seg_dense, obs_dense, largest = frame_pass(
        rows, labels, keep, ids, packed.view(np.uint32), outline_directions(rotations),
        np.frombuffer(seg_data, np.uint8), np.frombuffer(obs_data, np.uint8), not image)
    outlines = () if seg is None else outlines_from(rows, members, centroids, extremes, seg, rotations)
    if largest > FLOAT32_FINE:  # float32 may lose precision: each cloud's coordinates as coordinate_dtype says
        return _FramePass(_wide_segmented(header, result, ids, packed), _wide_obstacles(header, result), outlines)
    return _FramePass(cloud_message(header, seg_layout, seg_data, shape, types=sensor_msgs.msg, dense=seg_dense),
                      cloud_message(header, obs_layout, obs_data, shape if image else (1, kept),
                                    types=sensor_msgs.msg, dense=obs_dense),
                      outlines)


def _wide_segmented(header, result: FrameResult, ids: np.ndarray, packed: np.ndarray) -> sensor_msgs.msg.PointCloud2:
    """:func:`segmented_cloud` with coordinates far from the origin (see :func:`coordinate_dtype`)."""
    labels = c_array(result.labels, np.int32)  # label -1 indexes the last entry, the unassigned grey
    return _cloud(header, result, {'plane_id': ids[labels], 'rgb': packed[labels]}, {'plane_id': -1, 'rgb': packed[-1]})


def _wide_obstacles(header, result: FrameResult) -> sensor_msgs.msg.PointCloud2:
    """:func:`obstacle_cloud` with coordinates far from the origin (see :func:`coordinate_dtype`)."""
    mask = np.zeros(len(result.points), bool) if result.obstacles is None else result.obstacles
    if result.image_shape is None:
        return _cloud(header, result, {}, {}, rows=mask)
    return _cloud(header, result, {}, {}, hide=~mask)


def _cloud(header, result: FrameResult, columns: dict, fill: dict, *, rows: np.ndarray | None = None,
           hide: np.ndarray | None = None) -> sensor_msgs.msg.PointCloud2:
    """x, y, z of the valid points (those in ``rows``) and per-point ``columns``; of an organized input
    the H x W image, ``fill`` where a pixel has no valid point and NaN coordinates also where ``hide``."""
    pts = result.points if rows is None else result.points[rows]
    if result.image_shape is None:
        columns = {k: v if rows is None else v[rows] for k, v in columns.items()}
        shape = None
    else:
        if hide is not None:
            pts = np.where(hide[:, None], np.nan, pts)
        pts = result.as_image(pts, np.nan)
        columns = {k: result.as_image(v, fill[k]) for k, v in columns.items()}
        shape = result.image_shape
    pts = pts.astype(coordinate_dtype(pts))
    return create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2], **columns},
                        types=sensor_msgs.msg, shape=shape)


def _colors(result: FrameResult) -> np.ndarray:
    """(k, 3) uint8: each plane the colour of its track id, so a surface keeps its colour."""
    ids = np.asarray(result.plane_ids, np.int64)
    return id_colors(ids)


def _quaternion(rot: np.ndarray) -> Quaternion:
    """Quaternion (x, y, z, w) of a proper rotation matrix."""
    w = np.sqrt(max(0.0, 1 + rot[0, 0] + rot[1, 1] + rot[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + rot[0, 0] - rot[1, 1] - rot[2, 2])) / 2, rot[2, 1] - rot[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - rot[0, 0] + rot[1, 1] - rot[2, 2])) / 2, rot[0, 2] - rot[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - rot[0, 0] - rot[1, 1] + rot[2, 2])) / 2, rot[1, 0] - rot[0, 1])
    return Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))


def _outlines(result: FrameResult) -> tuple[PlaneOutline, ...]:
    if result.segmentation is None:
        return ()
    if result.image_labels is not None:
        return plane_outlines(result.organized, result.image_labels, result.segmentation)
    return plane_outlines(result.points, result.labels, result.segmentation)


def plane_poses(header, result: FrameResult, outlines: tuple[PlaneOutline, ...] | None = None) -> PoseArray:
    """Per plane (in ascending track id order) the inlier centroid, oriented so that its z axis is the
    plane normal."""
    outlines = _outlines(result) if outlines is None else outlines
    poses = [Pose(position=Point(x=float(o.centroid[0]), y=float(o.centroid[1]), z=float(o.centroid[2])),
                  orientation=_quaternion(o.rotation)) for o in outlines]
    return PoseArray(header=header, poses=poses)


def _point(p: np.ndarray) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def plane_markers(header, result: FrameResult, ns: str = 'planes',
                  outlines: tuple[PlaneOutline, ...] | None = None) -> MarkerArray:
    """DELETEALL, then per plane a filled hull patch (namespace ``<ns>/hull``), a normal arrow
    (``<ns>/normal``) and a text label (``<ns>/label``), each with the plane's track id as its id."""
    outlines = _outlines(result) if outlines is None else outlines
    markers = [Marker(header=header, ns=ns, action=Marker.DELETEALL)]
    base = Marker(header=header, action=Marker.ADD)  # each marker a copy of it: Marker() builds every default anew
    colors = _colors(result) / 255.0
    for k, outline in enumerate(outlines):
        plane, pid = result.segmentation.planes[k], int(result.plane_ids[k])
        centroid, corners, extent = outline.centroid, outline.corners, outline.extent
        color = ColorRGBA(r=float(colors[k, 0]), g=float(colors[k, 1]), b=float(colors[k, 2]), a=0.6)
        # Triangle fan around the centroid (the centroid is inside the convex hull); one Point per vertex, listed
        # by each triangle through it (a message holds their values: building them is what costs)
        hull = [Point(x=x, y=y, z=z) for x, y, z in corners.tolist()] if len(corners) >= 3 else []
        middle = _point(centroid)
        tri = [p for i in range(len(hull)) for p in (middle, hull[i], hull[(i + 1) % len(hull)])]
        markers.append(_marker(base, f'{ns}/hull', pid, Marker.TRIANGLE_LIST, Pose(orientation=Quaternion(w=1.0)),
                               Vector3(x=1.0, y=1.0, z=1.0), color, tri))
        tip = centroid + plane.normal * max(0.25 * extent, 1e-3)
        markers.append(_marker(base, f'{ns}/normal', pid, Marker.ARROW, Pose(orientation=Quaternion(w=1.0)),
                               Vector3(x=0.02 * extent, y=0.04 * extent, z=0.06 * extent),
                               ColorRGBA(r=color.r, g=color.g, b=color.b, a=1.0), [_point(centroid), _point(tip)]))
        text_at = tip + plane.normal * 0.05 * extent
        markers.append(_marker(base, f'{ns}/label', pid, Marker.TEXT_VIEW_FACING,
                               Pose(position=_point(text_at), orientation=Quaternion(w=1.0)),
                               Vector3(z=max(0.05 * extent, 1e-3)), ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0), [],
                               f'plane {pid}: {result.plane_counts[k]} pts, rms {plane.rms:.3g} m'))
    return MarkerArray(markers=markers)


def _marker(base: Marker, ns: str, pid: int, kind: int, pose: Pose, scale: Vector3, color: ColorRGBA,
            points: list, text: str = '') -> Marker:
    """A copy of ``base`` with these fields: what Marker(...) gives, without building the defaults (texture, mesh
    file, lifetime) once more for each marker; the copies share those unset defaults (and the header) with ``base``."""
    marker = copy.copy(base)
    marker.ns, marker.id, marker.type, marker.pose, marker.scale, marker.color = ns, pid, kind, pose, scale, color
    marker.points, marker.colors, marker.uv_coordinates, marker.text = points, [], [], text
    return marker


def plane_coefficients(result: FrameResult) -> Float64MultiArray:
    """k x 4 rows (a, b, c, d) of a x + b y + c z + d = 0 in ascending track id order (the ids are the
    diagnostics' ``plane_ids``); dims labelled 'planes' and 'coefficients'."""
    coeffs = np.zeros((0, 4)) if result.segmentation is None else result.segmentation.coefficients
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label='planes', size=len(coeffs), stride=4 * len(coeffs)),
                      MultiArrayDimension(label='coefficients', size=4, stride=4)]
    msg.data = coeffs.astype(float).ravel().tolist()
    return msg


def diagnostics(header, diagnostic: Diagnostic, name: str) -> DiagnosticArray:
    """One DiagnosticStatus named ``name`` carrying the frame's level, message and key-values."""
    status = DiagnosticStatus(level=bytes([int(diagnostic.level)]), name=name, message=diagnostic.message,
                              hardware_id=header.frame_id,
                              values=[KeyValue(key=k, value=v) for k, v in diagnostic.values])
    return DiagnosticArray(header=header, status=[status])


def diagnostic_from_status(status) -> Diagnostic:
    """The inverse of :func:`diagnostics` for one DiagnosticStatus (rclpy or rosbags)."""
    level = status.level if isinstance(status.level, int) else status.level[0]
    return Diagnostic(Level(level), str(status.message), tuple((str(kv.key), str(kv.value)) for kv in status.values))


def frame_messages(header, result: FrameResult, name: str, extra: tuple[tuple[str, str], ...] = (),
                   keys: Collection[str] | None = None) -> dict[str, object]:
    """The outputs of one frame keyed by their topic suffix, in OUTPUTS order: those in ``keys`` (None: every
    output); ``extra`` key-values are added to its diagnostics."""
    keys = OUTPUTS.keys() if keys is None else frozenset(keys)
    unknown = set(keys) - OUTPUTS.keys()
    if unknown:
        raise ValueError(f'no output {", ".join(sorted(unknown))}; outputs: {", ".join(OUTPUTS)}')
    frame = outlines = None
    if 'segmented' in keys or 'obstacles' in keys:
        frame = _frame_pass(header, result)  # one pass: both clouds and the outlines the markers and poses share
        outlines = frame.outlines
    elif 'planes' in keys or 'plane_poses' in keys:
        outlines = _outlines(result)
    build = {'segmented': lambda: frame.segmented, 'obstacles': lambda: frame.obstacles,
             'planes': lambda: plane_markers(header, result, outlines=outlines),
             'plane_poses': lambda: plane_poses(header, result, outlines),
             'plane_coefficients': lambda: plane_coefficients(result),
             'diagnostics': lambda: diagnostics(header, result.diagnostic.with_values(*extra), name)}
    return {key: build[key]() for key in OUTPUTS if key in keys}


#: The definitions a serialized PointCloud2 needs (ROS 2 Jazzy's fields of these messages): a typestore of these alone
#: is built in 0.01 s, rosbags' whole Jazzy store in 0.2 s (the node builds its reader as it starts).
CLOUD_DEFINITIONS = {
    'builtin_interfaces/msg/Time': 'int32 sec\nuint32 nanosec',
    'std_msgs/msg/Header': 'builtin_interfaces/Time stamp\nstring frame_id',
    'sensor_msgs/msg/PointField': 'string name\nuint32 offset\nuint8 datatype\nuint32 count',
    'sensor_msgs/msg/PointCloud2': 'std_msgs/Header header\nuint32 height\nuint32 width\n'
                                   'sensor_msgs/PointField[] fields\nbool is_bigendian\nuint32 point_step\n'
                                   'uint32 row_step\nuint8[] data\nbool is_dense',
}


@functools.cache
def cloud_types():
    """A rosbags typestore of CLOUD_DEFINITIONS."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.EMPTY)
    for name, text in CLOUD_DEFINITIONS.items():
        store.register(get_types_from_msg(text, name))
    return store


def cloud_from_cdr(raw: bytes):
    """(PointCloud2, rclpy Header) of a serialized sensor_msgs/PointCloud2 (a raw subscription's bytes): the cloud
    as a rosbags message whose data is a view of one writable copy of ``raw`` (the compiled reader takes writable,
    aligned words; rclpy's own deserialization costs four times as much), and its header for the outputs.
    ValueError when the bytes are not such a message."""
    try:
        msg = cloud_types().deserialize_cdr(bytearray(raw), 'sensor_msgs/msg/PointCloud2')
    except Exception as exc:  # rosbags raises struct.error, IndexError, its own errors on truncated bytes
        raise ValueError(f'not a serialized sensor_msgs/PointCloud2 ({len(raw)} bytes): {exc}') from exc
    return msg, _rclpy_header(msg.header)


def _rclpy_header(header):
    """The rclpy std_msgs/Header of a rosbags one (ROS 2 or ROS 1 layout)."""
    from builtin_interfaces.msg import Time
    from std_msgs.msg import Header
    stamp = header.stamp
    return Header(stamp=Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec)), frame_id=str(header.frame_id))


def to_rclpy_cloud(msg):
    """rosbags PointCloud2 (ROS 2 or ROS 1 layout) -> rclpy sensor_msgs/PointCloud2, data copied once."""
    import array

    from sensor_msgs.msg import PointCloud2, PointField

    out = PointCloud2(header=_rclpy_header(msg.header),
                      height=int(msg.height), width=int(msg.width), is_bigendian=bool(msg.is_bigendian),
                      point_step=int(msg.point_step), row_step=int(msg.row_step), is_dense=bool(msg.is_dense),
                      fields=[PointField(name=str(f.name), offset=int(f.offset), datatype=int(f.datatype),
                                         count=int(f.count)) for f in msg.fields])
    out.data = array.array('B', np.asarray(msg.data, dtype=np.uint8).tobytes())
    return out
