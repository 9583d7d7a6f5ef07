"""The reference a user would otherwise pick: Open3D's segment_plane called once per plane.

Optional: ``pip install -r benchmarks/requirements.txt`` (open3d-cpu; needs Debian's libusb-1.0-0).
"""
from __future__ import annotations

import numpy as np

try:
    import open3d as o3d
    MISSING = ''
except ImportError as exc:  # an optional benchmark extra; installed, it can still lack a system library (libusb-1.0)
    o3d = None
    MISSING = 'not installed' if exc.name == 'open3d' else f'not importable ({exc})'

ITERATIONS = 1000


def available() -> bool:
    return o3d is not None


def version() -> str:
    return o3d.__version__ if o3d is not None else MISSING


def params() -> str:
    """The call sequence and arguments used, as text for the report."""
    doc = (o3d.geometry.PointCloud.segment_plane.__doc__ or '') if o3d is not None else ''
    probability = ', probability left at its default 0.99999999' if 'probability' in doc else ''
    return (f'segment_plane(distance_threshold=t, ransac_n=3, num_iterations={ITERATIONS}{probability}) '
            'once per plane, select_by_index(inliers, invert=True) between calls, '
            'open3d.utility.random.seed(run) before each run')


def to_cloud(points: np.ndarray):
    """An Open3D PointCloud of (n, 3) finite points (timed apart from the plane search)."""
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))


def sequential_planes(cloud, n_points: int, tolerance: float, planes: int = 5,
                      seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``planes`` sequential segment_plane calls, removing each plane's inliers from the cloud.

    tolerance: m. Returns (coefficients (k, 4) with unit normals, labels (n_points,) in the input
    order, plane index or -1).
    """
    o3d.utility.random.seed(seed)
    labels = np.full(n_points, -1, np.int32)
    index = np.arange(n_points)
    coefficients = []
    rest = cloud
    for k in range(planes):
        if len(rest.points) < 3:
            break
        model, inliers = rest.segment_plane(distance_threshold=tolerance, ransac_n=3, num_iterations=ITERATIONS)
        if len(inliers) < 3:
            break
        model = np.asarray(model, dtype=float)
        coefficients.append(model / np.linalg.norm(model[:3]))
        inliers = np.asarray(inliers)
        labels[index[inliers]] = k
        index = np.delete(index, inliers)
        rest = rest.select_by_index(inliers, invert=True)
    return np.array(coefficients).reshape(-1, 4), labels
