"""A plain script's tune_tolerance with the library's own one-BLAS-thread limit vs without it,
side by side, with a second busy process on the machine (as a robot's other nodes would be).

Run: .venv/bin/python benchmarks/bench_blas.py [CLOUD] [--repeat 3] [--no-load]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
from pathlib import Path

DEFAULT = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'office1.pcd'
SCRIPT = '''
import sys, time
import contextlib
import plane_validation as pv
if sys.argv[2] == 'off':  # undo the library's limit
    import plane_validation.core.blas as blas
    blas._limiter = contextlib.nullcontext
from plane_validation.formats.files import load_points
points = load_points(sys.argv[1])
start = time.perf_counter()
pv.tune_tolerance(points, seed=0)
print(time.perf_counter() - start)
'''


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('cloud', nargs='?', default=str(DEFAULT))
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--no-load', action='store_true', help='no busy second process')
    args = parser.parse_args()
    load = None if args.no_load else subprocess.Popen([sys.executable, '-c', 'while True: pass'])
    try:
        times: dict[str, list[float]] = {'on': [], 'off': []}
        for _ in range(args.repeat):
            for mode in times:  # interleaved, so both see the same machine
                out = subprocess.run([sys.executable, '-c', SCRIPT, args.cloud, mode], capture_output=True, text=True,
                                     check=True, env={k: v for k, v in __import__('os').environ.items()
                                                      if not k.endswith('_NUM_THREADS')})
                times[mode].append(float(out.stdout.split()[-1]))
    finally:
        if load is not None:
            load.kill()
    on, off = statistics.median(times['on']), statistics.median(times['off'])
    print(f'{Path(args.cloud).name}: tune_tolerance from a plain script, {"no" if args.no_load else "one busy"} '
          f'other process, median of {args.repeat}: library limit {on:.2f} s, without it {off:.2f} s '
          f'(ratio {off / on:.1f}x)')


if __name__ == '__main__':
    main()
