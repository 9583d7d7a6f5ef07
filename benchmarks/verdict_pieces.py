"""One surface found as pieces (core/pieces.py) over the tuning seeds and the real frames: per scene the pairs of found
planes whose joint plane keeps most of each piece within t, against good / not good and the verdict.

Reads the detections benchmarks/verdict_seeds.py cached (--cache; scenes not cached yet are skipped), and runs the
real frames of ../shared/data through FramePipeline at its defaults (the node's: the verdict judge sees, recorded) and
through tune_tolerance as benchmarks/verdict.py does. Writes every pair's numbers to --out (a pickle) and prints per
scene the largest balance among pairs keeping at least each --keep of each piece, and a summary per group.

Only tuning seeds: choose the limits here; the held-out split is for quality.py's report.

Run: .venv/bin/python benchmarks/verdict_pieces.py --indoor 0-40 --lidar 0-39 --roofs 0-99 --gt DIR --cache DIR
         [--out FILE] [--keep 0.9,0.95,0.98]
"""
from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402
import verdict_seeds  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.app import pipeline  # noqa: E402
from plane_validation.core import kernels  # noqa: E402
from plane_validation.core.pieces import coplanar_pairs  # noqa: E402
from plane_validation.core.ransac import as_points  # noqa: E402
from plane_validation.core.scoring import segmentation_quality  # noqa: E402
from plane_validation.core.verdict import MIN_PLANE_POINTS, _sampled  # noqa: E402
from plane_validation.formats.files import load_cloud  # noqa: E402

DATA = Path('/work/shared/data') if not quality.GT.is_dir() else quality.GT.parent


def pairs_of(points: np.ndarray, seg) -> dict:
    """Every pair's numbers for ``seg`` on ``points``: kept, misfit, balance, the pair's share of the planes'
    points, the angle between the pieces' normals (degrees), their sizes."""
    pts = kernels.c_array(as_points(points), np.float64)
    _, frames, scales = _sampled(pts, seg)
    sizes = np.array([len(p.inliers) for p in seg.planes], dtype=float)
    p = coplanar_pairs(frames, scales, sizes, seg.tolerance, sizes >= MIN_PLANE_POINTS)
    normals = seg.coefficients[:, :3]
    cos = np.abs(np.einsum('ij,ij->i', normals[p.first], normals[p.second])) if len(p.first) else np.zeros(0)
    return dict(kept=p.kept, misfit=p.misfit, balance=p.balance, share=(sizes[p.first] + sizes[p.second]) / sizes.sum(),
                angle=np.degrees(np.arccos(np.clip(cos, 0, 1))), a=sizes[p.first], b=sizes[p.second])


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
        rows.append(dict(family=family, name=cloud.name, correct=q.correct, true=q.true_planes, ratio=ratio,
                         good=share >= quality.GOOD_CORRECT and ratio >= quality.GOOD_RATIO,
                         reliable=tuned.verdict.reliable, kinds=sorted(k.value for k in tuned.verdict.kinds),
                         **pairs_of(cloud.points, seg)))
    return rows


def frame_rows() -> list[dict]:
    """The real frames at FramePipeline's defaults (the judge call of the frame, recorded) and auto-tuned."""
    rows = []
    calls = []
    original = pipeline.judge

    def recorded(*a, **k):
        verdict = original(*a, **k)
        calls.append((a, verdict))
        return verdict

    pipeline.judge = recorded
    try:
        for path in sorted(DATA.glob('*.pcd')):
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


def feature(row: dict, keep: float, min_share: float = 0.0) -> float:
    """The largest balance among the scene's pairs keeping at least ``keep`` of each piece (0: none)."""
    on = (row['kept'] >= keep) & (row['share'] >= min_share)
    return float(row['balance'][on].max()) if on.any() else 0.0


def group(row: dict) -> str:
    if row['good'] is None:
        return row['family'] + (' reliable' if row['reliable'] else ' not reliable')
    if row['good']:
        return 'good'
    return 'not good, reliable' if row['reliable'] else 'not good, not reliable'


def summary(rows: list[dict], keeps: list[float]) -> None:
    for row in rows:
        cells = ' '.join(f'{feature(row, k):.2f}' for k in keeps)
        print(f'{row["name"]:42s} {group(row):24s} {row["correct"]}/{row["true"]} {cells}')
    print()
    for keep in keeps:
        print(f'keep >= {keep}:')
        for g in dict.fromkeys(group(r) for r in rows):
            v = np.array([feature(r, keep) for r in rows if group(r) == g])
            cuts = ' '.join(f'>={s}: {np.count_nonzero(v >= s)}' for s in (0.01, 0.1, 0.2, 0.3, 0.4))
            print(f'    {g:32s} {len(v):3d} scenes, max balance {cuts}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--indoor', default='0-40')
    parser.add_argument('--lidar', default='0-39')
    parser.add_argument('--roofs', default='0-99')
    parser.add_argument('--gt', type=Path, default=quality.GT)
    parser.add_argument('--cache', type=Path, default=verdict_seeds.CACHE)
    parser.add_argument('--out', type=Path, default=Path('/tmp/verdict_pieces.pkl'))
    parser.add_argument('--keep', default='0.9,0.95,0.98')
    parser.add_argument('--no-frames', action='store_true')
    args = parser.parse_args()
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    rows = scene_rows(args) + ([] if args.no_frames else frame_rows())
    args.out.write_bytes(pickle.dumps(rows))
    summary(rows, [float(k) for k in args.keep.split(',')])


if __name__ == '__main__':
    main()
