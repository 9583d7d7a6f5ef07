"""One RANSAC run: plane hypotheses from random triples, scored in batches on a subset, the best few confirmed
on every point (by their largest connected region, when the search has a neighbourhood) and refined by least
squares."""
from __future__ import annotations

import functools

import numpy as np

from .. import kernels
from .fit import MIN_SINE, allows_normal, fit_columns, plane_distances, tolerance_at, within_plane
from .neighbours import NORMAL_MIN_COS, Remaining
from .neighbours_graph import GraphSampler
from .neighbours_grid import GridSampler
from .types import Allows, Sampler, Tolerance

__all__ = ['best_plane', 'best_region', 'BATCH', 'SUBSET', 'CONFIRM', 'PRESCORE', 'LOCAL_SHARE', 'SUPPORT']


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


#: Least-squares refits of a region's plane on its region (each kept while the region does not shrink).
REFITS = 3


#: A little below NORMAL_MIN_COS: best_region's count of the inliers whose normal agrees is at
#: least what a region may keep (neighbours.Neighbours.coherent), whatever the rounding of the dot products.
_COHERENT_BOUND = NORMAL_MIN_COS - 1e-9


#: Share of the hypotheses drawn from nearby points (after Schnabel et al. 2007: a small plane is
#: hit far more often by a triple of neighbours than by three points drawn from the whole cloud).
LOCAL_SHARE = 0.5


#: Assumed chance that both nearby points of a local triple lie on the plane of its first point
#: (for the RANSAC stopping rule; below the 0.58-0.87 measured on the quality benchmark's scenes,
#: as planes of under 1 % of the points get 0.14-0.53).
LOCAL_HIT = 0.25


#: Where the noise exceeds t, a surface's points within t are too sparse to hold together (on an image
#: grid, below about 60 % of its pixels): the suite's synthetic room at t = 1 cm fell apart into pieces below
#: min_inliers (F1 0.04; Open3D 0.71). A region whose inliers fall apart (neighbours.fragmented) is connected
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
    them from ``sampler`` when given; degenerate triples dropped. Returns (normals (h, 3), offsets (h,)). The planes
    come from one compiled pass (:func:`.kernels.triple_planes`; :func:`_triple_planes_numpy` is its reference)."""
    return kernels.triple_planes(kernels.c_array(cols, np.float64), _triples(cols, rng, count, sampler), MIN_SINE)


def _triples(cols: np.ndarray, rng: np.random.Generator, count: int, sampler: Sampler | None) -> np.ndarray:
    """(h, 3) int64 column indices of ``count`` random triples of ``cols`` (3, n), LOCAL_SHARE of them from
    ``sampler`` (those with a point it did not find, -1, dropped)."""
    if sampler is None:
        return rng.integers(0, cols.shape[1], size=(count, 3))
    spread, local = _spread(cols, rng, count)
    idx = np.concatenate([spread, sampler(rng, local)])
    return idx[(idx >= 0).all(axis=1)]


def _spread(cols: np.ndarray, rng: np.random.Generator, count: int) -> tuple[np.ndarray, int]:
    """Of ``count`` triples of ``cols`` (3, n), those drawn from all of them ((count - local, 3) int64, drawn first)
    and how many (local, LOCAL_SHARE of them) are left to draw near each other."""
    local = int(round(LOCAL_SHARE * count))
    return rng.integers(0, cols.shape[1], size=(count - local, 3)), local


def _triple_planes_numpy(cols: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`.kernels.triple_planes` in numpy: the planes through the triples ``idx`` (h, 3) of ``cols`` (3, n)."""
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


class _NumpyScores:
    """The CONFIRM best hypotheses of a RANSAC run, scored on the ``pick`` subset of the points ``cols`` (3, m) with
    BLAS products in ``dtype``: float32 in the infinite-plane search (the paper's figures come from it), float64 as
    the reference of :class:`_CompiledScores`."""

    def __init__(self, cols: np.ndarray, tolerance: Tolerance, point_normals: np.ndarray | None, pick: np.ndarray,
                 head: int, dtype: type = np.float32):
        # Scoring only ranks hypotheses: float32 halves its memory traffic, and the rounding (~1e-7 of
        # the centred coordinates) only matters for points within a hair of t. A row beyond float32's
        # range becomes inf (its distances inf or NaN): never an inlier, as in float64.
        self.dtype = dtype
        with np.errstate(over='ignore'):
            self.subset = cols[:, pick].astype(dtype)
        self.tolerance = tolerance_at(tolerance, pick)
        self.normals = self.unknown = None
        if point_normals is not None:
            sub_normals = point_normals[:, pick]
            self.unknown = np.isnan(sub_normals[0])
            self.normals = np.nan_to_num(sub_normals).astype(dtype)
        self.head, self.scored = head, len(pick)
        self.best_normals, self.best_offsets = np.empty((0, 3)), np.empty(0)
        self.best_counts = np.empty(0, dtype=np.int64)

    def _score(self, typed_normals: np.ndarray, typed_offsets: np.ndarray, part: slice) -> np.ndarray:
        """(h,) inliers of the hypotheses among the subset's points ``part`` (whose normal agrees)."""
        with np.errstate(over='ignore', invalid='ignore'):  # far-out rows: inf or NaN, never inliers
            near = plane_distances(self.subset[:, part], typed_normals, typed_offsets)
            near = near <= tolerance_at(self.tolerance, part)
        if self.normals is not None:
            coherent = np.abs(typed_normals @ self.normals[:, part]) >= self.dtype(NORMAL_MIN_COS)
            coherent |= self.unknown[part]
            near &= coherent
        # a uint16 row sum is much faster than count_nonzero(axis=1); SUBSET < 65536
        return np.add.reduce(near.view(np.uint8), axis=1, dtype=np.uint16).astype(np.int64)

    def add(self, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Score a batch and keep the CONFIRM best so far; returns their counts, most first."""
        head, scored = self.head, self.scored
        typed_normals, typed_offsets = normals.astype(self.dtype), offsets.astype(self.dtype)
        counts = self._score(typed_normals, typed_offsets, slice(0, head))
        if scored > head:
            tail = slice(head, scored)
            share = _reference_share(self.best_counts, scored, counts, head)
            go_on = counts >= _low_count(head * share, head) - 1
            if go_on.all():
                counts += self._score(typed_normals, typed_offsets, tail)
            else:
                counts[go_on] += self._score(typed_normals[go_on], typed_offsets[go_on], tail)
                counts[~go_on] = -1  # not among the best: never kept
        best_normals = np.concatenate([self.best_normals, normals])
        best_offsets = np.concatenate([self.best_offsets, offsets])
        best_counts = np.concatenate([self.best_counts, counts])
        keep = np.argsort(-best_counts, kind='stable')[:CONFIRM]
        keep = keep[best_counts[keep] >= 0]
        self.best_normals, self.best_offsets, self.best_counts = best_normals[keep], best_offsets[keep], \
            best_counts[keep]
        return self.best_counts

    def counts(self) -> np.ndarray:
        return self.best_counts

    def planes(self) -> tuple[np.ndarray, np.ndarray]:
        return self.best_normals, self.best_offsets


_NO_NORMALS = np.empty((3, 0))


class _CompiledScores:
    """:class:`_NumpyScores` in float64, one compiled call per batch (:func:`.kernels.score_hypotheses`): the
    connected-regions search."""

    def __init__(self, ordered: np.ndarray, tolerance: Tolerance, point_normals: np.ndarray | None, pick: np.ndarray,
                 head: int, ray: np.ndarray = kernels.NO_RAY):
        self.ray = ray
        self.subset = ordered.take(pick, axis=1)  # C-ordered: a gather (take: several times faster than [:, pick])
        self.tolerance = _tolerances(tolerance_at(tolerance, pick))
        self.normals = _NO_NORMALS if point_normals is None else \
            kernels.c_array(point_normals.take(pick, axis=1), np.float64)
        self.head = head
        self.best_normals, self.best_offsets = np.empty((CONFIRM, 3)), np.empty(CONFIRM)
        self.best_counts = np.empty(CONFIRM, dtype=np.int64)
        self.held = 0

    def add(self, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        self.held = kernels.score_hypotheses(self.subset, self.tolerance, self.normals,
                                             kernels.c_array(normals, np.float64), kernels.c_array(offsets, np.float64),
                                             self.head, NORMAL_MIN_COS, PRESCORE_SIGMAS, self.best_normals,
                                             self.best_offsets, self.best_counts, self.held, self.ray)
        return self.best_counts[:self.held]

    def add_drawn(self, cols: np.ndarray, rng: np.random.Generator, count: int,
                  sampler: GridSampler | GraphSampler) -> np.ndarray:
        """:func:`_hypotheses` of ``count`` triples of ``cols`` (3, n), C-ordered (the same draws), scored as
        :meth:`add` scores them, in one compiled call (the sampler's ``scored_batch``)."""
        spread, local = _spread(cols, rng, count)
        self.held = sampler.scored_batch(cols, spread, rng, local, MIN_SINE, self.subset, self.tolerance, self.normals,
                                         self.head, NORMAL_MIN_COS, PRESCORE_SIGMAS, self.best_normals,
                                         self.best_offsets, self.best_counts, self.held, self.ray)
        return self.best_counts[:self.held]

    def counts(self) -> np.ndarray:
        return self.best_counts[:self.held]

    def planes(self) -> tuple[np.ndarray, np.ndarray]:
        return self.best_normals[:self.held], self.best_offsets[:self.held]


def best_plane(cols: np.ndarray, tolerance: Tolerance, probability: float, max_iterations: int,
               rng: np.random.Generator, region_of: Remaining | None = None,
               point_normals: np.ndarray | None = None, sampler: Sampler | None = None, allows: Allows = None
               ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray] | None:
    """One RANSAC run on the points ``cols`` (3, m): (normal, offset, inlier mask, mask of the points it
    takes out of the search) after refinement, or None when every sampled triple was degenerate. ``region_of``:
    the region rule over these points (:class:`.neighbours.Remaining`), which gives the part of its inliers a plane
    would really keep (its largest connected region) and the points it takes; hypotheses are then scored compiled,
    the confirmed ones compared by that region, and the plane is refitted on it. ``point_normals`` (3, m),
    local surface normals (NaN: unknown): hypotheses are scored only by the points whose normal
    agrees with theirs. ``sampler``: draws triples of nearby points for part of the hypotheses. ``allows``: the
    normals a plane may have; other hypotheses are dropped and a refit that leaves them is not taken."""
    m = cols.shape[1]
    # C-ordered for the kernels (a copy of a sample's columns at most once per plane); the scoring keeps ``cols`` as
    # given: BLAS rounds its products by the layout
    ordered = kernels.c_array(cols, np.float64)
    # the scored subset in random order (when it is all the points, a fixed shuffle of them), so
    # that its first PRESCORE points are a random sample of it
    pick = _shuffled(m) if m <= SUBSET else rng.choice(m, SUBSET, replace=False)
    scored = len(pick)
    head = PRESCORE if scored > 2 * PRESCORE else scored
    scorer = _NumpyScores(cols, tolerance, point_normals, pick, head) if region_of is None else \
        _CompiledScores(ordered, tolerance, point_normals, pick, head, getattr(region_of, 'ray', kernels.NO_RAY))
    best_counts = scorer.counts()
    drawn = isinstance(scorer, _CompiledScores) and isinstance(sampler, (GridSampler, GraphSampler)) and allows is None
    iterations = 0
    needed = float(max_iterations)
    while iterations < min(needed, max_iterations):
        batch = int(min(BATCH, max_iterations - iterations))
        if drawn:  # a batch in one call (no hypothesis left: the best as they were)
            iterations += batch
            best_counts = scorer.add_drawn(ordered, rng, batch, sampler)
        else:
            normals, offsets = _hypotheses(ordered, rng, batch, sampler)
            iterations += batch
            if allows is not None:
                ok = allows(normals)
                normals, offsets = normals[ok], offsets[ok]
            if len(normals) == 0:
                continue
            best_counts = scorer.add(normals, offsets)
        if len(best_counts):
            needed = _required_iterations(best_counts[0] / scored, probability, sampler is not None)
    best_normals, best_offsets = scorer.planes()
    if len(best_counts) == 0:
        return None
    # MSAC: the truncated squared distance prefers, of two planes with similar support, the one
    # its inliers hug (a plane tilted across a small face and its neighbours' edges loses).
    with np.errstate(over='ignore', invalid='ignore'):  # a far-out row (a driver's FLT_MAX): inf, no inlier
        if region_of is not None:
            return best_region(ordered, tolerance, best_normals, best_offsets, region_of, point_normals, allows=allows)
        dist = plane_distances(cols, best_normals, best_offsets)
    np.minimum(dist, tolerance, out=dist)
    winner = int(np.argmin(np.einsum('ij,ij->i', dist, dist)))
    normal, offset = best_normals[winner], best_offsets[winner]
    inliers = within_plane(cols, normal, offset, tolerance)
    # Least-squares refinement on the inliers; repeat while the inlier set changes (at most 3 times).
    for _ in range(3):
        count = int(np.count_nonzero(inliers))
        if count < 3:
            break
        new_normal, new_offset = fit_columns(np.compress(inliers, cols, axis=1))
        if not allows_normal(allows, new_normal):
            break  # the fit leaves the orientation constraint: keep the RANSAC plane
        new_inliers = within_plane(cols, new_normal, new_offset, tolerance)
        if np.count_nonzero(new_inliers) < count:
            break  # the fit drifted away from the consensus set: keep the RANSAC plane
        normal, offset = new_normal, new_offset
        if np.array_equal(new_inliers, inliers):
            break
        inliers = new_inliers
    return normal, offset, inliers, inliers


def _tolerances(tolerance: Tolerance) -> np.ndarray:
    """A tolerance as the kernels take it: (1,) or (m,) float64, meters."""
    return kernels.c_array(np.reshape(tolerance, -1), np.float64)


def best_region(cols: np.ndarray, tolerance: Tolerance, normals: np.ndarray, offsets: np.ndarray,
                remaining: Remaining, point_normals: np.ndarray | None = None, *, allows: Allows = None
                ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Of the confirmed hypotheses (``normals`` (h, 3), ``offsets`` (h,)) on the points ``cols`` (3, m), C-ordered,
    the one whose region (``remaining``: its largest connected one, see :meth:`.neighbours.Remaining.keep` and
    SUPPORT) is largest (ties: MSAC; :meth:`.neighbours.Remaining.best`); then refit on the region and take the
    region again, at most 3 times. ``point_normals`` (3, m), NaN where unknown: a region keeps only points whose
    normal agrees. Returns (normal, offset, region (m,), taken (m,): see :data:`Keep`)."""
    tolerances = _tolerances(tolerance)
    if allows is None:
        plane = remaining.refitted(cols, tolerances, normals, offsets, point_normals, SUPPORT, _COHERENT_BOUND, REFITS)
        if plane is not None:
            return plane
    winner, region, taken = remaining.best(cols, tolerances, normals, offsets, point_normals, SUPPORT,
                                           _COHERENT_BOUND)
    normal, offset = normals[winner], offsets[winner]
    for _ in range(REFITS):
        count = int(np.count_nonzero(region))
        if count < 3:
            break
        new_normal, new_offset, new_region, new_taken = remaining.refit(cols, tolerances, region, SUPPORT)
        if not allows_normal(allows, new_normal):
            break
        if np.count_nonzero(new_region) < count:
            break
        normal, offset = new_normal, new_offset
        same = np.array_equal(new_region, region)
        region, taken = new_region, new_taken
        if same:
            break
    return normal, offset, region, taken
