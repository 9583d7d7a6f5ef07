"""How soon a node process answers after it is started, with a warm and with a cold kernel cache.

A Kinect frame is published at 10 Hz over DDS (with the large-cloud Fast DDS profile) from the moment the node
process is started; prints, per run, the seconds from the start to the node's log line 'compiled kernels ready',
to its topics being discovered, to the first /diagnostics answer and to the fifth. Cold: a new empty
NUMBA_CACHE_DIR, so the kernels are compiled; warm: the same directory again. With ``--cache DIR`` every run uses
DIR (cold only while it is empty): warm starts alone, e.g. alternating with another checkout's.

The node starts as ``ros2 run`` starts it, through the ``plane_validation_node`` entry point
(``plane_validation.ros:main``; ``--entry module``: ``python -m plane_validation.ros.node``), importing the package
the environment resolves. ``--pycache DIR``: its modules' bytecode is written to and read from DIR
(PYTHONPYCACHEPREFIX), as an installed package's is, even where PYTHONDONTWRITEBYTECODE is set (without it,
such an environment compiles every module of the package from source at each start, about 0.3 s).

Run: OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/start_to_answer.py [PCD] [--runs 3] [--cache DIR]
         [--pycache DIR] [--entry script|module]
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from pvbench.node_e2e import NodeBench, cloud_message, domain_environment  # noqa: E402

from plane_validation.formats.files import load_cloud  # noqa: E402

PROFILE = Path(__file__).resolve().parents[1] / 'config' / 'fastdds_large_clouds.xml'
DEFAULT = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'kinect_frame_142255.pcd'
READY = re.compile(r'compiled kernels ready in ([0-9.]+) s')
#: How the node process is started: ros2 run's console script calls plane_validation.ros:main
ENTRIES = {'script': ['-c', 'import sys; from plane_validation.ros import main; sys.exit(main())'],
           'module': ['-m', 'plane_validation.ros.node']}
ANSWERS = 5  # answers waited for in each run
TIMEOUT_S = 600  # a cold start on a busy machine compiles for minutes; one cut short leaves a partial cache


def one_start(node, pub, msg, cache: str, log: Path, entry: str = 'script', pycache: str | None = None
              ) -> tuple[float, float, float, float, float]:
    """(to kernels ready, to topics discovered, to first answer, to the ANSWERS-th, the log's kernel seconds) of
    one node start."""
    from diagnostic_msgs.msg import DiagnosticArray
    answered: list[float] = []
    sub = node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: answered.append(time.perf_counter()), 10)
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, FASTRTPS_DEFAULT_PROFILES_FILE=str(PROFILE), PYTHONUNBUFFERED='1')
    if pycache:
        env.pop('PYTHONDONTWRITEBYTECODE', None)
        env['PYTHONPYCACHEPREFIX'] = pycache
    with open(log, 'w') as out:
        start = time.perf_counter()
        proc = subprocess.Popen([sys.executable, *ENTRIES[entry], '--ros-args', '-r', 'cloud:=/bench/points'],
                                env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    ready = discovered = float('nan')
    try:
        stamp = 0
        while len(answered) < ANSWERS and time.perf_counter() - start < TIMEOUT_S:
            if proc.poll() is not None:
                raise RuntimeError(f'node exited with {proc.returncode}: {log.read_text()}')
            if ready != ready and READY.search(log.read_text()):
                ready = time.perf_counter() - start
            if discovered != discovered and pub.get_subscription_count():
                discovered = time.perf_counter() - start
            stamp += 1
            msg.header.stamp.sec = stamp
            pub.publish(msg)
            end = time.perf_counter() + 0.1
            while time.perf_counter() < end and len(answered) < ANSWERS:
                rclpy_spin_once(node)
        first = answered[0] - start if answered else float('nan')
        last = answered[ANSWERS - 1] - start if len(answered) >= ANSWERS else float('nan')
    finally:
        NodeBench._stop(proc)  # SIGINT, then SIGKILL after 15 s
        node.destroy_subscription(sub)
    match = READY.search(log.read_text())
    return ready, discovered, first, last, float(match.group(1)) if match else float('nan')


def rclpy_spin_once(node) -> None:
    import rclpy
    rclpy.spin_once(node, timeout_sec=0.01)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('cloud', nargs='?', default=str(DEFAULT))
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--cache', help='the kernel cache every run uses (cold while empty); default: a new one '
                                        'per run, started cold then warm')
    parser.add_argument('--pycache', help='write and read the modules\' bytecode here (PYTHONPYCACHEPREFIX)')
    parser.add_argument('--entry', choices=sorted(ENTRIES), default='script')
    args = parser.parse_args()
    domain_environment()
    os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(PROFILE)
    import rclpy
    import sensor_msgs.msg
    from rclpy.qos import qos_profile_sensor_data
    points, shape = load_cloud(args.cloud)
    msg = cloud_message(points, *shape)
    rclpy.init()
    node = rclpy.create_node('start_bench')
    pub = node.create_publisher(sensor_msgs.msg.PointCloud2, '/bench/points', qos_profile_sensor_data)
    print(f'| run | cache | kernels ready (s after start) | log: kernels took (s) | topics discovered (s) '
          f'| first answer (s) | answer {ANSWERS} (s) |')
    print('|---|---|--:|--:|--:|--:|--:|')
    results: dict[str, list[float]] = {'cold': [], 'warm': []}

    def start(run: int, cache: str, kind: str, logs: str) -> None:
        ready, discovered, first, last, took = one_start(node, pub, msg, cache, Path(logs) / 'node.log', args.entry,
                                                         args.pycache)
        results[kind].append(first)
        print(f'| {run + 1} | {kind} | {ready:.2f} | {took:.2f} | {discovered:.2f} | {first:.2f} | {last:.2f} |',
              flush=True)
    try:
        with tempfile.TemporaryDirectory() as logs:
            for run in range(args.runs):
                if args.cache:
                    Path(args.cache).mkdir(parents=True, exist_ok=True)  # a new one: the first start is cold
                    start(run, args.cache, 'warm' if any(Path(args.cache).iterdir()) else 'cold', logs)
                    continue
                with tempfile.TemporaryDirectory() as cache:
                    for kind in ('cold', 'warm'):
                        start(run, cache, kind, logs)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    for kind, firsts in results.items():
        if not firsts:
            continue
        print(f'{kind} cache: first answer {statistics.median(firsts):.2f} s after the start (median of {len(firsts)})')


if __name__ == '__main__':
    main()
