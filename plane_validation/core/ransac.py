"""Sequential RANSAC plane detection (Lipnickas et al. 2014, section 3).

Pure numpy: no ROS import. Coordinates are in meters (or any consistent unit); the
tolerance ``t`` is an absolute point-to-plane distance in the same unit.

Internally the points are held as a (3, n) array centred on a median: distances to k planes
are then one (k, 3) @ (3, n) product (a (n, 3) @ (3, k) product is ~20x slower in numpy for
small k), columns are selected with ``np.compress``, and plane fits can use raw second moments
without losing precision to large absolute coordinates (each fit also centres its own points).
"""
from __future__ import annotations

import dataclasses
import decimal
import functools
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from . import kernels
from .noise import NOISE_REFERENCE, tolerance_scale
from .orientation import Orientation
from .regions import (
    FRAGMENT_PIECE,
    FRAGMENTED,
    NORMAL_MIN_COS,
    SUPPORT_BALANCE,
    Neighbours,
    VoxelIndex,
    graph_neighbours,
    grid_neighbours,
    voxel_index,
)

__all__ = ['Plane', 'Segmentation', 'SearchGraph', 'detect_planes', 'search_graph', 'fit_plane', 'as_points',
           'finite_rows', 'no_returns_as_nan', 'resolve_min_inliers', 'within_planes', 'carried']

#: Hypotheses scored per numpy call.
BATCH = 128
#: Points a hypothesis is scored on before the best few are confirmed on all points.
SUBSET = 4096
#: Best subset hypotheses confirmed on all points of the RANSAC sample.
CONFIRM = 4
#: Hypotheses are first scored on this many of the SUBSET points (a random share of them); only
#: those whose count there could still reach the CONFIRM best so far are scored on the rest. Most
#: hypotheses lie far from any plane, so this skips most of the scoring.
PRESCORE = 512
#: ... "could still reach": a count on the PRESCORE points at most this many binomial standard
#: deviations below the share the CONFIRM-th best holds of the whole subset (a hypothesis as good as that
#: one is dropped with a chance of about 1 in 700).
PRESCORE_SIGMAS = 3.0
#: Default for ``detect_planes(ransac_points=...)``: larger clouds are searched on a random
#: sample of this many points; every point is then labelled against the planes found.
RANSAC_POINTS = 32768
#: Default for ``detect_planes(grid_points=...)``: an image (``shape``) with more valid pixels is searched on a
#: regular sub-grid of about this many (a step of 3 pixels on a 640x480 Kinect frame). Fewer is faster but
#: loses small faces: at 20,000 (a step of 4) the Kinect frame's search is a third faster, but milk_cartoon's
#: auto-tuned planes go from 4 to 2 (the objects' fronts are lost; benchmarks/README.md).
GRID_POINTS = RANSAC_POINTS
#: Random points the degeneracy (spread) test looks at.
SPREAD_POINTS = 1024
#: A sample triple whose sine of the angle at its first point is below this is degenerate.
MIN_SINE = 1e-6
#: A little below NORMAL_MIN_COS: _best_region's count of the inliers whose normal agrees is at
#: least what a region may keep (regions.Neighbours.coherent), whatever the rounding of the dot products.
_COHERENT_BOUND = NORMAL_MIN_COS - 1e-9


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
    reason: why extraction stopped (human-readable). noise_model, noise_reference: how the
    tolerance grows with range (:mod:`.noise`; ``tolerance`` is t0, the one up to the reference range).
    viewpoint: (x, y, z) meters, where the sensor is in the cloud's frame. capped: the search stopped
    at ``max_planes`` with at least ``min_inliers`` points left, which may lie on planes it did not look
    for (or be clutter: no further search is made to tell).
    """

    labels: np.ndarray
    planes: tuple[Plane, ...]
    tolerance: float
    n_valid: int
    reason: str
    noise_model: str = 'constant'
    noise_reference: float = NOISE_REFERENCE
    viewpoint: tuple[float, float, float] = (0.0, 0.0, 0.0)
    capped: bool = False
    coefficients: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        coeffs = np.array([p.coefficients for p in self.planes]).reshape(-1, 4)
        object.__setattr__(self, 'coefficients', coeffs)

    @property
    def n_planes(self) -> int:
        return len(self.planes)


def within_planes(points: np.ndarray, labels: np.ndarray, seg: Segmentation) -> np.ndarray:
    """``labels`` (n,) of ``points`` (n, 3) meters, planes of ``seg``, with -1 where a point lies farther
    from its plane than the segmentation's tolerance scaled by its noise model at that point."""
    if seg.n_planes == 0:
        return labels
    plane = seg.coefficients[np.maximum(labels, 0)]
    distance = np.abs(np.einsum('ij,ij->i', points, plane[:, :3]) + plane[:, 3])
    scale = tolerance_scale(points, seg.noise_model, seg.noise_reference, seg.viewpoint)
    return np.where(distance <= seg.tolerance * (1.0 if scale is None else scale), labels, -1)


def carried(seg: Segmentation, points: np.ndarray, proxy: np.ndarray) -> Segmentation:
    """``seg``, found on a proxy of ``points`` (N, 3) meters (a lidar scan's ring image, voxel
    centroids), as a segmentation of the points themselves: ``proxy`` (n,) is the proxy row of each
    finite point, in order; a point takes its proxy's plane when it lies within the tolerance of it
    (:func:`within_planes`). The planes keep their coefficients; inliers and rms are the points'."""
    pts = as_points(points)
    finite = finite_rows(pts)
    valid = np.compress(finite, pts, axis=0)
    labels = np.full(len(pts), -1, dtype=np.int32)
    labels[finite] = within_planes(valid, seg.labels[proxy], seg)
    planes = []
    for k, plane in enumerate(seg.planes):
        inliers = np.flatnonzero(labels == k)
        residual = pts[inliers] @ plane.normal + plane.offset
        planes.append(Plane(plane.normal, plane.offset, inliers,
                            float(np.sqrt(np.mean(residual ** 2))) if len(inliers) else 0.0))
    return dataclasses.replace(seg, labels=labels, planes=tuple(planes), n_valid=len(valid))


def generator(seed: int | np.random.Generator | None) -> np.random.Generator:
    """A numpy Generator from ``seed``: an integer >= 0, a Generator (used as is), None (fresh entropy), or what
    else ``np.random.default_rng`` takes (a SeedSequence, a BitGenerator, integers); ValueError otherwise (the
    command line's and the node's seed -1 is None here)."""
    if isinstance(seed, np.random.Generator):
        return seed
    why = f'seed must be an integer >= 0, a numpy Generator or None (fresh entropy), got {seed!r}'
    if isinstance(seed, (bool, np.bool_, float, np.floating, str)) or \
            (isinstance(seed, (int, np.integer)) and seed < 0):
        raise ValueError(why)
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError):
        raise ValueError(why) from None


def check_integer(name: str, value, low: int | None) -> int:
    """``value`` as an int, or ValueError unless it is a whole number (not a bool), >= ``low`` unless that is None."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer, float, np.floating)) \
            or (isinstance(value, (float, np.floating)) and not np.isfinite(value)) or int(value) != value \
            or (low is not None and value < low):
        raise ValueError(f'{name} must be an integer{"" if low is None else f" >= {low}"}, got {value!r}')
    return int(value)


def check_number(name: str, value, what: str = 'a number') -> float:
    """``value`` as a float, or ValueError unless it is a real number (a numpy scalar or 0-d array too; not a bool,
    a string or None) that is finite; ``what`` says what was expected."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, decimal.Decimal)):
        raise ValueError(f'{name} must be {what}, got {value!r}')
    try:  # a Python int may be beyond float's range (np.isfinite cannot take it either)
        number = float(value)
    except OverflowError:
        number = np.inf
    if not np.isfinite(number):
        raise ValueError(f'{name} must be {what}, got {value!r}')
    return number


def check_flag(name: str, value) -> bool:
    """``value`` as a bool, or ValueError unless it is one (a string such as 'no' would count as true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f'{name} must be True or False, got {value!r}')
    return bool(value)


def as_points(points: np.ndarray) -> np.ndarray:
    """Validate an (N, 3) real array and return it as float64 (no copy when already float64); a masked array's
    masked coordinates become NaN (their rows are no points, as NaN rows)."""
    arr = np.asarray(points)  # (a masked array's data, mask dropped)
    if arr.dtype.kind not in 'fiu':
        raise ValueError(f'points must be a real numeric array, got dtype {arr.dtype}')
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f'points must have shape (N, 3), got {arr.shape}')
    if isinstance(points, np.ma.MaskedArray) and np.ma.is_masked(points):
        return np.where(np.ma.getmaskarray(points), np.nan, arr.astype(np.float64))
    return arr.astype(np.float64, copy=False)


def finite_rows(points: np.ndarray) -> np.ndarray:
    """(N,) bool: rows of the (N, 3) array whose three coordinates are finite (one compiled pass over a
    C-ordered float64 array; otherwise column by column: numpy's reduction along a length-3 axis is several
    times slower)."""
    if points.dtype == np.float64 and points.flags.c_contiguous and points.flags.writeable:
        return kernels.finite_mask(points)[0]
    ok = np.isfinite(points[:, 0])
    ok &= np.isfinite(points[:, 1])
    ok &= np.isfinite(points[:, 2])
    return ok


#: A row this close to a viewpoint other than the origin (meters, in each coordinate) is the driver's
#: (0, 0, 0) "no return" mark moved with the cloud (float32 rounding of the transform); no sensor
#: reports a point this close to itself.
AT_VIEWPOINT = 1e-6


def no_returns_as_nan(points: np.ndarray, viewpoint: Viewpoint = None) -> tuple[np.ndarray, int]:
    """``points`` (N, 3) with rows at exactly (0, 0, 0) set to NaN (a copy, only when there are any),
    and how many there were: the "no return" mark of sensor drivers that do not use NaN (a lidar
    or depth camera reports no point at its own origin). With a ``viewpoint`` (3,) other than the
    origin (a cloud moved to another frame), rows within AT_VIEWPOINT of it instead."""
    view = check_viewpoint(viewpoint)

    def at_mark(axis: int) -> np.ndarray:
        column = points[:, axis]
        return np.abs(column - view[axis]) <= AT_VIEWPOINT if view.any() else column == 0

    zero = at_mark(0)
    if not zero.any():  # the usual frame: one comparison
        return points, 0
    zero &= at_mark(1) & at_mark(2)
    count = int(np.count_nonzero(zero))
    if count == 0:
        return points, 0
    out = np.array(points, dtype=np.result_type(points.dtype, np.float32))
    out[zero] = np.nan
    return out, count


def no_returns_note(count: int) -> str:
    """What a message about too few points adds when ``count`` rows were left out as "no return" marks."""
    return f'; {count} were left out as a driver\'s "no return" mark (at (0, 0, 0), or at the viewpoint; ' \
        'zero_is_no_return)' if count else ''


#: Largest coordinate magnitude accepted, meters: squared distances of larger ones overflow float64 (a
#: single far row below it, such as a driver's FLT_MAX, is a point far from every plane).
MAX_COORDINATE = 1e150


#: Largest spread of a cloud's points around their middle, meters (the SPREAD_PERCENTILE of their largest
#: coordinate offset from the median, on about SPREAD_ROWS of them): the hypotheses are scored in float32,
#: whose range (3.4e38) such offsets and their planes' offsets would leave; no sensor sees this far.
MAX_SPREAD = 1e30
SPREAD_PERCENTILE = 90
SPREAD_ROWS = 1024


def check_magnitude(points: np.ndarray) -> None:
    """ValueError when a finite coordinate of ``points`` (N, 3) exceeds MAX_COORDINATE in magnitude
    (NaN and inf rows are ignored: they are no points), or when the points spread over more than MAX_SPREAD."""
    flat = points.reshape(-1)
    if len(flat) == 0:
        return
    largest = max(np.fmax.reduce(flat), -np.fmin.reduce(flat))  # NaN when every coordinate is NaN
    if largest > MAX_COORDINATE:
        big = np.abs(flat[np.abs(flat) > MAX_COORDINATE])
        worst = float(big[np.isfinite(big)].max(initial=0.0))
        if worst > MAX_COORDINATE:
            raise ValueError(f'a coordinate reaches {worst:.3g} m: beyond {MAX_COORDINATE:g} m squared distances '
                             'overflow (wrong units or a corrupt cloud?)')
    if not largest > MAX_SPREAD:  # (also NaN) no spread can exceed it
        return
    rows = points[::max(1, len(points) // SPREAD_ROWS)]
    rows = rows[finite_rows(rows)]
    if len(rows) == 0:
        return
    spread = float(np.percentile(np.abs(rows - np.median(rows, axis=0)).max(axis=1), SPREAD_PERCENTILE))
    if spread > MAX_SPREAD:
        raise ValueError(f'the points spread over {spread:.3g} m around their middle: beyond {MAX_SPREAD:g} m, which '
                         'the search cannot score (wrong units or a corrupt cloud?)')


def min_inliers_number(min_inliers) -> int | float:
    """``min_inliers`` as an int (a count) when given as an integer type, else as a float (a fraction when < 1, a
    count otherwise: a Decimal or Fraction too); ValueError unless a real number >= 0."""
    if isinstance(min_inliers, np.ndarray) and min_inliers.ndim == 0:
        min_inliers = min_inliers[()]  # a 0-d array means its number: a fraction stays a fraction
    number = check_number('min_inliers', min_inliers, 'a count >= 0 or a fraction in [0, 1)')
    if number < 0:
        raise ValueError(f'min_inliers must be a count >= 0 or a fraction in [0, 1), got {min_inliers!r}')
    return int(min_inliers) if isinstance(min_inliers, (int, np.integer)) else number


def resolve_min_inliers(min_inliers: int | float, n_valid: int) -> int:
    """An absolute count, or a fraction of ``n_valid`` when ``min_inliers`` is not of an integer type and < 1."""
    number = min_inliers_number(min_inliers)
    if isinstance(number, float) and number < 1:
        return max(3, int(np.ceil(number * n_valid)))
    return max(3, int(number))


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
    cols = np.array(pts.T)  # a copy: _fit_columns centres it
    centered = cols - cols.mean(axis=1, keepdims=True)
    spread = np.linalg.eigvalsh(centered @ centered.T)  # ascending; every point counts (no outlier guard here)
    if spread[2] <= 0 or np.all(pts == pts[0]):  # the mean need not round-trip: compare the points themselves
        raise ValueError('no plane fits these points: they are all identical')
    if spread[1] <= MIN_SINE ** 2 * spread[2]:
        raise ValueError('no plane fits these points: they all lie on one line')
    return _fit_columns(cols)


def _fit_columns(cols: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares plane through the columns of ``cols`` (3, n), a scratch copy: it is centred
    in place (raw second moments of far-away points would lose precision)."""
    centroid = cols.mean(axis=1)
    cols -= centroid[:, None]
    scatter = cols @ cols.T
    # Eigenvector of the smallest eigenvalue of the 3x3 scatter matrix.
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return normal, float(-normal @ centroid)


def _canonical(normal: np.ndarray, offset: float) -> tuple[np.ndarray, float]:
    """Fix the sign ambiguity: offset <= 0 (normal points away from the origin), ties by normal."""
    if offset > 0 or (offset == 0 and normal[np.argmax(np.abs(normal))] < 0):
        return -normal, -offset
    return normal, offset


def _degeneracy(cols: np.ndarray) -> str | None:
    """Reason why no plane can be fitted to the points ``cols`` (3, n), or None.

    The spread is judged on the points nearest the median (98 %), so that one far outlier (a
    driver's FLT_MAX instead of NaN) cannot make a planar cloud look collinear.
    """
    n = cols.shape[1]
    if n < 3:
        return f'fewer than 3 points left ({n})'
    # A random subset is plenty for a spread test (not a strided one: in an organized cloud a
    # stride can pick one image column, which lies on a line). Seeded by n: deterministic.
    core = cols.T if n <= SPREAD_POINTS else cols[:, np.random.default_rng(n).integers(0, n, SPREAD_POINTS)].T
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


#: Share of the hypotheses drawn from nearby points (after Schnabel et al. 2007: a small plane is
#: hit far more often by a triple of neighbours than by three points drawn from the whole cloud).
LOCAL_SHARE = 0.5
#: Assumed chance that both nearby points of a local triple lie on the plane of its first point
#: (for the RANSAC stopping rule; below the 0.58-0.87 measured on the quality benchmark's scenes,
#: as planes of under 1 % of the points get 0.14-0.53).
LOCAL_HIT = 0.25

#: Draws (count, 3) column indices of triples of nearby points (rows with a -1 are dropped).
Sampler = Callable[[np.random.Generator, int], np.ndarray]
#: Maps (inlier mask (m,), plane normal (3,), support mask (m,), mask (m,) of the points on the side of the plane
#: its normal points to) to (the part of the inliers a plane keeps, the points it takes out of the search: those,
#: or with them its surface's points beyond t).
Keep = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
#: Where the noise exceeds t, a surface's points within t are too sparse to hold together (on an image
#: grid, below about 60 % of its pixels): the suite's synthetic room at t = 1 cm fell apart into pieces below
#: min_inliers (F1 0.04; Open3D 0.71). A region whose inliers fall apart (regions.fragmented) is connected
#: through the points within this many tolerances of its plane whose normals agree, keeps those within one
#: (F1 0.70) and takes the others out of the search (else they came back as planes parallel to it). Always
#: joining them instead cost planes at the best t (quality.py's depth room 8/9 -> 7/9).
SUPPORT = 2.0


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (h, 3) arrays, the same values as np.cross without its per-call overhead."""
    out = np.empty_like(u)
    out[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
    out[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
    out[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    return out


def _hypotheses(cols: np.ndarray, rng: np.random.Generator, count: int,
                sampler: Sampler | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Planes through ``count`` random triples of the columns of ``cols`` (3, n), LOCAL_SHARE of
    them from ``sampler`` when given; degenerate triples dropped. Returns (normals (h, 3), offsets (h,))."""
    if sampler is None:
        idx = rng.integers(0, cols.shape[1], size=(count, 3))
    else:
        local = int(round(LOCAL_SHARE * count))
        idx = np.concatenate([rng.integers(0, cols.shape[1], size=(count - local, 3)), sampler(rng, local)])
        idx = idx[(idx >= 0).all(axis=1)]
    p0, p1, p2 = cols[:, idx[:, 0]].T, cols[:, idx[:, 1]].T, cols[:, idx[:, 2]].T
    u, v = p1 - p0, p2 - p0
    normals = _cross(u, v)
    norm = np.linalg.norm(normals, axis=1)
    scale = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)
    ok = norm > MIN_SINE * scale  # also rejects duplicates, where scale == 0
    normals = normals[ok] / norm[ok, None]
    offsets = -np.einsum('ij,ij->i', normals, p0[ok])
    return normals, offsets


def _required_iterations(inlier_ratio: float, probability: float, local: bool = False) -> float:
    """RANSAC iteration count for success ``probability`` with 3-point samples (``local``: LOCAL_SHARE
    of them from nearby points, each all-inlier with chance inlier_ratio * LOCAL_HIT)."""
    w3 = inlier_ratio ** 3
    if local:
        w3 = (1 - LOCAL_SHARE) * w3 + LOCAL_SHARE * inlier_ratio * LOCAL_HIT
    if w3 <= 0:
        return np.inf
    if w3 >= 1:
        return 1
    return np.log(1 - probability) / np.log(1 - w3)


def _signed(cols: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(k, n) signed distances of the points ``cols`` (3, n) to k planes (positive on the side the normal points to)."""
    dist = normals @ cols
    dist += offsets[:, None]
    return dist


def _distances(cols: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(k, n) absolute distances of the points ``cols`` (3, n) to k planes (in place, one buffer)."""
    dist = _signed(cols, normals, offsets)
    return np.abs(dist, out=dist)


#: Which of the unit normals (h, 3) a plane may have ((h,) bool; an orientation constraint), or None: any.
Allows = Callable[[np.ndarray], np.ndarray] | None
#: An inlier tolerance in meters: one for every point, or (n,) one per point (a noise model).
Tolerance = float | np.ndarray
#: Where the sensor is in a cloud's frame: (x, y, z) meters, or None for the origin.
Viewpoint = Sequence[float] | np.ndarray | None


def _at(tolerance: Tolerance, idx) -> Tolerance:
    """A tolerance for a subset ``idx`` of the points: a scalar as is, a per-point (n,) array indexed."""
    return tolerance if np.ndim(tolerance) == 0 else tolerance[idx]


def _within(cols: np.ndarray, normal: np.ndarray, offset: float, tolerance: Tolerance) -> np.ndarray:
    """(n,) bool: points ``cols`` (3, n) within ``tolerance`` of the plane."""
    return _distances(cols, normal[None, :], np.array([offset]))[0] <= tolerance


def _low_count(count: float, n: int) -> float:
    """PRESCORE_SIGMAS binomial standard deviations below ``count`` of ``n`` points."""
    return count - PRESCORE_SIGMAS * np.sqrt(count * (1 - count / n))


def _reference_share(best_counts: np.ndarray, scored: int, head_counts: np.ndarray, head: int) -> float:
    """The inlier share a hypothesis must be able to reach to join the CONFIRM best: the CONFIRM-th best
    count so far over the ``scored`` subset points, or before there are CONFIRM of them, a lower bound
    (_low_count) on the share of the CONFIRM-th best of ``head_counts`` over ``head`` points; 0 if neither."""
    if len(best_counts) == CONFIRM:
        return float(best_counts[-1]) / scored
    if len(head_counts) < CONFIRM:
        return 0.0
    return max(0.0, _low_count(float(np.partition(head_counts, -CONFIRM)[-CONFIRM]), head)) / head


@functools.lru_cache(maxsize=64)
def _shuffled(m: int) -> np.ndarray:
    """A fixed permutation of range(m) (read-only; it does not draw from the caller's generator)."""
    order = np.random.default_rng(m).permutation(m)
    order.flags.writeable = False
    return order


def _best_plane(cols: np.ndarray, tolerance: Tolerance, probability: float, max_iterations: int,
                rng: np.random.Generator, region_of: Keep | None = None,
                point_normals: np.ndarray | None = None, sampler: Sampler | None = None, allows: Allows = None
                ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
    """One RANSAC run on the points ``cols`` (3, m): (normal, offset, inlier mask, mask of the points it
    takes out of the search) after refinement, or None when every sampled triple was degenerate. ``region_of``
    maps an inlier mask (m,) to the part a plane would really keep (its largest connected region, see
    :data:`Keep`) and the points it takes; the confirmed
    hypotheses are then compared by that, and the plane is refitted on it. ``point_normals`` (3, m),
    local surface normals (NaN: unknown): hypotheses are scored only by the points whose normal
    agrees with theirs. ``sampler``: draws triples of nearby points for part of the hypotheses. ``allows``: the
    normals a plane may have; other hypotheses are dropped and a refit that leaves them is not taken."""
    m = cols.shape[1]
    # the scored subset in random order (when it is all the points, a fixed shuffle of them), so
    # that its first PRESCORE points are a random sample of it
    pick = _shuffled(m) if m <= SUBSET else rng.choice(m, SUBSET, replace=False)
    subset = cols[:, pick]
    # Scoring only ranks hypotheses: float32 halves its memory traffic, and the rounding (~1e-7 of
    # the centred coordinates) only matters for points within a hair of t. A row beyond float32's
    # range becomes inf (its distances inf or NaN): never an inlier, as in float64.
    with np.errstate(over='ignore'):
        subset32 = subset.astype(np.float32)
    sub_tolerance = _at(tolerance, pick)
    sub_normals = None
    if point_normals is not None:
        sub_normals = point_normals[:, pick]
        unknown = np.isnan(sub_normals[0])
        sub_normals = np.nan_to_num(sub_normals).astype(np.float32)
    scored = len(pick)
    head = slice(0, PRESCORE) if scored > 2 * PRESCORE else slice(0, scored)
    tail = slice(head.stop, scored)

    def score(normals32: np.ndarray, offsets32: np.ndarray, part: slice) -> np.ndarray:
        """(h,) inliers of the hypotheses among the subset's points ``part`` (whose normal agrees)."""
        with np.errstate(over='ignore', invalid='ignore'):  # far-out rows: inf or NaN, never inliers
            near = _distances(subset32[:, part], normals32, offsets32) <= _at(sub_tolerance, part)
        if sub_normals is not None:
            coherent = np.abs(normals32 @ sub_normals[:, part]) >= np.float32(NORMAL_MIN_COS)
            coherent |= unknown[part]
            near &= coherent
        # a uint16 row sum is much faster than count_nonzero(axis=1); SUBSET < 65536
        return np.add.reduce(near.view(np.uint8), axis=1, dtype=np.uint16).astype(np.int64)

    best_normals = np.empty((0, 3))
    best_offsets = np.empty(0)
    best_counts = np.empty(0, dtype=np.int64)
    iterations = 0
    needed = float(max_iterations)
    while iterations < min(needed, max_iterations):
        batch = int(min(BATCH, max_iterations - iterations))
        normals, offsets = _hypotheses(cols, rng, batch, sampler)
        iterations += batch
        if allows is not None:
            ok = allows(normals)
            normals, offsets = normals[ok], offsets[ok]
        if len(normals) == 0:
            continue
        normals32, offsets32 = normals.astype(np.float32), offsets.astype(np.float32)
        counts = score(normals32, offsets32, head)
        if tail.stop > tail.start:
            share = _reference_share(best_counts, scored, counts, head.stop)
            go_on = counts >= _low_count(head.stop * share, head.stop) - 1
            if go_on.all():
                counts += score(normals32, offsets32, tail)
            else:
                counts[go_on] += score(normals32[go_on], offsets32[go_on], tail)
                counts[~go_on] = -1  # not among the best: never kept
        # Keep the CONFIRM best hypotheses seen so far for confirmation on all points.
        best_normals = np.concatenate([best_normals, normals])
        best_offsets = np.concatenate([best_offsets, offsets])
        best_counts = np.concatenate([best_counts, counts])
        keep = np.argsort(-best_counts, kind='stable')[:CONFIRM]
        keep = keep[best_counts[keep] >= 0]
        best_normals, best_offsets, best_counts = best_normals[keep], best_offsets[keep], best_counts[keep]
        if len(best_counts):
            needed = _required_iterations(best_counts[0] / scored, probability, sampler is not None)
    if len(best_counts) == 0:
        return None
    # MSAC: the truncated squared distance prefers, of two planes with similar support, the one
    # its inliers hug (a plane tilted across a small face and its neighbours' edges loses).
    with np.errstate(over='ignore', invalid='ignore'):  # a far-out row (a driver's FLT_MAX): inf, no inlier
        if region_of is not None:
            signed = _signed(cols, best_normals, best_offsets)
            return _best_region(cols, tolerance, best_normals, best_offsets, np.abs(signed), signed > 0, region_of,
                                point_normals, allows=allows)
        dist = _distances(cols, best_normals, best_offsets)
    np.minimum(dist, tolerance, out=dist)
    winner = int(np.argmin(np.einsum('ij,ij->i', dist, dist)))
    normal, offset = best_normals[winner], best_offsets[winner]
    inliers = _within(cols, normal, offset, tolerance)
    # Least-squares refinement on the inliers; repeat while the inlier set changes (at most 3 times).
    for _ in range(3):
        count = int(np.count_nonzero(inliers))
        if count < 3:
            break
        new_normal, new_offset = _fit_columns(np.compress(inliers, cols, axis=1))
        if not _allowed(allows, new_normal):
            break  # the fit leaves the orientation constraint: keep the RANSAC plane
        new_inliers = _within(cols, new_normal, new_offset, tolerance)
        if np.count_nonzero(new_inliers) < count:
            break  # the fit drifted away from the consensus set: keep the RANSAC plane
        normal, offset = new_normal, new_offset
        if np.array_equal(new_inliers, inliers):
            break
        inliers = new_inliers
    return normal, offset, inliers, inliers


def _allowed(allows: Allows, normal: np.ndarray) -> bool:
    """Whether a plane may have the unit ``normal`` (3,) (``allows`` None: any)."""
    return allows is None or bool(allows(normal[None, :])[0])


def _best_region(cols: np.ndarray, tolerance: Tolerance, normals: np.ndarray, offsets: np.ndarray, dist: np.ndarray,
                 above: np.ndarray, keep: Keep, point_normals: np.ndarray | None = None, *, allows: Allows = None
                 ) -> tuple[np.ndarray, float, np.ndarray]:
    """Of the confirmed hypotheses (distances ``dist`` (h, m), ``above`` (h, m): the points on the side of each
    plane its normal points to), the one whose region (``keep``: its
    largest connected one, see :data:`Keep` and SUPPORT) is largest (ties: MSAC); then refit on the region
    and take the region again, at most 3 times. ``point_normals`` (3, m), NaN where unknown: a region keeps
    only points whose normal agrees. Returns (normal, offset, region (m,), taken (m,): see :data:`Keep`)."""
    inliers = dist <= tolerance
    support = dist <= SUPPORT * tolerance
    counts = np.count_nonzero(inliers, axis=1)
    np.minimum(dist, tolerance, out=dist)
    cost = np.einsum('ij,ij->i', dist, dist)
    winner, region, taken, size = -1, None, None, -1
    for h in np.lexsort((cost, -counts)):  # a hypothesis cannot keep more than its inliers: skip
        if counts[h] <= size:
            break
        if size > 0 and point_normals is not None:  # nor more than its coherent inliers: skip without labelling
            bound = np.count_nonzero(inliers[h] & ~(np.abs(normals[h] @ point_normals) < _COHERENT_BOUND))
            if bound < size or (bound == size and cost[h] >= cost[winner]):
                continue
        candidate, took = keep(inliers[h], normals[h], support[h], above[h])
        found = int(np.count_nonzero(candidate))
        if found > size or (found == size and cost[h] < cost[winner]):
            winner, region, taken, size = int(h), candidate, took, found
    normal, offset = normals[winner], offsets[winner]
    for _ in range(3):
        count = int(np.count_nonzero(region))
        if count < 3:
            break
        new_normal, new_offset = _fit_columns(np.compress(region, cols, axis=1))
        if not _allowed(allows, new_normal):
            break
        signed = _signed(cols, new_normal[None, :], np.array([new_offset]))[0]
        near = np.abs(signed)
        new_region, new_taken = keep(near <= tolerance, new_normal, near <= SUPPORT * tolerance, signed > 0)
        if np.count_nonzero(new_region) < count:
            break
        normal, offset = new_normal, new_offset
        same = np.array_equal(new_region, region)
        region, taken = new_region, new_taken
        if same:
            break
    return normal, offset, region, taken


def detect_planes(points: np.ndarray, tolerance: float, *, max_planes: int = 10,
                  min_inliers: int | float = 0.02, probability: float = 0.99,
                  max_iterations: int = 1000, seed: int | np.random.Generator | None = None,
                  ransac_points: int | None = RANSAC_POINTS, shape: tuple[int, int] | None = None,
                  connectivity: bool = True, graph: SearchGraph | None = None, noise_model: str = 'constant',
                  noise_reference: float = NOISE_REFERENCE, viewpoint: Viewpoint = None,
                  grid_points: int | None = GRID_POINTS, orientation: Orientation | None = None) -> Segmentation:
    """Find planes one by one with RANSAC, removing each plane's points before the next search.

    With ``connectivity`` (the default) a plane is a connected planar region: each candidate's
    inliers are split into connected regions (:mod:`.regions`), the largest becomes the plane, the
    other inliers go back to the pool (so coplanar patches of separate objects become separate
    planes), and candidates are compared by the region they would keep. Where the inliers fall apart
    into small pieces (noise above t) the region is instead connected through the points within
    SUPPORT * t whose normals agree: it keeps its inliers, and the others of that surface leave the pool
    unassigned. ``shape=(H, W)`` says the
    rows are an H x W image in row-major order (NaN rows for holes): neighbours are then image
    neighbours without a depth jump, and a large image is searched on a regular sub-grid;
    otherwise a nearest-neighbour graph. ``connectivity=False`` gives the paper's method: every
    point within ``t`` of an infinite plane (``shape`` is then only checked).

    points: (N, 3) float array, meters; rows with NaN/inf are ignored (label -1).
    tolerance: inlier distance ``t`` in meters (> 0).
    max_planes: stop after this many planes.
    min_inliers: stop when the best plane has fewer inliers; an absolute count, or a fraction of
        the valid points when given as a float < 1.
    probability: RANSAC success probability used to adapt the iteration count.
    max_iterations: cap on the hypotheses drawn per plane.
    seed: int, Generator, or None for fresh entropy.
    ransac_points: when there are more valid points, the sequential search runs on a random
        sample of this many (min_inliers scaled to the sample); None = always on all points.
    grid_points: with ``shape`` and connectivity, an image with more valid pixels is searched on a regular
        sub-grid of about this many (:func:`grid_step`); None = every pixel.
    graph: the :func:`search_graph` of these points, shape, ransac_points and grid_points, to reuse across calls
        on one cloud (a tolerance sweep); None builds it here.
    noise_model: 'constant', or 'depth_quadratic': a point at range r from the sensor is within
        t * max(1, (r / noise_reference)^2) of a plane (:mod:`.noise`).
    viewpoint: (3,) meters, where the sensor is in the cloud's frame (default the origin, as a driver
        publishes a scan): ranges for the noise model, and the rays along which the neighbourhood
        graph of an unorganized cloud tells a spinning lidar's rings (:func:`.regions.graph_neighbours`).
    orientation: an :class:`.orientation.Orientation` (from :func:`.orientation.orientation`): only planes whose
        normal satisfies it are searched for, refitted and merged (None: any plane).

    Without connectivity, each plane found is then refitted by least squares on the searched points
    nearest to it (within ``tolerance``), and every valid point is labelled with the nearest plane
    within ``tolerance`` (ties to the earlier plane, -1 when none): a point within ``t`` of two planes
    along a shared edge goes to the nearer, not to the first found. With connectivity, each region is
    refitted on its own points, border points go to the nearest plane of the regions they touch,
    touching regions of one surface are merged, and every valid point takes the region of the
    searched point nearest to it (organized: of the sub-grid pixels around it) when it lies within
    ``tolerance`` of that region's plane, else -1. Either way a plane left with fewer than
    ``min_inliers`` points is dropped (and said so in ``reason``); with connectivity its points stay
    unassigned, as they touch no other region.
    """
    pts = as_points(points)
    given, tolerance = tolerance, check_number('tolerance', tolerance, 'a finite distance > 0')
    if tolerance <= 0:
        raise ValueError(f'tolerance must be a finite distance > 0, got {given!r}')
    max_planes = check_integer('max_planes', max_planes, 0)
    if not 0 < check_number('probability', probability, 'in (0, 1)') < 1:
        raise ValueError(f'probability must be in (0, 1), got {probability!r}')
    max_iterations = check_integer('max_iterations', max_iterations, 1)
    connectivity = check_flag('connectivity', connectivity)
    _check_search_size('ransac_points', ransac_points)
    _check_search_size('grid_points', grid_points)
    if shape is not None:
        shape = check_shape(shape, len(pts))
    check_magnitude(pts)
    view = check_viewpoint(viewpoint)
    if orientation is not None and not isinstance(orientation, Orientation):
        raise ValueError(f'orientation must be an Orientation (orientation(axis, angle, mode)) or None, '
                         f'got {type(orientation).__name__}')
    allows = None if orientation is None else orientation.allows
    scale = tolerance_scale(pts, noise_model, noise_reference, view)
    model = dict(noise_model=noise_model, noise_reference=float(noise_reference), viewpoint=tuple(view.tolist()))
    point_tolerance = tolerance if scale is None else tolerance * scale  # (N,) with a noise model
    rng = generator(seed)
    if connectivity:
        seg = _detect_regions(pts, point_tolerance, max_planes, min_inliers, probability, int(max_iterations), rng,
                              ransac_points, shape, graph, view, grid_points, allows)
        return _facing_away(dataclasses.replace(seg, tolerance=tolerance, **model), view)

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
    valid_tolerance = _at(point_tolerance, valid_idx)
    search_tolerance = valid_tolerance
    if ransac_points is not None and n_valid > ransac_points:
        sample = np.sort(rng.choice(n_valid, int(ransac_points), replace=False))
        search, search_tolerance = valid[:, sample], _at(valid_tolerance, sample)
        search_min = max(3, int(np.ceil(min_count * ransac_points / n_valid)))
    found, reason, _, capped = _sequential(search, search_tolerance, max_planes, search_min, probability,
                                           int(max_iterations), rng, n_total=n_valid, allows=allows)
    labels = np.full(len(pts), -1, dtype=np.int32)
    tolerances = (valid_tolerance, search_tolerance)
    planes = _label_all(valid, search, valid_idx, center, labels, found, tolerances, allows)
    small = [j for j, plane in enumerate(planes) if len(plane.inliers) < min_count]
    if small:  # a sample's count is only an estimate (or a neighbour took the points): check all
        found = [plane for j, plane in enumerate(found) if j not in small]
        planes = _label_all(valid, search, valid_idx, center, labels, found, tolerances, allows)
        reason += (f'; dropped {len(small)} plane(s) left with fewer than min_inliers={min_count} points '
                   'once every point was labelled')
    return _facing_away(Segmentation(labels=labels, planes=planes, tolerance=tolerance, n_valid=n_valid,
                                     reason=reason, capped=capped, **model), view)


#: A plane passes through the viewpoint when the viewpoint lies within this many times the RMS residual of
#: the plane's points (plus a nanometre, for noise-free points): which side of it the viewpoint is on is noise.
THROUGH_VIEWPOINT_RMS = 3.0


def _facing_away(seg: Segmentation, viewpoint: np.ndarray) -> Segmentation:
    """``seg`` with each plane's normal pointing away from ``viewpoint`` (3,), so that a floor keeps
    its normal from frame to frame; a plane through the viewpoint (THROUGH_VIEWPOINT_RMS; the ground in
    ``base_link``, whose origin lies on it) has instead the largest component of its normal positive
    (the ground's points up)."""
    def flipped(p: Plane) -> bool:
        side = p.offset + p.normal @ viewpoint
        through = abs(side) <= THROUGH_VIEWPOINT_RMS * p.rms + 1e-9
        return p.normal[np.argmax(np.abs(p.normal))] < 0 if through else side > 0
    planes = tuple(dataclasses.replace(p, normal=-p.normal, offset=-p.offset) if flipped(p) else p for p in seg.planes)
    return dataclasses.replace(seg, planes=planes)


def _sequential(cols: np.ndarray, tolerance: Tolerance, max_planes: int, min_count: int, probability: float,
                max_iterations: int, rng: np.random.Generator, n_total: int,
                neighbours: Neighbours | None = None, allows: Allows = None
                ) -> tuple[list, str, np.ndarray | None, bool]:
    """Sequential RANSAC on the points ``cols`` (3, n): the planes [(normal, offset)] in
    extraction order, why the search stopped, with ``neighbours`` the region of each point
    (n,) (-1: none), and whether it stopped at ``max_planes`` with ``min_count`` points left."""
    n = cols.shape[1]
    rest = cols
    rest_idx = np.arange(n)
    if neighbours is not None and neighbours.usable is not None:  # only points that can join a region
        rest_idx = np.flatnonzero(neighbours.usable[neighbours.pixel])
        rest = cols[:, rest_idx]
        tolerance = _at(tolerance, rest_idx)
    region = None if neighbours is None else np.full(n, -1, dtype=np.int64)
    region_of = None
    local = None if neighbours is None or neighbours.shape is not None else neighbours.subgraph(rest_idx)
    found: list[tuple[np.ndarray, float]] = []
    reason = f'reached max_planes={max_planes}'
    while len(found) < max_planes:
        why = _degeneracy(rest)
        if why is not None:
            reason = why if rest.shape[1] < n or n_total < 3 else f'no plane: {why}'
            break
        if local is not None:  # the graph of the points left: one compiled call per region (kernels.graph_region)
            region_of = functools.partial(_graph_region, kernels.c_array(local.edges, np.int64),
                                          _NO_NORMALS if local.normals is None else local.normals)
        elif neighbours is not None:
            region_of = functools.partial(_grid_region if neighbours.normals is not None else _grid_region_numpy,
                                          neighbours, rest_idx)
        rest_normals = None if neighbours is None or neighbours.normals is None else \
            np.ascontiguousarray(neighbours.normals[rest_idx].T)
        sampler = None if neighbours is None else _nearby_sampler(neighbours, rest_idx)
        best = _best_plane(rest, tolerance, probability, max_iterations, rng, region_of, rest_normals, sampler,
                           allows)
        if best is None:
            reason = 'every sampled triple was degenerate (nearly collinear or duplicate points)' if allows is None \
                else 'no sampled plane satisfied the orientation constraint (or every triple was degenerate)'
            break
        normal, offset, inliers, taken = best
        count = int(np.count_nonzero(inliers))
        if count < min_count:
            reason = f'best remaining plane has {count} < min_inliers={min_count} points' + \
                ('' if n == n_total else f' (in a sample of {n} of {n_total} points)')
            break
        left = ~taken
        if region is not None:
            region[rest_idx[inliers]] = len(found)
            rest_idx = rest_idx[left]
            local = None if local is None else local.subgraph(np.flatnonzero(left))
        found.append((normal, offset))
        rest = np.compress(left, rest, axis=1)
        tolerance = _at(tolerance, left)
    return found, reason, region, len(found) == max_planes > 0 and rest.shape[1] >= min_count


#: What :func:`.kernels.grid_region` needs of :mod:`.regions`' rules, in its order.
_REGION_RULES = np.array([FRAGMENTED, FRAGMENT_PIECE, SUPPORT_BALANCE])
_NO_BRIDGES = np.empty((0, 3), np.int64)


def _grid_region(neighbours: Neighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                 support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) of the points ``rest_idx`` (r,) of a sub-grid for a plane of ``normal`` with inliers
    ``mask`` (r,), support band ``support`` (r,) and side ``above`` (r,): one compiled call
    (:func:`.kernels.grid_region`; :func:`_grid_region_numpy` is its reference)."""
    bridges = _NO_BRIDGES if neighbours.bridges is None else kernels.c_array(neighbours.bridges, np.int64)
    return kernels.grid_region(neighbours.pixel, neighbours.node, neighbours.usable, neighbours.shape[1], bridges,
                               neighbours.normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, rest_idx,
                               mask, support, above, _REGION_RULES)


_NO_NORMALS = np.empty((0, 3))


def _graph_region(edges: np.ndarray, normals: np.ndarray, mask: np.ndarray, normal: np.ndarray, support: np.ndarray,
                  above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (n,) of a graph of n points joined by ``edges`` (e, 2) with local ``normals`` (n, 3) ((0, 3):
    none known) for a plane of ``normal`` with inliers ``mask`` (n,), support band ``support`` and side ``above``:
    :func:`.kernels.graph_region` (:func:`_graph_region_numpy` is its reference)."""
    return kernels.graph_region(edges, normals, kernels.c_array(normal, np.float64), NORMAL_MIN_COS, mask, support,
                                above, _REGION_RULES)


def _graph_region_numpy(local: Neighbours, mask: np.ndarray, normal: np.ndarray, support: np.ndarray,
                        above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_graph_region` in numpy (:meth:`.regions.Neighbours.region` of the graph ``local``)."""
    coherent = local.coherent(normal)
    return local.region(mask & coherent, support & coherent, above)


def _grid_region_numpy(neighbours: Neighbours, rest_idx: np.ndarray, mask: np.ndarray, normal: np.ndarray,
                       support: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_grid_region` in numpy (:meth:`.regions.Neighbours.region`)."""
    n = neighbours.n
    wide = np.zeros(n, bool)
    wide[rest_idx[support]] = True
    wide &= neighbours.coherent(normal)  # an edge's normals cut the support as they cut the region
    full = np.zeros(n, bool)
    full[rest_idx[mask]] = True
    up = np.zeros(n, bool)
    up[rest_idx[support & above]] = True  # only the support's side is read: a far smaller scatter
    kept, taken = neighbours.region(full & wide, wide, up)
    return kept[rest_idx], taken[rest_idx]


def _nearby_sampler(neighbours: Neighbours, rest_idx: np.ndarray) -> Sampler:
    """Triples of nearby points among the points ``rest_idx`` (ascending) of ``neighbours``, as
    positions in ``rest_idx`` (-1: the nearby point is not among them)."""
    position = np.full(neighbours.n + 1, -1, dtype=np.int64)  # [-1] stays -1
    position[rest_idx] = np.arange(len(rest_idx))

    def sample(rng: np.random.Generator, count: int) -> np.ndarray:
        first = rng.integers(0, len(rest_idx), count)
        near = position[neighbours.nearby(np.tile(rest_idx[first], 2), rng)]
        return np.column_stack([first, near[:count], near[count:]])
    return sample


def _nearest(cols: np.ndarray, found: list[tuple[np.ndarray, float]], tolerance: Tolerance
             ) -> tuple[np.ndarray, np.ndarray]:
    """Label each point of ``cols`` (3, n) with the nearest plane within ``tolerance`` (ties to
    the earlier plane; -1 when none). Returns (labels (n,) int32, distance to that plane (n,))."""
    dist = _distances(cols, np.array([n for n, _ in found]), np.array([d for _, d in found]))
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
    found = [_kept_fit(_fit_columns(np.compress(own == j, search, axis=1)), plane, allows)
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
        normal, offset = _canonical(normal, offset - float(normal @ center))
        planes.append(Plane(normal=normal, offset=offset, inliers=valid_idx[own == j],
                            rms=float(np.sqrt(mean_sq[j]))))
    return tuple(planes)


def _check_search_size(name: str, value) -> None:
    """ValueError unless ``value`` (``ransac_points`` or ``grid_points``) is None or a whole number >= 3."""
    if value is not None:
        try:
            check_integer(name, value, 3)
        except ValueError:
            raise ValueError(f'{name} must be None or an integer >= 3, got {value!r}') from None


#: An image whose (sub-)grid would have fewer rows or columns than this is searched as an unorganized
#: cloud: a line of pixels has no 2-D neighbourhood.
MIN_GRID_SIDE = 3


def grid_step(shape: tuple[int, int], n_valid: int, limit: int | None) -> int:
    """The step of the regular sub-grid of an H x W image (``shape``) with ``n_valid`` valid pixels that
    keeps about ``limit`` of them (1: every pixel; ``limit`` None: 1), taking rows and columns from
    step // 2 on; 0 when that grid would have fewer than MIN_GRID_SIDE rows or columns."""
    h, w = shape
    step = 1 if limit is None or n_valid <= limit else int(np.ceil(np.sqrt(n_valid / limit)))
    return step if min(len(range(step // 2, h, step)), len(range(step // 2, w, step))) >= MIN_GRID_SIDE else 0


def grid_pixels(finite: np.ndarray, shape: tuple[int, int], step: int) -> np.ndarray:
    """(gh, gw) the pixel (row-major index into the H x W image ``shape``) that stands for each
    step x step block of the sub-grid of :func:`grid_step`: the block's centre pixel (step // 2,
    step // 2) when valid (``finite`` (H * W,) bool), else its valid pixel nearest to the centre;
    -1 for a block without one. A depth camera's scattered lost pixels then leave no holes in the
    sub-grid, which would cut its 4-connected regions apart (from about 40 % lost on)."""
    h, w = shape
    c = step // 2
    gh, gw = len(range(c, h, step)), len(range(c, w, step))
    valid = finite.reshape(h, w)
    out = np.full(gh * gw, -1, dtype=np.int64)
    block_r, block_c = np.divmod(np.arange(gh * gw), gw)
    offsets = sorted(((dr, dc) for dr in range(step) for dc in range(step)),
                     key=lambda o: ((o[0] - c) ** 2 + (o[1] - c) ** 2, o))
    missing = np.arange(gh * gw)
    for dr, dc in offsets:  # the centre first, then ever farther pixels, for the blocks still without one
        r, col = block_r[missing] * step + dr, block_c[missing] * step + dc
        ok = (r < h) & (col < w)
        ok[ok] = valid[r[ok], col[ok]]
        out[missing[ok]] = r[ok] * w + col[ok]
        missing = missing[~ok]
        if len(missing) == 0:
            break
    return out.reshape(gh, gw)


def grid_image(points: np.ndarray, finite: np.ndarray, shape: tuple[int, int], step: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """The sub-grid image of ``points`` (H * W, 3): (its (gh, gw, 3) points, NaN for blocks without a
    valid pixel, and their :func:`grid_pixels`)."""
    pixels = grid_pixels(finite, shape, step)
    image = np.full(pixels.shape + (3,), np.nan, dtype=points.dtype)
    image[pixels >= 0] = points[pixels[pixels >= 0]]
    return image, pixels


def check_shape(shape, n: int | None) -> tuple[int, int]:
    """``shape`` as (H, W) ints with H * W == n (any n when None), or ValueError."""
    try:
        h, w = (check_integer('shape', v, 1) for v in shape)
    except (TypeError, ValueError):
        raise ValueError(f'shape must be (H, W), two integers >= 1, got {shape!r}') from None
    if n is not None and h * w != n:
        raise ValueError(f'shape {shape!r} does not match {n} points (H * W must equal the number of rows)')
    return h, w


@dataclass(frozen=True, eq=False)
class SearchGraph:
    """The points a connected-regions search runs on and their neighbourhood graph.

    search_idx: (m,) rows of the cloud searched; step: the image sub-grid step (0: searched as an
    unorganized cloud, also an image too thin for a grid: :func:`grid_step`);
    center: (3,) meters subtracted before the search; neighbours: their graph; nearest: when the
    search is a sample of an unorganized cloud, for each valid row (ascending) the position in
    search_idx of the searched point nearest to it (the point then takes that one's region). It
    depends only on the cloud, ``shape``, ``ransac_points`` and ``grid_points``, not on the tolerance: a sweep builds
    it once (:func:`search_graph`) and passes it to every :func:`detect_planes` call on that cloud.
    viewpoint: (3,) meters, the sensor it was built for.
    """

    n_points: int
    search_idx: np.ndarray
    step: int
    center: np.ndarray
    neighbours: Neighbours
    shape: tuple[int, int] | None
    ransac_points: int | None
    n_valid: int
    nearest: np.ndarray | None = None
    viewpoint: tuple[float, float, float] = (0.0, 0.0, 0.0)
    grid_points: int | None = GRID_POINTS


def search_graph(points: np.ndarray, shape: tuple[int, int] | None = None,
                 ransac_points: int | None = RANSAC_POINTS, rng: np.random.Generator | None = None,
                 viewpoint: Viewpoint = None, grid_points: int | None = GRID_POINTS) -> SearchGraph | None:
    """The :class:`SearchGraph` of ``points`` (N, 3) meters seen from ``viewpoint`` (as in
    :func:`detect_planes`). An image (``shape``) of more than ``grid_points`` valid pixels is searched on a
    regular sub-grid of about that many; an unorganized cloud of more than ``ransac_points`` valid points is
    searched on a random sample drawn from ``rng``; without ``rng`` such a cloud has no fixed graph
    and None is returned."""
    pts = as_points(points)
    _check_search_size('ransac_points', ransac_points)
    _check_search_size('grid_points', grid_points)
    return _search_graph(pts, finite_rows(pts), None if shape is None else check_shape(shape, len(pts)),
                         ransac_points, rng, check_viewpoint(viewpoint), grid_points)


def check_viewpoint(viewpoint: Viewpoint) -> np.ndarray:
    """``viewpoint`` (3,) meters as a float array (None: the origin); ValueError unless 3 finite numbers."""
    why = f'viewpoint must be 3 finite coordinates (x, y, z) in meters, got {viewpoint!r}'
    try:
        view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(why) from None
    if view.shape != (3,) or not np.isfinite(view).all():
        raise ValueError(why)
    return view


def _search_graph(pts: np.ndarray, finite: np.ndarray, shape: tuple[int, int] | None, ransac_points: int | None,
                  rng: np.random.Generator | None, viewpoint: np.ndarray, grid_points: int | None
                  ) -> SearchGraph | None:
    """:func:`search_graph` of checked points ``pts`` with their finite rows ``finite`` (N,)."""
    valid_idx = np.flatnonzero(finite)
    n_valid = len(valid_idx)
    center = np.median(pts[valid_idx[::max(1, n_valid // 1024)]], axis=0) if n_valid else np.zeros(3)
    nearest = None
    step = 0 if shape is None else grid_step(shape, n_valid, grid_points)
    if step:
        grid, pixels = grid_image(pts, finite, shape, step)
        neighbours = grid_neighbours(grid - viewpoint if viewpoint.any() else grid, pixels >= 0)  # sensor ranges
        search_idx = pixels.reshape(-1)[neighbours.pixel]
    else:  # unorganized, or an image too thin for a 2-D grid
        search_idx = valid_idx
        if ransac_points is not None and n_valid > ransac_points:
            if rng is None:
                return None
            search_idx = valid_idx[np.sort(rng.choice(n_valid, int(ransac_points), replace=False))]
        searched = pts[search_idx] - center
        index = None
        if len(search_idx) < n_valid:
            nearest, index = _nearest_searched(searched, pts[valid_idx] - center)
        neighbours = graph_neighbours(searched, viewpoint=viewpoint - center, index=index)
    return SearchGraph(n_points=len(pts), search_idx=search_idx, step=step, center=center, neighbours=neighbours,
                       shape=shape, ransac_points=ransac_points, n_valid=n_valid, nearest=nearest,
                       viewpoint=tuple(viewpoint.tolist()), grid_points=grid_points)


def _nearest_searched(searched: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, VoxelIndex | None]:
    """(n,) the position among ``searched`` (m, 3) of the nearest to each of ``points`` (n, 3), through voxels; and
    the voxel index of ``searched`` (None for far-out coordinates: then by a kd-tree)."""
    index = voxel_index(searched, span=points)
    if index is None:
        return _nearest_searched_tree(searched, points), None
    return index.query(points, 1)[1][:, 0], index


def _nearest_searched_tree(searched: np.ndarray, points: np.ndarray) -> np.ndarray:
    """:func:`_nearest_searched` by scipy's kd-tree (the reference)."""
    return cKDTree(searched).query(points, k=1)[1]


def _detect_regions(pts: np.ndarray, tolerance: Tolerance, max_planes: int, min_inliers: int | float,
                    probability: float, max_iterations: int, rng: np.random.Generator,
                    ransac_points: int | None, shape: tuple[int, int] | None,
                    graph: SearchGraph | None, viewpoint: np.ndarray, grid_points: int | None,
                    allows: Allows = None) -> Segmentation:
    """detect_planes with connected regions (see its docstring)."""
    finite = finite_rows(pts)
    valid_idx = np.flatnonzero(finite)
    n_valid = len(valid_idx)
    min_count = resolve_min_inliers(min_inliers, n_valid)
    if graph is None:
        graph = _search_graph(pts, finite, shape, ransac_points, rng, viewpoint, grid_points)
    elif not isinstance(graph, SearchGraph):
        raise ValueError(f'graph must be a SearchGraph (search_graph) or None, got {type(graph).__name__}')
    elif (graph.n_points, graph.shape, graph.ransac_points, graph.grid_points) != \
            (len(pts), shape, ransac_points, grid_points):
        raise ValueError(f'graph was built for {graph.n_points} points, shape {graph.shape}, ransac_points '
                         f'{graph.ransac_points} and grid_points {graph.grid_points}, not {len(pts)}, {shape}, '
                         f'{ransac_points} and {grid_points}')
    elif graph.viewpoint != tuple(viewpoint.tolist()):
        raise ValueError(f'graph was built for viewpoint {graph.viewpoint}, not {tuple(viewpoint.tolist())}')
    elif graph.n_valid != n_valid or not finite[graph.search_idx].all():
        raise ValueError('graph was built for a cloud with other valid (finite) rows')
    search_idx, step, center, neighbours = graph.search_idx, graph.step, graph.center, graph.neighbours
    search = np.ascontiguousarray((pts[search_idx] - center).T)
    search_min = max(3, int(np.ceil(min_count * len(search_idx) / max(n_valid, 1))))
    search_tolerance = _at(tolerance, search_idx)
    found, reason, region, capped = _sequential(search, search_tolerance, max_planes, search_min, probability,
                                                max_iterations, rng, n_total=n_valid, neighbours=neighbours,
                                                allows=allows)
    labels = np.full(len(pts), -1, dtype=np.int32)
    if not found:
        return Segmentation(labels=labels, planes=(), tolerance=tolerance, n_valid=n_valid, reason=reason)
    # each region's plane refitted on its own points, then the borders settled by nearest plane
    found = _refit(search, region, found, allows)
    region = _compete(search, region, found, search_tolerance, neighbours, viewpoint - center)
    found = _refit(search, region, found, allows)
    searched = len(found)
    region, found = _merge_coplanar(search, region, found, search_tolerance, neighbours, allows)
    if len(found) < searched:
        reason += f'; merged {searched - len(found)} region(s) into a touching region of the same surface'
    residual = None
    if step:
        uncentred = [(normal, offset - float(normal @ center)) for normal, offset in found]
        labels, residual = _spread_grid(pts, finite, shape, step, region, neighbours, uncentred, tolerance)
    elif len(search_idx) == n_valid:
        own = np.where(region >= 0, region, 0)
        normals = np.array([n for n, _ in found])
        offsets = np.array([d for _, d in found])
        near = np.abs(np.einsum('ji,ij->j', normals[own], search) + offsets[own]) <= search_tolerance
        labels[search_idx] = np.where((region >= 0) & near, region, -1)  # within t of the refitted plane
    else:
        labels[valid_idx] = _spread_nearest(pts[valid_idx] - center, graph.nearest, region, found,
                                            _at(tolerance, valid_idx))
    counts = np.bincount(labels[labels >= 0], minlength=len(found))
    small = np.flatnonzero(counts < min_count)
    if len(small):
        keep = np.flatnonzero(counts >= min_count)
        remap = np.full(len(found) + 1, -1, dtype=np.int32)
        remap[keep] = np.arange(len(keep))
        labels = remap[labels]  # -1 indexes the last entry, which is -1
        found = [found[j] for j in keep]
        reason += (f'; dropped {len(small)} region(s) left with fewer than min_inliers={min_count} points '
                   'once every point was labelled')
    rows, bounds = kernels.group_by_label(labels, len(found))
    planes = []
    for j, (normal, offset) in enumerate(found):
        members = rows[bounds[j]:bounds[j + 1]]
        resid = residual[members] if residual is not None else (pts[members] - center) @ normal + offset
        normal, offset = _canonical(normal, offset - float(normal @ center))
        planes.append(Plane(normal=normal, offset=offset, inliers=members,
                            rms=float(np.sqrt(np.mean(resid ** 2))) if len(members) else 0.0))
    return Segmentation(labels=labels, planes=tuple(planes), tolerance=tolerance, n_valid=n_valid, reason=reason,
                        capped=capped)


def _refit(search: np.ndarray, region: np.ndarray, found: list, allows: Allows = None) -> list:
    """Each region's plane fitted to its points (3, m) ``search`` (kept when it has fewer than 3, or when the fit
    leaves the normals ``allows`` takes)."""
    return [_kept_fit(_fit_columns(np.compress(region == j, search, axis=1)), plane, allows)
            if np.count_nonzero(region == j) >= 3 else plane for j, plane in enumerate(found)]


def _kept_fit(fit: tuple[np.ndarray, float], plane: tuple[np.ndarray, float], allows: Allows
              ) -> tuple[np.ndarray, float]:
    """``fit`` when a plane may have its normal, else the ``plane`` it would replace."""
    return fit if _allowed(allows, fit[0]) else plane


#: Two touching regions whose joint plane keeps at least this share of their points within t, with
#: an RMS residual at most MERGE_SPREAD times that of their own planes, are one surface (split by
#: the order of the search or by points whose local normals disagreed; a step or a ledge within t
#: of the joint plane fits it much worse than its own plane).
MERGE_KEEP = 0.95
MERGE_SPREAD = 1.5


def _adjacent(neighbours: Neighbours) -> tuple[np.ndarray, np.ndarray]:
    """(src, dst) point pairs of the searched points that touch: graph edges, or right and down
    neighbours on the sub-grid that may both join a region (no depth jump between them), and the last
    and first pixels of each row when the image wraps around (a 360-degree scan); then the pixels on
    either side of a short run of pixels without a point (Neighbours.bridges)."""
    if neighbours.shape is None:
        return neighbours.edges[:, 0], neighbours.edges[:, 1]
    node = np.where(neighbours.usable, neighbours.node, -1).reshape(neighbours.shape)
    src = [node[:, :-1].ravel(), node[:-1].ravel()] + ([node[:, -1]] if neighbours.wraps else [])
    dst = [node[:, 1:].ravel(), node[1:].ravel()] + ([node[:, 0]] if neighbours.wraps else [])
    if neighbours.bridges is not None and len(neighbours.bridges):
        src.append(node.reshape(-1)[neighbours.bridges[:, 0]])
        dst.append(node.reshape(-1)[neighbours.bridges[:, 1]])
    src, dst = np.concatenate(src), np.concatenate(dst)
    both = (src >= 0) & (dst >= 0)
    return src[both], dst[both]


def _merge_coplanar(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance,
                    neighbours: Neighbours, allows: Allows = None) -> tuple[np.ndarray, list]:
    """Merge touching regions of one surface: a pair of regions joined by a neighbour pair whose
    joint least-squares plane has MERGE_KEEP of their points (3, m) within ``tolerance`` becomes one
    region (the earlier one's number), with that plane. Regions renumbered in order."""
    src, dst = _adjacent(neighbours)
    a, b = region[src], region[dst]
    touch = (a >= 0) & (b >= 0) & (a != b)
    if not touch.any():
        return region, found
    src, dst, a, b = src[touch], dst[touch], a[touch], b[touch]
    k = len(found)
    pairs = np.unique(np.minimum(a, b) * k + np.maximum(a, b))  # each touching pair of regions once, sorted
    root = np.arange(k)
    found = list(found)
    # the points of each region, ascending, kept up to date as regions merge (as are a, b: the regions at src, dst)
    order = np.argsort(region, kind='stable')
    bounds = np.searchsorted(region[order], np.arange(k + 1))
    points_of = [order[bounds[r]:bounds[r + 1]] for r in range(k)]
    for i, j in zip(*np.divmod(pairs, k)):
        i, j = root[i], root[j]
        if i == j:
            continue
        i, j = min(i, j), max(i, j)
        members = np.sort(np.concatenate([points_of[i], points_of[j]]), kind='stable')  # two sorted runs: merged
        cols = search[:, members]
        normal, offset = _fit_columns(cols.copy())
        if not _allowed(allows, normal):
            continue  # their joint plane leaves the orientation constraint
        contact = (a == i) & (b == j) | (a == j) & (b == i)
        if not (neighbours.coherent(normal, src[contact]) & neighbours.coherent(normal, dst[contact])).any():
            continue  # they touch where normals disagree only
        joint = _distances(cols, normal[None, :], np.array([offset]))[0]
        on_i = region[members] == i
        own = np.where(on_i, found[i][0] @ cols + found[i][1], found[j][0] @ cols + found[j][1])
        if np.count_nonzero(joint <= _at(tolerance, members)) >= MERGE_KEEP * cols.shape[1] and \
                np.mean(joint ** 2) <= MERGE_SPREAD ** 2 * np.mean(own ** 2):
            region[points_of[j]] = i
            points_of[i], points_of[j] = members, members[:0]
            a[a == j], b[b == j] = i, i
            root[root == j] = i
            found[i] = (normal, offset)
    keep = np.unique(root)
    if len(keep) == len(found):
        return region, found
    renumber = np.full(len(found) + 1, -1, dtype=np.int64)
    renumber[keep] = np.arange(len(keep))
    return renumber[region], [found[j] for j in keep]


#: Rounds of border settling in _compete: a region can win back this many pixels (or graph hops)
#: of a strip that a plane found before it took.
COMPETE_ROUNDS = 6
#: Border settling compares planes by the distance along each point's viewing ray (a range sensor's
#: noise lies along the ray, so a wall's point near a corner is nearer in meters to the other face,
#: seen at a grazing angle, but not along its ray); a ray farther than this from a plane's normal
#: counts as this far (degrees), so that the planes a ray nearly grazes still compete.
GRAZING_DEG = 75.0


def _compete(search: np.ndarray, region: np.ndarray, found: list, tolerance: Tolerance,
             neighbours: Neighbours, viewpoint: np.ndarray) -> np.ndarray:
    """Settle the borders between regions: each searched point (3, m) takes, of its own region and
    its neighbours' regions (8 image neighbours, or graph neighbours), the one whose plane within
    ``tolerance`` its ray from ``viewpoint`` (3,) meets nearest (see GRAZING_DEG), so a strip that
    an earlier plane took along an edge goes back to the surface it lies on, and unassigned points
    next to a region join it when they fit its plane; repeated COMPETE_ROUNDS times. Only points next
    to another region can change, and after the first round only the neighbours of points that
    changed: only they are looked at."""
    k, m = len(found), search.shape[1]
    normals = np.array([n for n, _ in found])
    dist = np.empty((k + 1, m))
    dist[:k] = _distances(search, normals, np.array([d for _, d in found]))
    dist[k] = np.inf
    dist[dist > tolerance] = np.inf  # only planes within t can be taken
    rays = search - viewpoint[:, None]
    with np.errstate(invalid='ignore', divide='ignore'):  # a point at the viewpoint: NaN, never nearer
        rays /= np.linalg.norm(rays, axis=0)
        dist[:k] /= np.maximum(np.abs(normals @ rays), np.cos(np.radians(GRAZING_DEG)))
    region = np.where(region >= 0, region, k)
    if neighbours.shape is not None:  # a sub-grid: one compiled call (kernels.grid_compete)
        region = kernels.grid_compete(dist, region, neighbours.pixel, neighbours.node, neighbours.shape[1],
                                      _EIGHT, COMPETE_ROUNDS)
        return np.where(region < k, region, -1)
    return _settle(dist, region, neighbours)


def _settle(dist: np.ndarray, region: np.ndarray, neighbours: Neighbours) -> np.ndarray:
    """The rounds of :func:`_compete` in numpy (graph form; on a sub-grid the reference of
    :func:`.kernels.grid_compete`): ``dist`` (k + 1, m), ``region`` (m,) 0..k (k: none)."""
    k, m = dist.shape[0] - 1, dist.shape[1]
    flat = dist.reshape(-1)
    best = flat[region * m + np.arange(m)]  # row k (no region) is inf
    around = _around(neighbours)
    dst, src = around(_bordering(neighbours, region))
    for _ in range(COMPETE_ROUNDS):
        cand = region[src]
        d = flat[cand * m + dst]
        better = d < best[dst]
        if not better.any():
            break
        dst, src, cand, d = dst[better], src[better], cand[better], d[better]
        # per point its nearest offer; equal distances: on a grid the first image direction (the
        # order of _EIGHT, which is ascending src), on a graph a smaller-index neighbour, then the
        # largest one
        ties = (src,) if neighbours.shape is not None else (-src, src > dst)
        order = np.lexsort(ties + (d, dst))
        first = order[np.r_[True, dst[order[1:]] != dst[order[:-1]]]]
        changed = dst[first]
        region[changed], best[changed] = cand[first], d[first]  # the offers above read the old labels
        src, dst = around(changed)  # their neighbours, offered the new labels
    return np.where(region < k, region, -1)


#: The 8 image neighbours (row, column offsets).
_EIGHT = kernels.EIGHT


def _around(neighbours: Neighbours) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """A function of points ``nodes`` (c,) giving every (node, neighbour) pair as two arrays: the 8
    image neighbours on a grid (whatever their depth), graph neighbours otherwise."""
    if neighbours.shape is not None:
        gh, gw = neighbours.shape

        def on_grid(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r, c = np.divmod(neighbours.pixel[nodes], gw)
            r, c = r[:, None] + _EIGHT[:, 0], c[:, None] + _EIGHT[:, 1]
            inside = (r >= 0) & (r < gh) & (c >= 0) & (c < gw)
            near = np.where(inside, neighbours.node[np.where(inside, r * gw + c, 0)], -1)
            ok = near >= 0
            return np.broadcast_to(nodes[:, None], near.shape)[ok], near[ok]
        return on_grid
    indptr, indices = neighbours.adjacency if neighbours.adjacency is not None else \
        (np.zeros(neighbours.n + 1, np.int64), np.empty(0, np.int64))

    def on_graph(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        degree = indptr[nodes + 1] - indptr[nodes]
        start = np.repeat(indptr[nodes] - np.cumsum(degree) + degree, degree)
        return np.repeat(nodes, degree), indices[start + np.arange(len(start))]
    return on_graph


def _bordering(neighbours: Neighbours, region: np.ndarray) -> np.ndarray:
    """The points (ascending) with a neighbour (as in :func:`_around`) in another region than theirs."""
    if neighbours.shape is None:
        src, dst = neighbours.edges.T
        differ = region[src] != region[dst]
        out = np.zeros(neighbours.n, bool)
        out[src[differ]] = out[dst[differ]] = True
        return np.flatnonzero(out)
    gh, gw = neighbours.shape
    image = np.full(gh * gw, -1, dtype=np.int64)  # -1: no point
    image[neighbours.pixel] = region
    pad = np.pad(image.reshape(gh, gw), 1, constant_values=-1)
    centre = pad[1:-1, 1:-1]
    out = np.zeros((gh, gw), bool)
    for dr, dc in _EIGHT:
        other = pad[1 + dr:gh + 1 + dr, 1 + dc:gw + 1 + dc]
        out |= (other != centre) & (other >= 0)
    out &= centre >= 0
    return neighbours.node[np.flatnonzero(out)]


def _spread_grid(pts: np.ndarray, valid: np.ndarray, shape: tuple[int, int], step: int, region: np.ndarray,
                 neighbours: Neighbours, planes: list, tolerance: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Labels (N,) of every pixel of the image ``pts`` (N, 3; ``valid`` (N,): its finite rows) from
    the regions of the searched sub-grid: the region of the nearest sub-grid pixel when the pixel is
    within ``tolerance`` of its plane (``planes`` in the coordinates of ``pts``), else, of the 3 x 3
    sub-grid pixels around it, the region whose plane is nearest within ``tolerance``; -1 otherwise.
    Also the distance (N,) to the chosen plane (inf when none). One compiled pass
    (:func:`.kernels.spread_grid`; :func:`_spread_grid_numpy` is its reference)."""
    sub, near_r, near_c = _sub_regions(shape, step, region, neighbours, len(planes))
    coeffs = np.array([np.append(normal, offset) for normal, offset in planes], dtype=np.float64).reshape(-1, 4)
    tol = kernels.c_array(np.reshape(tolerance, -1), np.float64)  # (1,) or (N,)
    return kernels.spread_grid(kernels.c_array(pts, np.float64), kernels.c_array(valid, bool), sub, near_r, near_c,
                               coeffs, tol, kernels.EIGHT)


def _sub_regions(shape: tuple[int, int], step: int, region: np.ndarray, neighbours: Neighbours, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sub-grid's regions as an image (gh, gw) int64 (k: no region), and the nearest sub-grid row of each
    image row (H,) and column of each image column (W,)."""
    h, w = shape
    gh, gw = neighbours.shape
    sub = np.full(gh * gw, k, dtype=np.int64)
    sub[neighbours.pixel] = np.where(region >= 0, region, k)
    near_r = np.clip(np.round((np.arange(h) - step // 2) / step).astype(np.int64), 0, gh - 1)
    near_c = np.clip(np.round((np.arange(w) - step // 2) / step).astype(np.int64), 0, gw - 1)
    return sub.reshape(gh, gw), near_r, near_c


def _spread_grid_numpy(pts: np.ndarray, valid: np.ndarray, shape: tuple[int, int], step: int, region: np.ndarray,
                       neighbours: Neighbours, planes: list, tolerance: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_spread_grid` in numpy: the reference its kernel is tested against."""
    h, w = shape
    gh, gw = neighbours.shape
    k, n = len(planes), len(pts)
    sub, near_r, near_c = _sub_regions(shape, step, region, neighbours, k)
    dist = np.empty((k + 1, n))  # row k: no region; NaN rows compare False
    np.matmul(np.array([p[0] for p in planes]), pts.T, out=dist[:k])
    dist[:k] += np.array([p[1] for p in planes])[:, None]
    np.abs(dist[:k], out=dist[:k])
    dist[k] = np.inf
    flat = dist.reshape(-1)
    # the nearest sub-grid pixel first, as whole images: most pixels take its region
    lab = sub.take(near_r, axis=0).take(near_c, axis=1).reshape(-1)
    d = flat[lab * n + np.arange(n)]
    take = d <= tolerance
    out = np.where(take, lab, -1).astype(np.int32)
    best = np.where(take, d, np.inf)
    todo = np.flatnonzero(~take & valid)  # valid pixels left
    todo_tolerance = _at(tolerance, todo)
    r, c = np.divmod(todo, w)
    around = np.pad(sub, 1, constant_values=k).reshape(-1)  # off the image: no region
    centre = (near_r[r] + 1) * (gw + 2) + near_c[c] + 1
    for dr, dc in _EIGHT:  # the rest: the eight sub-grid pixels around the nearest one
        lab = around[centre + dr * (gw + 2) + dc]
        d = flat[lab * n + todo]
        better = (d <= todo_tolerance) & (d < best[todo])
        out[todo[better]], best[todo[better]] = lab[better], d[better]
    return out, best


def _spread_nearest(points: np.ndarray, nearest: np.ndarray, region: np.ndarray, found: list,
                    tolerance: Tolerance) -> np.ndarray:
    """Labels of ``points`` (n, 3) from the region of their nearest searched point (``nearest`` (n,):
    its position among the searched points), when within ``tolerance`` of that region's plane; -1 otherwise."""
    lab = region[nearest]
    normals = np.array([n for n, _ in found])
    offsets = np.array([d for _, d in found])
    j = np.where(lab >= 0, lab, 0)
    dist = np.abs(np.einsum('ij,ij->i', points, normals[j]) + offsets[j])
    return np.where((lab >= 0) & (dist <= tolerance), lab, -1).astype(np.int32)
