"""Command line: ``plane-validation <command>`` (also ``python -m plane_validation.cli``)."""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from . import scenes
from .ransac import Segmentation, detect_planes


def format_planes(seg: Segmentation) -> str:
    """One line per plane: id, coefficients, inliers, rms."""
    lines = [f'{seg.n_planes} plane(s), tolerance {seg.tolerance:g}; stopped: {seg.reason}']
    for k, plane in enumerate(seg.planes):
        a, b, c, d = plane.coefficients
        lines.append(f'  plane {k}: {a:+.4f} x {b:+.4f} y {c:+.4f} z {d:+.4f} = 0   '
                     f'inliers {len(plane.inliers):6d}   rms {plane.rms:.4g}')
    return '\n'.join(lines)


def cmd_demo(args: argparse.Namespace) -> int:
    scene = scenes.SCENES[args.scene](noise=args.noise, seed=args.seed) if args.noise is not None \
        else scenes.SCENES[args.scene](seed=args.seed)
    tolerance = args.tolerance if args.tolerance else max(2 * scene.noise, 1e-3)
    start = time.perf_counter()
    seg = detect_planes(scene.points, tolerance, seed=args.seed, min_inliers=args.min_inliers)
    elapsed = 1000 * (time.perf_counter() - start)
    print(f'scene {scene.name}: {len(scene.points)} points, {scene.n_planes} true planes, noise {scene.noise:g}')
    print(format_planes(seg))
    print(f'detect_planes took {elapsed:.1f} ms')
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='plane-validation', description='Self-validating plane detection.')
    sub = parser.add_subparsers(dest='command', required=True)
    demo = sub.add_parser('demo', help='detect planes in a generated scene and print them')
    demo.add_argument('--scene', choices=sorted(scenes.SCENES), default='corner')
    demo.add_argument('--noise', type=float, default=None, help="scene noise e (scene units)")
    demo.add_argument('--tolerance', type=float, default=None, help='RANSAC tolerance t (default 2e)')
    demo.add_argument('--min-inliers', type=float, default=0.02)
    demo.add_argument('--seed', type=int, default=0)
    demo.set_defaults(func=cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError) as exc:
        print(f'plane-validation: error: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
