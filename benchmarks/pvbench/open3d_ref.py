"""The reference a user would otherwise pick: Open3D's segment_plane called once per plane."""
from __future__ import annotations

import numpy as np

try:
    import open3d as o3d
except ImportError:  # an optional benchmark extra (benchmarks/requirements.txt)
    o3d = None

ITERATIONS = 1000


def available() -> bool:
    return o3d is not None


def version() -> str:
    return o3d.__version__ if o3d is not None else 'not installed'


def to_cloud(points: np.ndarray):
    """An Open3D PointCloud of (n, 3) finite points (the conversion is not timed with the search)."""
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))


def sequential_planes(cloud, n_points: int, tolerance: float, planes: int = 5,
                      seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``planes`` sequential segment_plane calls (3-point samples, ITERATIONS iterations, the
    library's default probability), removing each plane's inliers from the cloud.

    Returns (coefficients (k, 4) with unit normals, labels (n_points,) into the input order, -1 none).
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
