"""The node end to end: a real plane_validation_node process fed PointCloud2s over Fast DDS.

The node runs as ``python -m plane_validation.node`` (what ``ros2 run`` starts) with a fixed
tolerance; this process publishes one organized frame over and over with fresh header stamps at
a fixed rate (sensor-data QoS, as a camera driver does) and listens to ``/diagnostics``. Both
processes use config/fastdds_large_clouds.xml (the caller sets FASTRTPS_DEFAULT_PROFILES_FILE
before rclpy starts). Latency: from ``publish()`` to the arrival of that stamp's diagnostics.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

import numpy as np

TOPIC = '/bench/points'
FIRST_STAMP = 10**12


@dataclass
class NodeRun:
    """One run at one input rate (Hz). latencies_ms: per answered frame; dropped: the node's own
    count; rss_mb: (frames sent, VmRSS MB) samples; peak_mb: VmHWM at the end."""

    rate: float
    sent: int
    answered: int = 0
    dropped: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    processing_ms: list[float] = field(default_factory=list)
    rss_mb: list[tuple[int, float]] = field(default_factory=list)
    peak_mb: float = float('nan')


def _status_mb(pid: int, key: str) -> float:
    with open(f'/proc/{pid}/status') as f:
        for line in f:
            if line.startswith(key + ':'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


class NodeBench:
    """A publisher/listener in this process; start() a node process per run."""

    def __init__(self, points: np.ndarray, height: int, width: int, tolerance: float = 0.01, planes: int = 5):
        import rclpy
        import sensor_msgs.msg
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
        from std_msgs.msg import Header

        from plane_validation.cloud import create_cloud

        self.tolerance, self.planes = tolerance, planes
        pts = np.asarray(points, dtype=np.float32)
        self.msg = create_cloud(Header(frame_id='camera'), {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]},
                                types=sensor_msgs.msg)
        self.msg.height, self.msg.width, self.msg.row_step = height, width, width * self.msg.point_step
        rclpy.init()
        self._rclpy = rclpy
        self.node = rclpy.create_node('plane_validation_bench')
        self.pub = self.node.create_publisher(sensor_msgs.msg.PointCloud2, TOPIC, qos_profile_sensor_data)
        self._lock = threading.Lock()
        self._answers: dict[int, tuple[float, dict[str, str]]] = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                      QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE))
        self._executor = rclpy.executors.SingleThreadedExecutor()
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._executor.spin, daemon=True)
        self._spinner.start()

    def _on_diag(self, msg) -> None:
        now = time.perf_counter()
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        if stamp >= FIRST_STAMP and msg.status:
            with self._lock:
                self._answers[stamp] = (now, {kv.key: kv.value for kv in msg.status[0].values})

    def run(self, rate: float, frames: int, rss_every: int = 0, params: tuple[str, ...] = ('auto_tune:=false',)
            ) -> NodeRun:
        """Start a node, send ``frames`` clouds at ``rate`` Hz, wait for the answers, stop it."""
        proc = subprocess.Popen(
            [sys.executable, '-m', 'plane_validation.node', '--ros-args', *[a for p in params for a in ('-p', p)],
             '-p', f'tolerance:={self.tolerance}', '-p', f'max_planes:={self.planes}', '-r', f'cloud:={TOPIC}',
             '--log-level', 'error'],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        run = NodeRun(rate=rate, sent=frames)
        sent: dict[int, float] = {}
        with self._lock:
            self._answers.clear()
        try:
            end = time.monotonic() + 30
            while self.pub.get_subscription_count() == 0 and time.monotonic() < end:
                time.sleep(0.05)
            time.sleep(1.0)  # let the node's publishers match our listener
            start = time.perf_counter()
            for i in range(frames):
                target = start + i / rate
                while (now := time.perf_counter()) < target:
                    time.sleep(min(0.002, target - now))
                stamp = FIRST_STAMP + i * 10**7
                self.msg.header.stamp.sec, self.msg.header.stamp.nanosec = stamp // 10**9, stamp % 10**9
                sent[stamp] = time.perf_counter()
                self.pub.publish(self.msg)
                if rss_every and (i + 1) % rss_every == 0:
                    run.rss_mb.append((i + 1, _status_mb(proc.pid, 'VmRSS')))
            time.sleep(1.5)
            run.peak_mb = _status_mb(proc.pid, 'VmHWM')
        finally:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        with self._lock:
            answers = dict(self._answers)
        for stamp, (arrived, values) in answers.items():
            if stamp in sent:
                run.latencies_ms.append(1e3 * (arrived - sent[stamp]))
                run.processing_ms.append(float(values.get('processing_ms', 'nan')))
                run.dropped = max(run.dropped, int(values.get('frames_dropped', '0')))
        run.answered = len(run.latencies_ms)
        return run

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=2)
        self.node.destroy_node()
        self._rclpy.try_shutdown()
