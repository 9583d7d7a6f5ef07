"""ROS 2 node: PointCloud2 in, segmented planes and validity diagnostics out.

    ros2 run plane_validation plane_validation_node --ros-args --params-file config/params.yaml \
        -r cloud:=/camera/depth/points

Data flow: the subscription callback only puts the newest cloud into a one-slot mailbox (an
older unprocessed cloud is dropped and counted); a worker thread takes it, runs the shared
:class:`~plane_validation.pipeline.FramePipeline` and publishes. The first frame is tuned inline;
later retunes (``retune_period``) run in a background thread while frames keep being processed
with the current tolerance.
"""
from __future__ import annotations

import dataclasses
import sys
import threading

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from .messages import frame_messages
from ..app.pipeline import (ERROR, LEVEL_NAMES, OK, WARN, FramePipeline, PipelineConfig, header_stamp_ns,
                       limit_blas_threads)

#: name -> (description, (min, max) or None). Defaults come from PipelineConfig.
PARAMETERS = {
    'tolerance': ('RANSAC inlier distance t in meters (used when auto_tune is false, and before the first tune)',
                  (1e-6, 10.0)),
    'auto_tune': ('choose t by sweeping candidates and scoring them with the validity indices', None),
    'tune_min': ('smallest tuning candidate in meters; 0 = derive the range from the cloud', (0.0, 10.0)),
    'tune_max': ('largest tuning candidate in meters; 0 = derive the range from the cloud', (0.0, 10.0)),
    'tune_count': ('number of tuning candidates, geometrically spaced', (2, 100)),
    'tune_points': ('random subsample of the cloud the tuning sweep runs on', (100, 10_000_000)),
    'criterion': ('index that picks t: gs_planes, gs, silhouette, dunn (max) or davies_bouldin (min)', None),
    'retune_period': ('seconds between retunes, in header time; 0 = tune on the first frame only', (0.0, 1e6)),
    'max_planes': ('stop after this many planes', (1, 100)),
    'min_inliers': ('stop when the best plane has fewer inliers: a fraction of the valid points when < 1, '
                    'else a count', (0.0, 1e9)),
    'probability': ('RANSAC success probability that sets the iteration count', (1e-6, 0.999999)),
    'max_iterations': ('cap on RANSAC hypotheses per plane', (1, 1_000_000)),
    'index_sample_size': ('points the validity indices are computed on per frame (stratified sample)',
                          (10, 1_000_000)),
    'exact_indices': ('compute Dunn and Davies-Bouldin on all points (exact but ~0.2 s on a 300k-point frame) '
                      'instead of on the index sample', None),
    'ransac_points': ('RANSAC searches a random sample of this many points, then labels every point; 0 = all',
                      (0, 100_000_000)),
    'voxel_size': ('voxel grid in meters applied before detection; 0 = off', (0.0, 10.0)),
    'seed': ('random seed; frames are seeded by (seed, header stamp); < 0 = fresh entropy', (-1, 2**31 - 1)),
}


def _descriptor(name: str, default) -> ParameterDescriptor:
    description, bounds = PARAMETERS[name]
    desc = ParameterDescriptor(description=description)
    if bounds is not None and isinstance(default, float):
        desc.floating_point_range = [FloatingPointRange(from_value=float(bounds[0]), to_value=float(bounds[1]))]
    elif bounds is not None and isinstance(default, int) and not isinstance(default, bool):
        desc.integer_range = [IntegerRange(from_value=int(bounds[0]), to_value=int(bounds[1]), step=1)]
    return desc


class PlaneValidationNode(Node):
    """Subscribes ``cloud``; publishes ``~/segmented``, ``~/planes``, ``~/plane_poses``,
    ``~/plane_coefficients`` and ``/diagnostics``."""

    def __init__(self, name: str = 'plane_validation', **kwargs) -> None:
        super().__init__(name, **kwargs)
        defaults = PipelineConfig()
        config = {f.name: self.declare_parameter(f.name, getattr(defaults, f.name),
                                                 _descriptor(f.name, getattr(defaults, f.name))).value
                  for f in dataclasses.fields(PipelineConfig)}
        reliability = self.declare_parameter('reliability', 'best_effort', ParameterDescriptor(
            description='subscription reliability: best_effort (sensor data) or reliable', read_only=True)).value
        self.pipeline = FramePipeline(PipelineConfig(**config))
        self.add_on_set_parameters_callback(self._on_set_parameters)

        qos = QoSProfile(depth=1, history=qos_profile_sensor_data.history,
                         durability=qos_profile_sensor_data.durability,
                         reliability=ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                         else ReliabilityPolicy.BEST_EFFORT)
        self.create_subscription(PointCloud2, 'cloud', self._on_cloud, qos)
        self._pubs = {'segmented': self.create_publisher(PointCloud2, '~/segmented', 1),
                      'planes': self.create_publisher(MarkerArray, '~/planes', 1),
                      'plane_poses': self.create_publisher(PoseArray, '~/plane_poses', 1),
                      'plane_coefficients': self.create_publisher(Float64MultiArray, '~/plane_coefficients', 1),
                      'diagnostics': self.create_publisher(DiagnosticArray, '/diagnostics', 10)}
        self.status_name = f'{self.get_name()}: plane detection'
        self.frames_dropped = 0
        self._dropped_reported = 0
        self.frames_processed = 0
        self._slot: PointCloud2 | None = None
        self._wake = threading.Condition()
        self._stopping = False
        self._retuner: threading.Thread | None = None
        self._worker = threading.Thread(target=self._work, name='plane_validation_worker', daemon=True)
        self._worker.start()

    # -- input: single-slot handoff -------------------------------------------------------------
    def _on_cloud(self, msg: PointCloud2) -> None:
        with self._wake:
            if self._slot is not None:
                self.frames_dropped += 1
            self._slot = msg
            self._wake.notify()

    def _work(self) -> None:
        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._slot is not None or self._stopping)
                if self._stopping:
                    return
                msg, self._slot = self._slot, None
            try:
                self.process(msg)
            except Exception as exc:  # never let one frame kill the worker
                self.get_logger().error(f'frame failed unexpectedly: {exc!r}', throttle_duration_sec=5.0)

    # -- one frame -------------------------------------------------------------------------------
    def process(self, msg: PointCloud2) -> None:
        """Convert, run the shared pipeline, publish every output stamped with the input header."""
        result = self.pipeline.process_cloud(msg, tune_inline=self.pipeline.tolerance is None)
        stamp_ns = header_stamp_ns(msg.header)
        if result.segmentation is not None and self.pipeline.retune_due(stamp_ns * 1e-9):
            self._start_retune(result.points, stamp_ns)  # frames go on with the current t meanwhile
        self.frames_processed += 1
        with self._wake:
            dropped_now, self._dropped_reported = self.frames_dropped - self._dropped_reported, self.frames_dropped
        if dropped_now:
            result = dataclasses.replace(result, level=max(result.level, WARN),
                                         message=f'{result.message}; {dropped_now} older frame(s) dropped '
                                                 '(clouds arrive faster than they are processed)')
        extra = (('frames_processed', str(self.frames_processed)), ('frames_dropped', str(self.frames_dropped)),
                 ('retune_running', str(self._retuner is not None and self._retuner.is_alive()).lower()))
        for topic, out in frame_messages(msg.header, result, self.status_name, extra).items():
            self._pubs[topic].publish(out)
        if result.level != OK:
            log = self.get_logger().error if result.level == ERROR else self.get_logger().warning
            log(f'{LEVEL_NAMES[result.level]}: {result.message}', throttle_duration_sec=5.0)

    def _start_retune(self, points, stamp_ns: int) -> None:
        if self._retuner is not None and self._retuner.is_alive():
            return

        def run() -> None:
            try:
                result = self.pipeline.retune(points, stamp_ns * 1e-9, stamp_ns)
                self.get_logger().info(f'retuned: t = {result.tolerance:.4g} m ({result.verdict})')
            except Exception as exc:  # a failed sweep keeps the current tolerance; the node goes on
                self.get_logger().warning(f'retune failed, keeping t: {exc!r}', throttle_duration_sec=5.0)
        self._retuner = threading.Thread(target=run, name='plane_validation_retune', daemon=True)
        self._retuner.start()

    # -- parameters ------------------------------------------------------------------------------
    def _on_set_parameters(self, params) -> SetParametersResult:
        changes = {p.name: p.value for p in params if p.name in PARAMETERS}
        try:
            config = dataclasses.replace(self.pipeline.config, **changes).validate()
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.pipeline.reconfigure(config)
        return SetParametersResult(successful=True)

    def destroy_node(self) -> None:
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        self._worker.join(timeout=10)
        if self._retuner is not None:
            self._retuner.join(timeout=30)  # a sweep cannot be interrupted; it ends within seconds
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    limit_blas_threads()
    rclpy.init(args=args)
    try:
        node = PlaneValidationNode()
    except Exception as exc:  # invalid parameters (range, type, consistency): say which and exit
        print(f'plane_validation_node: cannot start: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
