"""Where a steady-state frame's time goes: pyinstrument over repeated process_cloud + frame_messages.

    .venv/bin/python benchmarks/profile_frame.py [FILE | --synthetic room] [--runs 30] [--top 15] [--tree]

Same settings as figure (1) of benchmarks/suite.py (t = 0.01 m, up to 5 planes, indices on a
2,000-point sample). Prints two tables in ms per frame and share of the frame: the functions of
plane_validation by inclusive time, and all functions by self time (time in numpy's C code is
charged to the Python function that called it). Needs pyinstrument (benchmarks/requirements.txt).
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from pvbench.frames import VIEWS, load_frames, render  # noqa: E402
from pvbench.node_e2e import cloud_message  # noqa: E402
from pyinstrument import Profiler  # noqa: E402
from suite import STEADY  # noqa: E402

from plane_validation.app import pipeline as pv_pipeline  # noqa: E402
from plane_validation.app.pipeline import FramePipeline  # noqa: E402
from plane_validation.ros.messages import frame_messages  # noqa: E402

PACKAGE = 'plane_validation/'


def _key(frame) -> str:
    """'function (file:line)'; a built-in (numpy C code) also names its Python caller."""
    key = f'{frame.function} ({frame.file_path_short}:{frame.line_no})'
    if frame.file_path_short and frame.file_path_short.startswith('<built-in>'):
        caller = frame.parent
        while caller is not None and 'numpy/' in (caller.file_path_short or ''):  # numpy's Python wrappers
            caller = caller.parent
        if caller is not None:
            key = f'{frame.function} ← {caller.function} ({caller.file_path_short}:{caller.line_no})'
    return key


def aggregate(root) -> tuple[dict[str, float], dict[str, float]]:
    """(inclusive, self) seconds per function over a pyinstrument frame tree; inclusive time
    counts only the outermost call of a function on each stack (no double counting of recursion)."""
    inclusive: dict[str, float] = defaultdict(float)
    own: dict[str, float] = defaultdict(float)

    def walk(frame, active: frozenset[str]) -> None:
        key = _key(frame)
        children = [c for c in frame.children if not c.is_synthetic]
        own[key] += frame.time - sum(c.time for c in children)
        if key not in active:
            inclusive[key] += frame.time
        for child in children:
            walk(child, active | {key})

    walk(root, frozenset())
    return inclusive, own


def print_table(title: str, times: dict[str, float], runs: int, per_frame: float, top: int,
                only: str | None = None) -> None:
    print(f'\n{title}\n\n| function | ms per frame | share |\n| --- | ---: | ---: |')
    rows = [(k, v) for k, v in times.items() if only is None or only in k]
    for key, seconds in sorted(rows, key=lambda kv: -kv[1])[:top]:
        ms = 1e3 * seconds / runs
        print(f'| `{key}` | {ms:.2f} | {100 * ms / per_frame:.0f} % |')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('file', nargs='?', help='a frame file (default: a synthetic frame)')
    parser.add_argument('--synthetic', default='room', choices=sorted(VIEWS))
    parser.add_argument('--runs', type=int, default=30)
    parser.add_argument('--top', type=int, default=15)
    parser.add_argument('--tree', action='store_true', help='also print pyinstrument\'s call tree')
    args = parser.parse_args(argv)
    limit = getattr(pv_pipeline, 'limit_blas_threads', None)
    if limit:
        limit()
    frame = load_frames(args.file)[0] if args.file else render(args.synthetic, VIEWS[args.synthetic])
    msg = cloud_message(frame.points, frame.height, frame.width)
    pipe = FramePipeline(STEADY)

    def one_frame(i: int) -> None:
        msg.header.stamp.sec = 1000 + i
        frame_messages(msg.header, pipe.process_cloud(msg), 'bench')

    one_frame(0)  # warm-up
    profiler = Profiler(interval=0.0005)
    start = time.perf_counter()
    profiler.start()
    for i in range(args.runs):
        one_frame(i + 1)
    session = profiler.stop()
    per_frame = 1e3 * (time.perf_counter() - start) / args.runs
    inclusive, own = aggregate(session.root_frame())
    print(f'# steady-state frame profile: {frame.name} ({frame.n_valid} valid points), {args.runs} frames, '
          f'{per_frame:.1f} ms per frame under the profiler (sampling every 0.5 ms)')
    print_table('## plane_validation functions, inclusive time', inclusive, args.runs, per_frame, args.top, PACKAGE)
    print_table('## all functions, self time', own, args.runs, per_frame, args.top)
    if args.tree:
        print('\n```\n' + profiler.output_text(unicode=True, color=False, show_all=False) + '```')
    return 0


if __name__ == '__main__':
    sys.exit(main())
