"""The largest plane among the points no detected plane covers: a surface the search left behind.

:func:`leftover_plane` runs a small RANSAC (triples of nearby points) on a sample of the points in no plane that lie
farther than COVER tolerances from every detected plane within its extent, at the segmentation's own tolerance and
noise model. A large plane there is a surface the search did not find (a wall lost once the search stopped at
max_planes, the rest of a wall of which only a piece was found), which the tests of each found plane cannot see. The verdict's limit lives in
core/verdict.py (LEFTOVER_SHARE). Pure numpy/scipy, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .noise import tolerance_scale
from .ransac import Segmentation, as_points

__all__ = ['Leftover', 'leftover_plane', 'COVER', 'ROWS', 'SAMPLE', 'HYPOTHESES', 'NEIGHBOURS', 'MIN_POINTS']

#: Points within this many tolerances of a detected plane, inside its extent, are its surface's: the tails of its noise
#: beyond t are not a surface left behind (the rest of a coplanar surface beyond its extent may be).
COVER = 2.0
#: The cloud is read every so many rows, about this many of them (the share is a sample's estimate) ...
ROWS = 8000
#: ... and RANSAC runs on at most this many of the uncovered points among them, ...
SAMPLE = 1000
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
    pts = as_points(points)
    if len(seg.labels) != len(pts):
        raise ValueError(f'points has {len(pts)} rows but the segmentation labels {len(seg.labels)}: judge a '
                         'segmentation with the points it was found on')
    none = Leftover(0.0, np.full(3, np.nan), float('nan'), 0.0)
    rows = np.arange(0, len(pts), max(1, len(pts) // ROWS))
    cloud, labels = pts[rows], seg.labels[rows]
    valid = np.isfinite(cloud).all(axis=1)
    n_valid = int(np.count_nonzero(valid))
    if n_valid == 0:
        return none
    free = valid & (labels < 0)
    cloud = cloud[free]
    scale = tolerance_scale(cloud, seg.noise_model, seg.noise_reference, seg.viewpoint)
    t = seg.tolerance * (np.ones(len(cloud)) if scale is None else scale)
    if seg.n_planes and len(cloud):
        near = np.abs(cloud @ seg.coefficients[:, :3].T + seg.coefficients[:, 3]) <= COVER * t[:, None]  # (m, k)
        if extents is not None:
            axes, lo, hi = extents
            uv = cloud @ axes
            inside = (uv >= lo) & (uv <= hi)
            near &= inside[:, 0::2] & inside[:, 1::2]
        far = ~near.any(axis=1)
        cloud, t = cloud[far], t[far]
    free_share = float(np.count_nonzero(free)) / n_valid
    if len(cloud) < MIN_POINTS:
        return Leftover(0.0, none.normal, none.offset, free_share)
    rng = np.random.default_rng(len(cloud))
    if len(cloud) > SAMPLE:
        pick = rng.choice(len(cloud), SAMPLE, replace=False)
        sample, ts = cloud[pick], t[pick]
    else:
        sample, ts = cloud, t
    normal, offset, count = _best_plane(sample, ts, rng)
    share = count / len(sample) * len(cloud) / n_valid
    return Leftover(float(share), normal, offset, free_share)


def _best_plane(sample: np.ndarray, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, float, int]:
    """The plane through nearby triples of ``sample`` (m, 3) that most of its points lie within ``t`` (m,) of:
    (unit normal (3,), offset m, its count); (NaN, NaN, 0) when every triple is degenerate."""
    k = min(NEIGHBOURS, len(sample) - 1)
    first = rng.integers(0, len(sample), HYPOTHESES)
    seeds = sample[first]
    # (h, m) squared distances from each seed to every point, as |a|^2 + |b|^2 - 2 a.b (one matrix product)
    squared = np.einsum('ij,ij->i', sample, sample)[None, :] - 2 * seeds @ sample.T
    near = np.argpartition(squared, k, axis=1)[:, :k + 1]  # the seed itself and its k nearest, in no order
    others = np.take_along_axis(near, rng.integers(0, k + 1, (HYPOTHESES, 2)), axis=1)
    second, third = others[:, 0], others[:, 1]
    normals = np.cross(sample[second] - sample[first], sample[third] - sample[first])
    length = np.linalg.norm(normals, axis=1)
    ok = length > 0
    if not ok.any():
        return np.full(3, np.nan), float('nan'), 0
    normals = normals[ok] / length[ok, None]
    offsets = -np.einsum('ij,ij->i', normals, sample[first[ok]])
    counts = np.count_nonzero(np.abs(sample @ normals.T + offsets) <= t[:, None], axis=0)
    best = int(np.argmax(counts))
    return normals[best], float(offsets[best]), int(counts[best])
