"""A validity index made for planes: the plane silhouette (PS), from point-to-plane distances.

The paper's silhouettes compare point-to-point distances, which say little when planes touch along
edges. For a point i on region j, PS compares a_i, its distance to j's plane, with b_i, its distance
to the nearest *other* region, that region's plane clipped to the region's extent (its bounding
rectangle in the plane), at most j's own in-plane RMS radius (so that a lone region has a scale
too): s_i = (b_i - a_i) / max(a_i, b_i). A point of a thin, well separated
region has s_i near 1; a strip of one surface claimed by a plane crossing it (it lies on another
region, b_i ~ 0) has s_i near -1. PS is the mean s_i over all valid points with the unassigned
points counting 0, so it also rewards coverage: slivers found at a tiny tolerance score low.
Cost O(n k) on a sample of n points, k regions. Pure numpy.
"""
from __future__ import annotations

import numpy as np

from .ransac import as_points, finite_rows, generator

__all__ = ['plane_silhouette', 'region_frames', 'clipped_plane_distances', 'dense_codes']

#: Points per region its frame (plane and extent) is estimated from.
FRAME_POINTS = 4096
#: The regions' frames are estimated from a random subset of this many assigned points.
FRAME_SAMPLE = 16384
#: Points whose distances to every region are computed at once.
BLOCK = 65536
#: In-plane extent of a region: these percentiles of its points along each in-plane axis.
EXTENT_PERCENTILES = (0.5, 99.5)


def dense_codes(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ids, codes) of an integer array ``values`` (n,) with n > 0: its distinct values ascending, and
    each value's position among them (n,) (``np.unique(values, return_inverse=True)``)."""
    low = int(values.min())
    if int(values.max()) - low < 4 * len(values) + 1024:  # a lookup table instead of np.unique's sort
        present = np.bincount(values - low) > 0
        return np.flatnonzero(present) + low, (np.cumsum(present) - 1)[values - low]
    ids, codes = np.unique(values, return_inverse=True)
    return ids, codes.reshape(-1)


def region_frames(points: np.ndarray, labels: np.ndarray, k: int, rng: np.random.Generator
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per region 0..k-1 of ``labels`` (N,) on ``points`` (N, 3): centroids (k, 3), axes (k, 3, 3)
    with rows u, v in the plane and the normal last, extents lo, hi (k, 2) along u, v and in-plane
    RMS radii (k,), meters."""
    centroids, axes = np.zeros((k, 3)), np.tile(np.eye(3), (k, 1, 1))
    lo, hi, radius = np.zeros((k, 2)), np.zeros((k, 2)), np.zeros(k)
    order = np.argsort(labels, kind='stable')
    starts = np.searchsorted(labels[order], np.arange(k + 1))
    for j in range(k):
        rows = order[starts[j]:starts[j + 1]]
        if len(rows) > FRAME_POINTS:
            rows = rows[rng.choice(len(rows), FRAME_POINTS, replace=False)]
        if len(rows) == 0:
            continue
        p = points[rows]
        c = p.mean(axis=0)
        centered = p - c
        _, vectors = np.linalg.eigh(centered.T @ centered)  # ascending: the normal first
        frame = vectors[:, [2, 1, 0]].T
        uv = centered @ frame[:2].T
        centroids[j], axes[j] = c, frame
        lo[j], hi[j] = np.percentile(uv, EXTENT_PERCENTILES, axis=0)
        radius[j] = np.sqrt((uv ** 2).sum(axis=1).mean())
    return centroids, axes, lo, hi, radius


def clipped_plane_distances(x: np.ndarray, centroids: np.ndarray, axes: np.ndarray, lo: np.ndarray,
                            hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points ``x`` (m, 3): (m, k) distances to each region's clipped plane, and (m, k)
    distances to each region's infinite plane, meters."""
    rel = x[:, None, :] - centroids[None, :, :]
    local = np.einsum('mkd,kad->mka', rel, axes)  # (m, k, 3): u, v, normal
    outside = np.maximum(np.maximum(lo[None] - local[..., :2], local[..., :2] - hi[None]), 0.0)
    perp = np.abs(local[..., 2])
    return np.sqrt(perp ** 2 + (outside ** 2).sum(axis=-1)), perp


def plane_silhouette(points: np.ndarray, labels: np.ndarray, *, sample_size: int | None = 2000,
                     seed: int | np.random.Generator | None = None) -> float:
    """PS of the regions ``labels`` (N,) int, -1 unassigned, on ``points`` (N, 3) meters; in
    [-1, 1], larger is better; 0.0 without regions. Rows with NaN/inf are ignored. The mean is
    taken over a random sample of ``sample_size`` assigned points (None: all), times the share of
    valid points assigned. The regions' frames come from at most FRAME_POINTS points each, of at
    most FRAME_SAMPLE assigned points when sampled. Deterministic for a fixed int ``seed``."""
    pts = as_points(points)
    lab = np.asarray(labels).reshape(-1)
    if len(lab) != len(pts):
        raise ValueError(f'{len(lab)} labels for {len(pts)} points')
    keep = finite_rows(pts)
    lab = lab.astype(np.int64, copy=False)
    assigned = np.flatnonzero(keep & (lab >= 0))
    if len(assigned) == 0:
        return 0.0
    rng = generator(seed)
    coverage = len(assigned) / np.count_nonzero(keep)
    if sample_size is not None and len(assigned) > FRAME_SAMPLE:  # with replacement: much cheaper on large clouds
        assigned = np.sort(assigned[rng.integers(0, len(assigned), FRAME_SAMPLE)])
    ids, dense = dense_codes(lab[assigned])
    k = len(ids)
    origin = pts[assigned[0]]  # precision for far-away coordinates
    frame_pts = pts[assigned] - origin
    frames = region_frames(frame_pts, dense, k, rng)
    rows = np.arange(len(assigned)) if sample_size is None or len(assigned) <= sample_size else \
        rng.choice(len(assigned), int(sample_size), replace=False)
    total = sum(_silhouette_sum(frame_pts[part], dense[part], frames)  # bounded memory: (block, k, 3)
                for part in np.array_split(rows, -(-len(rows) // BLOCK)))
    return float(total / len(rows) * coverage)


def _silhouette_sum(x: np.ndarray, own: np.ndarray, frames: tuple) -> float:
    """Sum of s_i over the points ``x`` (m, 3) of regions ``own`` (m,), given the regions' ``frames``."""
    centroids, axes, lo, hi, radius = frames
    clipped, perp = clipped_plane_distances(x, centroids, axes, lo, hi)
    a = perp[np.arange(len(x)), own]
    clipped[np.arange(len(x)), own] = np.inf
    b = np.minimum(clipped.min(axis=1), radius[own])
    top = np.maximum(a, b)
    with np.errstate(invalid='ignore', divide='ignore'):
        return float(np.where(top > 0, (b - a) / top, 0.0).sum())
