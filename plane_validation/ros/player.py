"""Play clouds on a ROS topic at their recorded timing (like ``ros2 bag play``) and listen to a
plane_validation node's outputs, in a private rclpy context."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable

from .recorder import output_topics

__all__ = ['LiveSession', 'play', 'wait_for']


def wait_for(condition: Callable[[], bool], timeout: float, what: str, error: type[Exception]) -> None:
    """Poll ``condition`` every 20 ms; raise ``error`` naming ``what`` after ``timeout`` seconds."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return
        time.sleep(0.02)
    raise error(f'timed out after {timeout:.0f} s waiting for {what}')


def play(frames: list[tuple[int, object]], publish: Callable[[int, object], None], rate: float,
         before_each: Callable[[], None] = lambda: None) -> None:
    """Call ``publish(bag_timestamp_ns, msg)`` for each frame at its recorded time divided by ``rate``;
    the time ``before_each()`` takes (which may wait for the node) shifts the frames after it."""
    start = time.monotonic()
    first = frames[0][0]
    for ts, msg in frames:
        paused = time.monotonic()
        before_each()
        start += time.monotonic() - paused
        delay = start + (ts - first) / 1e9 / rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        publish(ts, msg)


class LiveSession:
    """A private rclpy context with a player node that publishes on ``cloud_topic`` and delivers
    every output of node ``node_name`` to ``receive(key, msg)``; optionally the node itself
    (``node_factory(context)``), all spun by one SingleThreadedExecutor thread."""

    def __init__(self, cloud_topic: str, node_name: str, receive: Callable[[str, object], None],
                 node_factory: Callable[[object], object] | None = None) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import PointCloud2

        from .messages import OUTPUTS

        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.nodes: list = []
        # One executor thread is plenty (the callbacks only hand messages over); rclpy's
        # MultiThreadedExecutor spins hard enough on the GIL to starve the node's worker thread.
        self.executor = SingleThreadedExecutor(context=self.context)
        try:
            self.player = rclpy.create_node('plane_validation_player', context=self.context)
            self.nodes.append(self.player)
            reliable = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE)
            self.publisher = self.player.create_publisher(PointCloud2, cloud_topic, QoSProfile(
                depth=10, reliability=ReliabilityPolicy.RELIABLE))
            self.topics = output_topics(node_name)
            for key, cls in OUTPUTS.items():
                self.player.create_subscription(cls, self.topics[key], lambda msg, key=key: receive(key, msg), reliable)
            if node_factory is not None:
                self.nodes.append(node_factory(self.context))
            for node in self.nodes:
                self.executor.add_node(node)
            self.spinning = threading.Thread(target=self.executor.spin, daemon=True)
            self.spinning.start()
        except BaseException:
            self.close()
            raise

    def connected(self) -> bool:
        """A node subscribes to the cloud topic and publishes every output."""
        return self.publisher.get_subscription_count() > 0 and all(
            self.player.count_publishers(t) > 0 for t in self.topics.values())

    def close(self) -> None:
        import rclpy
        self.executor.shutdown(timeout_sec=5)
        spinning = getattr(self, 'spinning', None)
        if spinning is not None and spinning is not threading.current_thread():
            # its spin returns after the shutdown; a process that exits while it is still in rclpy's wait (after
            # talking to a node in another process) was aborted ('terminate called without an active exception')
            spinning.join(timeout=5)
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)
