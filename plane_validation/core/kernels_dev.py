"""Development copy of the organized detect kernels (moved into kernels.py when done)."""
from __future__ import annotations

import numba
import numpy as np

from .kernels import _NUMPY_JIT, _ahead, _length, _coherent_near, _fragmented, _join, _msac_cost, _root, fit_members


@numba.njit(**_NUMPY_JIT)
def _member_at(members: np.ndarray, count: int, pixels: np.ndarray, p: int) -> int:
    """The place in ``members[:count]`` of the member at pixel ``p`` (``pixels`` by member, ascending), -1 for none."""
    lo, hi = 0, count
    while lo < hi:
        mid = (lo + hi) // 2
        if pixels[members[mid]] < p:
            lo = mid + 1
        else:
            hi = mid
    return lo if lo < count and pixels[members[lo]] == p else -1


@numba.njit(**_NUMPY_JIT)
def _run_of(starts: np.ndarray, n_runs: int, c: int) -> int:
    """The run (``starts`` (n_runs + 1,): where each begins) that holds place ``c``."""
    lo, hi = 0, n_runs - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if starts[mid] <= c:
            lo = mid
        else:
            hi = mid - 1
    return lo


@numba.njit(**_NUMPY_JIT)
def _run_components(members: np.ndarray, count: int, pixels: np.ndarray, width: int, bridges: np.ndarray,
                    counted: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, int, np.ndarray]:
    """Connected components of the points ``members[:count]`` (places in ``pixels``, whose flat pixels on a
    sub-grid ``width`` wide ascend with them) through their 4 image neighbours and the ``bridges`` (b, 3) that do not
    cross the seam, labelled by runs along the image rows (a run touches the runs of the row above that overlap it):
    (the component with the most ``counted`` (by place) points, the first of equals, -1 when there is none; the
    component of each run; where each run starts among the members (runs + 1,); the number of runs; the ``counted``
    points of each component), components numbered in the order of their first point (as
    :func:`grid_components`)."""
    starts = np.empty(count + 1, np.int64)
    n_runs = 0
    previous = -2
    row_end = 0  # where the row of the previous point ends
    for c in range(count):
        p = pixels[members[c]]
        if not (p == previous + 1 and p < row_end):
            starts[n_runs] = c
            n_runs += 1
            if p >= row_end:
                row_end = p - p % width + width
        previous = p
    starts[n_runs] = count
    parent = np.arange(n_runs)
    low = 0  # the first run that may lie above the current one: the runs before it end before its row does
    for k in range(n_runs):
        first, last = pixels[members[starts[k]]], pixels[members[starts[k + 1] - 1]]
        if first < width:
            continue
        while pixels[members[starts[low + 1] - 1]] < first - width:
            low += 1
        j = low
        while j < k and pixels[members[starts[j]]] <= last - width:
            _join(parent, k, j)
            j += 1
    for b in range(bridges.shape[0]):
        if bridges[b, 2] != 0:
            continue
        u, v = _member_at(members, count, pixels, bridges[b, 0]), _member_at(members, count, pixels, bridges[b, 1])
        if u >= 0 and v >= 0:
            _join(parent, _run_of(starts, n_runs, u), _run_of(starts, n_runs, v))
    component = np.empty(n_runs, np.int64)
    n_components = 0
    for k in range(n_runs):
        root = _root(parent, k)
        if root == k:  # a root is its component's first run: met first
            component[k] = n_components
            n_components += 1
        else:
            component[k] = component[root]
    sizes = np.zeros(n_components, np.int64)
    for k in range(n_runs):
        size = 0
        for c in range(starts[k], starts[k + 1]):
            size += counted[members[c]]
        sizes[component[k]] += size
    best = np.argmax(sizes) if n_components else -1
    return best, component, starts, n_runs, sizes


@numba.njit(**_NUMPY_JIT)
def _grid_keep(cols: np.ndarray, tolerance: np.ndarray, support: float, nx: float, ny: float, nz: float,
               offset: float, point_normals: np.ndarray, rest_pixel: np.ndarray, usable: np.ndarray, width: int,
               bridges: np.ndarray, min_cos: float, rules: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(kept, taken) (r,) bool: the region the plane (nx, ny, nz, ``offset``) keeps among the r points ``cols`` (3, r)
    meters of a sub-grid (``rest_pixel`` (r,) their pixels, ascending; ``point_normals`` (3, r)), as
    :func:`_plane_region` gives it."""
    r = cols.shape[1]
    per_point = tolerance.shape[0] > 1
    band = np.empty(r, np.int64)  # the band's points (places in cols) that may join a region, ascending
    pixels = np.empty(r, np.int64)  # ... their pixels
    inlier = np.empty(r, np.bool_)  # ... within t
    above = np.empty(r, np.bool_)  # ... on the side the normal points to
    n_band = 0
    for q in range(r):
        e = nx * cols[0, q] + ny * cols[1, q] + nz * cols[2, q] + offset
        t = tolerance[q] if per_point else tolerance[0]
        if not abs(e) <= support * t:
            continue
        cos = abs(point_normals[0, q] * nx + point_normals[1, q] * ny + point_normals[2, q] * nz)
        if not cos < min_cos and usable[rest_pixel[q]]:
            band[n_band] = q
            pixels[n_band] = rest_pixel[q]
            inlier[n_band] = abs(e) <= t
            above[n_band] = e > 0
            n_band += 1
    members = np.empty(n_band, np.int64)
    n_in = 0
    for b in range(n_band):
        members[n_in] = b
        n_in += inlier[b]
    best, component, starts, n_runs, sizes = _run_components(members, n_in, pixels, width, bridges, inlier)
    kept = np.zeros(r, np.bool_)
    kept_count = 0
    for k in range(n_runs):
        if component[k] == best:
            kept_count += starts[k + 1] - starts[k]
            for c in range(starts[k], starts[k + 1]):
                kept[band[members[c]]] = True
    if not _fragmented(sizes, rules[0], rules[1]):
        return kept, kept.copy()
    for b in range(n_band):
        members[b] = b
    best, component, starts, n_runs, _ = _run_components(members, n_band, pixels, width, bridges, inlier)
    beyond = above_count = joined = 0
    for k in range(n_runs):
        if component[k] == best:
            for b in range(starts[k], starts[k + 1]):
                if inlier[b]:
                    joined += 1
                else:
                    beyond += 1
                    above_count += above[b]
    below = beyond - above_count
    if min(above_count, below) >= rules[2] * max(above_count, below) and joined > kept_count:
        taken = np.zeros(r, np.bool_)
        joint = np.zeros(r, np.bool_)
        for k in range(n_runs):
            if component[k] == best:
                for b in range(starts[k], starts[k + 1]):
                    taken[band[b]] = True
                    joint[band[b]] = inlier[b]
        return joint, taken
    return kept, kept.copy()


@numba.njit(**_NUMPY_JIT)
def grid_plane(cols: np.ndarray, tolerance: np.ndarray, normals: np.ndarray, offsets: np.ndarray, support: float,
               bound_cos: float, point_normals: np.ndarray, rest_pixel: np.ndarray, usable: np.ndarray, width: int,
               bridges: np.ndarray, min_cos: float, rules: np.ndarray, refits: int
               ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """:func:`grid_best_region`, then up to ``refits`` least-squares refits of the winner on its region, each kept
    while its region holds at least as many points, until the region stays the same (``hypotheses.best_region``
    without an orientation constraint): (normal (3,), offset meters, region (r,), taken (r,))."""
    h, r = normals.shape[0], cols.shape[1]
    per_point = tolerance.shape[0] > 1
    counts = np.zeros(h, np.int64)
    x, y, z = cols[0], cols[1], cols[2]
    for j in range(h):
        nx, ny, nz, d = normals[j, 0], normals[j, 1], normals[j, 2], offsets[j]
        near = 0
        if per_point:
            for q in range(r):
                near += np.int64(abs(nx * x[q] + ny * y[q] + nz * z[q] + d) <= tolerance[q])
        else:
            t = tolerance[0]
            for q in range(r):
                near += np.int64(abs(nx * x[q] + ny * y[q] + nz * z[q] + d) <= t)
        counts[j] = near
    cost = np.full(h, np.nan)
    known = np.zeros(h, np.bool_)
    for j in range(h):
        for i in range(h):
            if i != j and counts[i] == counts[j]:
                _msac_cost(cols, tolerance, normals, offsets, j, cost, known)
    order = np.arange(h)
    for i in range(1, h):
        k = order[i]
        q = i
        while q > 0 and _ahead(k, order[q - 1], counts, cost):
            order[q] = order[q - 1]
            q -= 1
        order[q] = k
    winner, size = -1, -1
    region = taken = np.zeros(r, np.bool_)
    for i in range(h):
        j = order[i]
        if counts[j] <= size:
            break
        if size > 0:
            bound = _coherent_near(cols, tolerance, normals[j], offsets[j], point_normals, bound_cos)
            if bound < size or (bound == size and _msac_cost(cols, tolerance, normals, offsets, j, cost, known) >=
                                _msac_cost(cols, tolerance, normals, offsets, winner, cost, known)):
                continue
        kept, took = _grid_keep(cols, tolerance, support, normals[j, 0], normals[j, 1], normals[j, 2], offsets[j],
                                point_normals, rest_pixel, usable, width, bridges, min_cos, rules)
        found = np.count_nonzero(kept)
        if found > size or (found == size and _msac_cost(cols, tolerance, normals, offsets, j, cost, known) <
                            _msac_cost(cols, tolerance, normals, offsets, winner, cost, known)):
            winner, region, taken, size = j, kept, took, found
    normal = normals[winner].copy()
    offset = offsets[winner]
    for _ in range(refits):
        count = np.count_nonzero(region)
        if count < 3:
            break
        new_normal, new_offset = fit_members(cols, np.flatnonzero(region))
        new_region, new_taken = _grid_keep(cols, tolerance, support, new_normal[0], new_normal[1], new_normal[2],
                                           new_offset, point_normals, rest_pixel, usable, width, bridges, min_cos,
                                           rules)
        if np.count_nonzero(new_region) < count:
            break
        normal, offset = new_normal, new_offset
        same = True
        for q in range(r):
            if new_region[q] != region[q]:
                same = False
                break
        region, taken = new_region, new_taken
        if same:
            break
    return normal, offset, region, taken


@numba.njit(**_NUMPY_JIT)
def _ray_distance(search: np.ndarray, p: int, planes: np.ndarray, j: int, tolerance: np.ndarray,
                  viewpoint: np.ndarray, min_cos: float) -> float:
    """:func:`compete_distances`' entry (j, p): point ``p``'s distance to plane ``j`` along its ray (inf for j = k, no
    region), the same arithmetic."""
    if j >= planes.shape[0]:
        return np.inf
    x, y, z = search[0, p], search[1, p], search[2, p]
    rx, ry, rz = x - viewpoint[0], y - viewpoint[1], z - viewpoint[2]
    size = _length(rx, ry, rz)
    rx, ry, rz = rx / size, ry / size, rz / size
    tol = tolerance[p] if tolerance.shape[0] > 1 else tolerance[0]
    e = abs(planes[j, 0] * x + planes[j, 1] * y + planes[j, 2] * z + planes[j, 3])
    if e > tol:
        e = np.inf
    facing = abs(planes[j, 0] * rx + planes[j, 1] * ry + planes[j, 2] * rz)
    return e / (facing if np.isnan(facing) or facing > min_cos else min_cos)


@numba.njit(**_NUMPY_JIT)
def grid_settle(search: np.ndarray, planes: np.ndarray, tolerance: np.ndarray, viewpoint: np.ndarray, min_cos: float,
                region: np.ndarray, pixel: np.ndarray, node: np.ndarray, width: int, eight: np.ndarray, rounds: int
                ) -> np.ndarray:
    """:func:`grid_compete` with the distances of :func:`compete_distances` (``search`` (3, m) meters, ``planes`` (k,
    4), ``tolerance`` (1,) or (m,) meters, ``viewpoint`` (3,), ``min_cos``) worked out only where an offer compares
    them: the same regions (m,), k for none."""
    m = region.shape[0]
    height = node.shape[0] // width
    region = region.copy()
    padded = width + 2
    at = np.full((height + 2) * padded, -1, np.int64)
    place = np.empty(m, np.int64)
    r = 0
    for i in range(m):
        if i == 0 or pixel[i] >= (r + 1) * width:
            r = pixel[i] // width
        place[i] = (r + 1) * padded + pixel[i] - r * width + 1
        at[place[i]] = i
    n_eight = eight.shape[0]
    step = np.empty(n_eight, np.int64)
    for e in range(n_eight):
        step[e] = eight[e, 0] * padded + eight[e, 1]
    best = np.empty(m)
    known = np.zeros(m, np.bool_)  # best worked out (the distance to its region's plane, until it changes)
    offer_d = np.empty(m)
    offer_src = np.full(m, -1, np.int64)
    offer_region = np.empty(m, np.int64)
    touched = np.empty(m, np.int64)
    changed = np.empty(m, np.int64)
    n_changed = -1
    for _ in range(rounds):
        n_touched = 0
        first = n_changed < 0
        for q in range(m if first else n_changed):
            if first:
                centre = q
                bordering = False
                for e in range(n_eight):
                    j = at[place[centre] + step[e]]
                    if j >= 0 and region[j] != region[centre]:
                        bordering = True
                        break
                if not bordering:
                    continue
            else:
                centre = changed[q]
            for e in range(n_eight):
                other = at[place[centre] + step[e]]
                if other < 0:
                    continue
                dst, src = (centre, other) if first else (other, centre)
                cand = region[src]
                if cand == region[dst]:
                    continue  # its own plane is never nearer than itself
                if not known[dst]:
                    best[dst] = _ray_distance(search, dst, planes, region[dst], tolerance, viewpoint, min_cos)
                    known[dst] = True
                d = _ray_distance(search, dst, planes, cand, tolerance, viewpoint, min_cos)
                if not d < best[dst]:
                    continue
                if offer_src[dst] < 0:
                    touched[n_touched] = dst
                    n_touched += 1
                elif not (d < offer_d[dst] or (d == offer_d[dst] and src < offer_src[dst])):
                    continue
                offer_d[dst], offer_src[dst], offer_region[dst] = d, src, cand
        if n_touched == 0:
            break
        for q in range(n_touched):
            i = touched[q]
            region[i], best[i] = offer_region[i], offer_d[i]
            offer_src[i] = -1
            changed[q] = i
        n_changed = n_touched
    return region
