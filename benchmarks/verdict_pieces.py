"""One surface found as pieces over the tuning seeds and the real frames: per scene the pairs of found planes whose
joint plane keeps most of each piece within t, against good / not good and the verdict.

A far wall is sometimes found as two or more planes a few degrees apart that do not touch on the search's sub-grid;
each piece is a sound plane, but the true plane is Hoover-correct in neither. Per pair of planes, :func:`coplanar_pairs`
fits one plane to both pieces' sampled points (weighted by each piece's size: the plane a fit to all their points
would give) and measures the share of each piece within the segmentation's tolerance of it (scaled by the noise model
at each point, as the verdict's other tests measure), the pieces' RMS distance to it over their own, and how balanced
the pair is. Tried as verdict evidence and dropped (benchmarks/README.md, "Tried and dropped", issue 38).

Reads the detections benchmarks/verdict_seeds.py cached (--cache; scenes not cached yet are skipped), and runs the
real frames (the .pcd files beside --gt) through FramePipeline at its defaults (the node's: the verdict judge sees,
recorded) and through tune_tolerance as benchmarks/verdict.py does. Writes every pair's numbers to --out (a pickle)
and prints, per variant of the test (keep, misfit, the pair's share of the planes' points) and group of scenes, how
many scenes have a pair reaching each balance.

Only tuning seeds: choose the limits here; the held-out split is for quality.py's report.

Run: .venv/bin/python benchmarks/verdict_pieces.py --indoor 0-40 --lidar 0-39 --roofs 0-99 --gt DIR --cache DIR
         [--out FILE] [--no-frames]
"""
from __future__ import annotations

import argparse
import pickle
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402
import verdict_seeds  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.app import pipeline  # noqa: E402
from plane_validation.core import kernels  # noqa: E402
from plane_validation.core.ransac import as_points  # noqa: E402
from plane_validation.core.scoring import segmentation_quality  # noqa: E402
from plane_validation.core.verdict import MIN_PLANE_POINTS, _sampled  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402


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


def pairs_of(points: np.ndarray, seg) -> dict:
    """Every pair's numbers for ``seg`` on ``points``: kept, misfit, balance, the pair's share of the planes'
    points, the angle between the pieces' normals (degrees), their sizes and indices."""
    pts = kernels.c_array(as_points(points), np.float64)
    _, frames, scales = _sampled(pts, seg)
    sizes = np.array([len(p.inliers) for p in seg.planes], dtype=float)
    p = coplanar_pairs(frames, scales, sizes, seg.tolerance, sizes >= MIN_PLANE_POINTS)
    normals = seg.coefficients[:, :3]
    cos = np.abs(np.einsum('ij,ij->i', normals[p.first], normals[p.second])) if len(p.first) else np.zeros(0)
    return dict(kept=p.kept, misfit=p.misfit, balance=p.balance, share=(sizes[p.first] + sizes[p.second]) / sizes.sum(),
                angle=np.degrees(np.arccos(np.clip(cos, 0, 1))), a=sizes[p.first], b=sizes[p.second],
                i=p.first, j=p.second)


def dominant_truth(seg, truth: np.ndarray) -> np.ndarray:
    """Per plane of ``seg`` the true plane holding most of its points (-1: mostly no true plane's)."""
    out = np.full(seg.n_planes, -1, np.int64)
    for j, plane in enumerate(seg.planes):
        ids, counts = np.unique(truth[plane.inliers], return_counts=True)
        out[j] = ids[np.argmax(counts)] if len(ids) else -1
    return out


def scene_rows(args) -> list[dict]:
    rows = []
    for family, cloud in verdict_seeds.clouds(args):
        path = args.cache / f'{cloud.name}.pkl'
        if not path.exists():
            continue
        cached = pickle.loads(path.read_bytes())
        tuned = cached['tuned']
        seg = tuned.segmentation
        q = segmentation_quality(seg.labels, cloud.labels, points=cloud.points, pred_planes=seg.coefficients)
        ratio = q.f1 / cached['best'].f1 if cached['best'].f1 > 0 else float('nan')
        share = q.correct / q.true_planes if q.true_planes else 1.0
        pairs = pairs_of(cloud.points, seg)
        owner = dominant_truth(seg, cloud.labels)
        rows.append(dict(family=family, name=cloud.name, correct=q.correct, true=q.true_planes, ratio=ratio,
                         good=share >= quality.GOOD_CORRECT and ratio >= quality.GOOD_RATIO,
                         reliable=tuned.verdict.reliable, kinds=sorted(k.value for k in tuned.verdict.kinds),
                         same=(owner[pairs['i']] == owner[pairs['j']]) & (owner[pairs['i']] >= 0), **pairs))
    return rows


def frame_rows(data: Path) -> list[dict]:
    """The real frames (the .pcd files of ``data``) at FramePipeline's defaults (the judge call of the frame,
    recorded) and auto-tuned."""
    rows = []
    calls = []
    original = pipeline.judge

    def recorded(*a, **k):
        verdict = original(*a, **k)
        calls.append((a, verdict))
        return verdict

    pipeline.judge = recorded
    try:
        for path in sorted(data.glob('*.pcd')):
            points, shape = load_cloud(path)
            calls.clear()
            pipeline.FramePipeline(pipeline.PipelineConfig()).process(points, shape=shape)
            if calls:
                (pts, seg, *_), verdict = calls[-1]
                rows.append(dict(family='frame, defaults', name=path.stem, good=None, correct=0, true=0,
                                 ratio=np.nan, reliable=verdict.reliable,
                                 kinds=sorted(k.value for k in verdict.kinds), **pairs_of(pts, seg)))
            tuned = pv.tune_tolerance(points, seed=0, shape=shape)
            rows.append(dict(family='frame, tuned', name=path.stem, good=None, correct=0, true=0, ratio=np.nan,
                             reliable=tuned.reliable, kinds=sorted(k.value for k in tuned.verdict.kinds),
                             **pairs_of(points, tuned.segmentation)))
    finally:
        pipeline.judge = original
    return rows


def feature(row: dict, keep: float, misfit: float = np.inf, share: float = 0.0) -> float:
    """The largest balance among the scene's pairs keeping at least ``keep`` of each piece within t, with a joint RMS
    at most ``misfit`` times each piece's own and holding at least ``share`` of the planes' points (0: none)."""
    on = (row['kept'] >= keep) & (row['misfit'] <= misfit) & (row['share'] >= share)
    return float(row['balance'][on].max()) if on.any() else 0.0


def group(row: dict) -> str:
    if row['good'] is None:
        return row['family'] + (', reliable' if row['reliable'] else ', not reliable')
    if row['good']:
        return 'good'
    return 'not good, reliable' if row['reliable'] else 'not good, not reliable'


#: The per-scene feature's variants tabulated: (keep, misfit, share of the planes' points); the balance limits
KEEPS = (0.9, 0.95, 0.98)
MISFITS = (np.inf, 2.0, 1.5, 1.2)
SHARES = (0.0, 0.03, 0.1)
BALANCES = (0.01, 0.1, 0.2, 0.3, 0.4)


def summary(rows: list[dict]) -> None:
    """Per variant and group, how many scenes reach each balance limit (the first, 0.01, is the variant without
    the balance condition), and the same-true-plane share of the pairs counted in labelled scenes."""
    groups = list(dict.fromkeys(group(r) for r in rows))
    print('scenes per group: ' + ', '.join(f'{g} {sum(group(r) == g for r in rows)}' for g in groups))
    print(f'scenes whose largest balance reaches {"/".join(map(str, BALANCES))}, per group:')
    print('| keep | misfit | pair share | ' + ' | '.join(groups) + ' | pairs on one true plane (all scenes) |')
    print('|' + '---|' * (4 + len(groups)))
    for keep in KEEPS:
        for misfit in MISFITS:
            for share in SHARES:
                cells = []
                for g in groups:
                    v = np.array([feature(r, keep, misfit, share) for r in rows if group(r) == g])
                    cells.append('/'.join(str(np.count_nonzero(v >= b)) for b in BALANCES))
                same = [(r['same'] & (r['kept'] >= keep) & (r['misfit'] <= misfit) & (r['share'] >= share)
                         & (r['balance'] >= 0.1)) for r in rows if 'same' in r]
                on = [(r['kept'] >= keep) & (r['misfit'] <= misfit) & (r['share'] >= share) & (r['balance'] >= 0.1)
                      for r in rows if 'same' in r]
                print(f'| {keep} | {misfit:g} | {share} | ' + ' | '.join(cells) +
                      f' | {sum(int(x.sum()) for x in same)} of {sum(int(x.sum()) for x in on)} |')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--indoor', default='0-40')
    parser.add_argument('--lidar', default='0-39')
    parser.add_argument('--roofs', default='0-99')
    parser.add_argument('--gt', type=Path, default=quality.GT)
    parser.add_argument('--cache', type=Path, default=verdict_seeds.CACHE)
    parser.add_argument('--out', type=Path, default=Path('/tmp/verdict_pieces.pkl'))
    parser.add_argument('--no-frames', action='store_true')
    args = parser.parse_args()
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    rows = scene_rows(args) + ([] if args.no_frames else frame_rows(args.gt.parent))
    args.out.write_bytes(pickle.dumps(rows))
    summary(rows)


if __name__ == '__main__':
    main()
