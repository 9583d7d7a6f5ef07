"""ROS 2 node: PointCloud2 in, segmented planes and validity diagnostics out.

    ros2 run plane_validation plane_validation_node --ros-args --params-file config/params.yaml \
        -r cloud:=/camera/depth/points

Data flow: the subscription callback only puts the newest cloud into a one-slot mailbox (an
older unprocessed cloud is dropped and counted); a worker thread takes it, runs the shared
:class:`~plane_validation.app.pipeline.FramePipeline` and publishes. Tolerance sweeps (the first,
later ones every ``retune_period``, retries of a failed one) run in a background thread while frames keep being
processed with the current tolerance (a quick estimate until the first sweep ends). A frame that
comes due while a sweep runs is kept and swept when it ends, so the node sweeps the frames offline
replay sweeps (when it drops none).
"""
from __future__ import annotations

import dataclasses
import sys
import threading

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2

from ..app.config import PARAMETERS, Parameter, PipelineConfig
from ..app.diagnostics import Level
from ..app.pipeline import FramePipeline, header_stamp_ns, limit_blas_threads
from ..core.kernels import warm
from .messages import OUTPUTS, frame_messages, node_values, status_name

ERROR, WARN = Level.ERROR, Level.WARN
#: Seconds between two log lines of the same kind.
LOG_THROTTLE_S = 5.0
#: Seconds destroy_node waits for a running sweep to stop (it stops after its current candidate).
SWEEP_STOP_S = 3.0
#: Seconds between two looks at whether the node's context has shut down (spin).
SPIN_CHECK_S = 0.5

#: Node-only parameters (the pipeline's are in app/config.py's table).
NODE_PARAMETERS = {'reliability': Parameter('reliability', 'best_effort', 'subscription reliability: best_effort '
                                            '(sensor data) or reliable', choices=('best_effort', 'reliable'),
                                            read_only=True)}


def descriptor(spec: Parameter) -> ParameterDescriptor:
    """The ROS parameter descriptor of one table entry (its range includes the special value)."""
    desc = ParameterDescriptor(description=spec.description + (f' [{spec.unit}]' if spec.unit else ''),
                               read_only=spec.read_only,
                               # a whole number for a float (`tolerance: 1`, `-p min_inliers:=500`) is fine;
                               # (Parameter.converted); the table's check refuses every other type instead
                               dynamic_typing=spec.type is float)
    if spec.low is not None:
        lo, hi = spec.low, spec.high
        if spec.special is not None:
            lo, hi = min(lo, spec.special), max(hi, spec.special)
        if spec.type is float:
            desc.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
        elif spec.type is int:
            desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
    return desc


def params_yaml(node_name: str = 'plane_validation') -> str:
    """config/params.yaml: every node parameter at its default, with its description."""
    lines = ['# Parameters of plane_validation_node (generated from plane_validation/app/config.py and',
             '# ros/node.py by params_yaml(); a test checks it). Distances are in meters.',
             '#   ros2 run plane_validation plane_validation_node --ros-args --params-file config/params.yaml \\',
             '#     -r cloud:=/camera/depth/points',
             f'{node_name}:', '  ros__parameters:']
    for spec in {**PARAMETERS, **NODE_PARAMETERS}.values():
        value = str(spec.default).lower() if spec.type is bool else spec.default
        lines.append(f'    # {spec.description}' + (f' [{spec.unit}]' if spec.unit else ''))
        lines.append(f'    {spec.name}: {value}')
    return '\n'.join(lines) + '\n'


class PlaneValidationNode(Node):
    """Subscribes ``cloud``; publishes ``~/segmented``, ``~/planes``, ``~/plane_poses``,
    ``~/plane_coefficients`` and ``/diagnostics``."""

    def __init__(self, name: str = 'plane_validation', **kwargs) -> None:
        super().__init__(name, **kwargs)
        config = {name: spec.converted(self.declare_parameter(name, spec.default, descriptor(spec)).value)
                  for name, spec in PARAMETERS.items()}
        reliability = self.declare_parameter('reliability', NODE_PARAMETERS['reliability'].default,
                                             descriptor(NODE_PARAMETERS['reliability'])).value
        why = NODE_PARAMETERS['reliability'].problem(reliability)
        if why is not None:
            raise ValueError(why)
        self.pipeline = FramePipeline(PipelineConfig(**config))
        ready = warm()  # before the subscription: the first frame must not wait for a compiler
        self.get_logger().info(f'compiled kernels ready in {ready.seconds:.2f} s ' + (
            '(compiled now and cached: later starts load them)' if ready.compiled else '(loaded from the cache)'))
        self.add_on_set_parameters_callback(self._on_set_parameters)

        qos = QoSProfile(depth=1, history=qos_profile_sensor_data.history,
                         durability=qos_profile_sensor_data.durability,
                         reliability=ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                         else ReliabilityPolicy.BEST_EFFORT)
        self.create_subscription(PointCloud2, 'cloud', self._on_cloud, qos)
        self._pubs = {key: self.create_publisher(cls, '/diagnostics', 10) if key == 'diagnostics'
                      else self.create_publisher(cls, f'~/{key}', 1) for key, cls in OUTPUTS.items()}
        self.status_name = status_name(self.get_name())
        self.frames_dropped = 0
        self._dropped_reported = 0
        self.frames_processed = 0
        self._slot: PointCloud2 | None = None
        self._wake = threading.Condition()
        self._stopping = False
        self._sweep_idle = threading.Event()
        self._sweep_idle.set()
        self._sweep_lock = threading.Lock()
        self._sweeping_on: float | None = None  # stamp (s) of the frame the running sweep runs on
        self._next_sweep = None  # (frame, stamp_ns) kept for the sweep after it
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
                dropped = self.frames_dropped  # the clouds this one replaced: older than it
            try:
                self.process(msg, dropped)
            except Exception as exc:  # never let one frame kill the worker
                if self._stopping or not self.context.ok():
                    return  # shutting down: publishing failed because the context is gone
                self.get_logger().error(f'frame failed unexpectedly: {exc!r}', throttle_duration_sec=LOG_THROTTLE_S)

    # -- one frame -------------------------------------------------------------------------------
    def process(self, msg: PointCloud2, dropped: int) -> None:
        """Convert, run the shared pipeline, publish every output stamped with the input header.
        dropped: frames_dropped when this cloud was taken; the drops since the last frame are
        reported with it (those meanwhile are older than the next frame, not this one)."""
        result = self.pipeline.process_cloud(msg, tune_inline=False)
        stamp_ns = header_stamp_ns(msg.header)
        retune = result.segmentation is not None and self._reserve_sweep(result, stamp_ns)
        self.frames_processed += 1
        with self._wake:
            dropped_now, self._dropped_reported = dropped - self._dropped_reported, dropped
        if dropped_now:
            result = dataclasses.replace(result, diagnostic=result.diagnostic.escalated(
                WARN, f'{dropped_now} older frame(s) dropped (clouds arrive faster than they are processed)'))
        extra = node_values(self.frames_processed, dropped, retune or self._tuning(), dropped_now)
        for topic, out in frame_messages(msg.header, result, self.status_name, extra).items():
            self._pubs[topic].publish(out)
        if retune:  # after publishing: the sweep competes for the GIL; frames go on with the current t
            self._start_retune(result, stamp_ns)

        if not self.context.ok():
            return  # shutting down: rosout is gone, a line now would only say it cannot be published
        # rclpy ties a throttled call site to one severity: one call site per level, throttled apart
        if result.level == ERROR:
            self.get_logger().error(f'ERROR: {result.message}', throttle_duration_sec=LOG_THROTTLE_S)
        elif result.level == WARN:
            self.get_logger().warning(f'WARN: {result.message}', throttle_duration_sec=LOG_THROTTLE_S)

    def _tuning(self) -> bool:
        return not self._sweep_idle.is_set()

    def _reserve_sweep(self, frame, stamp_ns: int) -> bool:
        """Whether this frame starts a sweep (wait_for_sweep waits from now on). While a sweep runs,
        the first frame due after it is kept and swept when it ends, as offline replay would."""
        stamp = frame.clock
        with self._sweep_lock:
            if self._stopping:
                return False
            if self._sweeping_on is not None:
                if self._next_sweep is None and self.pipeline.due_after_failed_sweep(self._sweeping_on, stamp):
                    self._next_sweep = (frame, stamp_ns)
                return False
            if not self.pipeline.retune_due(stamp):
                return False
            self._sweeping_on = stamp
            self._sweep_idle.clear()
            return True

    def _sweep_ended(self) -> None:
        """Start the kept frame's sweep if it is due now that the last one ended, else go idle."""
        with self._sweep_lock:
            kept, self._next_sweep = self._next_sweep, None
            if kept is not None and not self._stopping and self.pipeline.retune_due(kept[0].clock):
                self._sweeping_on = kept[0].clock
            else:
                kept, self._sweeping_on = None, None
                self._sweep_idle.set()
        if kept is not None:
            self._start_retune(*kept)

    def _start_retune(self, frame, stamp_ns: int) -> None:
        points, shape = frame.sweep_cloud

        def run() -> None:
            try:
                result = self.pipeline.retune(points, frame.clock, stamp_ns, shape=shape,
                                              stop=lambda: self._stopping)
                if result is not None and self.pipeline.last_tuning is result and not self._stopping:
                    log = self.get_logger().info if result.reliable else self.get_logger().warning  # as the frames
                    log(f'retuned: t = {result.tolerance:.4g} m ({result.verdict})')
            except KeyboardInterrupt:  # Ctrl-C reached a worker process of a parallel sweep: the node stops
                pass
            except Exception as exc:  # a failed sweep keeps the current tolerance; the node goes on
                if not self._stopping:
                    self.get_logger().warning(f'retune failed, keeping t: {str(exc) or type(exc).__name__}',
                                              throttle_duration_sec=LOG_THROTTLE_S)
            finally:
                self._sweep_ended()
        threading.Thread(target=run, name='plane_validation_retune', daemon=True).start()

    def wait_for_sweep(self, timeout: float | None = None) -> bool:
        """Wait until no tolerance sweep is running (True) or ``timeout`` seconds pass (False)."""
        return self._sweep_idle.wait(timeout)

    # -- parameters ------------------------------------------------------------------------------
    def _on_set_parameters(self, params) -> SetParametersResult:
        changes = {p.name: PARAMETERS[p.name].converted(p.value) for p in params if p.name in PARAMETERS}
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
        # a sweep stops after its current candidate; one that takes longer is left to its daemon thread
        self._sweep_idle.wait(timeout=SWEEP_STOP_S)
        super().destroy_node()


def spin(node: Node, executor: SingleThreadedExecutor | None = None) -> None:
    """Serve ``node`` until its context shuts down, looking at the context every SPIN_CHECK_S: a SIGTERM's
    shutdown can fail to wake an executor that waits without a timeout (about 1 in 6 SIGTERMs during a parallel
    sweep left such an executor waiting forever with its context gone)."""
    executor = executor or SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok():
            executor.spin_once(timeout_sec=SPIN_CHECK_S)
    finally:
        executor.remove_node(node)


def usage() -> str:
    """The node's --help: how to start it, its topics and its parameters (from the parameter tables)."""
    lines = ['usage: plane_validation_node [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] '
             '[-r cloud:=TOPIC]]', '',
             'Subscribes to sensor_msgs/PointCloud2 on "cloud"; publishes '
             + ', '.join(f'~/{key}' for key in list(OUTPUTS)[:-1]) + ' and /diagnostics.',
             'config/params.yaml (installed in share/plane_validation/config) lists every parameter with its '
             'default. Parameters:']
    for spec in (*PARAMETERS.values(), *NODE_PARAMETERS.values()):
        allowed = f'; {spec.allowed}' if spec.allowed else ''
        lines.append(f'  {spec.name} (default {spec.default}{allowed}): {spec.description}')
    return '\n'.join(lines)


def main(args: list[str] | None = None) -> int:
    own = list(sys.argv[1:] if args is None else args)
    if '--ros-args' in own:  # the node's own arguments: those before it and after a '--' that ends the ROS ones
        ros = own[own.index('--ros-args') + 1:]
        own = own[:own.index('--ros-args')] + (ros[ros.index('--') + 1:] if '--' in ros else [])
    if '-h' in own or '--help' in own:  # rclpy would ignore them and start the node
        print(usage())
        return 0
    try:
        limit_blas_threads()
        rclpy.init(args=args)
    except KeyboardInterrupt:  # Ctrl-C while starting: as quiet as while spinning
        rclpy.try_shutdown()
        return 0
    except Exception as exc:  # malformed --ros-args, a params file that is missing or not YAML
        print(f'plane_validation_node: cannot start: {exc}', file=sys.stderr)
        return 2
    try:
        node = PlaneValidationNode()
    except KeyboardInterrupt:  # Ctrl-C while starting: as quiet as while spinning
        rclpy.try_shutdown()
        return 0
    except Exception as exc:  # invalid parameters (range, type, consistency): say which and exit
        print(f'plane_validation_node: cannot start: {exc}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:  # rclpy's RCLError "context is not valid": a signal shut it down as spin began
        if rclpy.ok():
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
