"""Plane quality beside speed: ground-truth F1 and agreement between two detectors."""
from __future__ import annotations

import numpy as np

#: True planes smaller than this share of a frame's valid points are left out of the F1 (a
#: detector that stops at min_inliers cannot be asked to find them).
MIN_TRUE_SHARE = 0.02


def truth_f1(truth: np.ndarray, labels: np.ndarray) -> float:
    """Mean over the true planes of the best F1 any detected plane reaches on it.

    truth: (n,) true plane per point (-1 clutter, -2 hole); labels: (n,) detected plane per point
    (-1 none). Only true planes holding at least MIN_TRUE_SHARE of the valid points count.
    """
    valid = truth > -2
    n_valid = int(valid.sum())
    scores = []
    for j in np.unique(truth[truth >= 0]):
        is_true = truth == j
        size = int(is_true.sum())
        if size < MIN_TRUE_SHARE * n_valid:
            continue
        found = labels[is_true]
        best = 0.0
        for k in np.unique(found[found >= 0]):
            tp = int((found == k).sum())
            precision, recall = tp / int((labels == k).sum()), tp / size
            best = max(best, 2 * precision * recall / (precision + recall))
        scores.append(best)
    return float(np.mean(scores)) if scores else float('nan')


def angle_deg(n1: np.ndarray, n2: np.ndarray) -> float:
    """Angle between two plane normals (sign-free), degrees."""
    cos = abs(float(np.dot(n1, n2)) / (np.linalg.norm(n1) * np.linalg.norm(n2)))
    return float(np.degrees(np.arccos(min(1.0, cos))))


def matched_dominant(reference: np.ndarray, planes: np.ndarray, max_offset: float = 0.05) -> tuple[float, int]:
    """(angle in degrees, index) of the plane in ``planes`` (k, 4) closest to ``reference`` (4,),
    among those whose offsets agree within ``max_offset`` m after aligning the normals; the
    closest by angle when none does. Unit normals assumed."""
    best = (float('inf'), -1)
    fallback = (float('inf'), -1)
    for k, plane in enumerate(planes):
        sign = 1.0 if plane[:3] @ reference[:3] >= 0 else -1.0
        angle = angle_deg(plane[:3], reference[:3])
        fallback = min(fallback, (angle, k))
        if abs(sign * plane[3] - reference[3]) <= max_offset:
            best = min(best, (angle, k))
    return best if best[1] >= 0 else fallback
