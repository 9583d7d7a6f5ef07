"""The node end to end: a real plane_validation node process fed PointCloud2s over Fast DDS.

The node runs as ``python -m plane_validation.ros.node`` (what ``ros2 run`` starts), one fresh
process per run, on this process's ROS_DOMAIN_ID with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and
the Fast DDS profile the caller put in FASTRTPS_DEFAULT_PROFILES_FILE (all set before rclpy
starts). This process publishes organized frames in turn with fresh header stamps at a fixed
rate (sensor-data QoS, as a camera driver does; stamps advance by 1/rate s, like a camera's) and
listens to ``/diagnostics`` and to the node's other ``outputs`` (by default every one) as serialized
messages, which it does not deserialize (the node builds only the outputs that have subscribers).

Per run: latency = arrival of a stamp's diagnostics - the moment just before ``publish()`` (both
on this process's perf_counter); ``dropped`` = the node's own ``frames_dropped`` count (its
one-slot mailbox); ``lost`` = frames neither answered nor counted by the node (lost in transport
or still unanswered when the run ended). RSS: VmRSS / VmHWM of the node process from /proc.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

TOPIC = '/bench/points'
NODE_NAME = 'plane_validation'  # the node's default name: its outputs are /plane_validation/<key>
FIRST_STAMP = 10**12   # ns; anything older on /diagnostics is not ours
ANSWER_TIMEOUT = 5.0   # s to wait for the last answers after the last frame


@dataclass
class NodeRun:
    """One run. rate: input Hz; latencies_ms / processing_ms / outputs_ms / retune_running: per answered frame
    in stamp order; rss_mb: (frames sent, VmRSS MB) samples; peak_mb: VmHWM at the end."""

    rate: float
    sent: int
    dropped: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    processing_ms: list[float] = field(default_factory=list)
    outputs_ms: list[float] = field(default_factory=list)
    retune_running: list[bool] = field(default_factory=list)
    tolerance_sources: list[str] = field(default_factory=list)
    rss_mb: list[tuple[int, float]] = field(default_factory=list)
    peak_mb: float = float('nan')
    startup_rss_mb: float = float('nan')
    received: dict[str, int] = field(default_factory=dict)  # messages this process got per output topic

    @property
    def answered(self) -> int:
        return len(self.latencies_ms)

    @property
    def lost(self) -> int:
        return self.sent - self.answered - self.dropped

    @property
    def sustained(self) -> bool:
        """Every frame answered: nothing dropped by the node, nothing lost on the way."""
        return self.answered == self.sent


def status_mb(pid: int, key: str) -> float:
    """A /proc/<pid>/status size (VmRSS, VmHWM) in MB, NaN when the process is gone."""
    try:
        with open(f'/proc/{pid}/status') as f:
            for line in f:
                if line.startswith(key + ':'):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float('nan')


def cloud_message(points: np.ndarray, height: int, width: int):
    """An rclpy PointCloud2 of (height*width, 3) points: x, y, z float32 and a zero rgb, organized
    when height > 1 (the layout of a depth camera driver), built by plane_validation's create_cloud."""
    import sensor_msgs.msg
    from std_msgs.msg import Header

    from plane_validation.formats.pointcloud2 import create_cloud, pack_rgb
    pts = np.asarray(points, dtype=np.float32)
    zero = np.zeros(len(pts), np.uint8)
    msg = create_cloud(Header(frame_id='camera'), {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2],
                                                   'rgb': pack_rgb(zero, zero, zero)}, types=sensor_msgs.msg)
    msg.height, msg.width, msg.row_step = height, width, width * msg.point_step
    return msg


class NodeBench:
    """Publisher and /diagnostics listener in this process; :meth:`run` starts one node process."""

    def __init__(self, clouds: list, tolerance: float, planes: int, log_dir: Path,
                 outputs: tuple[str, ...] | None = None) -> None:
        """outputs: the node's outputs (keys of messages.OUTPUTS) this process subscribes to besides /diagnostics;
        None: every one."""
        import rclpy
        import sensor_msgs.msg
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

        from plane_validation.ros.messages import OUTPUTS

        self.clouds, self.tolerance, self.planes, self.log_dir = clouds, tolerance, planes, log_dir
        rclpy.init()
        self._rclpy = rclpy
        self.node = rclpy.create_node('plane_validation_bench')
        self.pub = self.node.create_publisher(sensor_msgs.msg.PointCloud2, TOPIC, qos_profile_sensor_data)
        self._lock = threading.Lock()
        self._answers: dict[int, tuple[float, dict[str, str]]] = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                      QoSProfile(depth=500, reliability=ReliabilityPolicy.RELIABLE))
        self.received: dict[str, int] = {}
        wanted = [key for key in OUTPUTS if key != 'diagnostics' and (outputs is None or key in outputs)]
        self.output_topics = [f'/{NODE_NAME}/{key}' for key in wanted]
        for topic in self.output_topics:
            cls = OUTPUTS[topic.rsplit('/', 1)[1]]
            self.received[topic] = 0
            self.node.create_subscription(cls, topic, lambda _msg, topic=topic: self._count(topic),
                                          QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE), raw=True)
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._executor.spin, daemon=True)
        self._spinner.start()

    def _count(self, topic: str) -> None:
        with self._lock:
            self.received[topic] += 1

    def _on_diag(self, msg) -> None:
        now = time.perf_counter()
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        if stamp >= FIRST_STAMP and msg.status:
            with self._lock:
                self._answers[stamp] = (now, {kv.key: kv.value for kv in msg.status[0].values})

    def _start(self, params: dict[str, str], name: str) -> subprocess.Popen:
        args = {'auto_tune': 'false', 'tolerance': str(self.tolerance), 'max_planes': str(self.planes), **params}
        cmd = [sys.executable, '-m', 'plane_validation.ros.node', '--ros-args',
               *[a for k, v in args.items() for a in ('-p', f'{k}:={v}')], '-r', f'cloud:={TOPIC}']
        with open(self.log_dir / f'node_{name}.log', 'w') as log:  # the child keeps its own descriptor
            return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)

    @staticmethod
    def _stop(proc: subprocess.Popen) -> None:
        """SIGINT (a clean rclpy shutdown), then SIGKILL after 15 s."""
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    def _wait_ready(self, proc: subprocess.Popen) -> None:
        end = time.monotonic() + 30
        while self.pub.get_subscription_count() == 0 or any(
                self.node.count_publishers(t) == 0 for t in ('/diagnostics', *self.output_topics)):
            if proc.poll() is not None:
                raise RuntimeError(f'node exited with {proc.returncode} (see {self.log_dir})')
            if time.monotonic() > end:
                raise RuntimeError('node not discovered within 30 s')
            time.sleep(0.05)
        time.sleep(1.0)  # let the node's /diagnostics writer match our reader too

    def run(self, rate: float, frames: int, *, params: dict[str, str] | None = None, rss_every: int = 0,
            name: str = 'run') -> NodeRun:
        """Start a node, send ``frames`` clouds at ``rate`` Hz, collect the answers, stop the node."""
        with self._lock:
            self._answers.clear()
            self.received = dict.fromkeys(self.received, 0)
        proc = self._start(params or {}, name)
        run = NodeRun(rate=rate, sent=frames)
        sent: dict[int, float] = {}
        try:
            self._wait_ready(proc)
            run.startup_rss_mb = status_mb(proc.pid, 'VmRSS')
            start = time.perf_counter()
            for i in range(frames):
                target = start + i / rate
                while (now := time.perf_counter()) < target:
                    time.sleep(min(0.002, target - now))
                stamp = FIRST_STAMP + round(i * 1e9 / rate)
                msg = self.clouds[i % len(self.clouds)]
                msg.header.stamp.sec, msg.header.stamp.nanosec = stamp // 10**9, stamp % 10**9
                sent[stamp] = time.perf_counter()
                self.pub.publish(msg)
                if rss_every and (i + 1) % rss_every == 0:
                    run.rss_mb.append((i + 1, status_mb(proc.pid, 'VmRSS')))
            last = max(sent)
            end = time.monotonic() + ANSWER_TIMEOUT
            while time.monotonic() < end:
                with self._lock:
                    if last in self._answers:
                        break
                time.sleep(0.02)
            time.sleep(0.2)
            run.peak_mb = status_mb(proc.pid, 'VmHWM')
        finally:
            self._stop(proc)
        with self._lock:
            answers = dict(self._answers)
            run.received = dict(self.received)
        for stamp in sorted(answers):
            if stamp in sent:
                arrived, values = answers[stamp]
                run.latencies_ms.append(1e3 * (arrived - sent[stamp]))
                run.processing_ms.append(float(values.get('processing_ms', 'nan')))
                run.outputs_ms.append(float(values.get('outputs_ms', 'nan')))
                run.retune_running.append(values.get('retune_running', 'false') == 'true')
                run.tolerance_sources.append(values.get('tolerance_source', ''))
                run.dropped = max(run.dropped, int(values.get('frames_dropped', '0')))
        return run

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=2)
        self.node.destroy_node()
        self._rclpy.try_shutdown()


def domain_environment() -> None:
    """An isolated DDS domain for this process and its node processes (before rclpy starts)."""
    os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
