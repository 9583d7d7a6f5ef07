"""Plane geometry for display and input reduction: outlines (centroid, in-plane frame, convex-hull
polygon of each plane), plane colours, the voxel grid and a lidar scan's ring image.

Pure numpy/scipy (no ROS import); the node's markers and poses are built from these.
"""
from __future__ import annotations

import colorsys
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError, _qhull

from . import kernels
from .ransac import Segmentation

__all__ = ['PlaneOutline', 'plane_basis', 'plane_bases', 'hull_vertices', 'plane_outlines', 'outline_directions',
           'outlines_from', 'plane_rows', 'hull_polygon', 'plane_colors', 'id_colors', 'UNASSIGNED_RGB',
           'voxel_downsample', 'ring_image', 'beam_numbers', 'outside_polygon_numpy']

#: Largest point set whose hull is computed exactly (see hull_polygon).
HULL_POINTS = 2048
#: scipy's Qhull wrapper behind ConvexHull (None when it lacks the calls :func:`hull_vertices` makes).
_QHULL = getattr(_qhull, '_Qhull', None)
if not all(hasattr(_QHULL, name) for name in ('triangulate', 'get_extremes_2d', 'close')):
    _QHULL = None
#: Unit directions whose extreme points always take part in the hull.
_DIRECTIONS = np.array([[np.cos(a), np.sin(a)] for a in np.arange(8) * np.pi / 4])
#: Above this many points a hull is taken of those outside the polygon of their extreme points along _DIRECTIONS
#: only: a point inside it is no corner, and Qhull's time grows with the points it is given (0.38 ms for 2,056 points
#: a plane's outline passes it, 0.1 ms for a handful). The same corners, in the same order.
HULL_FILTER = 64
#: ... a point counts as inside when it lies this share of the points' extent within each of the polygon's sides: the
#: rounding of the test leaves every point near a side to Qhull.
_INSIDE_MARGIN = 1e-9


@dataclass(frozen=True, eq=False)
class PlaneOutline:
    """centroid: (3,) mean of the plane's points, meters; rotation: (3, 3) columns x, y in the
    plane and z = normal; corners: (h, 3) convex-hull polygon of the points projected into the
    plane, counter-clockwise about the normal; extent: largest in-plane side of their bounding
    box, meters."""

    centroid: np.ndarray
    rotation: np.ndarray
    corners: np.ndarray
    extent: float


def plane_basis(normal: np.ndarray) -> np.ndarray:
    """(3, 3) rotation whose columns are x, y in the plane and z = ``normal`` (unit (3,))."""
    helper = np.array([1.0, 0, 0]) if abs(normal[0]) < 0.9 else np.array([0, 1.0, 0])
    u = _cross(normal, helper)
    u /= np.linalg.norm(u)
    return np.column_stack([u, _cross(normal, u), normal])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The cross product of two (3,) vectors with np.cross's products and differences (the same values), without its
    per-call cost (tens of microseconds)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def hull_polygon(local: np.ndarray, max_points: int = HULL_POINTS) -> np.ndarray:
    """Indices of the convex hull of 2-D points ``local`` (2, m), counter-clockwise; the two
    extremes along the longer side when the points are collinear, all of them when fewer than 3.

    Above ``max_points`` points the hull is that of the extreme points in 8 directions plus a
    fixed pseudo-random sample of ``max_points``: for display it is indistinguishable from the
    exact hull (it lies inside it and touches it at the 8 extremes), at a fraction of the cost.
    """
    m = local.shape[1]
    if m <= max_points:
        return _hull(local)
    candidates = _hull_candidates(np.argmax(_DIRECTIONS @ local, axis=1), m, max_points)
    return candidates[_hull(local[:, candidates])]


def _hull_candidates(extremes: np.ndarray, m: int, max_points: int) -> np.ndarray:
    """The points of m that :func:`hull_polygon` takes the hull of: the ``extremes`` (8,) and its fixed sample."""
    return np.concatenate([extremes, kernels.seeded_draws(m, max_points)])  # Qhull merges repeats


def _hull(local: np.ndarray) -> np.ndarray:
    """The exact :func:`hull_polygon` of ``local`` (2, m); above HULL_FILTER points Qhull is given only those that may
    be corners (:func:`_outer`), and the whole set where that fails."""
    if local.shape[1] < 3:
        return np.arange(local.shape[1])
    if local.shape[1] > HULL_FILTER:
        outer = _outer(local)
        if len(outer) < local.shape[1]:
            try:
                return outer[hull_vertices(local[:, outer].T)]
            except (QhullError, ValueError):
                pass  # the whole set decides, as without the filter
    try:
        return hull_vertices(local.T)
    except (QhullError, ValueError):  # collinear: the two ends along the longer side
        axis = int(np.argmax(np.ptp(local, axis=1)))
        return np.array([int(np.argmin(local[axis])), int(np.argmax(local[axis]))])


def _outer(local: np.ndarray) -> np.ndarray:
    """The points of ``local`` (2, m) (ascending) not inside the polygon of their extreme points along _DIRECTIONS
    (counter-clockwise, some of them repeated) by _INSIDE_MARGIN (:func:`.kernels.outside_polygon`). Such a point lies
    inside the hull, so that the hull of the others has the same corners."""
    return kernels.outside_polygon(kernels.c_array(local, np.float64), _DIRECTIONS, _INSIDE_MARGIN)


def outside_polygon_numpy(local: np.ndarray, directions: np.ndarray, margin: float) -> np.ndarray:
    """:func:`.kernels.outside_polygon` in numpy: its reference."""
    values = directions[:, 0, None] * local[0] + directions[:, 1, None] * local[1]  # (d, m), the kernel's sums
    corners = local[:, np.argmax(values, axis=1)]  # (2, d)
    side = np.roll(corners, -1, axis=1) - corners
    limit = margin * np.maximum(np.abs(side[0]), np.abs(side[1])) * float(np.abs(local).max())
    cross = side[0][:, None] * (local[1] - corners[1][:, None]) - side[1][:, None] * (local[0] - corners[0][:, None])
    no_side = (side[0] == 0) & (side[1] == 0)
    inside = ((cross > limit[:, None]) | no_side[:, None]).all(axis=0)
    return np.flatnonzero(~inside)


def hull_vertices(points: np.ndarray) -> np.ndarray:
    """``ConvexHull(points).vertices`` of 2-D ``points`` (m, 2), counter-clockwise, and its errors: the same Qhull run
    and walk around the hull through scipy's wrapper, without the simplices, neighbours, equations, area and
    perimeter ConvexHull also computes (about 40 % of its time on a plane's 2,056 candidates); ConvexHull itself
    when the wrapper lacks what ConvexHull calls."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if _QHULL is None:
        return ConvexHull(pts).vertices
    qhull = _QHULL(b'i', pts, b'', required_options=b'Qt')  # as ConvexHull runs it for 2-D points
    try:
        qhull.triangulate()
        return qhull.get_extremes_2d()
    finally:
        qhull.close()


def plane_outlines(points: np.ndarray, labels: np.ndarray, seg: Segmentation) -> tuple[PlaneOutline, ...]:
    """Outline of each plane of ``seg`` from its points: ``points`` (n, 3) meters with plane
    ``labels`` (n,). A plane without points gets its foot point from the origin as centroid
    and no corners. One compiled pass over the points gives each plane's centroid and its extreme
    points in 8 in-plane directions (:func:`.kernels.centroids_and_extremes`)."""
    pts = kernels.c_array(points, np.float64)
    rows, bounds = kernels.group_by_label(kernels.c_array(labels, np.int32), seg.n_planes)
    rotations = plane_bases(seg)
    centroids, extremes = kernels.centroids_and_extremes(pts, rows, bounds, outline_directions(rotations))
    members = [rows[bounds[k]:bounds[k + 1]] for k in range(seg.n_planes)]
    return outlines_from(pts, members, centroids, extremes, seg, rotations)


def plane_rows(labels: np.ndarray, seg: Segmentation) -> list[np.ndarray]:
    """The rows labelled with each plane of ``seg`` in ``labels`` (n,), ascending: the planes' inliers when
    ``labels`` are the segmentation's own (its contract), else grouped from ``labels`` in one pass."""
    if labels is seg.labels:
        return [plane.inliers for plane in seg.planes]
    rows, bounds = kernels.group_by_label(kernels.c_array(labels, np.int32), seg.n_planes)
    return [rows[bounds[k]:bounds[k + 1]] for k in range(seg.n_planes)]


def plane_bases(seg: Segmentation) -> list[np.ndarray]:
    """:func:`plane_basis` of each plane of ``seg``: (3, 3) each."""
    return [plane_basis(plane.normal) for plane in seg.planes]


def outline_directions(rotations: list[np.ndarray]) -> np.ndarray:
    """(k, 8, 3): the 8 in-plane directions (meters along them are what the outlines compare) of each of the
    planes whose bases are ``rotations`` (:func:`plane_bases`)."""
    return np.array([_DIRECTIONS @ rotation[:, :2].T for rotation in rotations]).reshape(-1, 8, 3)


def outlines_from(points: np.ndarray, members: list[np.ndarray], centroids: np.ndarray, extremes: np.ndarray,
                  seg: Segmentation, rotations: list[np.ndarray]) -> tuple[PlaneOutline, ...]:
    """The :func:`plane_outlines` of the planes of ``seg`` from what a pass over their points gave: ``members``
    (the rows of ``points`` (N, 3) of each plane, ascending), ``centroids`` (k, 3) and the positions among its
    members of each plane's extreme points along :func:`outline_directions` (k, 8)."""
    out = []
    for k, plane in enumerate(seg.planes):
        rotation, rows = rotations[k], members[k]
        axes = rotation[:, :2]  # (3, 2): in-plane x, y
        if len(rows) == 0:
            out.append(PlaneOutline(-plane.offset * plane.normal, rotation, np.empty((0, 3)), 1.0))
            continue
        centroid = centroids[k]
        if len(rows) > HULL_POINTS:  # in-plane coordinates of the hull's candidates only
            rows = rows[_hull_candidates(extremes[k], len(rows), HULL_POINTS)]
        local = axes.T @ (np.take(points, rows, axis=0) - centroid).T  # (2, c)
        polygon = local[:, _hull(local)]
        extent = float(np.ptp(polygon, axis=1).max())
        out.append(PlaneOutline(centroid, rotation, centroid + (axes @ polygon).T, extent))
    return tuple(out)


def _plane_outlines_numpy(points: np.ndarray, labels: np.ndarray, seg: Segmentation) -> tuple[PlaneOutline, ...]:
    """:func:`plane_outlines` in numpy, one pass per plane: the reference its kernel is tested against."""
    cols = np.ascontiguousarray(np.asarray(points, dtype=np.float64).T)
    out = []
    for k, plane in enumerate(seg.planes):
        members = np.compress(labels == k, cols, axis=1)  # (3, m)
        rotation = plane_basis(plane.normal)
        axes = rotation[:, :2]
        if members.shape[1] == 0:
            out.append(PlaneOutline(-plane.offset * plane.normal, rotation, np.empty((0, 3)), 1.0))
            continue
        centroid = members.mean(axis=1)
        if members.shape[1] > HULL_POINTS:
            extremes = np.argmax((_DIRECTIONS @ axes.T) @ members, axis=1)
            members = members[:, _hull_candidates(extremes, members.shape[1], HULL_POINTS)]
        local = axes.T @ (members - centroid[:, None])
        polygon = local[:, _hull(local)]
        extent = float(np.ptp(polygon, axis=1).max())
        out.append(PlaneOutline(centroid, rotation, centroid + (axes @ polygon).T, extent))
    return tuple(out)


#: Grey for unassigned points.
UNASSIGNED_RGB = (128, 128, 128)


def plane_colors(count: int) -> np.ndarray:
    """(count, 3) uint8 distinct colours: golden-ratio steps around the hue circle."""
    return id_colors(np.arange(count))


def id_colors(ids: np.ndarray) -> np.ndarray:
    """(m, 3) uint8 the colours of ``ids`` (m,) (integers from 0), ``plane_colors(max(ids) + 1)[ids]`` without the
    colours of the ids between (a long-lived tracker's ids grow)."""
    hues = (np.asarray(ids, np.int64) * 0.618033988749895) % 1.0
    rgb = np.array([colorsys.hsv_to_rgb(h, 0.85, 1.0) for h in hues], dtype=float).reshape(-1, 3)
    return np.round(255 * rgb).astype(np.uint8)


def voxel_downsample(points: np.ndarray, voxel_size: float) -> tuple[np.ndarray, np.ndarray]:
    """Centroid of the points in each voxel of ``voxel_size`` meters.

    Returns (centroids (m, 3), inverse (n,)) with ``inverse[i]`` the voxel of point i.
    """
    cells = np.floor(points / voxel_size)
    low = cells.min(axis=0)
    dims = cells.max(axis=0) - low + 1
    if np.prod(dims) < 2**62:  # one integer key per voxel: a 1-D unique is much faster
        _, inverse = np.unique(np.ravel_multi_index((cells - low).T.astype(np.int64), dims.astype(np.int64)),
                               return_inverse=True)
    else:  # more voxels than an integer holds (a far outlier): rows of voxel numbers, as they are
        _, inverse = np.unique(cells, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    counts = np.bincount(inverse)
    sums = np.column_stack([np.bincount(inverse, weights=points[:, i], minlength=len(counts)) for i in range(3)])
    return sums / counts[:, None], inverse


#: A ring image is at most this many columns wide (a scan whose azimuth step comes out finer is no
#: spinning lidar's: 0.1 degrees is the finest in use, 3600 columns) ...
MAX_RING_COLUMNS = 8192
#: ... and has at most this many rings (128 beams is the most in use) ...
MAX_RINGS = 256
#: ... its rings are rings: the median of their elevations' median absolute deviations is at most this
#: share of the median step between rings (a 'ring' field that numbers something else is not used; an
#: HDL-64's beams, whose origins lie 14-20 cm above the frame's, spread 0.5-1 step seen from it near walls) ...
RING_SPREAD = 1.0
#: ... at least this share of the steps between a ring's neighbouring returns is one azimuth step (a scan
#: thinned at random or by a voxel grid keeping the ring field is no image: its pixels would be mostly holes) ...
RING_REGULAR = 0.5
#: ... and at most this share of the points falls on a pixel another point took (dual returns, two scans merged:
#: only one point per pixel is searched).
RING_COLLISIONS = 0.02
#: A full turn (radians).
TURN = 2 * np.pi


def beam_numbers(ring: np.ndarray) -> np.ndarray:
    """A ``ring`` field's values (n,) as int64 when they are whole numbers (an integer field, or a float one
    holding whole numbers only, as some drivers write it); other values unchanged, for :func:`ring_image` to
    refuse with its reason."""
    ring = np.asarray(ring)
    if np.issubdtype(ring.dtype, np.integer):
        return ring.astype(np.int64)
    if ring.dtype.kind != 'f':
        return ring
    with np.errstate(invalid='ignore'):
        whole = bool(np.all(np.abs(ring) < 2.0 ** 63) and np.array_equal(ring, np.round(ring)))  # NaN: not whole
    return ring.astype(np.int64) if whole else ring


def ring_image(points: np.ndarray, ring: np.ndarray, viewpoint=(0.0, 0.0, 0.0)
               ) -> tuple[np.ndarray, tuple[int, int], np.ndarray]:
    """A spinning lidar's unorganized scan laid out as its range image, as drivers that keep it
    organized publish it: rows the rings (``ring`` (n,) integers, each point's beam, as the ``ring``
    field of velodyne_pointcloud and its kind), top down by their median elevation seen from
    ``viewpoint`` (3,) meters; columns the azimuth about z in steps of the scan's own (the median step
    between a ring's neighbouring returns), each ring's returns on the nearest column from their own
    phase. ``points`` (n, 3) meters, finite. Returns (image (H * W, 3), NaN where no return, (H, W),
    inverse (n,) the pixel of each point); of points on one pixel the first stands for it.
    ValueError saying why when the scan forms no such image (MAX_RINGS, MAX_RING_COLUMNS, RING_SPREAD,
    RING_REGULAR, RING_COLLISIONS)."""
    ring = beam_numbers(ring)
    if ring.shape != (len(points),):
        raise ValueError(f'the ring numbers are not one integer per point (shape {ring.shape}, '
                         f'{len(points)} points)')
    if not np.issubdtype(ring.dtype, np.integer):
        kind = 'values that are not whole numbers' if ring.dtype.kind == 'f' else 'not numbers'
        raise ValueError(f'the ring numbers are not one integer per point ({ring.dtype}: {kind})')
    ids, row = np.unique(ring, return_inverse=True)
    row = row.reshape(-1)
    if not 3 <= len(ids) <= MAX_RINGS:
        raise ValueError(f'{len(ids)} rings (need 3 to {MAX_RINGS})')
    rays = points - np.asarray(viewpoint, dtype=float)
    azimuth = np.arctan2(rays[:, 1], rays[:, 0]) % TURN
    elevation = np.arctan2(rays[:, 2], np.hypot(rays[:, 0], rays[:, 1]))
    gaps, median_elevation, spread = kernels.ring_steps(row, azimuth, elevation, len(ids))
    width = int(round(TURN / float(np.median(gaps)))) if len(gaps) else 0
    if not 3 <= width <= MAX_RING_COLUMNS:
        raise ValueError(f'an azimuth step of {TURN / max(width, 1):.3g} rad ({width} columns, need 3 to '
                         f'{MAX_RING_COLUMNS})')
    step = TURN / width
    regular = float(np.mean(np.abs(gaps / step - 1.0) < 0.5))
    if regular < RING_REGULAR:
        raise ValueError(f'only {regular:.0%} of the steps along the rings are one azimuth step (need '
                         f'{RING_REGULAR:.0%}): thinned or filtered')
    if np.median(spread) > RING_SPREAD * np.median(np.diff(np.sort(median_elevation))):
        raise ValueError('the rings\' elevations overlap: the field does not number beams')
    rank = np.empty(len(ids), np.int64)
    rank[np.argsort(-median_elevation, kind='stable')] = np.arange(len(ids))  # the top ring first
    # a ring's azimuths sit at phase + k * step (its own phase: beams may fire at other azimuths)
    cos_sum, sin_sum = kernels.ring_turns(azimuth, row, len(ids), TURN, 1.0 / step)
    phase = np.arctan2(sin_sum, cos_sum) * step / TURN
    column = np.round((azimuth - phase[row]) / step).astype(np.int64) % width
    pixel = rank[row] * width + column
    image, taken = kernels.ring_scatter(kernels.c_array(points, np.float64), pixel, len(ids) * width)
    shared = 1.0 - taken / len(pixel)
    if shared > RING_COLLISIONS:
        raise ValueError(f'{shared:.1%} of the points share a pixel (dual returns, or scans merged; at most '
                         f'{RING_COLLISIONS:.0%})')
    return image, (len(ids), width), pixel


def ring_steps_numpy(row: np.ndarray, azimuth: np.ndarray, elevation: np.ndarray, rings: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`.kernels.ring_steps` in numpy."""
    order = np.lexsort((azimuth, row))
    same_ring = np.diff(row[order]) == 0
    gaps = np.diff(azimuth[order])[same_ring]
    bounds = np.searchsorted(row[order], np.arange(rings + 1))
    parts = [elevation[order[a:b]] for a, b in zip(bounds[:-1], bounds[1:])]
    middle = np.array([np.median(part) for part in parts])
    spread = np.array([np.median(np.abs(part - m)) for part, m in zip(parts, middle)])
    return gaps[gaps > 0], middle, spread


def ring_turns_numpy(azimuth: np.ndarray, row: np.ndarray, rings: int, turn: float, per_step: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`.kernels.ring_turns` in numpy."""
    turns = np.exp(1j * turn * azimuth * per_step)
    return (np.bincount(row, weights=turns.real, minlength=rings),
            np.bincount(row, weights=turns.imag, minlength=rings))


def ring_scatter_numpy(points: np.ndarray, pixel: np.ndarray, size: int) -> tuple[np.ndarray, int]:
    """:func:`.kernels.ring_scatter` in numpy."""
    first = np.unique(pixel, return_index=True)[1]
    image = np.full((size, 3), np.nan)
    image[pixel[first]] = points[first]
    return image, len(first)
