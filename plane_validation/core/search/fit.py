"""Least-squares planes and point-to-plane distances.

Points are held as (3, n) columns centred near the cloud: distances to k planes are then one (k, 3) @ (3, n)
product (a (n, 3) @ (3, k) product is ~20x slower in numpy for small k), and fits can use raw second moments
without losing precision to large absolute coordinates (each fit also centres its own points).
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from .checks import as_points, check_magnitude, finite_rows
from .types import Allows, Tolerance

__all__ = ['fit_plane', 'fit_columns', 'canonical', 'degeneracy', 'degeneracy_numpy', 'signed_distances',
           'plane_distances', 'tolerance_at', 'within_plane', 'allows_normal', 'kept_fit', 'refit_regions',
           'refit_regions_numpy', 'plane_rows', 'MIN_SINE']


#: Random points the degeneracy (spread) test looks at.
SPREAD_POINTS = 1024


#: A sample triple whose sine of the angle at its first point is below this is degenerate.
MIN_SINE = 1e-6


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane through (N, 3) points, meters (PCA): returns (unit normal (3,), offset), the plane
    normal . p + offset = 0. ValueError unless N >= 3 rows, all finite, that span a plane (not all on a line)."""
    pts = as_points(points)
    bad = len(pts) - int(np.count_nonzero(finite_rows(pts)))
    if bad:
        raise ValueError(f'points must be finite: {bad} of {len(pts)} rows hold NaN or inf (leave them out first)')
    if len(pts) < 3:
        raise ValueError(f'a plane needs at least 3 points, got {len(pts)}')
    check_magnitude(pts)
    cols = np.array(pts.T)  # a copy: fit_columns centres it
    centered = cols - cols.mean(axis=1, keepdims=True)
    spread = np.linalg.eigvalsh(centered @ centered.T)  # ascending; every point counts (no outlier guard here)
    if spread[2] <= 0 or np.all(pts == pts[0]):  # the mean need not round-trip: compare the points themselves
        raise ValueError('no plane fits these points: they are all identical')
    if spread[1] <= MIN_SINE ** 2 * spread[2]:
        raise ValueError('no plane fits these points: they all lie on one line')
    return fit_columns(cols)


def fit_columns(cols: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane through the columns of ``cols`` (3, n), a scratch copy: it is centred
    in place (raw second moments of far-away points would lose precision)."""
    centroid = cols.mean(axis=1)
    cols -= centroid[:, None]
    scatter = cols @ cols.T
    # Eigenvector of the smallest eigenvalue of the 3x3 scatter matrix.
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return normal, float(-normal @ centroid)


def canonical(normal: np.ndarray, offset: float) -> tuple[np.ndarray, float]:
    """Fix the sign ambiguity: offset <= 0 (normal points away from the origin), ties by normal."""
    if offset > 0 or (offset == 0 and normal[np.argmax(np.abs(normal))] < 0):
        return -normal, -offset
    return normal, offset


#: Why no plane fits, by :func:`.kernels.spread_test`'s answer.
_SPREAD_REASONS = (None, 'all remaining points are identical', 'almost all remaining points are identical',
                   'all remaining points are collinear')


def degeneracy(cols: np.ndarray) -> str | None:
    """Reason why no plane can be fitted to the points ``cols`` (3, n), or None.

    The spread is judged on the points nearest the median (98 %), so that one far outlier (a
    driver's FLT_MAX instead of NaN) cannot make a planar cloud look collinear. One compiled pass
    (:func:`.kernels.spread_test`; :func:`degeneracy_numpy` is its reference).
    """
    n = cols.shape[1]
    if n < 3:
        return f'fewer than 3 points left ({n})'
    idx = _spread_points(n)
    return _SPREAD_REASONS[kernels.spread_test(kernels.c_array(cols, np.float64), idx, len(idx) >= 50, MIN_SINE)]


def _spread_points(n: int) -> np.ndarray:
    """The points of n that the spread test looks at: all, or SPREAD_POINTS drawn at random (not a strided subset:
    in an organized cloud a stride can pick one image column, which lies on a line), seeded by n: deterministic."""
    if n <= SPREAD_POINTS:
        return np.arange(n)
    return kernels.seeded_draws(n, SPREAD_POINTS)  # np.random.default_rng(n).integers(0, n, SPREAD_POINTS)


def degeneracy_numpy(cols: np.ndarray) -> str | None:
    """:func:`degeneracy` in numpy: the reference its kernel is tested against."""
    n = cols.shape[1]
    if n < 3:
        return f'fewer than 3 points left ({n})'
    core = cols[:, _spread_points(n)].T
    if np.all(core == core[0]) and np.all(cols == cols[:, :1]):
        return 'all remaining points are identical'
    if len(core) >= 50:
        m = len(core)
        part = np.partition(core, [(m - 1) // 2, m // 2], axis=0)
        median = (part[(m - 1) // 2] + part[m // 2]) / 2  # np.median's value, without its overhead
        dist = np.abs(core - median).max(axis=1)
        k = int(0.98 * (m - 1))  # the 98th percentile's lower order statistic (np.quantile interpolates above it)
        core = core[dist <= np.partition(dist, k)[k]]
    centered = core - core.mean(axis=0)
    eig = np.linalg.eigvalsh(centered.T @ centered)  # ascending
    if eig[2] <= 0:
        return 'almost all remaining points are identical'
    if eig[1] <= MIN_SINE ** 2 * eig[2]:
        return 'all remaining points are collinear'
    return None


def signed_distances(cols: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(k, n) signed distances of the points ``cols`` (3, n) to k planes (positive on the side the normal points to)."""
    dist = normals @ cols
    dist += offsets[:, None]
    return dist


def plane_distances(cols: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(k, n) absolute distances of the points ``cols`` (3, n) to k planes (in place, one buffer)."""
    dist = signed_distances(cols, normals, offsets)
    return np.abs(dist, out=dist)


def plane_rows(found: list) -> np.ndarray:
    """(k, 4) float64: the planes ``found`` [(unit normal (3,), offset meters)] as rows (a, b, c, d), as the kernels
    take them."""
    rows = np.empty((len(found), 4))
    for j, (normal, offset) in enumerate(found):
        rows[j, :3] = normal
        rows[j, 3] = offset
    return rows


def tolerance_at(tolerance: Tolerance, idx) -> Tolerance:
    """A tolerance for a subset ``idx`` of the points: a scalar as is, a per-point (n,) array indexed."""
    return tolerance if np.ndim(tolerance) == 0 else tolerance[idx]


def within_plane(cols: np.ndarray, normal: np.ndarray, offset: float, tolerance: Tolerance) -> np.ndarray:
    """(n,) bool: points ``cols`` (3, n) within ``tolerance`` of the plane."""
    return plane_distances(cols, normal[None, :], np.array([offset]))[0] <= tolerance


def allows_normal(allows: Allows, normal: np.ndarray) -> bool:
    """Whether a plane may have the unit ``normal`` (3,) (``allows`` None: any)."""
    return allows is None or bool(allows(normal[None, :])[0])


def kept_fit(fit: tuple[np.ndarray, float], plane: tuple[np.ndarray, float], allows: Allows
             ) -> tuple[np.ndarray, float]:
    """``fit`` when a plane may have its normal, else the ``plane`` it would replace."""
    return fit if allows_normal(allows, fit[0]) else plane


def refit_regions(search: np.ndarray, region: np.ndarray, found: list, allows: Allows = None) -> list:
    """Each region's plane fitted to its points (3, m) ``search`` (kept when it has fewer than 3, or when the fit
    leaves the normals ``allows`` takes). One compiled pass (:func:`.kernels.fit_regions`; :func:`refit_regions_numpy`
    is its reference)."""
    normals, offsets, counts = kernels.fit_regions(kernels.c_array(search, np.float64),
                                                   kernels.c_array(region, np.int64), len(found))
    return [kept_fit((normals[j].copy(), float(offsets[j])), plane, allows) if counts[j] >= 3 else plane
            for j, plane in enumerate(found)]


def refit_regions_numpy(search: np.ndarray, region: np.ndarray, found: list, allows: Allows = None) -> list:
    """:func:`refit_regions` in numpy."""
    return [kept_fit(fit_columns(np.compress(region == j, search, axis=1)), plane, allows)
            if np.count_nonzero(region == j) >= 3 else plane for j, plane in enumerate(found)]
