"""What one frame produced (:class:`FrameResult`), its diagnostic's key-values, and the result of a frame
that failed."""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass, replace

import numpy as np

from ..core import kernels
from ..core.indices import ValidityIndices
from ..core.noise import noise_coefficient
from ..core.ransac import Segmentation, finite_rows
from .config import PipelineConfig
from .diagnostics import Diagnostic, Level, fmt

__all__ = ['FrameResult', 'by_track_id', 'frame_values', 'failed_result']


@dataclass(frozen=True, eq=False)
class FrameResult:
    """What one frame produced. points: (n, 3) valid points (before any voxel grid), labels:
    (n,) int32 for them; diagnostic: level, message and key-values to publish."""

    points: np.ndarray
    labels: np.ndarray
    segmentation: Segmentation | None
    indices: ValidityIndices | None
    tolerance: float
    tolerance_source: str
    diagnostic: Diagnostic
    seconds: float
    plane_counts: tuple[int, ...] = ()  # labelled points per plane (input points, also with voxels)
    organized: np.ndarray | None = None  # all (H * W, 3) rows of an organized input
    shape: tuple[int, int] | None = None  # its (H, W)
    ring_image: tuple[np.ndarray, tuple[int, int]] | None = None  # a scan laid out by rings: (H * W, 3), (H, W)
    clock: float = 0.0  # the frame's time for retune timing, s: its header stamp (see FROZEN_FRAME_S); 0 when failed
    plane_ids: tuple[int, ...] = ()  # each plane's track id (PlaneTracker), ascending: the planes are in this order
    obstacles: np.ndarray | None = None  # (n,) bool: which points are obstacles (app/obstacles.py)
    image_shape: tuple[int, int] | None = None  # (H, W) of an organized input (``organized`` holds its rows)
    image_labels: np.ndarray | None = None  # (H * W,) int32 ``labels`` on the rows of ``organized`` (-1: no point)

    def as_image(self, values: np.ndarray, fill) -> np.ndarray:
        """Per-point ``values`` (n, ...) laid out on the input's H * W rows (``fill`` where a pixel
        had no valid point); requires ``image_shape``."""
        full = np.full((len(self.organized),) + values.shape[1:], fill, dtype=values.dtype)
        full[self._valid_rows] = values
        return full

    @functools.cached_property
    def _valid_rows(self) -> np.ndarray:
        """The rows of ``organized`` that hold the valid points, ascending (found once: every organized output
        lays its values out on them)."""
        return np.flatnonzero(finite_rows(self.organized))

    @property
    def sweep_cloud(self) -> tuple[np.ndarray, tuple[int, int] | None]:
        """What a retune after this frame sweeps: (points, shape), the image of an organized input or of
        a ring-laid scan, else the valid points."""
        if self.shape:
            return self.organized, self.shape
        return self.ring_image if self.ring_image is not None else (self.points, None)

    @property
    def n_planes(self) -> int:
        return 0 if self.segmentation is None else self.segmentation.n_planes

    @property
    def level(self) -> Level:
        return self.diagnostic.level

    @property
    def message(self) -> str:
        return self.diagnostic.message

    @property
    def values(self) -> tuple[tuple[str, str], ...]:
        return self.diagnostic.values


def by_track_id(seg: Segmentation, labels: np.ndarray, ids: tuple[int, ...], finite: np.ndarray | None = None
                ) -> tuple[Segmentation, np.ndarray, tuple]:
    """The segmentation and the labels with the planes in ascending track id order, and those ids. ``finite``: the
    rows of an organized frame whose ``seg.labels`` are ``labels`` (both renumbered in one compiled pass)."""
    order = np.argsort(ids, kind='stable')
    if np.all(order == np.arange(len(ids))):
        return seg, labels, tuple(ids)
    rank = np.empty(len(ids) + 1, np.int32)
    rank[order], rank[-1] = np.arange(len(ids)), -1  # label -1 (taking the last entry) stays -1
    if finite is not None:
        renumbered, labels = kernels.relabel_rows(kernels.c_array(seg.labels, np.int32), finite, rank)
    else:  # (take wraps -1 round to the last entry, as an index does, in half the time)
        renumbered, labels = np.take(rank, seg.labels, mode='wrap'), np.take(rank, labels, mode='wrap')
    seg = replace(seg, planes=tuple(seg.planes[k] for k in order), labels=renumbered)
    return seg, labels, tuple(int(ids[k]) for k in order)


def frame_values(cfg: PipelineConfig, tolerance: float, source: str, n_input: int, n_valid: int,
                 left_out: tuple[int, int], n_unassigned: int, seg: Segmentation, counts: np.ndarray,
                 scores: ValidityIndices, noise: float, work: np.ndarray, ids: tuple[int, ...]
                 ) -> tuple[tuple[str, str], ...]:
    """The diagnostic's key-values of a frame with planes (``counts``: labelled points per plane; ``work``: the
    points the search ran on, (m, 3) meters; ``ids``: each plane's track id)."""
    values = [('tolerance', fmt(tolerance)), ('tolerance_source', source), ('criterion', cfg.criterion),
              ('planes', str(seg.n_planes)), ('input_points', str(n_input)), ('valid_points', str(n_valid)),
              ('no_return_points', str(left_out[0])), ('infinite_points', str(left_out[1])),
              ('unassigned_points', str(n_unassigned)),
              ('dunn', fmt(scores.dunn)), ('davies_bouldin', fmt(scores.davies_bouldin)),
              ('gs', fmt(scores.gs)), ('gs_se', fmt(scores.gs_se)),
              ('gs_planes', fmt(scores.gs_planes)), ('gs_planes_se', fmt(scores.gs_planes_se)),
              ('silhouette', fmt(scores.silhouette)), ('silhouette_se', fmt(scores.silhouette_se)),
              ('plane_silhouette', fmt(scores.plane_silhouette)),
              ('index_sample_size', str(scores.sample_size)), ('dunn_db_points', str(scores.separation_size)),
              ('noise_model', seg.noise_model), ('noise_estimate', fmt(noise)),
              ('stop_reason', seg.reason), ('plane_ids', ' '.join(map(str, ids)))]
    if any(cfg.viewpoint):
        values.append(('viewpoint', ' '.join(fmt(c) for c in cfg.viewpoint)))
    if seg.noise_model == 'depth_quadratic':  # sigma(r) = c r^2
        values.append(('noise_coefficient', fmt(noise_coefficient(work, seg.labels, seg.coefficients,
                                                                  seg.viewpoint))))
    for k, plane in enumerate(seg.planes):  # keyed by track id
        values += [(f'plane_{ids[k]}_inliers', str(int(counts[k]))), (f'plane_{ids[k]}_rms', fmt(plane.rms))]
    return tuple(values)


def failed_result(level: Level, message: str, start: float, tol: tuple[float, str], *,
                  n_input: int = 0, n_valid: int = 0) -> FrameResult:
    """A frame without planes: ``level`` and ``message`` say why; ``start``: its perf_counter start, s; ``tol``:
    the tolerance (m) and its source."""
    values = (('tolerance', fmt(tol[0])), ('tolerance_source', tol[1]), ('planes', '0'),
              ('input_points', str(n_input)), ('valid_points', str(n_valid)))
    seconds = time.perf_counter() - start
    return FrameResult(points=np.empty((0, 3)), labels=np.empty(0, np.int32), segmentation=None, indices=None,
                       tolerance=tol[0], tolerance_source=tol[1],
                       diagnostic=Diagnostic(level, message, values + (('processing_ms', f'{1000 * seconds:.1f}'),)),
                       seconds=seconds)
