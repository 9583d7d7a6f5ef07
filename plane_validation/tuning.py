"""Tolerance auto-tuning and plane-count selection by cluster validity indices (paper section 4).

``tune_tolerance`` sweeps the RANSAC tolerance ``t`` (meters), scores every segmentation with all
indices and picks ``t`` by one of them; ``select_plane_count`` scores the first k planes of one
segmentation for k = 1..K (the paper's Fig. 2). Pure numpy/scipy, no ROS import.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .indices import ValidityIndices, validity_indices
from .ransac import Segmentation, as_points, detect_planes

__all__ = ['CRITERIA', 'TuningRow', 'TuningResult', 'PlaneCountResult', 'default_tolerances', 'tune_tolerance',
           'select_plane_count', 'noise_from_segmentation', 'RELIABLE_GS_PLANES']

#: Index name -> True when larger is better.
CRITERIA = {'gs_planes': True, 'gs': True, 'silhouette': True, 'dunn': True, 'davies_bouldin': False,
            'davies_bouldin_classic': False}

#: Below this GSplanes the planes are not reported as reliable: on plane-free clouds (sphere, bunny)
#: the paper finds GS and GSplanes close to 0, on clouds with real planes ours stays above 0.3.
RELIABLE_GS_PLANES = 0.2


@dataclass(frozen=True, eq=False)
class TuningRow:
    """One candidate tolerance of a sweep: ``tolerance`` in meters, ``seconds`` of RANSAC + indices."""

    tolerance: float
    n_planes: int
    inlier_counts: tuple[int, ...]
    indices: ValidityIndices
    seconds: float

    def score(self, criterion: str) -> float:
        return float(getattr(self.indices, criterion))


@dataclass(frozen=True, eq=False)
class TuningResult:
    """Result of :func:`tune_tolerance`.

    rows: every candidate, ascending tolerance. tolerance: the chosen ``t`` (meters).
    segmentation: the chosen ``t`` applied to the full-resolution cloud; indices: its indices.
    noise_estimate: half-width ``e`` of the sensor noise (meters), estimated from the residuals of
    the chosen planes (for uniform noise on [-e, e] the residual RMS is e / sqrt(3)).
    reliable: whether the planes are trustworthy; verdict: one line saying why.
    """

    rows: tuple[TuningRow, ...]
    criterion: str
    best: int
    tolerance: float
    segmentation: Segmentation
    indices: ValidityIndices
    noise_estimate: float
    reliable: bool
    verdict: str
    seconds: float

    @property
    def tolerances(self) -> np.ndarray:
        return np.array([r.tolerance for r in self.rows])

    def scores(self, criterion: str | None = None) -> np.ndarray:
        return np.array([r.score(criterion or self.criterion) for r in self.rows])

    def table(self) -> str:
        """A plain-text table of the sweep, one row per tolerance."""
        head = f'{"t":>10} {"planes":>6} {"dunn":>8} {"DB":>8} {"GS":>7} {"GSpl":>7} {"sil":>7} {"ms":>7}'
        lines = [head]
        for i, r in enumerate(self.rows):
            x = r.indices
            mark = ' <' if i == self.best else ''
            lines.append(f'{r.tolerance:10.4g} {r.n_planes:6d} {x.dunn:8.4f} {x.davies_bouldin:8.3g} {x.gs:7.3f} '
                         f'{x.gs_planes:7.3f} {x.silhouette:7.3f} {1000 * r.seconds:7.1f}{mark}')
        return '\n'.join(lines)


@dataclass(frozen=True, eq=False)
class PlaneCountResult:
    """Result of :func:`select_plane_count`: indices[k-1] scores the first k planes."""

    counts: tuple[int, ...]
    indices: tuple[ValidityIndices, ...]
    criterion: str
    n_planes: int
    segmentation: Segmentation

    def best_by(self, criterion: str) -> int:
        """Plane count the given index would choose."""
        return self.counts[_best_position([getattr(x, criterion) for x in self.indices], criterion)]


def _finite(points: np.ndarray) -> np.ndarray:
    return points[np.isfinite(points).all(axis=1)]


def default_tolerances(points: np.ndarray, count: int = 16, *, seed=None) -> np.ndarray:
    """Candidate tolerances (meters) derived from the cloud itself, geometrically spaced from a
    twentieth of the median nearest-neighbour spacing up to 1/8 of the bounding-box diagonal."""
    pts = _finite(as_points(points))
    if len(pts) < 3:
        raise ValueError(f'need at least 3 finite points to derive tolerances, got {len(pts)}')
    rng = np.random.default_rng(seed)
    probe = pts if len(pts) <= 20000 else pts[rng.choice(len(pts), 20000, replace=False)]
    spacing, _ = cKDTree(probe).query(probe, k=2)
    spacing = spacing[:, 1]
    spacing = float(np.median(spacing[spacing > 0])) if np.any(spacing > 0) else 0.0
    # The probe is sparser than the whole cloud: surfaces are 2-D, spacing ~ 1/sqrt(density).
    spacing *= np.sqrt(len(probe) / len(pts))
    diagonal = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    if diagonal <= 0:
        raise ValueError('all points are identical: no tolerance can be derived')
    hi = diagonal / 8
    lo = min(spacing / 20, hi / 100) if spacing > 0 else hi / 1000
    return np.geomspace(lo, hi, count)


def _best_position(values, criterion: str) -> int:
    values = np.asarray(values, dtype=float)
    values = np.where(np.isnan(values), -np.inf if CRITERIA[criterion] else np.inf, values)
    return int(np.argmax(values) if CRITERIA[criterion] else np.argmin(values))


def _check_criterion(criterion: str) -> None:
    if criterion not in CRITERIA:
        raise ValueError(f'unknown criterion {criterion!r}; choose one of {sorted(CRITERIA)}')


def noise_from_segmentation(seg: Segmentation) -> float:
    """Half-width e (meters) of uniform noise matching the pooled residual RMS of the planes."""
    counts = np.array([len(p.inliers) for p in seg.planes])
    if counts.sum() == 0:
        return float('nan')
    rms = np.array([p.rms for p in seg.planes])
    return float(np.sqrt(3 * np.sum(counts * rms ** 2) / counts.sum()))


def tune_tolerance(points: np.ndarray, tolerances=None, criterion: str = 'gs_planes', *,
                   max_planes: int = 10, min_inliers: int | float = 0.02, probability: float = 0.99,
                   max_iterations: int = 1000, sample_size: int | None = 2000, tune_points: int | None = 20000,
                   seed: int | None = None) -> TuningResult:
    """Sweep the RANSAC tolerance and pick the best by ``criterion``.

    points: (N, 3) meters. tolerances: candidate ``t`` values in meters, or None to derive them
    from the cloud (:func:`default_tolerances`). criterion: one of :data:`CRITERIA`.
    tune_points: the sweep runs on a random subsample of this many points (None = all); the
    chosen ``t`` is then applied to the full cloud. sample_size: silhouette sample per score.
    Among candidates whose score is within two standard errors of the best (indistinguishable
    given the silhouette sampling), the smallest ``t`` wins.
    """
    _check_criterion(criterion)
    start = time.perf_counter()
    pts = as_points(points)
    finite = _finite(pts)
    if len(finite) < 3:
        raise ValueError(f'need at least 3 finite points to tune, got {len(finite)}')
    rng = np.random.default_rng(seed)
    cand = default_tolerances(finite, seed=rng) if tolerances is None else np.asarray(tolerances, dtype=float)
    cand = np.unique(cand)
    if cand.size == 0 or not np.all(np.isfinite(cand)) or cand[0] <= 0:
        raise ValueError('tolerances must be finite and > 0')
    sweep_pts = finite if tune_points is None or len(finite) <= tune_points else \
        finite[rng.choice(len(finite), tune_points, replace=False)]
    ransac_seed, index_seed = rng.integers(0, 2**63, size=2)
    opts = dict(max_planes=max_planes, min_inliers=min_inliers, probability=probability,
                max_iterations=max_iterations)

    rows: list[TuningRow] = []
    previous: tuple[np.ndarray, ValidityIndices] | None = None
    for t in cand:
        t0 = time.perf_counter()
        seg = detect_planes(sweep_pts, t, seed=int(ransac_seed), **opts)
        if previous is not None and np.array_equal(previous[0], seg.labels):
            scores = previous[1]  # same partition as the last candidate: same indices
        else:
            scores = validity_indices(sweep_pts, seg.labels, sample_size=sample_size, seed=int(index_seed))
        previous = (seg.labels, scores)
        rows.append(TuningRow(tolerance=float(t), n_planes=seg.n_planes,
                              inlier_counts=tuple(len(p.inliers) for p in seg.planes), indices=scores,
                              seconds=time.perf_counter() - t0))

    best = _choose(rows, criterion)
    t_best = rows[best].tolerance
    if sweep_pts is finite and len(finite) == len(pts):
        final = detect_planes(pts, t_best, seed=int(ransac_seed), **opts)
        final_scores = rows[best].indices
    else:
        final = detect_planes(pts, t_best, seed=int(ransac_seed), **opts)
        final_scores = validity_indices(pts, final.labels, sample_size=sample_size, seed=int(index_seed))
    reliable, verdict = judge(final, final_scores)
    return TuningResult(rows=tuple(rows), criterion=criterion, best=best, tolerance=t_best, segmentation=final,
                        indices=final_scores, noise_estimate=noise_from_segmentation(final), reliable=reliable,
                        verdict=verdict, seconds=time.perf_counter() - start)


def _choose(rows: list[TuningRow], criterion: str) -> int:
    """Index of the smallest tolerance whose score is within 2 SE of the best one."""
    scores = np.array([r.score(criterion) for r in rows])
    best = _best_position(scores, criterion)
    se_name = {'gs_planes': 'gs_planes_se', 'gs': 'gs_se', 'silhouette': 'silhouette_se'}.get(criterion)
    margin = 2 * getattr(rows[best].indices, se_name) if se_name else 0.0
    sign = 1 if CRITERIA[criterion] else -1
    close = np.flatnonzero(sign * scores >= sign * scores[best] - margin)
    return int(close[0]) if len(close) else best


def judge(seg: Segmentation, scores: ValidityIndices) -> tuple[bool, str]:
    """Whether the planes of ``seg`` are reliable, with a one-line reason.

    No plane at all is not reliable; one plane has no GSplanes (it needs two) and is judged reliable
    when it holds most of the points; otherwise GSplanes must reach :data:`RELIABLE_GS_PLANES`.
    """
    if seg.n_planes == 0:
        return False, f'no plane found ({seg.reason})'
    if seg.n_planes == 1:
        share = len(seg.planes[0].inliers) / max(seg.n_valid, 1)
        if share >= 0.5:
            return True, f'one plane holding {share:.0%} of the points'
        return False, f'a single plane holding only {share:.0%} of the points'
    if scores.gs_planes >= RELIABLE_GS_PLANES:
        return True, f'{seg.n_planes} planes, GSplanes {scores.gs_planes:.2f}'
    return False, f'{seg.n_planes} planes but GSplanes {scores.gs_planes:.2f} < {RELIABLE_GS_PLANES}: ' \
                  'the planes are not well separated'


def select_plane_count(points: np.ndarray, tolerance: float, max_planes: int = 10,
                       criterion: str = 'gs_planes', *, min_inliers: int | float = 0.02, probability: float = 0.99,
                       max_iterations: int = 1000, sample_size: int | None = 2000,
                       seed: int | None = None) -> PlaneCountResult:
    """Score the first k planes (the rest unassigned) for k = 1..K and pick k (paper Fig. 2).

    One sequential RANSAC run with ``max_planes`` finds up to K planes at ``tolerance`` meters;
    labels of planes k.. are set to -1 before scoring. Returns every k's indices.
    """
    _check_criterion(criterion)
    rng = np.random.default_rng(seed)
    ransac_seed, index_seed = rng.integers(0, 2**63, size=2)
    seg = detect_planes(points, tolerance, max_planes=max_planes, min_inliers=min_inliers,
                        probability=probability, max_iterations=max_iterations, seed=int(ransac_seed))
    pts = as_points(points)
    counts, scores = [], []
    for k in range(1, seg.n_planes + 1):
        labels = np.where(seg.labels < k, seg.labels, -1)
        counts.append(k)
        scores.append(validity_indices(pts, labels, sample_size=sample_size, seed=int(index_seed)))
    n_planes = counts[_best_position([getattr(s, criterion) for s in scores], criterion)] if counts else 0
    return PlaneCountResult(counts=tuple(counts), indices=tuple(scores), criterion=criterion, n_planes=n_planes,
                            segmentation=seg)
