"""What a connected-regions search runs on: the searched points of a cloud and their neighbourhood
(:class:`SearchGraph`), built once per cloud and reusable across tolerances."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .. import kernels
from ..params import GRID_POINTS, RANSAC_POINTS
from ..regions import VoxelIndex, graph_neighbours, voxel_index
from .checks import as_points, check_search_size, check_shape, check_viewpoint, finite_rows
from .fit import plane_rows
from .grid import grid_image, grid_step
from .grid_build import grid_neighbours
from .neighbours import Neighbours
from .types import Tolerance, Viewpoint

__all__ = ['SearchGraph', 'VoxelNodes', 'search_graph', 'build_search_graph', 'checked_search_graph', 'spread_nearest',
           'spread_nearest_numpy']


@dataclass(frozen=True, eq=False)
class SearchGraph:
    """The points a connected-regions search runs on and their neighbourhood graph.

    search_idx: (m,) rows of the cloud searched; step: the image sub-grid step (0: searched as an
    unorganized cloud, also an image too thin for a grid: :func:`grid_step`);
    center: (3,) meters subtracted before the search; neighbours: their graph; nearest: when the
    search is a sample of an unorganized cloud, which searched point each valid row (ascending) takes its region
    from, the nearest (:class:`VoxelNodes`). It
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
    nearest: VoxelNodes | None = None
    viewpoint: tuple[float, float, float] = (0.0, 0.0, 0.0)
    grid_points: int | None = GRID_POINTS


@dataclass(frozen=True, eq=False)
class VoxelNodes:
    """Which searched point each valid point of an unorganized cloud takes its region from: the nearest one. Found
    through ``index``, a voxel hash of the searched points, in one pass (:func:`.kernels.voxel_nodes`): ``node``
    (n,) a searched point (its position in search_idx) in each point's own voxel, near enough that the nearest lies in
    the 27 voxels around (else the nearest in its voxel), or the nearest of all where ``exact`` (n,) bool; ``voxel``
    (n,) that voxel (-1: none, ``exact``), ``d2`` (n,) the node's squared distance, m^2, ``near`` (n,) bool: the
    nearest lies in the 27 voxels around. Where no searched point of another region can lie as near in those voxels,
    the node's region is the nearest's, so only the others need a nearest-point query (:meth:`for_regions`); ``node``
    and ``exact`` cache those answers across the calls of a tolerance sweep. ``index`` None: every node is the nearest
    (far-out coordinates)."""

    index: VoxelIndex | None
    node: np.ndarray
    voxel: np.ndarray
    d2: np.ndarray
    near: np.ndarray
    exact: np.ndarray

    def for_regions(self, region: np.ndarray, pts: np.ndarray, rows: np.ndarray, center: np.ndarray) -> np.ndarray:
        """(n,) for each of the valid rows ``rows`` of ``pts`` (N, 3) meters a searched point in the region
        (``region`` (m,) of the searched points, -1: none) of the searched point nearest to it (less ``center``
        (3,))."""
        if self.index is None:
            return self.node
        index, c_array = self.index, kernels.c_array
        doubt = np.flatnonzero(kernels.uncertain_nodes(
            c_array(region, np.int64), self.node, self.d2, self.voxel, self.near, self.exact, c_array(pts, np.float64),
            c_array(rows, np.int64), c_array(center, np.float64), index.ordered, *index.grid, index.origin, index.cell,
            index.dims))
        if len(doubt):  # kept: later calls on this graph (a sweep over one prebuilt graph) need not ask again
            queries = kernels.rows_less(c_array(pts, np.float64), rows[doubt], center)
            self.node[doubt] = index.query(queries, 1)[1][:, 0]
            self.exact[doubt] = True
        return self.node


def search_graph(points: np.ndarray, shape: tuple[int, int] | None = None,
                 ransac_points: int | None = RANSAC_POINTS, rng: np.random.Generator | None = None,
                 viewpoint: Viewpoint = None, grid_points: int | None = GRID_POINTS) -> SearchGraph | None:
    """The :class:`SearchGraph` of ``points`` (N, 3) meters seen from ``viewpoint`` (as in
    :func:`detect_planes`). An image (``shape``) of more than ``grid_points`` valid pixels is searched on a
    regular sub-grid of about that many; an unorganized cloud of more than ``ransac_points`` valid points is
    searched on a random sample drawn from ``rng``; without ``rng`` such a cloud has no fixed graph
    and None is returned."""
    pts = as_points(points)
    check_search_size('ransac_points', ransac_points)
    check_search_size('grid_points', grid_points)
    return build_search_graph(pts, finite_rows(pts), None if shape is None else check_shape(shape, len(pts)),
                              ransac_points, rng, check_viewpoint(viewpoint), grid_points)


def checked_search_graph(graph: SearchGraph | None, pts: np.ndarray, finite: np.ndarray, shape: tuple[int, int] | None,
                         ransac_points: int | None, rng: np.random.Generator, viewpoint: np.ndarray,
                         grid_points: int | None) -> SearchGraph:
    """``graph`` when it was built for these checked points ``pts`` (finite rows ``finite`` (N,)), ``shape``,
    ``ransac_points``, ``grid_points`` and ``viewpoint`` (3,), else ValueError; None: built here, from ``rng``."""
    n_valid = int(np.count_nonzero(finite))
    if graph is None:
        return build_search_graph(pts, finite, shape, ransac_points, rng, viewpoint, grid_points)
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
    return graph


def build_search_graph(pts: np.ndarray, finite: np.ndarray, shape: tuple[int, int] | None, ransac_points: int | None,
                       rng: np.random.Generator | None, viewpoint: np.ndarray, grid_points: int | None
                       ) -> SearchGraph | None:
    """:func:`search_graph` of checked points ``pts`` with their finite rows ``finite`` (N,)."""
    n_valid = int(np.count_nonzero(finite))
    step = 0 if shape is None else grid_step(shape, n_valid, grid_points)
    stride = max(1, n_valid // 1024)
    valid_idx = None if step else np.flatnonzero(finite)  # a sub-grid's search needs only every stride-th of them
    centred = kernels.strided_rows(kernels.c_array(finite, bool), n_valid, stride) if step else valid_idx[::stride]
    center = np.median(pts[centred], axis=0) if n_valid else np.zeros(3)
    nearest = None
    if step:
        grid, pixels = grid_image(pts, finite, shape, step)
        neighbours = grid_neighbours(grid - viewpoint if viewpoint.any() else grid, pixels >= 0)  # sensor ranges
        search_idx = pixels.reshape(-1).take(neighbours.pixel)
    else:  # unorganized, or an image too thin for a 2-D grid
        search_idx = valid_idx
        if ransac_points is not None and n_valid > ransac_points:
            if rng is None:
                return None
            search_idx = valid_idx[np.sort(rng.choice(n_valid, int(ransac_points), replace=False))]
        searched = kernels.rows_less(kernels.c_array(pts, np.float64), search_idx, center)
        index = None
        if len(search_idx) < n_valid:
            nearest, index = _nearest_searched(searched, pts, valid_idx, center)
        neighbours = graph_neighbours(searched, viewpoint=viewpoint - center, index=index)
    return SearchGraph(n_points=len(pts), search_idx=search_idx, step=step, center=center, neighbours=neighbours,
                       shape=shape, ransac_points=ransac_points, n_valid=n_valid, nearest=nearest,
                       viewpoint=tuple(viewpoint.tolist()), grid_points=grid_points)


def _nearest_searched(searched: np.ndarray, cloud: np.ndarray, rows: np.ndarray, center: np.ndarray
                      ) -> tuple[VoxelNodes, VoxelIndex | None]:
    """The :class:`VoxelNodes` of the points ``cloud[rows] - center`` (``cloud`` (N, 3) meters, ``rows`` (n,),
    ``center`` (3,)) among ``searched`` (m, 3) and the voxel index of ``searched`` they use (None for far-out
    coordinates: then every node is the nearest, by a kd-tree)."""
    every = cloud if len(rows) == len(cloud) else cloud[rows]  # all valid: no copy
    lo, hi = kernels.coordinate_bounds(kernels.c_array(every, np.float64))
    # the bounds of every - center, that array not built (rounding is monotonic)
    index = voxel_index(searched, span=(lo - center, hi - center))
    if index is None:
        node = _nearest_searched_tree(searched, every - center)
        none = np.zeros(len(node), bool)
        return VoxelNodes(None, node, np.full(len(node), -1), np.zeros(len(node)), none, ~none), None
    node, voxel, d2, near = kernels.voxel_nodes(index.ordered, *index.grid, index.origin, index.cell, index.dims,
                                                kernels.c_array(cloud, np.float64), kernels.c_array(rows, np.int64),
                                                kernels.c_array(center, np.float64))
    exact = voxel < 0  # no searched point in its voxel: the nearest, now
    alone = np.flatnonzero(exact)
    if len(alone):
        queries = kernels.rows_less(kernels.c_array(cloud, np.float64), rows[alone], center)
        node[alone] = index.query(queries, 1)[1][:, 0]
    return VoxelNodes(index, node, voxel, d2, near, exact), index


def _nearest_searched_tree(searched: np.ndarray, points: np.ndarray) -> np.ndarray:
    """:func:`_nearest_searched` by scipy's kd-tree (the reference)."""
    return cKDTree(searched).query(points, k=1)[1]


def spread_nearest(pts: np.ndarray, rows: np.ndarray, center: np.ndarray, nearest: np.ndarray, region: np.ndarray,
                   found: list, tolerance: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Labels (N,) of ``pts`` (N, 3) meters: each of ``rows`` (n,) takes the region of its nearest searched point
    (``nearest`` (n,): its position among the searched points, ``region`` their regions) when within ``tolerance``
    (scalar or (n,)) of that region's plane (``found``: (normal, offset) about ``center`` (3,)); -1 otherwise. Also the
    distance (N,) to the plane of each point's label, inf where none. One compiled pass
    (:func:`.kernels.spread_nearest`; :func:`spread_nearest_numpy` is its reference)."""
    planes = plane_rows(found)
    return kernels.spread_nearest(kernels.c_array(pts, np.float64), kernels.c_array(rows, np.int64),
                                  kernels.c_array(center, np.float64), kernels.c_array(nearest, np.int64),
                                  kernels.c_array(region, np.int64), planes,
                                  kernels.c_array(np.reshape(tolerance, -1), np.float64))


def spread_nearest_numpy(points: np.ndarray, nearest: np.ndarray, region: np.ndarray, found: list,
                         tolerance: Tolerance) -> np.ndarray:
    """:func:`spread_nearest`'s labels of the points ``points`` (n, 3), less the center, in numpy (the reference)."""
    lab = region[nearest]
    normals = np.array([n for n, _ in found])
    offsets = np.array([d for _, d in found])
    j = np.where(lab >= 0, lab, 0)
    dist = np.abs(np.einsum('ij,ij->i', points, normals[j]) + offsets[j])
    return np.where((lab >= 0) & (dist <= tolerance), lab, -1).astype(np.int32)
