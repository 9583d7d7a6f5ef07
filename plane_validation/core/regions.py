"""Which points touch: the neighbourhood graph that splits a plane's inliers into connected regions.

A plane is a connected planar region (after Schnabel, Wahl and Klein 2007, who score a candidate by
its largest connected component). :class:`Neighbours` is built once per detection on the searched
points; :meth:`Neighbours.components` then labels the connected components of any subset.

* Organized clouds (an H x W image): neighbours on the image grid (4-connected), except across a
  depth jump: two pixels whose 3-D distance exceeds ``JUMP`` typical pixel spacings at their range
  are on different surfaces, and a pixel at such a jump joins no region (its full-resolution
  neighbours are labelled afterwards from the regions around them). Components come from
  ``scipy.ndimage.label``.
* Unorganized clouds: each point's ``NEIGHBOURS`` nearest neighbours within ``RADIUS`` median
  neighbour spacings (scipy's kd-tree), components by ``scipy.sparse.csgraph``.
Pure numpy/scipy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

__all__ = ['Neighbours', 'grid_neighbours', 'graph_neighbours', 'JUMP', 'NEIGHBOURS', 'RADIUS']

#: Grid neighbours farther apart than this many typical pixel spacings (at their range) are not
#: joined: a depth jump. Generous, since a surface seen at a grazing angle has stretched pixels.
JUMP = 8.0
#: Unorganized clouds: each point is joined to up to this many nearest neighbours ...
NEIGHBOURS = 10
#: ... that lie within this many median k-th-neighbour distances.
RADIUS = 2.0


@dataclass(frozen=True, eq=False)
class Neighbours:
    """Adjacency of n points. Grid form: ``shape`` (h, w) with point i at flat pixel ``pixel[i]``,
    ``usable`` (h * w,) the pixels that may join a region (valid, at no depth jump); graph form:
    ``edges`` (e, 2) point pairs."""

    n: int
    shape: tuple[int, int] | None = None
    pixel: np.ndarray | None = None
    usable: np.ndarray | None = None
    edges: np.ndarray | None = None

    def components(self, mask: np.ndarray) -> tuple[np.ndarray, int]:
        """Connected components of the points where ``mask`` (n,) is True: (labels (n,) int, -1
        outside the mask, components 0..c-1; c)."""
        if self.shape is not None:
            return self._grid_components(mask)
        inside = self.edges[mask[self.edges[:, 0]] & mask[self.edges[:, 1]]]
        graph = coo_matrix((np.ones(len(inside), np.int8), (inside[:, 0], inside[:, 1])), shape=(self.n, self.n))
        _, labels = connected_components(graph, directed=False)
        labels = np.where(mask, labels, -1)
        ids, dense = np.unique(labels[mask], return_inverse=True)
        out = np.full(self.n, -1, dtype=np.int64)
        out[mask] = dense
        return out, len(ids)

    def _grid_components(self, mask: np.ndarray) -> tuple[np.ndarray, int]:
        image = np.zeros(self.shape[0] * self.shape[1], bool)
        image[self.pixel[mask]] = True
        image &= self.usable
        labelled, count = ndimage.label(image.reshape(self.shape))
        return labelled.reshape(-1)[self.pixel] - 1, count

    def largest(self, mask: np.ndarray) -> np.ndarray:
        """(n,) bool: the largest connected component of ``mask`` (empty when ``mask`` is)."""
        labels, count = self.components(mask)
        if count == 0:
            return np.zeros(self.n, bool)
        sizes = np.bincount(labels[labels >= 0], minlength=count)
        return labels == int(np.argmax(sizes))


def grid_neighbours(image_points: np.ndarray, valid: np.ndarray) -> Neighbours:
    """Neighbours of the valid pixels of an (h, w, 3) image of points (meters; the sensor at the
    origin). Points are numbered in row-major order of the valid pixels ``valid`` (h, w)."""
    h, w = valid.shape
    rng_ = np.linalg.norm(np.where(valid[..., None], image_points, 0.0), axis=-1)

    def ok(a: np.ndarray, b: np.ndarray, va: np.ndarray, vb: np.ndarray, ra: np.ndarray, rb: np.ndarray):
        both = va & vb
        gap = np.linalg.norm(np.where(both[..., None], a - b, 0.0), axis=-1)
        scale = np.maximum(np.maximum(ra, rb), 1e-12)
        angular = gap / scale  # pixel spacing relative to range
        typical = np.median(angular[both]) if both.any() else 0.0
        return both & (angular <= JUMP * typical)

    right_ok = ok(image_points[:, :-1], image_points[:, 1:], valid[:, :-1], valid[:, 1:], rng_[:, :-1], rng_[:, 1:])
    down_ok = ok(image_points[:-1], image_points[1:], valid[:-1], valid[1:], rng_[:-1], rng_[1:])
    # a jump is an edge between two valid pixels that is not ok; both its pixels are unusable
    jump_r = valid[:, :-1] & valid[:, 1:] & ~right_ok
    jump_d = valid[:-1] & valid[1:] & ~down_ok
    usable = valid.copy()
    usable[:, :-1] &= ~jump_r
    usable[:, 1:] &= ~jump_r
    usable[:-1] &= ~jump_d
    usable[1:] &= ~jump_d
    pixel = np.flatnonzero(valid.reshape(-1))
    return Neighbours(n=len(pixel), shape=(h, w), pixel=pixel, usable=usable.reshape(-1))


def graph_neighbours(points: np.ndarray) -> Neighbours:
    """Neighbours of unorganized (n, 3) points: each joined to its NEIGHBOURS nearest within
    RADIUS median NEIGHBOURS-th-neighbour distances."""
    n = len(points)
    k = min(NEIGHBOURS + 1, n)
    if k < 2:
        return Neighbours(n=n, edges=np.empty((0, 2), np.int64))
    dist, idx = cKDTree(points).query(points, k=k)
    reach = RADIUS * float(np.median(dist[:, -1]))
    near = dist[:, 1:] <= reach
    rows = np.repeat(np.arange(n), k - 1).reshape(n, k - 1)
    edges = np.column_stack([rows[near], idx[:, 1:][near]])
    return Neighbours(n=n, edges=edges)
