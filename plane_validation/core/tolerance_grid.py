"""The candidate tolerances of a sweep, derived from the cloud's local noise and point spacing.

Pure numpy/scipy, no ROS import.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from . import kernels
from .ransac import as_points, check_magnitude, finite_rows, generator
from .search.checks import gathered_rows

__all__ = ['TUNE_CANDIDATES', 'TOP_DIAGONAL_SHARE', 'local_noise', 'quick_tolerance', 'default_tolerances',
           'finite_points', 'box_diagonal']

#: Default number of tuning candidates.
TUNE_CANDIDATES = 12
#: The largest derived candidate is at most this share of the bounding-box diagonal (default_tolerances).
TOP_DIAGONAL_SHARE = 1 / 8


def finite_points(points: np.ndarray) -> np.ndarray:
    """The rows of ``points`` (N, 3) whose three coordinates are finite: ``points`` itself when all are (no copy of a
    whole cloud)."""
    finite = finite_rows(points)
    return points if finite.all() else np.compress(finite, points, axis=0)


def box_diagonal(points: np.ndarray) -> float:
    """The length (m) of the bounding box's diagonal of ``points`` (n, 3) meters, n >= 1, in one compiled pass
    (numpy's reductions along the rows of an (n, 3) array are several times slower)."""
    if not len(points):
        raise ValueError('no finite points: no bounding box')
    lo, hi = kernels.coordinate_bounds(kernels.c_array(points, np.float64))
    return float(np.linalg.norm(hi - lo))


def local_noise(points: np.ndarray, *, k: int = 16, queries: int = 2000, seed=None) -> tuple[float, float]:
    """(median nearest-neighbour spacing, median local RMS thickness) of a cloud, meters.

    The thickness is the square root of the smallest eigenvalue of the k-neighbourhood scatter
    at ``queries`` random points: about e / sqrt(3) on a plane with uniform noise e, lower when
    the noise is large against the neighbourhood. Both are scaled to the whole cloud's density
    when only a 50k-point probe is searched.
    """
    pts = finite_points(as_points(points))
    check_magnitude(pts)
    rng = generator(seed)
    probe = pts if len(pts) <= 50000 else gathered_rows(pts, rng.choice(len(pts), 50000, replace=False))
    k = min(k, len(probe))
    q = probe if len(probe) <= queries else probe[rng.choice(len(probe), queries, replace=False)]
    dist, idx = cKDTree(probe).query(q, k=k)
    nn = dist[:, 1]
    spacing = float(np.median(nn[nn > 0])) if np.any(nn > 0) else 0.0
    spacing *= np.sqrt(len(probe) / len(pts))  # surfaces are 2-D: spacing ~ 1/sqrt(density)
    nb = gathered_rows(probe, idx.reshape(-1)).reshape(len(q), k, 3)
    centered = nb - nb.mean(axis=1, keepdims=True)
    smallest = np.linalg.eigvalsh(np.einsum('nki,nkj->nij', centered, centered) / k)[:, 0]
    return spacing, float(np.median(np.sqrt(np.maximum(smallest, 0.0))))


#: quick_tolerance is this many local noise thicknesses (tuned t on the Kinect frames of
#: benchmarks/README.md: 4-10 thicknesses) ...
QUICK_TOLERANCE_THICKNESSES = 6.0
#: ... and at least this many point spacings: the 16 nearest points of a lidar return lie on its ring,
#: whose cone is flat to a fraction of a millimetre whatever the range noise (a 16-beam room scan:
#: thickness 0.05 mm, spacing 13.5 mm). On the Kinect frames 6 thicknesses are 2-7 spacings.
QUICK_TOLERANCE_SPACINGS = 2.0


def quick_tolerance(points: np.ndarray, *, seed=None) -> float:
    """A rough tolerance (meters) from the local noise probe alone, without a sweep: what a
    caller can use while :func:`tune_tolerance` runs. Raises ValueError on fewer than 3 points."""
    pts = finite_points(as_points(points))
    if len(pts) < 3:
        raise ValueError(f'need at least 3 finite points, got {len(pts)}')
    spacing, thickness = local_noise(pts, seed=seed)
    t = max(QUICK_TOLERANCE_THICKNESSES * thickness, QUICK_TOLERANCE_SPACINGS * spacing)
    return float(t if t > 0 else 1e-6)


def default_tolerances(points: np.ndarray, count: int = TUNE_CANDIDATES, *, lo: float | None = None,
                       hi: float | None = None, seed=None) -> np.ndarray:
    """``count`` candidate tolerances (meters), geometrically spaced from ``lo`` to ``hi``.

    Bounds not given are derived from the cloud: ``lo`` is a twentieth of the median
    nearest-neighbour spacing; ``hi`` is 1/8 of the bounding-box diagonal, capped at the larger of
    10 local noise thicknesses (about 6 e; the paper's useful t is up to about 2 e) and 5
    spacings, so that dense real clouds are not swept up to tolerances that merge every plane.
    """
    if count < 2:
        raise ValueError(f'need at least 2 candidates, got {count}')
    pts = finite_points(as_points(points))
    if lo is None or hi is None:
        if len(pts) < 3:
            raise ValueError(f'need at least 3 finite points to derive tolerances, got {len(pts)}')
        diagonal = box_diagonal(pts)
        if diagonal <= 0:
            raise ValueError('all points are identical: no tolerance can be derived')
        spacing, thickness = local_noise(pts, seed=seed)
        if hi is None:
            cap = max(10 * thickness, 5 * spacing)
            top = TOP_DIAGONAL_SHARE * diagonal
            hi = min(top, cap) if cap > 0 else top
            if lo is not None and lo >= hi:
                raise ValueError(f'the smallest candidate {lo:g} m (t_min, the node\'s tune_min) is not below the '
                                 f'largest one derived from this cloud, {hi:.3g} m: lower it or give t_max too')
        if lo is None:
            lo = min(spacing / 20, hi / 100) if spacing > 0 else hi / 1000
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f'tolerance range must satisfy 0 < lo < hi, got lo={lo}, hi={hi}')
    return np.geomspace(lo, hi, count)
