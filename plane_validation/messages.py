"""ROS 2 messages for one processed frame: segmented cloud, markers, poses, coefficients, diagnostics.

Used by the node and by bag replay (which serializes them with ``rclpy.serialization``), so both
publish byte-identical messages for the same frame. Needs the ROS message packages, not rclpy.
"""
from __future__ import annotations

import colorsys

import numpy as np
import sensor_msgs.msg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, Pose, PoseArray, Quaternion, Vector3
from scipy.spatial import ConvexHull, QhullError
from std_msgs.msg import ColorRGBA, Float64MultiArray, MultiArrayDimension
from visualization_msgs.msg import Marker, MarkerArray

from .cloud import create_cloud, pack_rgb
from .pipeline import FrameResult

__all__ = ['plane_colors', 'segmented_cloud', 'plane_markers', 'plane_poses', 'plane_coefficients',
           'diagnostics', 'frame_messages']

_LEVELS = {0: DiagnosticStatus.OK, 1: DiagnosticStatus.WARN, 2: DiagnosticStatus.ERROR}
#: Grey for unassigned points.
UNASSIGNED_RGB = (128, 128, 128)


def plane_colors(count: int) -> np.ndarray:
    """(count, 3) uint8 distinct colours: golden-ratio steps around the hue circle."""
    hues = (np.arange(count) * 0.618033988749895) % 1.0
    rgb = np.array([colorsys.hsv_to_rgb(h, 0.85, 1.0) for h in hues], dtype=float).reshape(-1, 3)
    return np.round(255 * rgb).astype(np.uint8)


def segmented_cloud(header, result: FrameResult) -> sensor_msgs.msg.PointCloud2:
    """x, y, z (float32), plane_id (int32, -1 unassigned) and packed rgb of the valid points."""
    labels = result.labels.astype(np.int32)
    palette = np.vstack([plane_colors(result.n_planes), np.array([UNASSIGNED_RGB], np.uint8)])
    colors = palette[np.where(labels >= 0, labels, len(palette) - 1)]
    pts = result.points.astype(np.float32)
    return create_cloud(header, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2], 'plane_id': labels,
                                 'rgb': pack_rgb(colors[:, 0], colors[:, 1], colors[:, 2])},
                        types=sensor_msgs.msg)


def _basis(normal: np.ndarray) -> np.ndarray:
    """(3, 3) rotation whose columns are x, y in the plane and z = normal."""
    helper = np.array([1.0, 0, 0]) if abs(normal[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    return np.column_stack([u, np.cross(normal, u), normal])


def _quaternion(rot: np.ndarray) -> Quaternion:
    """Quaternion (x, y, z, w) of a proper rotation matrix."""
    w = np.sqrt(max(0.0, 1 + rot[0, 0] + rot[1, 1] + rot[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1 + rot[0, 0] - rot[1, 1] - rot[2, 2])) / 2, rot[2, 1] - rot[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1 - rot[0, 0] + rot[1, 1] - rot[2, 2])) / 2, rot[0, 2] - rot[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1 - rot[0, 0] - rot[1, 1] + rot[2, 2])) / 2, rot[1, 0] - rot[0, 1])
    return Quaternion(x=float(x), y=float(y), z=float(z), w=float(w))


def _plane_frames(result: FrameResult) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per plane (centroid (3,), rotation (3, 3), inlier points (m, 3))."""
    frames = []
    if result.segmentation is None:
        return frames
    for k, plane in enumerate(result.segmentation.planes):
        pts = result.points[result.labels == k]
        centroid = pts.mean(axis=0) if len(pts) else -plane.offset * plane.normal
        frames.append((centroid, _basis(plane.normal), pts))
    return frames


def plane_poses(header, result: FrameResult) -> PoseArray:
    """Per plane the inlier centroid, oriented so that its z axis is the plane normal."""
    poses = [Pose(position=Point(x=float(c[0]), y=float(c[1]), z=float(c[2])), orientation=_quaternion(rot))
             for c, rot, _ in _plane_frames(result)]
    return PoseArray(header=header, poses=poses)


def _hull_polygon(local: np.ndarray) -> np.ndarray:
    """Indices of the 2-D convex hull of (m, 2) in-plane coordinates, counter-clockwise."""
    if len(local) < 3:
        return np.arange(len(local))
    try:
        return ConvexHull(local).vertices
    except (QhullError, ValueError):
        return np.array([np.argmin(local[:, 0]), np.argmax(local[:, 0])])


def plane_markers(header, result: FrameResult, ns: str = 'planes') -> MarkerArray:
    """DELETEALL, then per plane a filled hull patch, a normal arrow and a text label."""
    markers = [Marker(header=header, ns=ns, action=Marker.DELETEALL)]
    colors = plane_colors(result.n_planes) / 255.0
    for k, (centroid, rot, pts) in enumerate(_plane_frames(result)):
        plane = result.segmentation.planes[k]
        local = (pts - centroid) @ rot[:, :2]
        hull = local[_hull_polygon(local)]
        color = ColorRGBA(r=float(colors[k, 0]), g=float(colors[k, 1]), b=float(colors[k, 2]), a=0.6)
        # Triangle fan around the centroid (the centroid is inside the convex hull).
        corners = centroid + hull @ rot[:, :2].T
        tri = []
        for i in range(len(corners) if len(corners) >= 3 else 0):
            for p in (centroid, corners[i], corners[(i + 1) % len(corners)]):
                tri.append(Point(x=float(p[0]), y=float(p[1]), z=float(p[2])))
        markers.append(Marker(header=header, ns=ns, id=3 * k, type=Marker.TRIANGLE_LIST, action=Marker.ADD,
                              pose=Pose(orientation=Quaternion(w=1.0)), scale=Vector3(x=1.0, y=1.0, z=1.0),
                              color=color, points=tri))
        extent = float(np.ptp(local, axis=0).max()) if len(local) else 1.0
        tip = centroid + plane.normal * max(0.25 * extent, 1e-3)
        markers.append(Marker(header=header, ns=ns, id=3 * k + 1, type=Marker.ARROW, action=Marker.ADD,
                              pose=Pose(orientation=Quaternion(w=1.0)),
                              scale=Vector3(x=0.02 * extent, y=0.04 * extent, z=0.06 * extent),
                              color=ColorRGBA(r=color.r, g=color.g, b=color.b, a=1.0),
                              points=[Point(x=float(c), y=float(d), z=float(e)) for c, d, e in (centroid, tip)]))
        text_at = tip + plane.normal * 0.05 * extent
        markers.append(Marker(header=header, ns=ns, id=3 * k + 2, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD,
                              pose=Pose(position=Point(x=float(text_at[0]), y=float(text_at[1]), z=float(text_at[2])),
                                        orientation=Quaternion(w=1.0)),
                              scale=Vector3(z=max(0.05 * extent, 1e-3)), color=ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0),
                              text=f'plane {k}: {result.plane_counts[k]} pts, rms {plane.rms:.3g} m'))
    return MarkerArray(markers=markers)


def plane_coefficients(result: FrameResult) -> Float64MultiArray:
    """k x 4 rows (a, b, c, d) of a x + b y + c z + d = 0; dims labelled 'planes' and 'coefficients'."""
    coeffs = np.zeros((0, 4)) if result.segmentation is None else result.segmentation.coefficients
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label='planes', size=len(coeffs), stride=4 * len(coeffs)),
                      MultiArrayDimension(label='coefficients', size=4, stride=4)]
    msg.data = coeffs.astype(float).ravel().tolist()
    return msg


def diagnostics(header, result: FrameResult, name: str, extra: tuple[tuple[str, str], ...] = ()) -> DiagnosticArray:
    """One DiagnosticStatus named ``name`` carrying the frame's level, message and key-values."""
    status = DiagnosticStatus(level=_LEVELS[result.level], name=name, message=result.message,
                              hardware_id=header.frame_id,
                              values=[KeyValue(key=k, value=v) for k, v in result.values + tuple(extra)])
    return DiagnosticArray(header=header, status=[status])


def frame_messages(header, result: FrameResult, name: str,
                   extra: tuple[tuple[str, str], ...] = ()) -> dict[str, object]:
    """Every output of one frame keyed by its topic suffix."""
    return {'segmented': segmented_cloud(header, result), 'planes': plane_markers(header, result),
            'plane_poses': plane_poses(header, result), 'plane_coefficients': plane_coefficients(result),
            'diagnostics': diagnostics(header, result, name, extra)}
