"""The points on no plane (obstacles), optionally without those near the ground. No ROS import."""
from __future__ import annotations

import numpy as np

from ..core.ransac import Segmentation

__all__ = ['GROUND_MAX_TILT_DEG', 'ground_plane', 'obstacle_mask']

#: A plane is horizontal when its normal lies within this angle of the up direction (degrees).
GROUND_MAX_TILT_DEG = 20.0


def ground_plane(seg: Segmentation, counts: tuple[int, ...] | np.ndarray,
                 up: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> int | None:
    """Index of the horizontal plane (normal within GROUND_MAX_TILT_DEG of ``up``, any length but 0) with the most
    labelled points (``counts``, one per plane), or None when no plane is horizontal."""
    axis = np.asarray(up, float)
    if not axis.any():
        raise ValueError(f'the up direction must not be (0, 0, 0), got {up!r}')
    axis = axis / np.abs(axis).max()  # scaled first: the squares of a tiny vector's parts underflow to a length 0
    axis = axis / np.linalg.norm(axis)
    cos = np.cos(np.radians(GROUND_MAX_TILT_DEG))
    horizontal = [k for k, p in enumerate(seg.planes) if abs(float(p.normal @ axis)) >= cos]
    return max(horizontal, key=lambda k: (counts[k], -k)) if horizontal else None


def obstacle_mask(points: np.ndarray, labels: np.ndarray, seg: Segmentation | None,
                  counts: tuple[int, ...] | np.ndarray = (), ground_margin: float = 0.0,
                  up: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> np.ndarray:
    """(n,) bool: which of ``points`` (n, 3) m, labelled ``labels`` (n,) (-1 on no plane), are obstacles:
    on no plane, and with ``ground_margin`` > 0 (m) also farther than it from the largest horizontal plane
    (the ground, its normal near ``up``: see :func:`ground_plane`)."""
    mask = labels < 0
    if seg is None or ground_margin <= 0 or not mask.any():
        return mask
    ground = ground_plane(seg, counts, up)
    if ground is not None:
        a, b, c, d = seg.coefficients[ground]
        idx = np.flatnonzero(mask)
        near = np.abs(points[idx] @ np.array([a, b, c]) + d) <= ground_margin
        mask[idx[near]] = False
    return mask
