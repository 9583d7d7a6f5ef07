"""Segmentation quality against per-point ground truth: point F1 after one-to-one matching, the
Hoover et al. (1996) region counts, and the matched planes' angle errors. Pure numpy/scipy.

Hoover et al., "An experimental comparison of range image segmentation algorithms", PAMI 1996:
with overlap threshold T, a detected region D and a true region G with |D n G| >= T|D| and
>= T|G| are a *correct* detection; a true region covered (>= T) by several detected regions, each
mostly (>= T) inside it, is *over-segmented*; a detected region covering (>= T) several true ones,
each mostly (>= T) inside it, is an *under-segmentation*; true regions in none of these are
*missed*, detected ones *noise*.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

__all__ = ['Quality', 'segmentation_quality', 'HOOVER_OVERLAP', 'miss_cause', 'MissCause']

#: Hoover's overlap threshold T.
HOOVER_OVERLAP = 0.8


@dataclass(frozen=True)
class Quality:
    """precision, recall, f1: of the points on true planes, after one-to-one matching of detected
    to true planes by overlap; correct, over, under, missed, noise: Hoover counts (regions);
    angle_deg: median angle between matched detected and true plane normals (NaN without)."""

    precision: float
    recall: float
    f1: float
    correct: int
    over: int
    under: int
    missed: int
    noise: int
    true_planes: int
    detected: int
    angle_deg: float


def _overlaps(pred: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(counts (d, g) of points in detected d and true g, sizes of d (d,), sizes of g (g,))."""
    d, g = int(pred.max(initial=-1)) + 1, int(truth.max(initial=-1)) + 1
    both = (pred >= 0) & (truth >= 0)
    counts = np.bincount(pred[both] * g + truth[both], minlength=d * g).reshape(d, g).astype(float)
    return counts, np.bincount(pred[pred >= 0], minlength=d).astype(float), \
        np.bincount(truth[truth >= 0], minlength=g).astype(float)


def _hoover(counts: np.ndarray, dsize: np.ndarray, gsize: np.ndarray, t: float) -> tuple[int, int, int, int, int]:
    d, g = counts.shape
    used_d, used_g = np.zeros(d, bool), np.zeros(g, bool)
    correct = 0
    ok = (counts >= t * dsize[:, None]) & (counts >= t * gsize[None, :]) & (counts > 0)
    for i, j in zip(*np.nonzero(ok)):
        if not used_d[i] and not used_g[j]:
            used_d[i] = used_g[j] = True
            correct += 1
    inside_g = counts >= t * dsize[:, None]   # detected i mostly inside true j
    inside_d = counts >= t * gsize[None, :]   # true j mostly inside detected i
    over = 0
    for j in np.flatnonzero(~used_g):
        parts = np.flatnonzero(inside_g[:, j] & ~used_d & (counts[:, j] > 0))
        if len(parts) >= 2 and counts[parts, j].sum() >= t * gsize[j]:
            used_d[parts] = True
            used_g[j] = True
            over += 1
    under = 0
    for i in np.flatnonzero(~used_d):
        parts = np.flatnonzero(inside_d[i, :] & ~used_g & (counts[i, :] > 0))
        if len(parts) >= 2 and counts[i, parts].sum() >= t * dsize[i]:
            used_g[parts] = True
            used_d[i] = True
            under += 1
    missed = int(np.count_nonzero(~used_g & (gsize > 0)))
    return correct, over, under, missed, int(np.count_nonzero(~used_d & (dsize > 0)))


def segmentation_quality(pred: np.ndarray, truth: np.ndarray, *, points: np.ndarray | None = None,
                         pred_planes: np.ndarray | None = None, overlap: float = HOOVER_OVERLAP) -> Quality:
    """Score detected labels ``pred`` (N,) against true labels ``truth`` (N,) (-1: none in both).

    Precision is over all detected points (a plane that takes clutter pays for it), recall over
    the points of true planes. ``points`` (N, 3) and ``pred_planes`` (d, 4) give the angle errors (the true planes
    are fitted to their points).
    """
    pred = np.asarray(pred).astype(np.int64).reshape(-1)
    truth = np.asarray(truth).astype(np.int64).reshape(-1)
    if len(pred) != len(truth):
        raise ValueError(f'{len(pred)} detected labels for {len(truth)} true labels')
    counts, dsize, gsize = _overlaps(pred, truth)
    matched = 0.0
    pairs: list[tuple[int, int]] = []
    if counts.size:
        # imported here: scipy.optimize takes 0.1-0.2 s to import and a node's first frame does not use it
        from scipy.optimize import linear_sum_assignment
        rows, cols = linear_sum_assignment(-counts)
        keep = counts[rows, cols] > 0
        pairs = list(zip(rows[keep], cols[keep]))
        matched = float(counts[rows, cols][keep].sum())
    precision = matched / dsize.sum() if dsize.sum() else 0.0
    recall = matched / gsize.sum() if gsize.sum() else 0.0
    f1 = 2 * precision * recall / (precision + recall) if precision + recall else 0.0
    correct, over, under, missed, noise = _hoover(counts, dsize, gsize, overlap)
    angle = float('nan')
    if points is not None and pred_planes is not None and pairs:
        angles = []
        for i, j in pairs:
            true_pts = points[truth == j]
            true_pts = true_pts[np.isfinite(true_pts).all(axis=1)]
            if len(true_pts) < 3:
                continue
            centered = true_pts - true_pts.mean(axis=0)
            normal = np.linalg.eigh(centered.T @ centered)[1][:, 0]
            cos = abs(float(normal @ pred_planes[i, :3]) / np.linalg.norm(pred_planes[i, :3]))
            angles.append(np.degrees(np.arccos(min(1.0, cos))))
        angle = float(np.median(angles)) if angles else float('nan')
    return Quality(precision=precision, recall=recall, f1=f1, correct=correct, over=over, under=under, missed=missed,
                   noise=noise, true_planes=int(np.count_nonzero(gsize)), detected=int(np.count_nonzero(dsize)),
                   angle_deg=angle)


class MissCause(enum.Enum):
    """Why a true plane was not matched (:func:`miss_cause`), in the order they are tested."""

    SMALL = 'small'
    MERGED = 'merged'
    SPLIT = 'split'
    UNASSIGNED = 'unassigned'
    ABSORBED = 'absorbed'
    PARTIAL = 'partial'


#: A detected plane that takes at least this share of a true plane's points is one of its pieces (split) when most of
#: its own points (MISS_PIECE_OWN) are that plane's.
MISS_PIECE = 0.1
MISS_PIECE_OWN = 0.5


def miss_cause(truth: np.ndarray, labels: np.ndarray, plane: int, min_inliers: int) -> MissCause:
    """Why the true plane ``plane`` of ``truth`` (N,) is not matched by the detected ``labels`` (N,) (both -1:
    none): SMALL it has fewer points than the search's ``min_inliers`` (no t finds it);
    MERGED one detected plane holds HOOVER_OVERLAP of it, but it is less than that share of that plane (other
    surfaces found with it); SPLIT two or more detected planes each hold MISS_PIECE of it and are mostly
    (MISS_PIECE_OWN) made of it; UNASSIGNED half of it or more is in no plane; ABSORBED the plane that took most
    of it is mostly another true plane's; else PARTIAL (its own plane holds less than HOOVER_OVERLAP of it, the rest
    spread)."""
    truth = np.asarray(truth).reshape(-1)
    labels = np.asarray(labels).reshape(-1)
    if len(truth) != len(labels):
        raise ValueError(f'{len(labels)} detected labels for {len(truth)} true labels')
    on = truth == plane
    size = int(np.count_nonzero(on))
    if size < min_inliers:
        return MissCause.SMALL
    found = labels[on]
    ids, counts = np.unique(found[found >= 0], return_counts=True)
    if not len(ids) or np.mean(found < 0) >= 0.5:
        return MissCause.UNASSIGNED
    top = int(ids[np.argmax(counts)])
    top_size = int(np.count_nonzero(labels == top))
    if counts.max() >= HOOVER_OVERLAP * size and counts.max() < HOOVER_OVERLAP * top_size:
        return MissCause.MERGED
    sizes = np.array([np.count_nonzero(labels == d) for d in ids])
    if np.count_nonzero((counts >= MISS_PIECE * size) & (counts >= MISS_PIECE_OWN * sizes)) >= 2:
        return MissCause.SPLIT
    owners = np.bincount(truth[(labels == top) & (truth >= 0)], minlength=plane + 1)
    return MissCause.ABSORBED if owners.argmax() != plane else MissCause.PARTIAL
