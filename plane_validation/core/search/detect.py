"""Sequential RANSAC plane detection (Lipnickas et al. 2014, section 3): :func:`detect_planes`, the entry that
checks its arguments and runs the infinite-plane or the connected-regions search."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..interrupts import keeps_interrupts
from ..noise import NOISE_REFERENCE, ray_band, tolerance_scale
from ..orientation import Orientation
from ..params import GRID_POINTS, MAX_ITERATIONS, MAX_PLANES, MIN_INLIERS, PROBABILITY, RANSAC_POINTS
from .checks import (
    as_points,
    check_flag,
    check_integer,
    check_magnitude,
    check_number,
    check_search_size,
    check_shape,
    check_viewpoint,
    finite_extent,
    generator,
)
from .connected import detect_regions
from .graph import SearchGraph
from .infinite import detect_infinite
from .types import Plane, Segmentation, Viewpoint

__all__ = ['detect_planes']


@keeps_interrupts
def detect_planes(points: np.ndarray, tolerance: float, *, max_planes: int = MAX_PLANES,
                  min_inliers: int | float = MIN_INLIERS, probability: float = PROBABILITY,
                  max_iterations: int = MAX_ITERATIONS, seed: int | np.random.Generator | None = None,
                  ransac_points: int | None = RANSAC_POINTS, shape: tuple[int, int] | None = None,
                  connectivity: bool = True, graph: SearchGraph | None = None, noise_model: str = 'constant',
                  noise_reference: float = NOISE_REFERENCE, viewpoint: Viewpoint = None,
                  grid_points: int | None = GRID_POINTS, orientation: Orientation | None = None,
                  extent: tuple[np.ndarray, float] | None = None) -> Segmentation:
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
        t * max(1, (r / noise_reference)^2) of a plane (:mod:`.noise`), measured along its viewing ray in the
        connected-regions search (times max(|n . u|, RAY_FLOOR): :func:`.noise.ray_band`).
    viewpoint: (3,) meters, where the sensor is in the cloud's frame (default the origin, as a driver
        publishes a scan): ranges for the noise model, the rays along which the neighbourhood
        graph of an unorganized cloud tells a spinning lidar's rings (:func:`.regions.graph_neighbours`), and
        those that tell whether coplanar regions apart are one surface hidden between them (:mod:`.occluded`).
    orientation: an :class:`.orientation.Orientation` (from :func:`.orientation.orientation`): only planes whose
        normal satisfies it are searched for, refitted and merged (None: any plane).
    extent: (finite rows (N,) bool, the largest |coordinate| not NaN, inf counting; NaN when none) of ``points``
        when the caller's own pass over them already found them (:func:`.kernels.read_rows` of a frame): what
        :func:`.checks.finite_extent` would find, which then does not read the points again. None: found here.

    Without connectivity, each plane found is then refitted by least squares on the searched points
    nearest to it (within ``tolerance``), and every valid point is labelled with the nearest plane
    within ``tolerance`` (ties to the earlier plane, -1 when none): a point within ``t`` of two planes
    along a shared edge goes to the nearer, not to the first found. With connectivity, each region is
    refitted on its own points, border points go to the nearest plane of the regions they touch,
    touching regions of one surface are merged (and coplanar regions apart where the sensor sees nothing
    through their plane between them and something hides it or it is out of view), a region holding the two sides
    of a shallow ridge is split at it, or the faces of a shallow hip roof into them (:mod:`.tents`), while there are
    fewer than ``max_planes`` (:mod:`.folds`), nearly parallel regions that cut across such a roof in slabs are
    replaced by its faces (:func:`.folds.split_terraces`), the points along a shallow fold between two regions go to
    the face on their side of it, and every valid point
    takes the region of the searched point nearest to it (organized: of the sub-grid pixels around it) when it
    lies within ``tolerance`` of that region's plane, else -1. Either way a plane left with fewer than
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
    check_search_size('ransac_points', ransac_points)
    check_search_size('grid_points', grid_points)
    if shape is not None:
        shape = check_shape(shape, len(pts))
    finite, largest = finite_extent(pts) if extent is None else _given_extent(extent, len(pts))
    check_magnitude(pts, largest)
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
        seg = detect_regions(pts, finite, point_tolerance, max_planes, min_inliers, probability, int(max_iterations),
                             rng, ransac_points, shape, graph, view, grid_points, allows, ray_band(view, noise_model))
    else:
        seg = detect_infinite(pts, point_tolerance, max_planes, min_inliers, probability, int(max_iterations), rng,
                              ransac_points, allows)
    return _facing_away(dataclasses.replace(seg, tolerance=tolerance, **model), view)


def _given_extent(extent: tuple[np.ndarray, float], n: int) -> tuple[np.ndarray, float]:
    """``extent`` as detect_planes takes it, checked against ``n`` rows."""
    finite, largest = extent
    if not isinstance(finite, np.ndarray) or finite.dtype != np.bool_ or finite.shape != (n,):
        raise ValueError(f'extent: its finite rows must be a ({n},) bool array, got '
                         f'{getattr(finite, "dtype", type(finite).__name__)} {getattr(finite, "shape", "")}')
    return finite, float(largest)


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
