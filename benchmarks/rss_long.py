"""Node memory over a long run: the 640 x 480 frames in turn (the synthetic ones plus any FILE),
at 20 Hz, VmRSS of the node process every 100 frames.

    .venv/bin/python benchmarks/rss_long.py [--frames 3000] [FILE ...]     # about 3 min
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import suite  # noqa: E402  (sets the Fast DDS profile and the DDS domain before rclpy starts)
from pvbench.frames import load_frames, synthetic_frames  # noqa: E402
from pvbench.node_e2e import NodeBench  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('files', nargs='*')
    parser.add_argument('--frames', type=int, default=3000)
    parser.add_argument('--rate', type=float, default=20.0)
    args = parser.parse_args()
    frames = synthetic_frames() + [f for path in args.files for f in load_frames(path)]
    clouds = [suite.cloud_message(f.points, f.height, f.width) for f in frames if f.height * f.width == 307_200]
    with tempfile.TemporaryDirectory() as logs:
        bench = NodeBench(clouds, suite.TOLERANCE, suite.PLANES, Path(logs))
        try:
            run = bench.run(args.rate, args.frames, rss_every=100, name='long')
        finally:
            bench.close()
    print(f'answered {run.answered}, dropped {run.dropped}, peak RSS (VmHWM) {run.peak_mb:.0f} MB')
    print('RSS (MB) by frame: ' + ' '.join(f'{n}:{mb:.0f}' for n, mb in run.rss_mb))
    return 0


if __name__ == '__main__':
    sys.exit(main())
