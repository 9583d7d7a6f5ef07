"""Replay recorded PointCloud2 bags through the plane detector.

Offline (default): read each cloud with ``rosbags`` (rosbag2 sqlite3/MCAP, compressed or not,
and ROS 1 ``.bag``), run the node's per-frame pipeline (:meth:`FramePipeline.process_cloud`) and
write an output bag with the input clouds and every node output at the original timestamps.
Live: publish the clouds on ROS topics at their recorded timing (like ``ros2 bag play``),
optionally with the node started in the same process, and record what it publishes.
"""
from __future__ import annotations

import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from ..app.pipeline import FramePipeline, FrameResult, PipelineConfig, header_stamp_ns

__all__ = ['ReplayError', 'FrameSummary', 'ReplaySummary', 'read_clouds', 'replay_offline', 'replay_live',
           'output_topics', 'POINTCLOUD2']

POINTCLOUD2 = 'sensor_msgs/msg/PointCloud2'
_TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
#: Output topic suffix -> message type, as the node publishes them (under /<node name>/).
OUTPUT_TYPES = {'segmented': POINTCLOUD2, 'planes': 'visualization_msgs/msg/MarkerArray',
                'plane_poses': 'geometry_msgs/msg/PoseArray',
                'plane_coefficients': 'std_msgs/msg/Float64MultiArray'}


class ReplayError(ValueError):
    """A bag that cannot be replayed: missing, corrupt, no such topic, wrong type, bad output path."""


def output_topics(node_name: str = 'plane_validation') -> dict[str, str]:
    """Output key -> topic name, as the node publishes them."""
    topics = {key: f'/{node_name}/{key}' for key in OUTPUT_TYPES}
    topics['diagnostics'] = '/diagnostics'
    return topics


@dataclass(frozen=True)
class FrameSummary:
    """One replayed frame: bag timestamp (ns), planes, tolerance (m), GSplanes, level, ms."""

    index: int
    timestamp: int
    n_planes: int
    tolerance: float
    gs_planes: float
    level: int
    message: str
    ms: float

    def line(self) -> str:
        level = ('OK', 'WARN', 'ERROR')[self.level]
        return (f'frame {self.index:4d}  t={self.timestamp / 1e9:.3f}s  planes {self.n_planes:2d}  '
                f'tolerance {self.tolerance:.4g} m  GSplanes {self.gs_planes:6.3f}  {self.ms:7.1f} ms  '
                f'{level}: {self.message}')


@dataclass
class ReplaySummary:
    bag: Path
    topic: str
    output: Path | None
    frames: list[FrameSummary] = field(default_factory=list)
    dropped: int = 0
    last_segmented: object | None = None  # the last frame's segmented PointCloud2 (rclpy)

    def line(self) -> str:
        if not self.frames:
            return f'{self.bag}: no frames replayed'
        ms = np.array([f.ms for f in self.frames])
        counts = np.bincount([f.n_planes for f in self.frames])
        planes = ', '.join(f'{k} planes x{c}' for k, c in enumerate(counts) if c)
        out = f'; output bag {self.output}' if self.output else ''
        dropped = f', {self.dropped} dropped' if self.dropped else ''
        return (f'{len(self.frames)} frames from {self.bag} [{self.topic}]{dropped}: {planes}; '
                f'median {np.median(ms):.1f} ms per frame; last tolerance {self.frames[-1].tolerance:.4g} m{out}')


def _open(bag: Path) -> AnyReader:
    if not bag.exists():
        raise ReplayError(f'bag not found: {bag}')
    try:
        reader = AnyReader([bag], default_typestore=_TYPESTORE)
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise ReplayError(f'cannot open bag {bag}: {exc}') from exc
    return reader


def _pick_topic(reader: AnyReader, bag: Path, topic: str | None) -> list:
    clouds = sorted({c.topic for c in reader.connections if c.msgtype == POINTCLOUD2})
    if topic is None:
        if len(clouds) != 1:
            found = ', '.join(clouds) or 'none'
            raise ReplayError(f'{bag}: cannot pick the cloud topic automatically (PointCloud2 topics: {found}); '
                              'pass --topic')
        topic = clouds[0]
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise ReplayError(f'{bag}: no topic {topic!r}; PointCloud2 topics: {", ".join(clouds) or "none"}')
    if any(c.msgtype != POINTCLOUD2 for c in conns):
        raise ReplayError(f'{bag}: topic {topic!r} carries {conns[0].msgtype}, not {POINTCLOUD2}')
    return conns


def read_clouds(bag: str | Path, topic: str | None = None) -> Iterator[tuple[str, int, object]]:
    """Yield (topic, bag timestamp ns, rosbags PointCloud2) for every cloud on ``topic``
    (auto-detected when the bag has exactly one PointCloud2 topic)."""
    bag = Path(bag)
    reader = _open(bag)
    try:
        conns = _pick_topic(reader, bag, topic)
        try:
            for conn, timestamp, raw in reader.messages(connections=conns):
                yield conn.topic, timestamp, reader.deserialize(raw, conn.msgtype)
        except ReplayError:
            raise
        except Exception as exc:  # rosbags raises many types on damaged data
            raise ReplayError(f'{bag}: cannot read message: {type(exc).__name__}: {exc}') from exc
    finally:
        reader.close()


def to_rclpy_cloud(msg):
    """rosbags PointCloud2 (ROS 2 or ROS 1 layout) -> rclpy sensor_msgs/PointCloud2, data copied once."""
    import array

    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import PointCloud2, PointField
    from std_msgs.msg import Header

    stamp = msg.header.stamp
    out = PointCloud2(header=Header(stamp=Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec)),
                                    frame_id=str(msg.header.frame_id)),
                      height=int(msg.height), width=int(msg.width), is_bigendian=bool(msg.is_bigendian),
                      point_step=int(msg.point_step), row_step=int(msg.row_step), is_dense=bool(msg.is_dense),
                      fields=[PointField(name=str(f.name), offset=int(f.offset), datatype=int(f.datatype),
                                         count=int(f.count)) for f in msg.fields])
    out.data = array.array('B', np.asarray(msg.data, dtype=np.uint8).tobytes())
    return out


def _output_path(bag: Path, out: str | Path | None) -> Path:
    path = Path(out) if out is not None else bag.parent / f'{bag.name.removesuffix(".bag")}.planes'
    if path.exists():
        raise ReplayError(f'output {path} already exists; remove it or pass another --out')
    return path


class BagRecorder:
    """Writes the input clouds and node outputs to a rosbag2 directory; only a complete bag is kept.

    Writes go to ``<path>.partial`` which is renamed to ``path`` on :meth:`close`; on
    :meth:`abort` (or an exception inside ``with``) it is deleted.
    """

    def __init__(self, path: Path, input_topic: str, node_name: str = 'plane_validation',
                 storage: StoragePlugin = StoragePlugin.SQLITE3) -> None:
        self.path = path
        self.partial = path.with_name(path.name + '.partial')
        if self.partial.exists():
            shutil.rmtree(self.partial)
        try:
            self.writer = Writer(self.partial, version=9, storage_plugin=storage)
            self.writer.open()
            self.connections = {'input': self.writer.add_connection(input_topic, POINTCLOUD2,
                                                                    typestore=_TYPESTORE)}
            for key, topic in output_topics(node_name).items():
                msgtype = OUTPUT_TYPES.get(key, 'diagnostic_msgs/msg/DiagnosticArray')
                self.connections[key] = self.writer.add_connection(topic, msgtype, typestore=_TYPESTORE)
        except Exception as exc:
            shutil.rmtree(self.partial, ignore_errors=True)
            raise ReplayError(f'cannot write output bag {path}: {exc}') from exc

    def write(self, key: str, timestamp: int, msg) -> None:
        from rclpy.serialization import serialize_message
        self.writer.write(self.connections[key], timestamp, serialize_message(msg))

    def close(self) -> Path:
        self.writer.close()
        self.partial.rename(self.path)
        return self.path

    def abort(self) -> None:
        try:
            self.writer.close()
        except Exception:  # noqa: BLE001 - the bag is being thrown away anyway
            pass
        shutil.rmtree(self.partial, ignore_errors=True)

    def __enter__(self) -> 'BagRecorder':
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def _summary(index: int, timestamp: int, result: FrameResult) -> FrameSummary:
    gs_planes = result.indices.gs_planes if result.indices is not None else float('nan')
    return FrameSummary(index=index, timestamp=timestamp, n_planes=result.n_planes, tolerance=result.tolerance,
                        gs_planes=gs_planes, level=result.level, message=result.message, ms=1000 * result.seconds)


def _progress(total: int, enabled: bool | None):
    """A tqdm bar on a terminal (None = auto), else a no-op with the same interface."""
    from tqdm import tqdm
    return tqdm(total=total, unit='frame', disable=None if enabled is None else not enabled, file=sys.stderr)


def replay_offline(bag: str | Path, *, topic: str | None = None, out: str | Path | None = None,
                   config: PipelineConfig | None = None, node_name: str = 'plane_validation',
                   echo: Callable[[str], None] | None = print, progress: bool | None = None) -> ReplaySummary:
    """Run every cloud of ``bag`` through the node's per-frame pipeline and write ``out``.

    out: output rosbag2 directory (default ``<bag>.planes`` beside the bag); it appears only once
    complete. echo: receives the per-frame lines (None = silent). Raises ReplayError.
    """
    from .messages import frame_messages

    bag = Path(bag)
    out_path = _output_path(bag, out)
    reader = _open(bag)
    try:
        conns = _pick_topic(reader, bag, topic)
        total = sum(c.msgcount for c in conns)
    finally:
        reader.close()
    pipeline = FramePipeline(config or PipelineConfig())
    summary = ReplaySummary(bag=bag, topic=conns[0].topic, output=out_path)
    status_name = f'{node_name}: plane detection'
    bar = _progress(total, progress)
    recorder = None
    try:
        recorder = BagRecorder(out_path, conns[0].topic, node_name)
        for index, (_, timestamp, cloud) in enumerate(read_clouds(bag, conns[0].topic)):
            msg = to_rclpy_cloud(cloud)
            result = pipeline.process_cloud(msg)
            extra = (('frames_processed', str(index + 1)), ('frames_dropped', '0'), ('retune_running', 'false'))
            recorder.write('input', timestamp, msg)
            for key, out_msg in frame_messages(msg.header, result, status_name, extra).items():
                recorder.write(key, timestamp, out_msg)
                if key == 'segmented':
                    summary.last_segmented = out_msg
            frame = _summary(index, timestamp, result)
            summary.frames.append(frame)
            bar.update(1)
            if echo is not None:
                bar.write(frame.line(), file=sys.stdout) if not bar.disable else echo(frame.line())
    except BaseException:
        if recorder is not None:
            recorder.abort()
        raise
    finally:
        bar.close()
    if not summary.frames:
        recorder.abort()
        raise ReplayError(f'{bag}: topic {conns[0].topic} has no messages')
    recorder.close()
    return summary


def _frame_from_diagnostics(index: int, timestamp: int, diag) -> FrameSummary:
    status = diag.status[0]
    values = {kv.key: kv.value for kv in status.values}

    def num(key: str) -> float:
        try:
            return float(values.get(key, 'nan'))
        except ValueError:
            return float('nan')
    return FrameSummary(index=index, timestamp=timestamp, n_planes=int(num('planes')),
                        tolerance=num('tolerance'), gs_planes=num('gs_planes'), level=status.level[0],
                        message=status.message, ms=num('processing_ms'))


def replay_live(bag: str | Path, *, topic: str | None = None, out: str | Path | None = None, rate: float = 1.0,
                start_node: bool = True, config: PipelineConfig | None = None, node_name: str = 'plane_validation',
                echo: Callable[[str], None] | None = print, discovery_timeout: float = 15.0,
                drain_timeout: float = 60.0) -> ReplaySummary:
    """Publish the bag's clouds on their topic at the recorded timing / ``rate``, like
    ``ros2 bag play``, and record what the node publishes into ``out``.

    start_node: run :class:`~plane_validation.node.PlaneValidationNode` (named ``node_name``,
    configured from ``config``) in this process, subscribed to the bag's topic; otherwise a node
    must already be running. Uses its own rclpy context. Returns one FrameSummary per frame the
    node answered (frames it dropped under load have none; ``dropped`` counts them).
    """
    import threading

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import PointCloud2
    from std_msgs.msg import Float64MultiArray
    from visualization_msgs.msg import MarkerArray

    if not rate > 0:
        raise ReplayError(f'rate must be > 0, got {rate}')
    bag = Path(bag)
    out_path = _output_path(bag, out)
    frames = [(t, ts, to_rclpy_cloud(c)) for t, ts, c in read_clouds(bag, topic)]
    if not frames:
        raise ReplayError(f'{bag}: no PointCloud2 messages to play')
    cloud_topic = frames[0][0]
    bag_time = {header_stamp_ns(msg.header): ts for _, ts, msg in frames}
    order = {header_stamp_ns(msg.header): i for i, (_, _, msg) in enumerate(frames)}
    summary = ReplaySummary(bag=bag, topic=cloud_topic, output=out_path)
    lock = threading.Lock()
    pending: list[tuple[str, int, object]] = []  # written by the main thread: sqlite3 is single-threaded
    recorder = BagRecorder(out_path, cloud_topic, node_name)

    def drain() -> None:
        with lock:
            batch = pending[:]
            pending.clear()
        for key, ts, msg in batch:
            recorder.write(key, ts, msg)
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    nodes = []
    # One executor thread is plenty (the callbacks only hand messages over); rclpy's
    # MultiThreadedExecutor spins hard enough on the GIL to starve the node's worker thread
    # (a 30k-point round trip took 1-1.7 s instead of 40 ms in the tests' harness).
    executor = SingleThreadedExecutor(context=context)
    try:
        player = rclpy.create_node('plane_validation_player', context=context)
        nodes.append(player)
        pub = player.create_publisher(PointCloud2, cloud_topic, QoSProfile(depth=10,
                                                                            reliability=ReliabilityPolicy.RELIABLE))
        topics = output_topics(node_name)
        classes = {'segmented': PointCloud2, 'planes': MarkerArray, 'plane_poses': PoseArray,
                   'plane_coefficients': Float64MultiArray, 'diagnostics': DiagnosticArray}
        # Float64MultiArray has no header: the node publishes one coefficients message right before
        # each frame's diagnostics, and DDS keeps each topic in order, so the n-th coefficients
        # message belongs to the n-th diagnostics message of the node.
        coefficients: list = []
        diag_stamps: list[int] = []

        def pair_coefficients() -> None:
            while coefficients and diag_stamps:
                pending.append(('plane_coefficients', bag_time[diag_stamps.pop(0)], coefficients.pop(0)))

        def recorder_for(key: str):
            def record(msg) -> None:
                with lock:
                    if key == 'plane_coefficients':
                        coefficients.append(msg)
                        pair_coefficients()
                        return
                    header = msg.markers[0].header if key == 'planes' else msg.header
                    if key == 'planes' and not msg.markers:
                        return
                    if key == 'diagnostics' and not any(s.name.startswith(f'{node_name}:') for s in msg.status):
                        return  # another node's diagnostics
                    stamp = header_stamp_ns(header)
                    if stamp not in bag_time:
                        return  # not a frame of this bag
                    pending.append((key, bag_time[stamp], msg))
                    if key == 'segmented':
                        summary.last_segmented = msg
                    if key == 'diagnostics':
                        diag_stamps.append(stamp)
                        pair_coefficients()
                        frame = _frame_from_diagnostics(order[stamp], bag_time[stamp], msg)
                        summary.frames.append(frame)
                        values = {kv.key: kv.value for kv in msg.status[0].values}
                        summary.dropped = int(values.get('frames_dropped', '0') or 0)
                        if echo is not None:
                            echo(frame.line())
            return record

        reliable = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE)
        for key, cls in classes.items():
            player.create_subscription(cls, topics[key], recorder_for(key), reliable)
        if start_node:
            from .node import PlaneValidationNode
            cfg = config or PipelineConfig()
            overrides = [Parameter(name, value=getattr(cfg, name)) for name in cfg.__dataclass_fields__]
            node = PlaneValidationNode(node_name, context=context, parameter_overrides=overrides,
                                       cli_args=['--ros-args', '-r', f'cloud:={cloud_topic}'])
            nodes.append(node)
        for n in nodes:
            executor.add_node(n)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        _wait_for(lambda: pub.get_subscription_count() > 0 and all(
            player.count_publishers(t) > 0 for t in topics.values()), discovery_timeout,
            f'a node subscribed to {cloud_topic} and publishing {", ".join(topics.values())}')
        start = time.monotonic()
        first = frames[0][1]
        for _, ts, msg in frames:
            drain()
            delay = start + (ts - first) / 1e9 / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            recorder.write('input', ts, msg)
            pub.publish(msg)
        last = header_stamp_ns(frames[-1][2].header)
        _wait_for(lambda: any(f.timestamp == bag_time[last] for f in summary.frames), drain_timeout,
                  'the node to answer the last frame')
        time.sleep(0.2)  # let the other outputs of the last frame arrive
    except BaseException:
        recorder.abort()
        raise
    finally:
        executor.shutdown(timeout_sec=5)
        for n in nodes:
            n.destroy_node()
        rclpy.try_shutdown(context=context)
    try:
        drain()
        recorder.close()
    except BaseException:
        recorder.abort()
        raise
    summary.frames.sort(key=lambda f: f.index)
    return summary


def _wait_for(condition: Callable[[], bool], timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return
        time.sleep(0.02)
    raise ReplayError(f'timed out after {timeout:.0f} s waiting for {what}')
