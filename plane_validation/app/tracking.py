"""Stable plane ids across frames: :class:`PlaneTracker` (plain, deterministic, no ROS import).

Each frame's planes are matched to the tracks of the previous frames by normal, offset and
in-plane overlap (an optimal assignment on a gated cost); a matched plane takes its track's id,
an unmatched one starts a new track, and a track unseen for up to ``max_missed`` frames keeps
its id should its surface come back. Distances are in meters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.kernels import c_array, group_by_label, near_count

__all__ = ['PlaneTracker', 'TrackerConfig', 'plane_samples']

#: Cost of a pair the gates refuse (the assignment never takes it).
_REFUSED = 1e6


@dataclass(frozen=True)
class TrackerConfig:
    """Gates of a match. max_angle_deg: normals at most this far apart; max_offset: m, the planes'
    distances from the origin (the sensor: the d of a b c d) at most this far apart; overlap_radius: m, a
    sample point overlaps the other plane when one of its sample points is this close; min_overlap: the
    larger of the two fractions of overlapping sample points; max_missed: frames a track is kept unseen;
    samples: points kept per plane."""

    max_angle_deg: float = 15.0
    max_offset: float = 0.15
    overlap_radius: float = 0.3
    min_overlap: float = 0.3
    max_missed: int = 5
    samples: int = 256

    def __post_init__(self) -> None:
        if not (0 < self.max_angle_deg <= 90 and self.max_offset > 0 and self.overlap_radius > 0
                and 0 < self.min_overlap <= 1 and self.max_missed >= 0 and self.samples >= 3):
            raise ValueError(f'invalid tracker configuration: {self}')


@dataclass
class _Track:
    id: int
    coefficients: np.ndarray  # (4,) a b c d, unit normal
    sample: np.ndarray  # (m, 3) points
    missed: int = 0


def plane_samples(points: np.ndarray, labels: np.ndarray, n_planes: int, count: int,
                  members: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Per plane k up to ``count`` of its points (labels == k), evenly spaced in their order
    (deterministic): (m_k, 3) each. ``members``: the rows of each plane, ascending, when known (a
    segmentation's inliers), else grouped from ``labels``."""
    if members is None:
        rows, bounds = group_by_label(c_array(labels, np.int32), n_planes)  # a stable counting sort, compiled
        members = [rows[bounds[k]:bounds[k + 1]] for k in range(n_planes)]
    out = []
    for rows in members:
        if len(rows) > count:
            rows = rows[np.linspace(0, len(rows) - 1, count).round().astype(np.int64)]
        out.append(np.asarray(np.take(points, rows, axis=0), dtype=float))  # (faster than points[rows])
    return out


class PlaneTracker:
    """Gives each frame's planes a track id that stays the same while their surface stays in view."""

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config or TrackerConfig()
        self._tracks: list[_Track] = []
        self._next_id = 0

    def reset(self) -> None:
        """Forget every track; ids start from 0 again."""
        self._tracks, self._next_id = [], 0

    @property
    def track_ids(self) -> tuple[int, ...]:
        """The ids of the tracks kept (seen lately), ascending."""
        return tuple(sorted(t.id for t in self._tracks))

    def update(self, points: np.ndarray, labels: np.ndarray, coefficients: np.ndarray,
               members: list[np.ndarray] | None = None) -> tuple[int, ...]:
        """The id of each of this frame's planes. points: (n, 3) m; labels: (n,) plane index, -1 none;
        coefficients: (k, 4) rows a b c d of the planes (unit normals); members: each plane's rows of
        ``points`` (labels == k), ascending, when known. A frame without planes only ages the tracks."""
        cfg = self.config
        coefficients = np.asarray(coefficients, dtype=float).reshape(-1, 4)
        samples = plane_samples(np.asarray(points), labels, len(coefficients), cfg.samples, members)
        cost = np.full((len(self._tracks), len(coefficients)), _REFUSED)
        for i, track in enumerate(self._tracks):
            for j, (coeff, sample) in enumerate(zip(coefficients, samples)):
                cost[i, j] = self._cost(track, coeff, sample)
        ids = [-1] * len(coefficients)
        if cost.size:
            from scipy.optimize import linear_sum_assignment  # here: a first frame has nothing to match
            for i, j in zip(*linear_sum_assignment(cost)):
                if cost[i, j] < _REFUSED:
                    track = self._tracks[i]
                    track.coefficients, track.sample, track.missed = coefficients[j], samples[j], 0
                    ids[j] = track.id
        matched = set(ids)
        for track in self._tracks:
            if track.id not in matched:
                track.missed += 1
        self._tracks = [t for t in self._tracks if t.missed <= cfg.max_missed]
        for j, coeff in enumerate(coefficients):  # new surfaces, in the frame's order
            if ids[j] < 0:
                ids[j] = self._next_id
                self._tracks.append(_Track(self._next_id, coeff, samples[j]))
                self._next_id += 1
        return tuple(ids)

    def _cost(self, track: _Track, coeff: np.ndarray, sample: np.ndarray) -> float:
        cfg = self.config
        if len(track.sample) == 0 or len(sample) == 0:
            return _REFUSED
        dot = float(track.coefficients[:3] @ coeff[:3])
        angle = np.degrees(np.arccos(min(abs(dot), 1.0)))
        if angle > cfg.max_angle_deg:
            return _REFUSED
        # the planes' distances from the sensor (the origin): unchanged by the sensor turning, changed
        # by its moving no more than its step
        sign = 1.0 if dot >= 0 else -1.0
        offset = abs(float(track.coefficients[3]) - sign * float(coeff[3]))
        if offset > cfg.max_offset:
            return _REFUSED
        overlap = max(_near_share(sample, track.sample, cfg.overlap_radius),
                      _near_share(track.sample, sample, cfg.overlap_radius))
        if overlap < cfg.min_overlap:
            return _REFUSED
        # a track seen lately is preferred to one that has been missing
        return angle / cfg.max_angle_deg + offset / cfg.max_offset + (1.0 - overlap) + 0.1 * track.missed


def _near_share(a: np.ndarray, b: np.ndarray, radius: float) -> float:
    """The share of the points ``a`` (m, 3) with one of ``b`` (p, 3) closer than ``radius`` (m): every pair of two
    samples of a few hundred points, compiled (:func:`_near_share_kdtree` is its reference)."""
    return near_count(a, b, radius) / len(a)


def _near_share_kdtree(a: np.ndarray, b: np.ndarray, radius: float) -> float:
    """:func:`_near_share` through a kd-tree query bounded by ``radius``: the reference its kernel is tested
    against."""
    from scipy.spatial import cKDTree
    return float(np.isfinite(cKDTree(b).query(a, distance_upper_bound=radius)[0]).mean())
