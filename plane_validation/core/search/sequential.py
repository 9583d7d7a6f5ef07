"""Sequential RANSAC: the best plane, its points taken out, and again, until none is large enough."""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import kernels
from .fit import allows_normal, degeneracy, fit_columns, plane_distances, tolerance_at
from .hypotheses import best_plane
from .neighbours import NORMAL_MIN_COS, Neighbours
from .types import Allows, Tolerance

__all__ = ['sequential_search', 'SET_ASIDE', 'SCATTERED_AGREE', 'SCATTERED_SPREAD']

_ORIGIN = np.zeros(3)

#: With a neighbourhood, when the best remaining plane keeps fewer than min_inliers points as a region but at least
#: that many of the searched points lie within t of it, and their normals scatter (SCATTERED_AGREE), those points are
#: one surface whose noise exceeds what its normals can tell (a far wall of a noisy depth camera). Their largest
#: connected piece, whatever its normals, becomes the plane when it holds min_inliers points; else they are set aside,
#: unassigned, and the search goes on, at most this many times. Stopping there lost the wall and the smaller surfaces it
#: outnumbers (a table top under it): indoor_depth tuning seeds 0-15, auto-tuned 55 -> 63 of 132 planes correct
#: (set aside only: 60); the tuning split 125 -> 130 of 170.
SET_ASIDE = 3
#: ... when fewer than this share of those points have a normal that agrees with the plane (or none): noise scatters
#: the normals. A surface whose normals agree but whose region breaks (a quantized depth camera's walls, cut at each
#: depth step) is not set aside: its pieces came back as slabs (on the tuning scenes, the points of the scattered
#: walls agreed 9-52 %, the quantized walls 55-96 %).
SCATTERED_AGREE = 0.5
#: ... and when those points spread over the band within t of the plane: their RMS distance at least this share of
#: t (noise beyond t fills the band evenly: 0.58 t). The layers of a far wall whose depth comes in steps larger than
#: t lie each exactly on one plane (RMS 0) though their normals scatter: office1.pcd at t = 1 cm gave three planes
#: 7 cm apart; the scattered surfaces of the indoor tuning scenes spread 0.25-0.6 t.
SCATTERED_SPREAD = 0.2


def sequential_search(cols: np.ndarray, tolerance: Tolerance, max_planes: int, min_count: int, probability: float,
                      max_iterations: int, rng: np.random.Generator, n_total: int,
                      neighbours: Neighbours | None = None, allows: Allows = None, start: np.ndarray | None = None,
                      ray: np.ndarray = kernels.NO_RAY) -> tuple[list, str, np.ndarray | None, bool]:
    """Sequential RANSAC on the points ``cols`` (3, n): the planes [(normal, offset)] in
    extraction order, why the search stopped, with ``neighbours`` the region of each point
    (n,) (-1: none), and whether it stopped at ``max_planes`` with ``min_count`` points left. ``start``: the points
    (indices into ``cols``) the search may use, of those ``neighbours`` can search (None: all)."""
    n = cols.shape[1]
    rest = cols
    rest_idx = np.arange(n) if neighbours is None else neighbours.searchable()  # the points that can join a region
    if start is not None:
        rest_idx = np.intersect1d(rest_idx, start)
    if len(rest_idx) < n:
        rest = cols.take(rest_idx, axis=1)
        tolerance = tolerance_at(tolerance, rest_idx)
    region = None if neighbours is None else np.full(n, -1, dtype=np.int64)
    remaining = None if neighbours is None else neighbours.remaining(rest_idx)
    if len(ray) and hasattr(remaining, 'ray'):  # the sub-grid's kernels measure the tolerance along the rays
        remaining = dataclasses.replace(remaining, ray=ray)
    rest_normals = None if neighbours is None or neighbours.normals is None else \
        kernels.columns_at(kernels.c_array(neighbours.normals, np.float64), kernels.c_array(rest_idx, np.int64),
                           _ORIGIN)  # (3, r), kept in step with rest
    found: list[tuple[np.ndarray, float]] = []
    reason = f'reached max_planes={max_planes}'
    set_aside = 0
    while len(found) < max_planes:
        why = degeneracy(rest)
        if why is not None:
            reason = why if rest.shape[1] < n or n_total < 3 else f'no plane: {why}'
            break
        sampler = None if neighbours is None else neighbours.sampler(rest_idx)
        best = best_plane(rest, tolerance, probability, max_iterations, rng, remaining, rest_normals, sampler,
                          allows)
        if best is None:
            reason = 'every sampled triple was degenerate (nearly collinear or duplicate points)' if allows is None \
                else 'no sampled plane satisfied the orientation constraint (or every triple was degenerate)'
            break
        normal, offset, inliers, taken = best
        count = int(np.count_nonzero(inliers))
        left, kept = ~taken, count >= min_count
        if not kept:
            scattered = None if rest_normals is None or set_aside >= SET_ASIDE else \
                _scattered(rest, rest_normals, normal, offset, tolerance, min_count)
            if scattered is None:
                reason = f'best remaining plane has {count} < min_inliers={min_count} points' + \
                    ('' if n == n_total else f' (in a sample of {n} of {n_total} points)')
                break
            left &= ~scattered
            joined = _joined(neighbours, rest_idx, scattered, min_count)
            fit = None if joined is None else fit_columns(np.compress(joined, rest, axis=1))
            if fit is not None and allows_normal(allows, fit[0]):
                (normal, offset), inliers, kept = fit, joined, True
            else:
                set_aside += 1  # unassigned
        if region is not None:
            if kept:
                region[rest_idx[inliers]] = len(found)
            rest_idx = rest_idx[left]
            remaining = remaining.without(left)
        if kept:
            found.append((normal, offset))
        rest = np.compress(left, rest, axis=1)
        if rest_normals is not None:
            rest_normals = np.compress(left, rest_normals, axis=1)
        tolerance = tolerance_at(tolerance, left)
    if set_aside:
        reason += f'; set aside {set_aside} surface(s) whose points within t hold no region of min_inliers'
    return found, reason, region, len(found) == max_planes > 0 and rest.shape[1] >= min_count


def _scattered(rest: np.ndarray, rest_normals: np.ndarray, normal: np.ndarray, offset: float, tolerance: Tolerance,
               min_count: int) -> np.ndarray | None:
    """(r,) bool: the points ``rest`` (3, r) within ``tolerance`` of the plane (``normal`` (3,), ``offset`` m) when
    they are a scattered surface (at least ``min_count`` of them, fewer than SCATTERED_AGREE with a normal
    (``rest_normals`` (3, r), NaN: none) that agrees, spread over SCATTERED_SPREAD of the band); else None."""
    dist = plane_distances(rest, normal[None, :], np.array([offset]))[0]
    near = dist <= tolerance
    if np.count_nonzero(near) < min_count:
        return None
    agree = ~(np.abs(normal @ rest_normals[:, near]) < NORMAL_MIN_COS)  # NaN (unknown) agrees, as in coherence
    if not float(np.mean(agree)) < SCATTERED_AGREE:
        return None
    spread = np.sqrt(np.mean(dist[near] ** 2))
    return near if spread >= SCATTERED_SPREAD * float(np.median(tolerance_at(tolerance, near))) else None


def _joined(neighbours: Neighbours, rest_idx: np.ndarray, scattered: np.ndarray, min_count: int) -> np.ndarray | None:
    """(r,) bool: the largest connected piece of the ``scattered`` points (r,) of the searched points ``rest_idx`` (r,),
    normals aside, when it holds ``min_count`` points or more; else None."""
    mask = np.zeros(neighbours.n, bool)
    mask[rest_idx[scattered]] = True
    piece = neighbours.largest(mask)[rest_idx]
    return piece if np.count_nonzero(piece) >= min_count else None
