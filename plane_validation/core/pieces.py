"""One surface found as pieces: pairs of found planes whose points one plane, fitted to both, keeps within t.

A far wall whose grid normals scatter is sometimes found as two or more planes a few degrees apart that do not touch
on the search's sub-grid; each piece is a sound plane, but the true plane is Hoover-correct in neither. Per pair of
planes :func:`coplanar_pairs` fits one plane to both pieces' sampled points (weighted by each piece's size: the
plane a fit to all their points would give) and measures the share of each piece within the segmentation's tolerance
of it (scaled by the noise model at each point, as the verdict's other tests measure), and how balanced the pair is.
Pure numpy, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['PiecePairs', 'coplanar_pairs', 'joint_plane']


@dataclass(frozen=True)
class PiecePairs:
    """Per pair (i, j), i < j, of planes measured: ``first`` (p,) and ``second`` (p,) their indices; ``kept`` (p,)
    the smaller of the two shares of each piece's sampled points within t of their joint plane; ``misfit`` (p,) the
    larger of the two pieces' RMS distance to the joint plane over their RMS distance to their own (1: the joint
    plane fits them as well as their own); ``balance`` (p,) the smaller piece's share of the pair's points (0..0.5)."""

    first: np.ndarray
    second: np.ndarray
    kept: np.ndarray
    misfit: np.ndarray
    balance: np.ndarray


def joint_plane(centres: tuple[np.ndarray, np.ndarray], scatters: tuple[np.ndarray, np.ndarray],
                counts: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(unit normal (3,), a point on it (3,)) of the least-squares plane of two point sets, each given by its
    ``centres`` (3,), its ``scatters`` (3, 3) (sum of outer products of its points about its centre) and its
    ``counts`` of points: the plane a fit to all their points gives."""
    (ca, cb), (sa, sb), (na, nb) = centres, scatters, counts
    centre = (na * ca + nb * cb) / (na + nb)
    d = ca - cb
    # the pooled scatter about the joint centre: each set's own, plus its centre's offset from the joint one
    pooled = sa + sb + (na * nb / (na + nb)) * np.outer(d, d)
    return np.linalg.eigh(pooled)[1][:, 0], centre


def coplanar_pairs(frames: list, scales: list, sizes: np.ndarray, tolerance: float,
                   eligible: np.ndarray) -> PiecePairs:
    """:class:`PiecePairs` of the ``eligible`` (k,) bool planes, from their sampled inliers'
    :func:`.plane_shape.principal_frame` ``frames`` (None: too few points), their :func:`.noise.tolerance_scale`
    ``scales`` (None: constant), their inlier counts ``sizes`` (k,) and the segmentation's ``tolerance`` (m)."""
    ids = [j for j in range(len(frames)) if eligible[j] and frames[j] is not None]
    first, second, kept, misfit, balance = [], [], [], [], []
    for a_pos, a in enumerate(ids):
        for b in ids[a_pos + 1:]:
            first.append(a)
            second.append(b)
            share, worse = _kept(frames[a], frames[b], scales[a], scales[b], float(sizes[a]), float(sizes[b]),
                                 tolerance)
            kept.append(share)
            misfit.append(worse)
            balance.append(min(sizes[a], sizes[b]) / (sizes[a] + sizes[b]))
    return PiecePairs(np.array(first, np.int64), np.array(second, np.int64), np.array(kept, float),
                      np.array(misfit, float), np.array(balance, float))


def _kept(fa, fb, scale_a: np.ndarray | None, scale_b: np.ndarray | None, size_a: float, size_b: float,
          tolerance: float) -> tuple[float, float]:
    """(the smaller share of the two pieces' sampled points within t (times each point's scale) of their joint plane,
    the larger ratio of a piece's RMS distance to it over its RMS distance to its own plane); ``fa``, ``fb``: their
    principal frames (centre, centred sample, eigenvalues, eigenvectors)."""
    (ca, pa, va, _), (cb, pb, vb, _) = fa, fb
    # each sample's scatter scaled to its piece's size: the fit weighs the pieces as all their points would
    normal, centre = joint_plane((ca, cb), (size_a / len(pa) * (pa.T @ pa), size_b / len(pb) * (pb.T @ pb)),
                                 (size_a, size_b))
    shares, ratios = [], []
    for c, part, scale, values in ((ca, pa, scale_a, va), (cb, pb, scale_b, vb)):
        distance = np.abs(part @ normal + (c - centre) @ normal)
        limit = tolerance if scale is None else tolerance * scale
        shares.append(float(np.mean(distance <= limit)))
        own = max(float(values[0]), 0.0) / len(part)  # mean squared distance to its own least-squares plane
        ratios.append(float(np.sqrt(np.mean(distance ** 2) / own)) if own > 0 else np.inf)
    return min(shares), max(ratios)
