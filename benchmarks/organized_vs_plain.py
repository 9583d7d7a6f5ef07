"""The same points searched organized (the image's sub-grid) and as a plain N x 3 array (the voxel graph).

For every organized cloud of a split (quality.py's: the indoor depth frames of the scene families, and in the
tuning split the labelled organized clouds of --gt), ours with regions at each t of quality.py's grid, once with
``shape`` and once without, and each auto-tuned both ways; Hoover-correct planes (T = 0.8) and F1. A row says
where the organized search found fewer planes than the plain one at the same t. The summary gives the count of
(cloud, t) cases organized < plain and organized > plain, and the totals at the best fixed t and auto-tuned.

Issue 38's target: an organized cloud finds at least the planes its points find as a plain array.

Run: .venv/bin/python benchmarks/organized_vs_plain.py [--split tuning|held-out|both] [--gt DIR] [--count 8]
         [--seeds N]
"""
from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import quality  # noqa: E402

import plane_validation as pv  # noqa: E402
from plane_validation.core import scene_families  # noqa: E402
from plane_validation.core.scoring import Quality, segmentation_quality  # noqa: E402

FAMILY = 'indoor_depth'


def organized_clouds(split: str, gt: Path, seeds: int) -> list[quality.Cloud]:
    """The split's organized clouds: its first ``seeds`` indoor depth frames, and in tuning the labelled ones."""
    out = [c for c in quality.labelled_clouds(gt) if c.shape is not None] if split == 'tuning' else []
    for seed in scene_families.SPLITS[split][:seeds]:
        out.append(quality.Cloud.of_scene(scene_families.FAMILIES[FAMILY](seed)))
    return out


def _scored(cloud: quality.Cloud, seg) -> Quality:
    return segmentation_quality(seg.labels, cloud.labels, points=cloud.points, pred_planes=seg.coefficients)


def compare(cloud: quality.Cloud, count: int) -> dict:
    """Per t of the grid (organized, plain) qualities, and both auto-tuned (t, quality)."""
    params = quality._params(cloud)
    fixed = []
    for t in quality._split_grid(cloud, count):
        fixed.append((float(t), *(_scored(cloud, pv.detect_planes(cloud.points, float(t), seed=0, shape=shape,
                                                                  **params))
                                  for shape in (cloud.shape, None))))
    tuned = {}
    for key, shape in (('organized', cloud.shape), ('plain', None)):
        result = pv.tune_tolerance(cloud.points, seed=0, shape=shape, **params)
        tuned[key] = (float(result.tolerance), _scored(cloud, result.segmentation))
    return {'fixed': fixed, 'tuned': tuned}


def _best(pairs: list[tuple[float, Quality]]) -> tuple[float, Quality]:
    return max(pairs, key=lambda p: (p[1].correct, p[1].f1))


def lines(name: str, true_planes: int, c: dict) -> list[str]:
    fixed = c['fixed']
    out = []
    for t, org, plain in fixed:
        mark = ' organized < plain' if org.correct < plain.correct else ''
        out.append(f'  t {1000 * t:7.2f} mm: organized {org.correct:2d} F1 {org.f1:.3f} | plain {plain.correct:2d} '
                   f'F1 {plain.f1:.3f}{mark}')
    (to, bo), (tp, bp) = _best([(t, o) for t, o, _ in fixed]), _best([(t, p) for t, _, p in fixed])
    (ao_t, ao), (ap_t, ap) = c['tuned']['organized'], c['tuned']['plain']
    head = (f'{name} ({true_planes} true planes): best fixed t organized {bo.correct} F1 {bo.f1:.3f} @ '
            f'{1000 * to:.3g} mm, plain {bp.correct} F1 {bp.f1:.3f} @ {1000 * tp:.3g} mm; auto-tuned organized '
            f'{ao.correct} F1 {ao.f1:.3f} @ {1000 * ao_t:.3g} mm, plain {ap.correct} F1 {ap.f1:.3f} @ '
            f'{1000 * ap_t:.3g} mm')
    return [head, *out]


def summary(results: list[tuple[str, dict]]) -> list[str]:
    fewer = more = cases = 0
    best_o = best_p = auto_o = auto_p = 0
    best_fewer = []
    for name, c in results:
        for _, org, plain in c['fixed']:
            cases += 1
            fewer += org.correct < plain.correct
            more += org.correct > plain.correct
        bo = _best([(t, o) for t, o, _ in c['fixed']])[1].correct
        bp = _best([(t, p) for t, _, p in c['fixed']])[1].correct
        best_o, best_p = best_o + bo, best_p + bp
        auto_o += c['tuned']['organized'][1].correct
        auto_p += c['tuned']['plain'][1].correct
        if bo < bp:
            best_fewer.append(name)
    return [f'{len(results)} clouds, {cases} (cloud, t) cases: organized finds fewer correct planes than plain in '
            f'{fewer}, more in {more}',
            f'best fixed t: organized {best_o}, plain {best_p} correct planes; organized fewer on '
            f'{len(best_fewer)} clouds ({", ".join(best_fewer) or "none"})',
            f'auto-tuned: organized {auto_o}, plain {auto_p} correct planes']


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--split', choices=[*quality.SPLIT_NAMES, 'both'], default='tuning')
    parser.add_argument('--gt', type=Path, default=quality.GT, help='the labelled clouds (tuning split only)')
    parser.add_argument('--count', type=int, default=8, help='tolerances in the grid (default 8)')
    parser.add_argument('--seeds', type=int, default=8, help='indoor depth frames per split (default 8)')
    args = parser.parse_args()
    from plane_validation.core.blas import limit_blas_threads
    limit_blas_threads()
    start = time.perf_counter()
    for split in quality.SPLIT_NAMES if args.split == 'both' else [args.split]:
        print(f'## {split}', flush=True)
        results = []
        for cloud in organized_clouds(split, args.gt, args.seeds):
            c = compare(cloud, args.count)
            results.append((cloud.name, c))
            print(*lines(cloud.name, cloud.true_planes, c), sep='\n', flush=True)
        print('', *summary(results), '', sep='\n', flush=True)
    command = shlex.join(['python', 'benchmarks/organized_vs_plain.py', *sys.argv[1:]])
    print(f'{time.perf_counter() - start:.0f} s: `{command}`')


if __name__ == '__main__':
    main()
