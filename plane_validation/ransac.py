"""Sequential RANSAC plane detection (Lipnickas et al. 2014, section 3).

Pure numpy: no ROS import. Coordinates are in meters (or any consistent unit); the
tolerance ``t`` is an absolute point-to-plane distance in the same unit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ['Plane', 'Segmentation', 'detect_planes', 'fit_plane', 'as_points', 'resolve_min_inliers']

#: Hypotheses scored per numpy call.
BATCH = 128
#: Points a hypothesis is scored on before the best few are confirmed on all points.
SUBSET = 4096
#: Best subset hypotheses confirmed on the full remaining cloud.
CONFIRM = 4
#: A sample triple whose sine of the angle at its first point is below this is degenerate.
MIN_SINE = 1e-6


@dataclass(frozen=True, eq=False)
class Plane:
    """One detected plane ``normal · x + offset = 0``.

    normal: (3,) unit vector; offset: meters; inliers: (m,) int64 indices into the input points;
    rms: point-to-plane RMS distance of the inliers, meters.
    """

    normal: np.ndarray
    offset: float
    inliers: np.ndarray
    rms: float

    @property
    def coefficients(self) -> np.ndarray:
        """(4,) array ``(a, b, c, d)`` with ``a x + b y + c z + d = 0``."""
        return np.append(self.normal, self.offset)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Absolute distance of each row of ``points`` (n, 3) to the plane, meters."""
        return np.abs(points @ self.normal + self.offset)


@dataclass(frozen=True, eq=False)
class Segmentation:
    """Result of :func:`detect_planes`.

    labels: (N,) int32, plane index 0..k-1 in extraction order, -1 unassigned or invalid row.
    planes: detected planes in extraction order. tolerance: meters. n_valid: finite rows.
    reason: why extraction stopped (human-readable).
    """

    labels: np.ndarray
    planes: tuple[Plane, ...]
    tolerance: float
    n_valid: int
    reason: str
    coefficients: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        coeffs = np.array([p.coefficients for p in self.planes]).reshape(-1, 4)
        object.__setattr__(self, 'coefficients', coeffs)

    @property
    def n_planes(self) -> int:
        return len(self.planes)


def as_points(points: np.ndarray) -> np.ndarray:
    """Validate an (N, 3) real array and return it as float64 (no copy when already float64)."""
    arr = np.asarray(points)
    if arr.dtype.kind not in 'fiu':
        raise ValueError(f'points must be a real numeric array, got dtype {arr.dtype}')
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f'points must have shape (N, 3), got {arr.shape}')
    return arr.astype(np.float64, copy=False)


def resolve_min_inliers(min_inliers: int | float, n_valid: int) -> int:
    """An absolute count, or a fraction of ``n_valid`` when ``min_inliers`` is a float < 1."""
    if isinstance(min_inliers, (bool, np.bool_)) or not np.isfinite(min_inliers) or min_inliers < 0:
        raise ValueError(f'min_inliers must be a count >= 0 or a fraction in [0, 1), got {min_inliers!r}')
    if isinstance(min_inliers, (float, np.floating)) and min_inliers < 1:
        return max(3, int(np.ceil(min_inliers * n_valid)))
    return max(3, int(min_inliers))


def fit_plane(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane through (n, 3) points (PCA): returns (unit normal (3,), offset)."""
    centroid = points.mean(axis=0)
    centered = points - centroid
    # Eigenvector of the smallest eigenvalue of the scatter matrix: 3x3, cheaper than an SVD of n x 3.
    _, vecs = np.linalg.eigh(centered.T @ centered)
    normal = vecs[:, 0]
    return normal, float(-normal @ centroid)


def _canonical(normal: np.ndarray, offset: float) -> tuple[np.ndarray, float]:
    """Fix the sign ambiguity: offset <= 0 (normal points away from the origin), ties by normal."""
    if offset > 0 or (offset == 0 and normal[np.argmax(np.abs(normal))] < 0):
        return -normal, -offset
    return normal, offset


def _degeneracy(points: np.ndarray) -> str | None:
    """Reason why no plane can be fitted to (n, 3) points, or None.

    The spread is judged on the points nearest the median (98 %), so that one far outlier (a
    driver's FLT_MAX instead of NaN) cannot make a planar cloud look collinear.
    """
    if len(points) < 3:
        return f'fewer than 3 points left ({len(points)})'
    if np.all(points == points[0]):
        return 'all remaining points are identical'
    # A random subset is plenty for a spread test (not a strided one: in an organized cloud a
    # stride can pick one image column, which lies on a line). Seeded by n: deterministic.
    core = points if len(points) <= SUBSET else \
        points[np.random.default_rng(len(points)).integers(0, len(points), SUBSET)]
    if len(core) >= 50:
        dist = np.abs(core - np.median(core, axis=0)).max(axis=1)
        core = core[dist <= np.quantile(dist, 0.98)]
    centered = core - core.mean(axis=0)
    eig = np.linalg.eigvalsh(centered.T @ centered)  # ascending
    if eig[2] <= 0:
        return 'almost all remaining points are identical'
    if eig[1] <= MIN_SINE ** 2 * eig[2]:
        return 'all remaining points are collinear'
    return None


def _hypotheses(points: np.ndarray, rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Planes through ``count`` random triples; degenerate triples dropped. Returns (normals (h,3), offsets (h,))."""
    idx = rng.integers(0, len(points), size=(count, 3))
    p0, p1, p2 = points[idx[:, 0]], points[idx[:, 1]], points[idx[:, 2]]
    u, v = p1 - p0, p2 - p0
    normals = np.cross(u, v)
    norm = np.linalg.norm(normals, axis=1)
    scale = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)
    ok = norm > MIN_SINE * scale  # also rejects duplicates, where scale == 0
    normals = normals[ok] / norm[ok, None]
    offsets = -np.einsum('ij,ij->i', normals, p0[ok])
    return normals, offsets


def _required_iterations(inlier_ratio: float, probability: float) -> float:
    """RANSAC iteration count for success ``probability`` with 3-point samples."""
    w3 = inlier_ratio ** 3
    if w3 <= 0:
        return np.inf
    if w3 >= 1:
        return 1
    return np.log(1 - probability) / np.log(1 - w3)


def _best_plane(points: np.ndarray, tolerance: float, probability: float, max_iterations: int,
                rng: np.random.Generator) -> tuple[np.ndarray, float, np.ndarray] | None:
    """One RANSAC run on (m, 3) points: (normal, offset, inlier mask) after refinement, or None."""
    m = len(points)
    subset = points if m <= SUBSET else points[rng.choice(m, SUBSET, replace=False)]
    best_normals = np.empty((0, 3))
    best_offsets = np.empty(0)
    best_counts = np.empty(0, dtype=np.int64)
    iterations = 0
    needed = float(max_iterations)
    while iterations < min(needed, max_iterations):
        batch = int(min(BATCH, max_iterations - iterations))
        normals, offsets = _hypotheses(points, rng, batch)
        iterations += batch
        if len(normals) == 0:
            continue
        counts = (np.abs(subset @ normals.T + offsets) <= tolerance).sum(axis=0)
        # Keep the CONFIRM best hypotheses seen so far for confirmation on all points.
        best_normals = np.concatenate([best_normals, normals])
        best_offsets = np.concatenate([best_offsets, offsets])
        best_counts = np.concatenate([best_counts, counts])
        keep = np.argsort(-best_counts, kind='stable')[:CONFIRM]
        best_normals, best_offsets, best_counts = best_normals[keep], best_offsets[keep], best_counts[keep]
        needed = _required_iterations(best_counts[0] / len(subset), probability)
    if len(best_counts) == 0:
        return None
    full_counts = (np.abs(points @ best_normals.T + best_offsets) <= tolerance).sum(axis=0)
    winner = int(np.argmax(full_counts))
    normal, offset = best_normals[winner], best_offsets[winner]
    inliers = np.abs(points @ normal + offset) <= tolerance
    # Least-squares refinement on the inliers; repeat while the inlier set changes (at most 3 times).
    for _ in range(3):
        if inliers.sum() < 3:
            break
        new_normal, new_offset = fit_plane(points[inliers])
        new_inliers = np.abs(points @ new_normal + new_offset) <= tolerance
        if new_inliers.sum() < inliers.sum():
            break  # the fit drifted away from the consensus set: keep the RANSAC plane
        normal, offset = new_normal, new_offset
        if np.array_equal(new_inliers, inliers):
            break
        inliers = new_inliers
    return normal, offset, inliers


def detect_planes(points: np.ndarray, tolerance: float, *, max_planes: int = 10,
                  min_inliers: int | float = 0.02, probability: float = 0.99,
                  max_iterations: int = 1000, seed: int | np.random.Generator | None = None) -> Segmentation:
    """Find planes one by one with RANSAC, removing each plane's inliers before the next search.

    points: (N, 3) float array, meters; rows with NaN/inf are ignored (label -1).
    tolerance: inlier distance ``t`` in meters (> 0).
    max_planes: stop after this many planes.
    min_inliers: stop when the best plane has fewer inliers; an absolute count, or a fraction of
        the valid points when given as a float < 1.
    probability: RANSAC success probability used to adapt the iteration count.
    max_iterations: cap on the hypotheses drawn per plane.
    seed: int, Generator, or None for fresh entropy.

    After extraction, each plane point within ``tolerance`` of several planes goes to the nearest,
    so the first plane does not keep the band of its neighbours along shared edges.
    """
    pts = as_points(points)
    tolerance = float(tolerance)
    if not np.isfinite(tolerance) or tolerance <= 0:
        raise ValueError(f'tolerance must be a finite distance > 0, got {tolerance!r}')
    if int(max_planes) != max_planes or max_planes < 0:
        raise ValueError(f'max_planes must be an integer >= 0, got {max_planes!r}')
    if not 0 < probability < 1:
        raise ValueError(f'probability must be in (0, 1), got {probability!r}')
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f'max_iterations must be an integer >= 1, got {max_iterations!r}')
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)

    labels = np.full(len(pts), -1, dtype=np.int32)
    valid_idx = np.flatnonzero(np.isfinite(pts).all(axis=1))
    n_valid = len(valid_idx)
    min_count = resolve_min_inliers(min_inliers, n_valid)
    remaining = valid_idx
    found: list[tuple[np.ndarray, float]] = []
    reason = f'reached max_planes={max_planes}'
    while len(found) < max_planes:
        rest = pts[remaining]
        why = _degeneracy(rest)
        if why is not None:
            reason = why if len(remaining) < n_valid or n_valid < 3 else f'no plane: {why}'
            break
        best = _best_plane(rest, tolerance, probability, int(max_iterations), rng)
        if best is None:
            reason = 'every sampled triple was degenerate (nearly collinear or duplicate points)'
            break
        normal, offset, inliers = best
        if inliers.sum() < min_count:
            reason = f'best remaining plane has {int(inliers.sum())} < min_inliers={min_count} points'
            break
        found.append(_canonical(normal, offset))
        labels[remaining[inliers]] = len(found) - 1
        remaining = remaining[~inliers]

    planes = _assign_nearest(pts, labels, found, tolerance)
    return Segmentation(labels=labels, planes=planes, tolerance=tolerance, n_valid=n_valid, reason=reason)


def _assign_nearest(pts: np.ndarray, labels: np.ndarray, found: list[tuple[np.ndarray, float]],
                    tolerance: float, rounds: int = 2) -> tuple[Plane, ...]:
    """Give each labelled point within ``tolerance`` of several planes to the nearest; between
    ``rounds`` of this, refit each plane on its cleaned inliers. Updates ``labels`` in place."""
    if not found:
        return ()
    assigned = np.flatnonzero(labels >= 0)
    rows = np.arange(len(assigned))
    for round_ in range(rounds if len(found) > 1 else 0):
        normals = np.array([n for n, _ in found])
        offsets = np.array([d for _, d in found])
        dist = np.abs(pts[assigned] @ normals.T + offsets)  # (m, k)
        # A point keeps its own plane unless another is strictly nearer and within tolerance.
        own = labels[assigned]
        masked = np.where(dist <= tolerance, dist, np.inf)
        nearest = np.argmin(masked, axis=1)
        move = masked[rows, nearest] < dist[rows, own]
        labels[assigned[move]] = nearest[move]
        if round_ == rounds - 1:
            break  # end on an assignment, so labels are consistent with the final planes
        # The first fit saw the edge bands of its neighbours; refit on the cleaned inliers.
        found = [_canonical(*fit_plane(pts[labels == k])) if np.sum(labels == k) >= 3 else plane
                 for k, plane in enumerate(found)]
    planes = []
    for k, (normal, offset) in enumerate(found):
        inliers = np.flatnonzero(labels == k)
        d = pts[inliers] @ normal + offset
        rms = float(np.sqrt(np.mean(d ** 2))) if len(d) else 0.0
        planes.append(Plane(normal=normal, offset=offset, inliers=inliers, rms=rms))
    return tuple(planes)
