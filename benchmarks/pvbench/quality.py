"""Quality beside speed: ground-truth F1, and our planes against Open3D's on the same points.

Every labelling here is over one frame's finite points (the rows xyz_array gives, NaN rows
removed): (n,) int labels, plane index >= 0, -1 unassigned; truth also has -1 for clutter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Ground-truth planes scored per frame: the largest visible ones, as many as planes detected.
TRUE_PLANES = 5
#: A true plane is visible when it holds at least this share of the frame's finite points.
VISIBLE_SHARE = 0.01


def _overlaps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(ka, kb) counts of points labelled i in ``a`` and j in ``b`` (labels < 0 ignored)."""
    ka, kb = int(a.max(initial=-1)) + 1, int(b.max(initial=-1)) + 1
    both = (a >= 0) & (b >= 0)
    flat = np.bincount(a[both] * max(kb, 1) + b[both], minlength=ka * kb)
    return flat.reshape(ka, kb)


def truth_f1(truth: np.ndarray, labels: np.ndarray, count: int = TRUE_PLANES) -> float:
    """Mean F1 over the ``count`` largest visible true planes, each matched to the detected plane
    with the best IoU (F1 0 when no detected plane overlaps it).

    truth: (n,) true plane per point, -1 clutter, -2 hole; labels: (n,) detected plane, -1 none.
    """
    sizes = np.bincount(truth[truth >= 0])
    visible = np.flatnonzero(sizes >= VISIBLE_SHARE * np.count_nonzero(truth > -2))
    chosen = visible[np.argsort(sizes[visible])[::-1][:count]]
    if len(chosen) == 0:
        return math.nan
    found = np.bincount(labels[labels >= 0], minlength=int(labels.max(initial=-1)) + 1)
    inter = _overlaps(truth, labels)
    scores = []
    for j in chosen:
        if inter.shape[1] == 0 or j >= inter.shape[0] or inter[j].max() == 0:
            scores.append(0.0)
            continue
        union = sizes[j] + found - inter[j]
        best = int(np.argmax(inter[j] / np.maximum(union, 1)))
        scores.append(2.0 * inter[j, best] / (sizes[j] + found[best]))
    return float(np.mean(scores))


@dataclass(frozen=True)
class DominantMatch:
    """Open3D's first (dominant) plane against our plane with the best inlier IoU.

    angle_deg: angle between the two normals; iou: of the two inlier sets; ours_rank: the
    extraction index of our matched plane (0 = our dominant plane too)."""

    angle_deg: float
    iou: float
    ours_inliers: int
    open3d_inliers: int
    ours_rank: int


def normal_angle_deg(n1: np.ndarray, n2: np.ndarray) -> float:
    """Angle between two plane normals in degrees, sign-insensitive (0..90)."""
    cos = abs(float(np.dot(n1, n2))) / (np.linalg.norm(n1) * np.linalg.norm(n2))
    return math.degrees(math.acos(min(1.0, cos)))


def match_dominant(ours_labels: np.ndarray, ours_normals: np.ndarray, o3d_labels: np.ndarray,
                   o3d_normals: np.ndarray) -> DominantMatch | None:
    """Match Open3D's plane 0 to our best-IoU plane; None when either found no plane."""
    if len(ours_normals) == 0 or len(o3d_normals) == 0:
        return None
    theirs = o3d_labels == 0
    inter = np.bincount(ours_labels[theirs & (ours_labels >= 0)], minlength=len(ours_normals))
    sizes = np.bincount(ours_labels[ours_labels >= 0], minlength=len(ours_normals))
    iou = inter / np.maximum(sizes + theirs.sum() - inter, 1)
    k = int(np.argmax(iou))
    return DominantMatch(angle_deg=normal_angle_deg(ours_normals[k], o3d_normals[0]), iou=float(iou[k]),
                         ours_inliers=int(sizes[k]), open3d_inliers=int(theirs.sum()), ours_rank=k)
