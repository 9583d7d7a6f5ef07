"""The largest plane among the points no detected plane covers: a surface the search left behind.

:func:`leftover_plane` runs a small RANSAC (triples of nearby points) on a sample of the points in no plane that lie
farther than COVER tolerances from every detected plane within its extent, at the segmentation's own tolerance and
noise model. A large plane there is a surface the search did not find (a wall lost once the search stopped at
max_planes, the rest of a wall of which only a piece was found), which the tests of each found plane cannot see.
The verdict's limit lives in core/verdict.py (LEFTOVER_SHARE). Its two passes are compiled
(:func:`.kernels.leftover_rows`, :func:`.kernels.leftover_best`); :func:`leftover_rows_numpy` and
:func:`leftover_best_numpy` are their references. Pure numpy and the compiled kernels, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernels
from .noise import MAX_SCALE, check_noise_model, tolerance_scale
from .ransac import Segmentation, as_points

__all__ = ['Leftover', 'leftover_plane', 'leftover_rows_numpy', 'leftover_best_numpy', 'COVER', 'ROWS', 'SAMPLE',
           'HYPOTHESES', 'NEIGHBOURS', 'MIN_POINTS']

#: Points within this many tolerances of a detected plane, inside its extent, are its surface's: the tails of its noise
#: beyond t are not a surface left behind (the rest of a coplanar surface beyond its extent may be).
COVER = 2.0
#: The cloud is read every so many rows, about this many of them (the share is a sample's estimate) ...
ROWS = 4000
#: ... and RANSAC runs on at most this many of the uncovered points among them (every so many-th), ...
SAMPLE = 500
#: ... with this many planes through a point and two of its NEIGHBOURS nearest (a surface's points lie together:
#: triples of nearby points find it in a few tries where random ones across clutter would not).
HYPOTHESES = 64
NEIGHBOURS = 8
#: Fewer uncovered points than this in the sample: nothing left to find.
MIN_POINTS = 30


@dataclass(frozen=True)
class Leftover:
    """The largest plane among the uncovered points: ``share`` of the valid points within its tolerance (estimated
    on a sample; 0 when too few points are left), its unit ``normal`` (3,) and ``offset`` (m; NaN when none), and
    ``free``: the share of the valid points in no plane."""

    share: float
    normal: np.ndarray
    offset: float
    free: float


def leftover_plane(points: np.ndarray, seg: Segmentation, extents: tuple | None = None) -> Leftover:
    """:class:`Leftover` of ``seg`` on ``points`` (N, 3) meters (NaN rows are no points): its tolerance t per point
    under its noise model; points within COVER t of a detected plane are left out, only within its extent when
    ``extents`` gives them (axes (3, 2k): each plane's two in-plane axes; lo, hi (2k,): the range of its points
    along them, meters; an empty range covers nothing), else everywhere on its infinite plane; RANSAC on up to
    SAMPLE of the rest, deterministic for a given cloud and segmentation."""
    pts = kernels.c_array(as_points(points), np.float64)
    if len(seg.labels) != len(pts):
        raise ValueError(f'points has {len(pts)} rows but the segmentation labels {len(seg.labels)}: judge a '
                         'segmentation with the points it was found on')
    args = _row_args(seg, extents)
    cloud, t, valid, free = kernels.leftover_rows(pts, kernels.c_array(seg.labels, np.int32),
                                                  max(1, len(pts) // ROWS), *args)
    if valid == 0:
        return Leftover(0.0, np.full(3, np.nan), float('nan'), 0.0)
    if len(cloud) < MIN_POINTS:
        return Leftover(0.0, np.full(3, np.nan), float('nan'), free / valid)
    step = -(-len(cloud) // SAMPLE)
    sample, ts = np.ascontiguousarray(cloud[::step]), np.ascontiguousarray(t[::step])
    first, picks = _draws(len(sample))
    normal, offset, count = kernels.leftover_best(sample, ts, first, picks, NEIGHBOURS)
    return Leftover(count / len(sample) * len(cloud) / valid, normal, float(offset), free / valid)


def _row_args(seg: Segmentation, extents: tuple | None) -> tuple:
    """The arguments of :func:`.kernels.leftover_rows` after the rows and their stride: the planes, t and the noise
    model's terms, COVER and the planes' extents (infinite without ``extents``)."""
    reference = check_noise_model(seg.noise_model, seg.noise_reference)
    k = seg.n_planes
    if extents is None:
        axes, lo, hi = np.zeros((3, 2 * k)), np.full(2 * k, -np.inf), np.full(2 * k, np.inf)
    else:
        axes, lo, hi = extents
    return (kernels.c_array(seg.coefficients, np.float64), float(seg.tolerance), seg.noise_model == 'depth_quadratic',
            reference, kernels.c_array(seg.viewpoint, np.float64), MAX_SCALE, COVER, kernels.c_array(axes, np.float64),
            kernels.c_array(lo, np.float64), kernels.c_array(hi, np.float64))


def _draws(m: int) -> tuple[np.ndarray, np.ndarray]:
    """The hypotheses' first points (HYPOTHESES,), spread evenly over the ``m`` in the sample's order (the cloud's rows:
    over its extent), and the places (HYPOTHESES, 2) of the other two among each one's NEIGHBOURS nearest (1..; 0 is
    itself), every pair in turn: fixed draws, cheaper than a generator's."""
    size = min(NEIGHBOURS + 1, m)
    pairs = np.array([(i, j) for i in range(1, size) for j in range(i + 1, size)], dtype=np.int64).reshape(-1, 2)
    return np.arange(HYPOTHESES, dtype=np.int64) * m // HYPOTHESES, pairs[np.arange(HYPOTHESES) % len(pairs)]


def leftover_rows_numpy(points: np.ndarray, labels: np.ndarray, stride: int, seg: Segmentation,
                        extents: tuple | None = None) -> tuple[np.ndarray, np.ndarray, int, int]:
    """:func:`.kernels.leftover_rows` in numpy (the planes, t and noise model of ``seg``): its reference."""
    coefficients, tolerance, _, reference, viewpoint, max_scale, cover, axes, lo, hi = _row_args(seg, extents)
    cloud, labels = points[::stride], labels[::stride]
    valid = np.isfinite(cloud).all(axis=1)
    free = valid & (labels < 0)
    cloud = cloud[free]
    scale = tolerance_scale(cloud, seg.noise_model, reference, viewpoint)
    t = tolerance * (np.ones(len(cloud)) if scale is None else scale)
    x, y, z = (cloud[:, i:i + 1] for i in range(3))  # (m, 1): every plane's sums in the kernel's order
    near = np.abs(x * coefficients[:, 0] + y * coefficients[:, 1] + z * coefficients[:, 2] + coefficients[:, 3]) \
        <= cover * t[:, None]
    uv = x * axes[0] + y * axes[1] + z * axes[2]
    inside = (uv >= lo) & (uv <= hi)
    keep = ~(near & inside[:, 0::2] & inside[:, 1::2]).any(axis=1)
    return cloud[keep], t[keep], int(np.count_nonzero(valid)), int(np.count_nonzero(free))


def leftover_best_numpy(sample: np.ndarray, t: np.ndarray, first: np.ndarray, picks: np.ndarray,
                        neighbours: int) -> tuple[np.ndarray, float, int]:
    """:func:`.kernels.leftover_best` in numpy: its reference."""
    best_normal, best_offset, best = np.full(3, np.nan), float('nan'), 0
    size = min(neighbours + 1, len(sample))
    for s, pick in zip(first, picks):
        d = sample - sample[s]
        near = np.argsort(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2], kind='stable')[:size]
        a, b = sample[near[pick[0]]] - sample[s], sample[near[pick[1]]] - sample[s]
        n = np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
        length = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        if not length > 0:
            continue
        n = n / length
        offset = -(n[0] * sample[s, 0] + n[1] * sample[s, 1] + n[2] * sample[s, 2])
        count = int(np.count_nonzero(np.abs(n[0] * sample[:, 0] + n[1] * sample[:, 1] + n[2] * sample[:, 2] + offset)
                                     <= t))
        if count > best:
            best_normal, best_offset, best = n, float(offset), count
    return best_normal, best_offset, best
