"""A segmentation's labels carried to other points: within a plane's tolerance, or -1."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..noise import tolerance_scale
from .checks import as_points, finite_rows
from .types import Plane, Segmentation

__all__ = ['within_planes', 'carried']


def within_planes(points: np.ndarray, labels: np.ndarray, seg: Segmentation) -> np.ndarray:
    """``labels`` (n,) of ``points`` (n, 3) meters, planes of ``seg``, with -1 where a point lies farther
    from its plane than the segmentation's tolerance scaled by its noise model at that point."""
    if seg.n_planes == 0:
        return labels
    plane = seg.coefficients[np.maximum(labels, 0)]
    distance = np.abs(np.einsum('ij,ij->i', points, plane[:, :3]) + plane[:, 3])
    scale = tolerance_scale(points, seg.noise_model, seg.noise_reference, seg.viewpoint)
    return np.where(distance <= seg.tolerance * (1.0 if scale is None else scale), labels, -1)


def carried(seg: Segmentation, points: np.ndarray, proxy: np.ndarray) -> Segmentation:
    """``seg``, found on a proxy of ``points`` (N, 3) meters (a lidar scan's ring image, voxel
    centroids), as a segmentation of the points themselves: ``proxy`` (n,) is the proxy row of each
    finite point, in order; a point takes its proxy's plane when it lies within the tolerance of it
    (:func:`within_planes`). The planes keep their coefficients; inliers and rms are the points'."""
    pts = as_points(points)
    finite = finite_rows(pts)
    valid = np.compress(finite, pts, axis=0)
    labels = np.full(len(pts), -1, dtype=np.int32)
    labels[finite] = within_planes(valid, seg.labels[proxy], seg)
    planes = []
    for k, plane in enumerate(seg.planes):
        inliers = np.flatnonzero(labels == k)
        residual = pts[inliers] @ plane.normal + plane.offset
        planes.append(Plane(plane.normal, plane.offset, inliers,
                            float(np.sqrt(np.mean(residual ** 2))) if len(inliers) else 0.0))
    return dataclasses.replace(seg, labels=labels, planes=tuple(planes), n_valid=len(valid))
