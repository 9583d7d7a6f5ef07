"""Command line: ``plane-validation <command>`` (also ``python -m plane_validation.cli``).

    plane-validation demo                     # the main job: a bundled bag through the node over DDS
    plane-validation replay BAG [--live] ...  # replay a bag offline (default) or live
    plane-validation detect FILE [--tolerance T | --tune]   # .pcd, .npy, .xyz/.txt/.csv
    plane-validation tune FILE               # the tolerance sweep table
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from .files import load_points
from .pipeline import PipelineConfig
from .ransac import Segmentation, detect_planes

#: The bag the demo replays and where its outputs go (relative to the repository / current directory).
DEMO_BAG = 'bags/room'
DEMO_OUT = 'out/demo'


def format_planes(seg: Segmentation) -> str:
    """One line per plane: id, coefficients, inliers, rms."""
    lines = [f'{seg.n_planes} plane(s), tolerance {seg.tolerance:.4g} m; stopped: {seg.reason}']
    for k, plane in enumerate(seg.planes):
        a, b, c, d = plane.coefficients
        lines.append(f'  plane {k}: {a:+.4f} x {b:+.4f} y {c:+.4f} z {d:+.4f} = 0   '
                     f'inliers {len(plane.inliers):7d}   rms {plane.rms:.4g} m')
    return '\n'.join(lines)


def _config(args: argparse.Namespace) -> PipelineConfig:
    """PipelineConfig from the common options (only those given override the defaults)."""
    changes = {name: getattr(args, name) for name in ('tolerance', 'seed', 'max_planes', 'min_inliers', 'voxel_size')
               if getattr(args, name, None) is not None}
    if getattr(args, 'fixed', False):
        changes['auto_tune'] = False
    return dataclasses.replace(PipelineConfig(), **changes).validate()


def _min_inliers(cfg: PipelineConfig) -> int | float:
    return cfg.min_inliers if cfg.min_inliers < 1 else int(cfg.min_inliers)


def _add_config_options(parser: argparse.ArgumentParser, *, pipeline: bool) -> None:
    """Options shared by the commands; ``pipeline`` adds those only the node's pipeline has."""
    parser.add_argument('--tolerance', type=float, help='RANSAC tolerance t in meters' +
                        (' (with --fixed, or before tuning)' if pipeline else ' (default: auto-tuned)'))
    parser.add_argument('--seed', type=int, help='random seed (default 0)')
    parser.add_argument('--max-planes', dest='max_planes', type=int)
    parser.add_argument('--min-inliers', dest='min_inliers', type=float, help='count, or fraction when < 1')
    if pipeline:
        parser.add_argument('--fixed', action='store_true', help='use --tolerance as is, no auto-tuning')
        parser.add_argument('--voxel-size', dest='voxel_size', type=float, help='voxel grid in meters (0 = off)')


def cmd_detect(args: argparse.Namespace) -> int:
    points = load_points(args.file)
    cfg = _config(args)
    start = time.perf_counter()
    if args.tune or args.tolerance is None:
        from .tuning import tune_tolerance
        result = tune_tolerance(points, seed=cfg.seed, max_planes=cfg.max_planes, min_inliers=_min_inliers(cfg))
        seg = result.segmentation
        print(f'tuned tolerance {result.tolerance:.4g} m, noise estimate {result.noise_estimate:.3g} m; '
              f'{"reliable" if result.reliable else "NOT reliable"}: {result.verdict}')
    else:
        seg = detect_planes(points, args.tolerance, seed=cfg.seed, max_planes=cfg.max_planes,
                            min_inliers=_min_inliers(cfg))
    print(f'{args.file}: {len(points)} points, {seg.n_valid} valid')
    print(format_planes(seg))
    print(f'took {1000 * (time.perf_counter() - start):.0f} ms')
    if args.png:
        from .plot import plot_planes
        valid = np.isfinite(points).all(axis=1)
        print(f'wrote {plot_planes(points[valid], seg.labels[valid], args.png, title=str(args.file))}')
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    from .tuning import tune_tolerance
    points = load_points(args.file)
    result = tune_tolerance(points, criterion=args.criterion, seed=args.seed or 0)
    print(result.table())
    print(f'chosen t = {result.tolerance:.4g} m by {result.criterion}; {result.segmentation.n_planes} planes; '
          f'noise estimate {result.noise_estimate:.3g} m; {"reliable" if result.reliable else "NOT reliable"}: '
          f'{result.verdict}; {result.seconds:.1f} s')
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from .replay import replay_live, replay_offline
    cfg = _config(args)
    if args.live:
        summary = replay_live(args.bag, topic=args.topic, out=args.out, rate=args.rate, start_node=not args.no_node,
                              config=cfg)
    else:
        summary = replay_offline(args.bag, topic=args.topic, out=args.out, config=cfg)
    print(summary.line())
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .plot import plot_cloud_message
    from .replay import replay_live
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    out_bag = out_dir / f'{Path(args.bag).name}.planes'
    if out_bag.exists():
        import shutil
        shutil.rmtree(out_bag)
    print(f'Replaying {args.bag} live over DDS into plane_validation_node (auto-tuned tolerance, seed 0)...')
    start = time.perf_counter()
    summary = replay_live(args.bag, out=out_bag, rate=args.rate, config=PipelineConfig())
    print(summary.line())
    png = out_dir / 'last_frame.png'
    if summary.last_segmented is not None:
        plot_cloud_message(summary.last_segmented, png, title=f'{Path(args.bag).name}: last frame')
    print(f'Outputs: node outputs recorded in the rosbag2 bag {out_bag} (input cloud, segmented, planes, '
          f'plane_poses, plane_coefficients, /diagnostics); picture of the last frame: {png}. '
          f'Took {time.perf_counter() - start:.1f} s.')
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='plane-validation', description='Self-validating plane detection.')
    sub = parser.add_subparsers(dest='command', required=True)

    demo = sub.add_parser('demo', help='the main job: replay a bundled bag through the node over DDS')
    demo.add_argument('--bag', default=DEMO_BAG)
    demo.add_argument('--out', default=DEMO_OUT, help='directory for the output bag and PNG')
    demo.add_argument('--rate', type=float, default=0.25,
                      help='playback speed (slow enough that the node answers every frame)')
    demo.set_defaults(func=cmd_demo)

    replay = sub.add_parser('replay', help='replay a bag through the per-frame pipeline')
    replay.add_argument('bag')
    replay.add_argument('--topic', help='PointCloud2 topic (auto-detected when there is one)')
    replay.add_argument('--out', help='output rosbag2 directory (default: <bag>.planes beside the bag)')
    replay.add_argument('--live', action='store_true', help='publish on ROS topics at the recorded timing')
    replay.add_argument('--rate', type=float, default=1.0, help='playback speed factor for --live')
    replay.add_argument('--no-node', action='store_true', help='with --live: do not start the node in-process')
    _add_config_options(replay, pipeline=True)
    replay.set_defaults(func=cmd_replay)

    detect = sub.add_parser('detect', help='detect planes in a point file (.pcd, .npy, .xyz, .txt, .csv)')
    detect.add_argument('file')
    detect.add_argument('--tune', action='store_true', help='auto-tune t (the default without --tolerance)')
    detect.add_argument('--png', help='write a picture of the planes here')
    _add_config_options(detect, pipeline=False)
    detect.set_defaults(func=cmd_detect)

    tune = sub.add_parser('tune', help='print the tolerance sweep table for a point file')
    tune.add_argument('file')
    tune.add_argument('--criterion', default='gs_planes')
    tune.add_argument('--seed', type=int, default=0)
    tune.set_defaults(func=cmd_tune)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        return 130
    except (ValueError, OSError) as exc:
        print(f'plane-validation: error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
