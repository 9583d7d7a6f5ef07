"""The verdict over many tuning seeds per scene family: which bad results it calls reliable, which good ones not.

Per scene (the families of plane_validation.core.scene_families at TUNING seeds, and the labelled clouds of
--gt): the best fixed t over quality.py's grid, the auto-tuned result as quality.py makes it, both scored
(core/scoring.py), and ``judge`` on the tuned planes. Each scene's detections are cached in --cache (a pickle per
scene) so that the verdict can be re-judged after a change of core/verdict.py without detecting again
(--rejudge). Lists the bad scenes called reliable and the good ones called not reliable, with the true planes
the tuned result did not get right (their size, range, where their points went and why: core/scoring.py's
miss_cause), and per family how many true planes of its scenes not good were missed for each cause.

Only tuning seeds: choose the verdict's limits here; the held-out split is for quality.py's report.

Run: .venv/bin/python benchmarks/verdict_seeds.py [--indoor 0-40] [--lidar 0-20] [--roofs 0-60] [--gt DIR]
         [--cache DIR] [--rejudge] [--jobs N]
"""
from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.core import scene_families  # noqa: E402
from plane_validation.core.scoring import (  # noqa: E402
    HOOVER_OVERLAP,
    MissCause,
    miss_cause,
    segmentation_quality,
)
from plane_validation.core.verdict import judge  # noqa: E402

CACHE = Path('/tmp/verdict_seeds_cache')


def _seeds(text: str) -> list[int]:
    """'0-40' or '3,5,7' -> seeds; every one must be a tuning seed."""
    seeds = []
    for part in text.split(','):
        lo, _, hi = part.partition('-')
        seeds += list(range(int(lo), int(hi or lo) + 1))
    if not set(seeds) <= set(scene_families.TUNING_SEEDS):
        raise SystemExit(f'only tuning seeds here ({min(scene_families.TUNING_SEEDS)}..'
                         f'{max(scene_families.TUNING_SEEDS)}), got {text}')
    return seeds


def clouds(args) -> list[tuple[str, quality.Cloud]]:
    out = [(quality.LABELLED, c) for c in quality.labelled_clouds(args.gt)] if args.gt else []
    for family, text in (('indoor_depth', args.indoor), ('lidar_scan', args.lidar), ('aerial_roof', args.roofs)):
        for seed in _seeds(text) if text else ():
            out.append((family, quality.Cloud.of_scene(scene_families.FAMILIES[family](seed))))
    return out


def detect(cloud: quality.Cloud) -> dict:
    """The best fixed t's quality (quality.py's grid and rule) and the auto-tuned result."""
    best = quality._best([(t, *quality.ours(cloud, t, True)) for t in quality._split_grid(cloud, 12)])
    tuned = pv.tune_tolerance(cloud.points, seed=0, shape=cloud.shape, **quality._params(cloud))
    return {'best_t': float(best[0]), 'best': best[1], 'tuned': tuned}


def _row(family: str, cloud: quality.Cloud, cached: dict, rejudge: bool) -> dict:
    tuned = cached['tuned']
    seg = tuned.segmentation
    verdict = judge(cloud.points, seg, tuned.indices, tuned.seed_agreement) if rejudge else tuned.verdict
    q = segmentation_quality(seg.labels, cloud.labels, points=cloud.points, pred_planes=seg.coefficients)
    ratio = q.f1 / cached['best'].f1 if cached['best'].f1 > 0 else float('nan')
    share = q.correct / q.true_planes if q.true_planes else 1.0
    return dict(family=family, name=cloud.name, q=q, ratio=ratio, t=tuned.tolerance, verdict=verdict,
                good=share >= quality.GOOD_CORRECT and ratio >= quality.GOOD_RATIO,
                bad=share < quality.BAD_CORRECT or not ratio >= quality.BAD_RATIO,
                missed=missed_planes(cloud, seg.labels, int(quality._params(cloud)['min_inliers'])),
                noise=tuned.noise_level)


def missed_planes(cloud: quality.Cloud, labels: np.ndarray, min_inliers: int) -> list[tuple[str, str]]:
    """The true planes not matched Hoover-correctly (HOOVER_OVERLAP both ways): (their miss_cause, a line with
    their size, median range (m) and what took their points)."""
    out = []
    truth = cloud.labels
    pts = cloud.points
    for g in np.unique(truth[truth >= 0]):
        on = truth == g
        found = labels[on]
        ids, counts = np.unique(found, return_counts=True)
        k = int(np.argmax(np.where(ids >= 0, counts, -1))) if (ids >= 0).any() else None
        if k is not None:
            d = ids[k]
            inter = counts[k]
            if inter >= HOOVER_OVERLAP * on.sum() and inter >= HOOVER_OVERLAP * np.count_nonzero(labels == d):
                continue
        r = float(np.median(np.linalg.norm(pts[on], axis=1)))
        free = float(np.mean(found < 0))
        top = ', '.join(f'p{i}:{c / on.sum():.0%}({np.count_nonzero(labels == i)})'
                        for i, c in sorted(zip(ids, counts), key=lambda x: -x[1])[:3] if i >= 0)
        cause = miss_cause(truth, labels, int(g), min_inliers)
        out.append((cause, f'true {g} ({cause.value}): {on.sum()} pts at {r:.1f} m, {free:.0%} unassigned, {top}'))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--indoor', default='0-40')
    parser.add_argument('--lidar', default='0-20')
    parser.add_argument('--roofs', default='0-60')
    parser.add_argument('--gt', type=Path, default=quality.GT)
    parser.add_argument('--cache', type=Path, default=CACHE)
    parser.add_argument('--rejudge', action='store_true', help='judge the cached planes with today\'s verdict')
    parser.add_argument('--detail', action='store_true', help='list every scene, with its missed planes')
    args = parser.parse_args()
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    args.cache.mkdir(parents=True, exist_ok=True)
    rows = []
    start = time.process_time()
    for family, cloud in clouds(args):
        path = args.cache / f'{cloud.name}.pkl'
        if path.exists():
            cached = pickle.loads(path.read_bytes())
        else:
            cached = detect(cloud)
            path.write_bytes(pickle.dumps(cached))
        r = _row(family, cloud, cached, args.rejudge)
        rows.append(r)
        kinds = ','.join(sorted(k.value for k in r['verdict'].kinds)) or '-'
        flag = ('BAD-RELIABLE' if r['bad'] and r['verdict'].reliable else
                'GOOD-NOT' if r['good'] and not r['verdict'].reliable else '')
        if args.detail or flag:
            q = r['q']
            print(f'{cloud.name}: {q.correct}/{q.true_planes} F1 {q.f1:.3f} ratio {r["ratio"]:.3f} '
                  f't {1000 * r["t"]:.1f} mm (noise {1000 * r["noise"]:.2f} mm) '
                  f'{"reliable" if r["verdict"].reliable else kinds} {flag}',
                  flush=True)
            if flag == 'BAD-RELIABLE' or args.detail:
                for _, line in r['missed']:
                    print('   ', line)
    print()
    for family in dict.fromkeys(r['family'] for r in rows):
        g = [r for r in rows if r['family'] == family]
        print(f'{family}: {len(g)} scenes, good {sum(r["good"] for r in g)}, bad {sum(r["bad"] for r in g)}, '
              f'reliable {sum(r["verdict"].reliable for r in g)}; bad called reliable '
              f'{sum(r["bad"] and r["verdict"].reliable for r in g)}, good called not reliable '
              f'{sum(r["good"] and not r["verdict"].reliable for r in g)}, agreement '
              f'{np.mean([r["good"] == r["verdict"].reliable for r in g]):.2f}')
        causes = [cause for r in g if not r['good'] for cause, _ in r['missed']]
        print('    true planes missed in the scenes not good, by cause: '
              + ', '.join(f'{c.value} {causes.count(c)}' for c in MissCause))
    print(f'all: {len(rows)} scenes; bad called reliable {sum(r["bad"] and r["verdict"].reliable for r in rows)}/'
          f'{sum(r["bad"] for r in rows)}, good called not reliable '
          f'{sum(r["good"] and not r["verdict"].reliable for r in rows)}/{sum(r["good"] for r in rows)}, agreement '
          f'{np.mean([r["good"] == r["verdict"].reliable for r in rows]):.3f} '
          f'({time.process_time() - start:.0f} s CPU)')


if __name__ == '__main__':
    main()
