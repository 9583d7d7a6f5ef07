"""A real rclpy harness for node tests: the plane node and a probe node on one executor.

The probe publishes clouds on ``/cloud`` and records what the plane node publishes, keyed by
header stamp, so a test can wait for the outputs of one particular frame.
"""
from __future__ import annotations

import threading
import time
from collections import defaultdict

import numpy as np
import rclpy
import sensor_msgs.msg
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray, Header
from visualization_msgs.msg import MarkerArray

from plane_validation.formats.pointcloud2 import create_cloud

OUTPUTS = {'segmented': PointCloud2, 'obstacles': PointCloud2, 'planes': MarkerArray, 'plane_poses': PoseArray,
           'plane_coefficients': Float64MultiArray}


def stamp_key(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def make_header(stamp_ns: int, frame_id: str = 'sensor') -> Header:
    return Header(stamp=Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000), frame_id=frame_id)


def xyz_cloud(points: np.ndarray, stamp_ns: int) -> PointCloud2:
    pts = np.asarray(points, dtype=np.float32)
    return create_cloud(make_header(stamp_ns), {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]},
                        types=sensor_msgs.msg)


class Harness:
    """Runs ``node`` and a probe on a background executor; collects outputs per stamp."""

    def __init__(self, node, node_name: str = 'plane_validation', outputs=tuple(OUTPUTS)) -> None:
        """outputs: the node's outputs the probe subscribes to (:meth:`listen` adds one later), besides
        /diagnostics."""
        self.node = node
        self.probe = rclpy.create_node('probe')
        self.received: dict[str, dict[int, object]] = defaultdict(dict)
        self.counts: dict[str, int] = defaultdict(int)  # messages received per output (stamps may repeat)
        self.lock = threading.Lock()
        self.pub = self.probe.create_publisher(PointCloud2, '/cloud',
                                               QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self.node_name = node_name
        for name in outputs:
            self.listen(name)
        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag,
                                       QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE))
        # not MultiThreadedExecutor: its spinning starves the node's worker thread of the GIL
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(node)
        self.executor.add_node(self.probe)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        self._wait(lambda: self.pub.get_subscription_count() > 0 and all(
            self.probe.count_publishers(f'/{node_name}/{n}') > 0 for n in OUTPUTS), 10, 'discovery')

    def listen(self, name: str) -> None:
        """Subscribe the probe to the node's output ``name``."""
        reliable = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.probe.create_subscription(OUTPUTS[name], f'/{self.node_name}/{name}', self._recorder(name), reliable)

    def _recorder(self, name):
        def record(msg) -> None:
            with self.lock:
                self.received[name][self._key(name, msg)] = msg
                self.counts[name] += 1
        return record

    def _key(self, name: str, msg) -> int:
        if name == 'plane_coefficients':
            # Float64MultiArray has no header: keyed by arrival order (negative counter).
            return -len(self.received[name]) - 1
        if name == 'planes':
            return stamp_key(msg.markers[0].header)
        return stamp_key(msg.header)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        with self.lock:
            self.received['diagnostics'][stamp_key(msg.header)] = msg
            self.counts['diagnostics'] += 1

    @staticmethod
    def _wait(condition, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if condition():
                return
            time.sleep(0.02)
        raise TimeoutError(f'timed out waiting for {what}')

    def send(self, msg: PointCloud2, timeout: float = 30.0, outputs=('diagnostics',)) -> dict[str, object]:
        """Publish one cloud and wait for the given outputs of its stamp (new ones: the stamp may repeat
        an earlier frame's)."""
        key = stamp_key(msg.header)
        with self.lock:
            before = {o: self.counts[o] for o in outputs}
            for o in outputs:  # an earlier frame's output of this stamp is no answer (nor is a new count alone)
                self.received[o].pop(key, None)
        self.pub.publish(msg)
        self._wait(lambda: all(key in self.received[o] and self.counts[o] > before[o] for o in outputs),
                   timeout, f'outputs of frame {key}')
        with self.lock:
            return {o: self.received[o][key] for o in outputs}

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=5)
        self.thread.join(timeout=5)
        self.node.destroy_node()
        self.probe.destroy_node()


def diag_values(diag: DiagnosticArray) -> dict[str, str]:
    (status,) = diag.status
    return {kv.key: kv.value for kv in status.values}
