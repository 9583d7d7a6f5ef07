"""A frame's rows: the valid points of an N x 3 array or of a PointCloud2's words, in one compiled pass where
the array allows it, with a plain-numpy path for other arrays (and as the kernels' reference)."""
from __future__ import annotations

import numpy as np

from ..core import kernels
from ..core.ransac import AT_VIEWPOINT, check_viewpoint, finite_rows, no_returns_as_nan
from .config import PipelineConfig

__all__ = ['frame_rows', 'marks_as_nan', 'on_rows', 'valid_rows', 'valid_rows_numpy']


def frame_rows(points: np.ndarray | None, words: tuple[np.ndarray, np.ndarray] | None, cfg: PipelineConfig
               ) -> tuple[np.ndarray, int, np.ndarray, np.ndarray, int, float | None]:
    """A frame's rows (N, 3) meters (with ``zero_is_no_return`` its "no return" marks NaN) and how many were marks,
    which rows are valid (N,) bool, they themselves (n, 3), how many other rows have an infinite coordinate, and the
    rows' largest |coordinate| not NaN (None when not found here): of ``points`` (N, 3), else of a PointCloud2's
    float32 ``words`` and x, y, z columns (:func:`~..formats.pointcloud2.xyz_words`) in one compiled pass."""
    if words is not None:
        pts, finite, valid, infinite, marked, largest = kernels.read_rows(*words, check_viewpoint(cfg.viewpoint),
                                                                          AT_VIEWPOINT, cfg.zero_is_no_return)
        return pts, marked, finite, valid, infinite, float(largest)
    pts, no_returns = marks_as_nan(points, cfg.viewpoint) if cfg.zero_is_no_return else (points, 0)
    return (pts, no_returns, *valid_rows(pts), None)


def marks_as_nan(points: np.ndarray, viewpoint) -> tuple[np.ndarray, int]:
    """:func:`~.ransac.no_returns_as_nan`, with the usual frame's answer (no row at the mark: ``points`` as they are)
    found in one compiled pass over a C-ordered float64 array."""
    if points.dtype == np.float64 and points.flags.c_contiguous and points.flags.writeable and \
            kernels.marked_rows(points, check_viewpoint(viewpoint), AT_VIEWPOINT) == 0:
        return points, 0
    return no_returns_as_nan(points, viewpoint)


def on_rows(values: np.ndarray, rows: np.ndarray, fill) -> np.ndarray:
    """Per-point ``values`` (n,) laid out on the N rows of which ``rows`` (N,) bool are the points', ``fill``
    elsewhere."""
    out = np.full(len(rows), fill, values.dtype)
    out[rows] = values
    return out


def valid_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """The rows of ``points`` (N, 3) with three finite coordinates: (which (N,) bool, they themselves (n, 3)), and
    how many other rows have an infinite coordinate: left out as no points, as NaN rows are (REP 117 marks a return
    out of range with +inf and one too close with -inf), and counted. One compiled pass over a C-ordered float64
    array."""
    if points.dtype == np.float64 and points.flags.c_contiguous and points.flags.writeable:
        return kernels.valid_rows(points)
    return valid_rows_numpy(points)


def valid_rows_numpy(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """:func:`valid_rows` in numpy: for other arrays, and the reference its kernel is tested against."""
    finite = finite_rows(points)
    valid = np.compress(finite, points, axis=0)  # much faster than a boolean index
    if len(valid) == len(points):
        return finite, valid, 0
    return finite, valid, int(np.count_nonzero(np.isinf(np.compress(~finite, points, axis=0)).any(axis=1)))
