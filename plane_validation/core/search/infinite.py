"""The paper's search (``connectivity=False``): infinite planes, each holding every point within t of it."""
from __future__ import annotations

import numpy as np

from .checks import resolve_min_inliers
from .fit import canonical, fit_columns, kept_fit, plane_distances, tolerance_at
from .sequential import sequential_search
from .types import Allows, Plane, Segmentation, Tolerance

__all__ = ['detect_infinite']


def detect_infinite(pts: np.ndarray, tolerance: Tolerance, max_planes: int, min_inliers: int | float,
                    probability: float, max_iterations: int, rng: np.random.Generator, ransac_points: int | None,
                    allows: Allows = None) -> Segmentation:
    """detect_planes without connectivity (see its docstring): the planes found on a sample of the valid points
    (``ransac_points``), refitted and every valid point of ``pts`` (N, 3) labelled with its nearest plane."""
    cols = np.ascontiguousarray(pts.T)
    finite = np.isfinite(cols).all(axis=0)
    valid_idx = np.flatnonzero(finite)
    n_valid = len(valid_idx)
    min_count = resolve_min_inliers(min_inliers, n_valid)
    valid = np.compress(finite, cols, axis=1)
    # Centre on a median (robust to a stray FLT_MAX point), from a strided subset: it only has
    # to be near the points for the raw-moment fits to keep their precision.
    center = np.median(valid[:, ::max(1, n_valid // 1024)], axis=1) if n_valid else np.zeros(3)
    valid -= center[:, None]

    search, search_min = valid, min_count
    valid_tolerance = tolerance_at(tolerance, valid_idx)
    search_tolerance = valid_tolerance
    if ransac_points is not None and n_valid > ransac_points:
        sample = np.sort(rng.choice(n_valid, int(ransac_points), replace=False))
        search, search_tolerance = valid[:, sample], tolerance_at(valid_tolerance, sample)
        search_min = max(3, int(np.ceil(min_count * ransac_points / n_valid)))
    found, reason, _, capped = sequential_search(search, search_tolerance, max_planes, search_min, probability,
                                                 max_iterations, rng, n_total=n_valid, allows=allows)
    labels = np.full(len(pts), -1, dtype=np.int32)
    tolerances = (valid_tolerance, search_tolerance)
    planes = _label_all(valid, search, valid_idx, center, labels, found, tolerances, allows)
    small = [j for j, plane in enumerate(planes) if len(plane.inliers) < min_count]
    if small:  # a sample's count is only an estimate (or a neighbour took the points): check all
        found = [plane for j, plane in enumerate(found) if j not in small]
        planes = _label_all(valid, search, valid_idx, center, labels, found, tolerances, allows)
        reason += (f'; dropped {len(small)} plane(s) left with fewer than min_inliers={min_count} points '
                   'once every point was labelled')
    return Segmentation(labels=labels, planes=planes, tolerance=tolerance, n_valid=n_valid, reason=reason,
                        capped=capped)


def _nearest(cols: np.ndarray, found: list[tuple[np.ndarray, float]], tolerance: Tolerance
             ) -> tuple[np.ndarray, np.ndarray]:
    """Label each point of ``cols`` (3, n) with the nearest plane within ``tolerance`` (ties to
    the earlier plane; -1 when none). Returns (labels (n,) int32, distance to that plane (n,))."""
    dist = plane_distances(cols, np.array([n for n, _ in found]), np.array([d for _, d in found]))
    best = dist[0]  # the running minimum, in place (dist is our own buffer)
    labels = np.zeros(cols.shape[1], dtype=np.int32)
    for j in range(1, len(found)):
        closer = dist[j] < best
        labels[closer] = j
        np.minimum(best, dist[j], out=best)
    labels[best > tolerance] = -1
    return labels, best


def _label_all(valid: np.ndarray, search: np.ndarray, valid_idx: np.ndarray, center: np.ndarray,
               labels: np.ndarray, found: list[tuple[np.ndarray, float]], tolerances: tuple, allows: Allows = None
               ) -> tuple[Plane, ...]:
    """Refit each plane on the searched points ``search`` (3, m) nearest to it, then label every
    valid point (``valid`` (3, n); both centred on ``center``) with its nearest plane within
    tolerance (``tolerances``: for ``valid`` and for ``search``); fills ``labels`` (N,) at ``valid_idx``
    and returns the planes in the caller's coordinates."""
    if not found:
        labels[valid_idx] = -1  # also after every plane was dropped
        return ()
    own, _ = _nearest(search, found, tolerances[1])
    # Each plane's first fit saw the edge bands of the planes found after it: refit on the points
    # nearest to it (on the search sample when there is one: as precise, and 4x fewer points).
    found = [kept_fit(fit_columns(np.compress(own == j, search, axis=1)), plane, allows)
             if np.count_nonzero(own == j) >= 3 else plane for j, plane in enumerate(found)]
    own, dist = _nearest(valid, found, tolerances[0])
    labels[valid_idx] = own
    k = len(found)
    dist *= dist
    # label -1 counts in bin 0: no boolean selection of the assigned points needed
    sizes = np.bincount(own + 1, minlength=k + 1)[1:]
    mean_sq = np.bincount(own + 1, weights=dist, minlength=k + 1)[1:] / np.maximum(sizes, 1)
    planes = []
    for j, (normal, offset) in enumerate(found):
        normal, offset = canonical(normal, offset - float(normal @ center))
        planes.append(Plane(normal=normal, offset=offset, inliers=valid_idx[own == j],
                            rms=float(np.sqrt(mean_sq[j]))))
    return tuple(planes)
