"""The volume test of the verdict: how much of the cloud lies just beyond each plane's band, within its extent.

A plane cut out of a volume (clutter, or a t far below its surface's noise) has about as many points at t..2t from it
as within t; a surface has few. The verdict's limit lives in core/verdict.py (MAX_BEYOND). Pure numpy and the compiled
kernels, no ROS import.
"""
from __future__ import annotations

import numpy as np

from . import kernels
from .noise import tolerance_scale
from .plane_silhouette import EXTENT_PERCENTILES
from .ransac import Segmentation
from .search.neighbours import NORMAL_MIN_COS

__all__ = ['BEYOND_SAMPLE', 'beyond_share', 'beyond_share_numpy', 'in_plane_axes', 'plane_extents', 'check_rows']

#: The cloud's points plane_beyond counts among, at most (every so many rows).
BEYOND_SAMPLE = 10000


def beyond_share(pts: np.ndarray, seg: Segmentation, frames: list, thin: np.ndarray, extents: tuple | None = None
                 ) -> np.ndarray:
    """Per plane of ``seg`` (k,): the points of ``pts`` (N, 3) meters (about BEYOND_SAMPLE of them) at t..2t from it,
    per point within t, both within its in-plane extent, not counting the points of a ``thin`` (k,) bool plane
    parallel to it; from each plane's inlier :func:`.plane_shape.principal_frame` (and its :func:`plane_extents`
    when known). All planes at once, the counts in one compiled pass (:func:`.kernels.beyond_counts`;
    :func:`beyond_share_numpy` is the reference)."""
    if len(seg.planes) == 0:
        return np.zeros(0)
    labels, t, box, d = _beyond_rows(pts, seg, frames)
    lo, hi, surface = _beyond_frames(seg, frames, thin, extents)
    t = np.full(1, t) if np.ndim(t) == 0 else np.ascontiguousarray(t[:, 0])
    within, beyond = kernels.beyond_counts(box, d, kernels.c_array(labels, np.int32), t, lo, hi, surface)
    return beyond / np.maximum(within, 1)


def _beyond_rows(pts: np.ndarray, seg: Segmentation, frames: list
                 ) -> tuple[np.ndarray, float | np.ndarray, np.ndarray, np.ndarray]:
    """The rows :func:`beyond_share` counts among (every so many of ``pts``, those whose coordinates sum to a finite
    value, gathered in one compiled pass: :func:`.kernels.beyond_rows`): (their labels (m,), the tolerance (a number,
    or (m, 1) by the noise model), their coordinates along each plane's in-plane axes (m, 2k) and their distances to
    each plane (m, k), meters)."""
    check_rows(pts, seg)
    cloud, labels = kernels.beyond_rows(kernels.c_array(pts, np.float64), max(1, -(-len(pts) // BEYOND_SAMPLE)),
                                        kernels.c_array(seg.labels, np.int32))
    scale = tolerance_scale(cloud, seg.noise_model, seg.noise_reference, seg.viewpoint)
    t = seg.tolerance * (1.0 if scale is None else scale[:, None])
    axes = in_plane_axes(frames)
    normals = np.array([p.normal for p in seg.planes])
    d = cloud @ normals.T
    d += np.array([p.offset for p in seg.planes])  # in place: a large temporary less each (page faults)
    return labels, t, cloud @ axes, np.abs(d, out=d)


def in_plane_axes(frames: list) -> np.ndarray:
    """(3, 2k) each plane's two in-plane principal axes from its :func:`.plane_shape.principal_frame` (zeros without
    one)."""
    axes = np.zeros((3, 2 * len(frames)))
    for j, pca in enumerate(frames):
        if pca is not None:
            axes[:, 2 * j:2 * j + 2] = pca[3][:, 1:]
    return axes


def check_rows(pts: np.ndarray, seg: Segmentation) -> None:
    """ValueError unless ``seg`` labels the rows of ``pts`` (N, 3): the compiled passes index them by its labels."""
    if len(seg.labels) != len(pts):
        raise ValueError(f'points has {len(pts)} rows but the segmentation labels {len(seg.labels)}: judge a '
                         'segmentation with the points it was found on')


def _beyond_frames(seg: Segmentation, frames: list, thin: np.ndarray, extents: tuple | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each plane's box (its :func:`plane_extents`, or ``extents`` when known) and which planes' points count as a
    surface for which (k, k) bool: those of a ``thin`` plane nearby, parallel to one (a rug on a floor)."""
    lo, hi = plane_extents(frames) if extents is None else extents
    normals = np.array([p.normal for p in seg.planes])
    return lo, hi, (np.abs(normals @ normals.T) >= NORMAL_MIN_COS) & np.asarray(thin, bool)[None, :]


def plane_extents(frames: list) -> tuple[np.ndarray, np.ndarray]:
    """Each plane's box along its in-plane principal axes from its :func:`.plane_shape.principal_frame`: (lo, hi (2k,),
    in the cloud's coordinates; empty without inliers)."""
    k = len(frames)
    lo, hi = np.full(2 * k, np.inf), np.full(2 * k, -np.inf)  # no inliers: nothing inside
    for j, pca in enumerate(frames):
        if pca is not None:
            centre, centred, _, vectors = pca
            low, high = _extent(vectors[:, 1:].T @ centred.T)
            shift = centre @ vectors[:, 1:]  # the box in the cloud's coordinates
            lo[2 * j:2 * j + 2], hi[2 * j:2 * j + 2] = low + shift, high + shift
    return lo, hi


def beyond_share_numpy(pts: np.ndarray, seg: Segmentation, frames: list, thin: np.ndarray) -> np.ndarray:
    """:func:`beyond_share` in numpy: the reference its kernel is tested against."""
    if len(seg.planes) == 0:
        return np.zeros(0)
    labels, t, box, d = _beyond_rows(pts, seg, frames)
    lo, hi, surface = _beyond_frames(seg, frames, thin)
    box = (box >= lo) & (box <= hi)
    d[~(box[:, 0::2] & box[:, 1::2])] = np.inf  # (m, k): outside a plane's extent counts for neither
    within = np.count_nonzero(d <= t, axis=0)
    beyond = (d > t) & (d <= 2 * t) & ~np.where(labels[:, None] >= 0, surface.T[np.maximum(labels, 0)], False)
    return np.count_nonzero(beyond, axis=0) / np.maximum(within, 1)


def _extent(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (2,) of points ``uv`` (2, m): their EXTENT_PERCENTILES along each axis, as order statistics."""
    lo, hi = (int(q / 100 * (uv.shape[1] - 1) + 0.5) for q in EXTENT_PERCENTILES)
    ends = [kernels.order_statistics(np.ascontiguousarray(axis), lo, lo, hi, hi) for axis in uv]  # (np.partition's)
    return np.array([end[0] for end in ends]), np.array([end[2] for end in ends])
