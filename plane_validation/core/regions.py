"""How an unorganized cloud's neighbourhood graph is built: :func:`graph_neighbours`, the
:class:`.search.neighbours_graph.GraphNeighbours` of the searched points (an image's grid form is built by
:func:`.search.grid_build.grid_neighbours`; both answer the search through one interface,
:class:`.search.neighbours.Neighbours`).

Each point is joined to its ``NEIGHBOURS`` nearest neighbours within ``RADIUS`` median neighbour spacings (exact,
through a voxel hash: :class:`VoxelIndex`; scipy's kd-tree for far-out coordinates and the searches across lidar
rings). A point whose neighbours all lie on one lidar ring (a line, or a strip widened by range noise) is also
joined to the next ring; a strip's own normal is the beam cone's, so it takes one from both rings, or none.
numpy/scipy, with the loops over points in compiled kernels (:mod:`.kernels`).
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from . import kernels
from .search.checks import gathered_rows
from .search.neighbours import NORMAL_MIN_COS, Neighbours, row_starts
from .search.neighbours_graph import GraphNeighbours

__all__ = ['Neighbours', 'GraphNeighbours', 'VoxelIndex', 'graph_neighbours', 'voxel_index', 'NEIGHBOURS', 'RADIUS',
           'NORMAL_MIN_COS']

#: Unorganized clouds: each point is joined to up to this many nearest neighbours ...
NEIGHBOURS = 10
#: ... that lie within this many median k-th-neighbour distances: the cloud's, or where larger, the median of the
#: point's neighbours' own. A surface far from a lidar has its rings farther apart than the cloud's typical spacing;
#: with the cloud's alone, its rings stayed apart (a corridor's end wall 8.7 m away: 15 pieces, found as no plane)
#: and the tuning split's lidar scans had 29/46 planes Hoover-correct at the best t, 34/46 with this (no scene worse).
#: A point at a depth jump keeps the near side's reach: its neighbours there are dense.
RADIUS = 2.0
#: ... and always to this many nearest, however far (along a far lidar ring the spacing exceeds the radius).
ALWAYS_JOINED = 2
#: Points whose neighbours lie along a line are also joined across it, to the nearest of this many;
#: those with none off the line (a far lidar ring on the ground) look again among as many of every
#: ACROSS_FAR_STRIDE-th point (reaching about as far as the 528 nearest).
ACROSS_CANDIDATES = 48
ACROSS_FAR_STRIDE = 11
#: "Off the line": the offset makes more than 45 degrees with it (cosine below this) ...
OFF_LINE_COS = 0.7
#: ... "off the plane" of a strip: more than 30 degrees with it (cosine with its normal above this).
OFF_PLANE_COS = 0.5
#: A point whose neighbours all lie on its own lidar ring (their elevations seen from the sensor, about
#: the z axis as a spinning lidar's frame has it, within this many radians: range noise keeps a ring's
#: elevation, but not that of a noisy surface through the sensor; and spread over more than ANOTHER_RING
#: in direction, which a patch far from the sensor, as a scan not in the sensor's frame has, is not) ...
ONE_RING = float(np.radians(0.01))
#: ... looks for the nearest point in direction (the next ring at about the same azimuth, as in the
#: scan's image) whose elevation differs by more than this, instead of one off its line or plane:
#: otherwise a ring on a corridor's floor is joined to itself where it climbs the wall, or finds nothing
#: within reach. Rings lie 0.3-2 degrees apart.
ANOTHER_RING = float(np.radians(0.1))
#: ... among this many nearest in direction (then among as many of every ACROSS_FAR_STRIDE-th): a ring's
#: returns are 0.1-0.4 degrees apart, the next ring 0.3-2 degrees away.
RING_CANDIDATES = 16
#: Only this fixed random share of the points looking across searches; the others take the point
#: found by one of their searching neighbours (the points along a ring share the next ring), or search
#: themselves when none of their neighbours searches.
ACROSS_SEARCHING = 0.25
#: Neighbour indices held at once by that search (rows x candidates).
ACROSS_BLOCK = 1 << 20
#: The neighbours of a point on one lidar ring with range noise lie on the beam's cone: a flat strip
#: across the surface, whose normal is not the surface's (on a wall facing the sensor it is 90 degrees
#: off). A neighbourhood flat to within this share of its width (eigenvalues) with one of the
#: ACROSS_CANDIDATES nearest off its plane (OFF_PLANE_COS; the next ring, whose strip is parallel) is
#: such a strip: it is joined to that point, and its normal comes from both points' neighbours
#: together, unknown (NaN) where the rings' noise swamps that too (most of them at 2 cm noise).
STRIP_FLATNESS = 0.01
#: ... and seen edge-on from the sensor (graph_neighbours' viewpoint), as the cone is (sine of the
#: angle between the plane and the ray).
STRIP_EDGE_ON = float(np.sin(np.radians(10.0)))
#: A neighbourhood thicker than this share of its width (eigenvalues) is noise above the spacing: no normal.
NOISY = 0.1
#: Nearest-neighbour queries hash the points into voxels holding about this many points each (kernels.voxel_grid) ...
VOXEL_POINTS = 4.0
#: ... and search up to this many rings of voxels around a query's own; a query whose nearest are not certain
#: within them (an outlier far from the rest) is answered by a kd-tree.
VOXEL_RINGS = 5
#: A cloud spanning more voxels than this along an axis (a far-out coordinate) is searched by a kd-tree alone.
VOXEL_SPAN = 1 << 20
#: Queries the voxel rings leave (far from every point) are answered by every distance up to this many query-point
#: pairs (about 4 ms), by a kd-tree beyond (its build costs about 10 ms for a frame's 32,768 searched points).
BRUTE_PAIRS = 1 << 22


_NO_POINTS = np.empty((0, 3))
_NO_FLAGS = np.empty(0, bool)
_NO_DIST, _NO_IDX, _NO_REACH = np.empty((0, 1)), np.empty((0, 1), np.int64), np.empty(0)

#: Searchers (voxel indices, or kd-trees) over coordinates and over every ACROSS_FAR_STRIDE-th of them, each built on
#: first use, the coordinates and how many nearest candidates a search looks at: (tree(), far(), coordinates (n, 3),
#: candidates).
_Space = tuple[Callable[[], 'VoxelIndex | cKDTree'], Callable[[], 'VoxelIndex | cKDTree'], np.ndarray, int]
def _space(coords: np.ndarray, candidates: int, searcher: VoxelIndex | cKDTree | None = None) -> _Space:
    return ((lambda: searcher) if searcher is not None else functools.cache(lambda: _searcher(coords)),
            functools.cache(lambda: _searcher(coords[::ACROSS_FAR_STRIDE])), coords, candidates)


def _searcher(coords: np.ndarray) -> VoxelIndex | cKDTree:
    """Nearest-neighbour queries over ``coords`` (n, 3): a :class:`VoxelIndex`, or a kd-tree for far-out coordinates."""
    index = voxel_index(coords) if len(coords) else None
    return cKDTree(coords) if index is None else index


@dataclass(frozen=True, eq=False)
class _Across:
    """Which of its candidates a point joins across rings: one on another lidar ring (``elevation`` (n,) differs by
    more than ANOTHER_RING); with ``direction`` (n, 3) instead one off the line along it (OFF_LINE_COS), or with
    ``off_plane`` off the plane of that normal (OFF_PLANE_COS), of the ``points`` (n, 3), and for a point of
    ``one_ring`` (n,) also on another ring."""

    elevation: np.ndarray
    points: np.ndarray | None = None
    direction: np.ndarray | None = None
    off_plane: bool = False
    one_ring: np.ndarray | None = None

    def first(self, rows: np.ndarray, near: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For the points ``rows`` (m,) with candidates ``near`` (m, c), nearest first: whether one is across, and the
        first such one (the first candidate where none is): :func:`.kernels.first_across` (:meth:`numpy` is its
        reference)."""
        if self.direction is None:
            kind, points, direction, one_ring = 0, _NO_POINTS, _NO_POINTS, _NO_FLAGS
        else:
            kind, one_ring = 2 if self.off_plane else 1, self.one_ring
            points, direction = kernels.c_array(self.points, np.float64), kernels.c_array(self.direction, np.float64)
        return kernels.first_across(kernels.c_array(rows, np.int64), kernels.c_array(near, np.int64), points,
                                    direction, self.elevation, one_ring, kind,
                                    OFF_PLANE_COS if self.off_plane else OFF_LINE_COS, ANOTHER_RING)

    def numpy(self, rows: np.ndarray, near: np.ndarray) -> np.ndarray:
        """(m, c) bool: which candidates are across, in numpy."""
        another = np.abs(self.elevation[near] - self.elevation[rows, None]) > ANOTHER_RING
        if self.direction is None:
            return another
        offs = self.points[near] - self.points[rows, None, :]
        with np.errstate(invalid='ignore', divide='ignore'):
            cos = np.abs(np.einsum('nkd,nd->nk', offs, self.direction[rows])) / np.linalg.norm(offs, axis=-1)
        off = cos > OFF_PLANE_COS if self.off_plane else cos < OFF_LINE_COS  # NaN (the point itself) is neither
        return off & (~self.one_ring[rows, None] | another)


def _across(tree: cKDTree, coords: np.ndarray, rows: np.ndarray, test: _Across, candidates: int, skip: int,
            stride: int) -> tuple[np.ndarray, np.ndarray]:
    """For the points ``rows``: whether one of their ``candidates`` nearest in ``tree`` (after the
    first ``skip``) is across (``test``), and the nearest such one. ``tree`` holds every ``stride``-th of
    ``coords`` (n, 3)."""
    candidates = min(candidates, tree.n)
    if len(rows) * candidates > ACROSS_BLOCK:  # bounded memory: a block of rows at a time
        step = max(1, ACROSS_BLOCK // candidates)
        parts = [_across(tree, coords, rows[i:i + step], test, candidates, skip, stride)
                 for i in range(0, len(rows), step)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    queries = gathered_rows(coords, rows)
    _, near = tree.query(queries, k=candidates)
    near = near.reshape(len(rows), -1)[:, skip:]
    near = np.where(near < tree.n, near * stride, rows[:, None])  # no neighbour found: the point itself
    return test.first(rows, near)


def _partners(tree: cKDTree, coords: np.ndarray, idx: np.ndarray, rows: np.ndarray, test: _Across,
              candidates: int, skip: int, stride: int) -> np.ndarray:
    """:func:`_across` for the points ``rows`` (ascending) with neighbours ``idx`` (n, k): (n,) the
    point found for each row, -1 where none (and for other points). A fixed random ACROSS_SEARCHING
    share of the rows search; the others take a searching neighbour's."""
    n = len(idx)
    partner = np.full(n, -1, dtype=np.int64)
    among = np.zeros(n, bool)
    among[rows] = True
    searching = (np.random.default_rng(0).random(n) < ACROSS_SEARCHING) & among  # by index: order matters
    for group in (rows[searching[rows]], None):
        if group is None:  # the rest: a searching neighbour's point (or none), without one their own search
            rest = rows[~searching[rows]]
            found = partner[idx[rest, 1:]]
            has = (found >= 0).any(axis=1)
            partner[rest[has]] = found[has, np.argmax(found[has] >= 0, axis=1)]
            group = rest[~searching[idx[rest, 1:]].any(axis=1)]
        if len(group):
            ok, target = _across(tree, coords, group, test, candidates, skip, stride)
            partner[group[ok]] = target[ok]
    return partner


def _search(space: _Space, idx: np.ndarray, rows: np.ndarray, test: _Across, skip: int, far: bool
            ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_partners` among the nearest in ``space`` (after the first ``skip``), then, with ``far``,
    for the rows without one among every ACROSS_FAR_STRIDE-th point: (rows found (m,), partners (m,))."""
    tree, far_tree, coords, candidates = space
    found_rows, found_targets = [rows[:0]], [rows[:0]]
    for stride in (1, ACROSS_FAR_STRIDE) if far else (1,):
        if len(rows) == 0 or len(coords) <= idx.shape[1]:
            break
        sub = tree() if stride == 1 else far_tree()
        partner = _partners(sub, coords, idx, rows, test, candidates, skip if stride == 1 else 0, stride)[rows]
        found = partner >= 0
        found_rows.append(rows[found])
        found_targets.append(partner[found])
        rows = rows[~found]
    return np.concatenate(found_rows), np.concatenate(found_targets)


@dataclass(frozen=True, eq=False)
class VoxelIndex:
    """``points`` (m, 3) meters hashed into cubic voxels of side ``cell`` from ``origin`` (3,), ``dims`` (3,)
    voxels along each axis (the rest: :func:`kernels.voxel_grid`'s output), for exact nearest-neighbour queries
    of points inside those voxels."""

    points: np.ndarray
    origin: np.ndarray
    cell: float
    dims: np.ndarray
    grid: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]

    @property
    def n(self) -> int:
        """How many points (as cKDTree.n)."""
        return len(self.points)

    @functools.cached_property
    def _tree(self) -> cKDTree:
        return cKDTree(self.points)

    @functools.cached_property
    def ordered(self) -> np.ndarray:
        """(m, 3) the points voxel by voxel (in the grid's order)."""
        return gathered_rows(self.points, self.grid[0])

    def query(self, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` nearest points to each of ``queries`` (q, 3), inside the voxels, as cKDTree.query gives them
        (distances (q, k) meters, nearest first; indices (q, k), len(points) where fewer than k exist; ties may be
        ordered otherwise). The points themselves as ``queries`` (the same array) are answered voxel by voxel."""
        grid = (self.ordered, *self.grid, self.origin, self.cell, self.dims)
        if k == 1:
            dist, idx, exact = kernels.voxel_nearest(*grid, kernels.c_array(queries, np.float64), VOXEL_RINGS)
        elif queries is self.points:
            dist, idx, exact = kernels.voxel_knn_points(*grid, k, VOXEL_RINGS)
        else:
            dist, idx, exact = kernels.voxel_knn(*grid, kernels.c_array(queries, np.float64), k, VOXEL_RINGS)
        rest = np.flatnonzero(~exact)
        if len(rest):  # far from every point (or fewer than k of them): every point, or the kd-tree for many
            d, i = _far_nearest(self, kernels.c_array(queries[rest], np.float64), k)
            dist[rest], idx[rest] = d.reshape(len(rest), k), i.reshape(len(rest), k)
        return dist, idx


def _far_nearest(index: VoxelIndex, queries: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest of ``index``'s points to each of ``queries`` (q, 3), as cKDTree.query gives them: by every
    distance (:func:`.kernels.brute_knn`) for up to BRUTE_PAIRS query-point pairs, else by its kd-tree (built once)."""
    if len(queries) * index.n <= BRUTE_PAIRS and '_tree' not in index.__dict__:
        return kernels.brute_knn(index.points, queries, k)
    return index._tree.query(queries, k=k)


def voxel_index(points: np.ndarray, span: np.ndarray | tuple[np.ndarray, np.ndarray] | None = None
                ) -> VoxelIndex | None:
    """A :class:`VoxelIndex` of ``points`` (m, 3) meters, m >= 1, finite, with about VOXEL_POINTS points per
    occupied voxel; ``span`` (q, 3): the queries, when others than ``points``, or their smallest and largest
    coordinates ((3,), (3,)). None when the voxels would span more than VOXEL_SPAN along an axis, or no voxel size
    gives about that many (far-out coordinates: use a kd-tree)."""
    points = kernels.c_array(points, np.float64)
    lo, hi = kernels.coordinate_bounds(points)
    if isinstance(span, tuple):
        lo, hi = np.minimum(lo, span[0]), np.maximum(hi, span[1])
    elif span is not None and len(span):
        span_lo, span_hi = kernels.coordinate_bounds(kernels.c_array(span, np.float64))
        lo, hi = np.minimum(lo, span_lo), np.maximum(hi, span_hi)
    extent = hi - lo
    size = float(extent.max())
    if not size > 0:
        size = 1.0
    cell = size / max(1.0, len(points) / VOXEL_POINTS) ** (1 / 3)  # as if filling a cube: then refined
    for _ in range(8):
        if not (size / cell < VOXEL_SPAN and np.prod(extent // cell + 1) < 2.0 ** 62):
            return None
        # one voxel more than the extent needs: the kernels' (p - lo) / cell may round up to extent // cell + 1
        dims = (extent // cell).astype(np.int64) + 2
        occupied = kernels.voxel_count(points, lo, cell, dims)  # the grid is built for the size chosen only
        per_voxel = len(points) / occupied
        if per_voxel <= 2 * VOXEL_POINTS and (per_voxel >= VOXEL_POINTS / 2 or occupied == len(points)):
            return VoxelIndex(points=points, origin=lo, cell=cell, dims=dims,
                              grid=kernels.voxel_grid(points, lo, cell, dims))
        cell *= float(np.clip(np.sqrt(VOXEL_POINTS / per_voxel), 0.25, 4.0))  # a surface: points grow as cell^2
    return None  # the points' spacing varies beyond what one voxel size serves (far-out coordinates)


def _knn(points: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest of ``points`` (n, 3) to each of them (distances (n, k), indices (n, k), as cKDTree.query)."""
    return _searcher(points).query(points, k=k)


def _knn_tree(points: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_knn` by scipy's kd-tree (the reference)."""
    return cKDTree(points).query(points, k=k)


def graph_neighbours(points: np.ndarray, viewpoint: np.ndarray | None = None, index: VoxelIndex | None = None
                     ) -> GraphNeighbours:
    """Neighbours of unorganized (n, 3) points (meters): each joined to its NEIGHBOURS nearest within
    RADIUS median NEIGHBOURS-th-neighbour distances (the cloud's, or its neighbours' where larger) and, where those
    lie along a line or a strip of one lidar ring, to a point of the next ring (see ACROSS_CANDIDATES, ACROSS_SEARCHING,
    STRIP_FLATNESS, ONE_RING). ``viewpoint`` (3,): where the sensor is in these coordinates (default
    the origin; a spinning lidar's axis is taken as z), for the strip and ring tests. Exact copies of
    a point are joined to it and share its neighbours and normal. ``index``: a :func:`voxel_index` of ``points``
    already built (else one is)."""
    return _graph(points, merge_copies=True, viewpoint=np.zeros(3) if viewpoint is None else viewpoint, index=index)


def _graph(points: np.ndarray, merge_copies: bool, viewpoint: np.ndarray, index: VoxelIndex | None = None
           ) -> GraphNeighbours:
    n = len(points)
    k = min(NEIGHBOURS + 1, n)
    if k < 2:
        return GraphNeighbours(n=n, edges=np.empty((0, 2), np.int64))
    searcher = _searcher(points) if index is None else index
    dist, idx = searcher.query(points, k=k)
    if merge_copies and np.any(dist[:, 1] == 0):  # copies would fill the neighbour lists (stacked scans)
        return _with_copies(points, viewpoint)
    missing = idx >= n  # far-out coordinates (a driver's FLT_MAX rows) find no neighbour
    if missing.any():
        idx = np.where(missing, np.arange(n)[:, None], idx)
        dist = np.where(missing, np.inf, dist)
    kth = dist[:, k - 1]
    reach = np.full(n, RADIUS * float(np.median(kth)))
    sparse = np.flatnonzero(kth > reach)  # some of its nearest lie beyond the cloud's typical reach
    if len(sparse):  # there the spacing of its own neighbourhood counts (see RADIUS)
        around = kth[idx[sparse]]
        local = np.partition(np.where(np.isfinite(around), around, 0.0), k // 2, axis=1)[:, k // 2]
        reach[sparse] = np.maximum(reach[sparse], RADIUS * local)
    edges = [np.empty((0, 2), np.int64)]  # and the pairs within reach (_neighbours)
    normals = None
    if k >= 4:  # local normals: the smallest principal axis of each point's neighbourhood
        values, vectors = _principal_axes(points, idx)
        normals = _normals(values, vectors)
        line = values[:, 1] < 0.05 * values[:, 2]  # neighbours along a line: no normal, a ring
        normals[line] = np.nan
        rays, elevation, unit = _sensor_rays(points, viewpoint)
        one_ring = kernels.spread_among(elevation, idx) <= ONE_RING
        flat_rows = np.flatnonzero(one_ring)  # of those, the ones whose widest neighbour is a ring's spacing off
        widest = np.einsum('nkd,nd->nk', unit[idx[flat_rows]], unit[flat_rows]).min(axis=1)
        one_ring[flat_rows] = widest < np.cos(ANOTHER_RING)
        directions = _space(unit, RING_CANDIDATES)
        nearby = _space(points, ACROSS_CANDIDATES, searcher)

        def search(rows: np.ndarray, direction: np.ndarray, off_plane: bool, far: bool
                   ) -> tuple[np.ndarray, np.ndarray]:
            """Each row's partner: the nearest point off its line along ``direction`` (n, 3) or with ``off_plane``
            off its plane of that normal (farther only with ``far``; for a point of one ring, on another ring too),
            else the nearest in direction on another ring. A point of one ring is also joined to the latter (the
            next ring at about its azimuth, as in the scan's image), whatever the surface: across an edge that
            joins nothing, as the region growth takes only points near its plane."""
            found, target = _search(nearby, idx, rows, _Across(elevation, points, direction, off_plane, one_ring), k,
                                    far)
            found_d, target_d = _search(directions, idx, rows[one_ring[rows]], _Across(elevation), 0, True)
            edges.append(np.column_stack([found_d, target_d]))
            rest = ~np.isin(found_d, found)
            return np.concatenate([found, found_d[rest]]), np.concatenate([target, target_d[rest]])

        rows_s, target = _strips(points, ~line & (values[:, 0] < STRIP_FLATNESS * values[:, 1]), normals,
                                 rays, search)
        edges.append(np.column_stack([rows_s, target]))
        normals[rows_s] = _normals(*_principal_axes(points, np.concatenate([idx[rows_s], idx[target]], axis=1)))
        rows_l, target = search(np.flatnonzero(line), vectors[:, :, 2], False, True)
        edges.append(np.column_stack([rows_l, target]))
    return _neighbours(n, np.concatenate(edges), normals, (dist, idx, reach))


def _sensor_rays(points: np.ndarray, viewpoint: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rays from ``viewpoint`` (3,) to ``points`` (n, 3), their elevations about the z axis and their unit
    directions (a zero ray as is), in one compiled pass (:func:`.kernels.sensor_rays`; :func:`_sensor_rays_numpy` is
    its reference)."""
    return kernels.sensor_rays(kernels.c_array(points, np.float64), kernels.c_array(viewpoint, np.float64))


def _sensor_rays_numpy(points: np.ndarray, viewpoint: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_sensor_rays` in numpy."""
    rays = points - viewpoint
    elevation = np.arctan2(rays[:, 2], np.hypot(rays[:, 0], rays[:, 1]))
    length = np.linalg.norm(rays, axis=1, keepdims=True)
    return rays, elevation, rays / np.where(length > 0, length, 1.0)


def _knn_edges_numpy(dist: np.ndarray, idx: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The pairs (e, 2) joining each point to those of its nearest (``dist``, ``idx`` (n, k), the point itself first)
    within its ``reach`` (n,) meters, and to its ALWAYS_JOINED nearest, in numpy (:func:`_neighbours` joins them in
    its compiled pass)."""
    n, k = idx.shape
    near = dist[:, 1:k] <= reach[:, None]
    near[:, :ALWAYS_JOINED] |= np.isfinite(dist[:, 1:1 + ALWAYS_JOINED])
    rows = np.repeat(np.arange(n), k - 1).reshape(n, k - 1)
    return np.column_stack([rows[near], idx[:, 1:k][near]])


def _principal_axes(points: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (m, 3), ascending, and unit principal axes (m, 3, 3), as columns (signs arbitrary), of the point
    sets ``points[idx]`` (``points`` (n, 3), ``idx`` (m, k))."""
    return kernels.principal_axes(kernels.c_array(points, np.float64), kernels.c_array(idx, np.int64))


def _principal_axes_numpy(neighbourhoods: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_principal_axes` of point sets (m, k, 3) by numpy (the reference)."""
    nb = neighbourhoods - neighbourhoods.mean(axis=1, keepdims=True)
    x, y, z = nb[..., 0], nb[..., 1], nb[..., 2]
    xy, xz, yz = (np.einsum('nk,nk->n', a, b) for a, b in ((x, y), (x, z), (y, z)))  # 2-d products are faster
    scatter = np.stack([np.einsum('nk,nk->n', x, x), xy, xz, xy, np.einsum('nk,nk->n', y, y), yz,
                        xz, yz, np.einsum('nk,nk->n', z, z)], axis=-1).reshape(-1, 3, 3)
    return np.linalg.eigh(scatter)


def _normals(values: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(m, 3) smallest principal axes of :func:`_principal_axes`' output, NaN where the thickness is
    above NOISY (noise above the spacing: no normal)."""
    return np.where((values[:, 0] > NOISY * values[:, 1])[:, None], np.nan, axes[:, :, 0])


def _strips(points: np.ndarray, flat: np.ndarray, normals: np.ndarray, rays: np.ndarray,
            search: Callable[[np.ndarray, np.ndarray, bool, bool], tuple[np.ndarray, np.ndarray]]
            ) -> tuple[np.ndarray, np.ndarray]:
    """Points whose ``flat`` neighbourhood (normal ``normals``, (n, 3)) is a strip of one lidar ring
    seen along ``rays`` (n, 3) from the sensor (see STRIP_FLATNESS), and for each the point of the
    next ring found by ``search``: (rows (m,), targets (m,))."""
    with np.errstate(invalid='ignore'):
        edge_on = np.abs(np.einsum('ij,ij->i', normals, rays)) < STRIP_EDGE_ON * np.linalg.norm(rays, axis=1)
    rows, target = search(np.flatnonzero(flat & edge_on), normals, True, False)
    # the next ring's strip lies on a cone of nearly the same normal; a point of another surface
    # across an edge (or a point without a flat neighbourhood) is not taken
    found = np.abs(np.einsum('ij,ij->i', normals[rows], normals[target])) >= NORMAL_MIN_COS
    return rows[found], target[found]


def _with_copies(points: np.ndarray, viewpoint: np.ndarray) -> GraphNeighbours:
    """:func:`graph_neighbours` of points with exact copies: the graph of the distinct points, each
    copy joined to the first point at its place."""
    n = len(points)
    _, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    distinct = _graph(points[first], merge_copies=False, viewpoint=viewpoint)
    owner = first[inverse]  # the first point at each point's place
    copies = np.flatnonzero(owner != np.arange(n))
    edges = np.concatenate([first[distinct.edges], np.column_stack([owner[copies], copies])])
    return _neighbours(n, edges, None if distinct.normals is None else distinct.normals[inverse])


def _neighbours(n: int, edges: np.ndarray, normals: np.ndarray | None,
                knn: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> GraphNeighbours:
    """The graph form of :class:`Neighbours` from joined pairs ``edges`` (e, 2), in any order, repeats allowed, and
    with ``knn`` (dist, idx (n, k), reach (n,)) each point joined to those of its nearest within its reach and to its
    ALWAYS_JOINED nearest (:func:`_knn_edges_numpy` is the reference of those pairs)."""
    dist, idx, reach = (_NO_DIST, _NO_IDX, _NO_REACH) if knn is None else knn
    if len(idx) not in (0, n) or dist.shape != idx.shape or len(reach) != len(idx) or \
            (idx.size and not 0 <= int(idx.min()) <= int(idx.max()) < n):
        raise ValueError(f'the nearest-neighbour lists must hold a row per point (of {n}) with indices below it')
    unique, indptr, indices, starts = kernels.pair_graph(n, kernels.c_array(edges.reshape(-1, 2), np.int64),
                                                         kernels.c_array(dist, np.float64),
                                                         kernels.c_array(idx, np.int64),
                                                         kernels.c_array(reach, np.float64), ALWAYS_JOINED)
    return GraphNeighbours(n=n, edges=unique, normals=normals, adjacency=(indptr, indices), edge_starts=starts)


def _neighbours_numpy(n: int, edges: np.ndarray, normals: np.ndarray | None) -> GraphNeighbours:
    """:func:`_neighbours` by numpy (the reference)."""
    edges = np.sort(edges, axis=1)  # each joined pair once, smaller index first
    key = np.sort(edges[:, 0] * n + edges[:, 1])  # sorted by source, then destination
    key = key[np.r_[True, key[1:] != key[:-1]][:len(key)]]  # each pair once (numpy 2's np.unique is much slower)
    edges = np.ascontiguousarray(np.stack([key // n, key % n]))  # (2, e): each row contiguous
    both = np.concatenate([edges, edges[::-1]], axis=1)
    order = np.argsort(both[0], kind='stable')
    indptr = row_starts(both[0], n)
    return GraphNeighbours(n=n, edges=edges.T, normals=normals, adjacency=(indptr, both[1][order]))
