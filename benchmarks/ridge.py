"""The verdict's ridge test (plane_shape.FOLD_LACK, FOLD_FIT) on the tuning split's scenes: per plane, whether it lies
on one true plane or holds two, its lack of fit with one plane, with two planes meeting at a line, and with a quadric
(plane_shape.plane_lack_of_fit, plane_fold); then how many planes of each kind the test fails, beside a lack-of-fit
limit alone.

Planes are those of the auto-tuned result and of three fixed t per scene that hold 2 % of the planes' points or more;
"one true plane" means under 5 % of its points from a second true plane or clutter, "two" means 20 % or more.
--extra N adds N more tuning seeds per family (the split's seed sets are disjoint; see
plane_validation.core.scene_families). Only the tuning split: thresholds are chosen there.

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/ridge.py [--extra 20]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.core import scene_families  # noqa: E402
from plane_validation.core.blas import limit_blas_threads  # noqa: E402
from plane_validation.core.plane_shape import FOLD_FIT, FOLD_LACK, plane_fold, plane_lack_of_fit  # noqa: E402
from plane_validation.core.verdict import MAX_LACK_OF_FIT  # noqa: E402

FIXED_T = {'organized': (0.006, 0.02, 0.063), 'plain': (0.011, 0.032, 0.089)}


def clouds(extra: int, gt: Path) -> list[tuple[str, quality.Cloud]]:
    """The tuning split's clouds, and ``extra`` more tuning seeds per family after those the split uses."""
    out = quality.split_clouds('tuning', gt=gt)
    used = scene_families.SCENES_PER_SPLIT
    for family, make in scene_families.FAMILIES.items():
        for seed in scene_families.TUNING_SEEDS[used[family]:used[family] + extra]:
            out.append((family, quality.Cloud.of_scene(make(seed))))
    return out


def plane_rows(cloud: quality.Cloud, seg) -> list[tuple[float, float, float, float]]:
    """(share of a second true plane or clutter, lack of fit, with a fold, with a quadric) of each plane holding 2 %
    of the planes' points or more."""
    if not seg.n_planes:
        return []
    sizes = np.array([len(p.inliers) for p in seg.planes], float)
    lack, folds = plane_lack_of_fit(cloud.points, seg), plane_fold(cloud.points, seg)
    rows = []
    for j, plane in enumerate(seg.planes):
        if sizes[j] < 0.02 * sizes.sum():
            continue
        truth = cloud.labels[plane.inliers]
        shares = np.sort(np.bincount(np.where(truth >= 0, truth + 1, 0)))[::-1] / len(truth)
        rows.append((float(shares[1]) if len(shares) > 1 else 0.0, float(lack[j]), *map(float, folds[j])))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--extra', type=int, default=0, help='more tuning seeds per family')
    parser.add_argument('--gt', type=Path, default=quality.GT, help='the labelled clouds')
    args = parser.parse_args()
    limit_blas_threads()
    rows = []
    for family, cloud in clouds(args.extra, args.gt):
        params = quality._params(cloud)
        segs = [pv.tune_tolerance(cloud.points, seed=0, shape=cloud.shape, **params).segmentation]
        for t in FIXED_T['organized' if cloud.shape is not None else 'plain']:
            segs.append(pv.detect_planes(cloud.points, t, seed=0, shape=cloud.shape, **params))
        rows += [(family, *r) for seg in segs for r in plane_rows(cloud, seg)]
        print(f'{cloud.name}: {len(rows)} planes so far', file=sys.stderr, flush=True)
    table = np.array([r[1:] for r in rows], float)
    one, two = table[table[:, 0] < 0.05], table[table[:, 0] >= 0.2]
    print(f'| planes | count | lack of fit: median / 95th / 99th | >= {MAX_LACK_OF_FIT:g} | ridge test | '
          f'either |')
    print('|---|--:|---|--:|--:|--:|')
    for name, part in (('one true plane', one), ('two true planes', two)):
        judged = part[np.isfinite(part[:, 1])]
        merged = judged[:, 1] >= MAX_LACK_OF_FIT
        ridge = (judged[:, 1] >= FOLD_LACK) & (judged[:, 1] < MAX_LACK_OF_FIT) & (judged[:, 2] <= FOLD_FIT) & \
            (judged[:, 2] < judged[:, 3])
        q = np.quantile(judged[:, 1], [0.5, 0.95, 0.99]) if len(judged) else [np.nan] * 3
        print(f'| {name} | {len(judged)} | {q[0]:.2f} / {q[1]:.2f} / {q[2]:.2f} | {int(merged.sum())} | '
              f'{int(ridge.sum())} | {int((merged | ridge).sum())} |')


if __name__ == '__main__':
    main()
