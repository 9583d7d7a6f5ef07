"""Replay recorded PointCloud2 bags through the plane detector.

Offline (default): read each cloud with ``rosbags`` (rosbag2 sqlite3/MCAP, compressed or not,
and ROS 1 ``.bag``), run the node's per-frame pipeline (:meth:`FramePipeline.process_cloud`) and
write an output bag with the input clouds and every node output at the original timestamps.
Live: publish the clouds on ROS topics at their recorded timing (like ``ros2 bag play``),
optionally with the node started in the same process, and record what it publishes.
Either way the output bag appears only once complete.
"""
from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ..app.config import PipelineConfig
from ..app.frame_result import FrameResult
from ..app.pipeline import TUNE_FAILURES, FramePipeline, header_stamp_ns
from ..app.summary import FrameSummary, ReplaySummary
from ..formats.bags import POINTCLOUD2, BagError, bag_storage, open_bag, pick_topic, read_clouds
from .messages import frame_messages, node_values, status_name, to_rclpy_cloud
from .pairing import OutputPairing
from .player import LiveSession, play, wait_for
from .recorder import BagRecorder, output_topics

__all__ = ['ReplayError', 'FrameSummary', 'ReplaySummary', 'read_clouds', 'replay_offline', 'replay_live',
           'output_topics', 'POINTCLOUD2', 'output_storage']

#: Raised for a bag that cannot be replayed: missing, corrupt, no such topic, wrong type, bad output.
ReplayError = BagError
#: Where the last frame's stamp is shared (see OutputPairing.answered_last), live replay stops waiting
#: once an answer with it came after it was played and the node was then silent this long (s).
DRAIN_QUIET_S = 1.0


def output_storage(bag: Path, storage: str | None) -> str:
    """The output bag's storage: ``storage`` when given, else the input's (MCAP for ROS 1 bags,
    as rosbag2 in Jazzy defaults to)."""
    return storage or bag_storage(bag) or 'mcap'


def _output_path(bag: Path, out: str | Path | None) -> Path:
    path = Path(out) if out is not None else bag.parent / f'{bag.name.removesuffix(".bag")}.planes'
    if path.suffix.lower() in ('.mcap', '.db3', '.bag'):
        raise ReplayError(f'output {path}: replay writes a rosbag2 bag, a folder (metadata.yaml and the storage '
                          'file); give it a folder name such as out.planes, and the storage with --storage')
    if path.exists():
        raise ReplayError(f'output {path} already exists; remove it or pass another --out')
    return path


def _progress(total: int, enabled: bool | None):
    """A tqdm bar on a terminal (None = auto), else a no-op with the same interface."""
    from tqdm import tqdm
    return tqdm(total=total, unit='frame', disable=None if enabled is None else not enabled, file=sys.stderr)


def replay_offline(bag: str | Path, *, topic: str | None = None, out: str | Path | None = None,
                   config: PipelineConfig | None = None, node_name: str = 'plane_validation',
                   echo: Callable[[str], None] | None = print, progress: bool | None = None,
                   storage: str | None = None,
                   on_frame: Callable[[FrameSummary, FrameResult], None] | None = None) -> ReplaySummary:
    """Run every cloud of ``bag`` through the node's per-frame pipeline and write ``out``.

    out: output rosbag2 directory (default ``<bag>.planes`` beside the bag); storage: 'mcap' or
    'sqlite3' (default: the input's). echo: receives the per-frame lines (None = silent); on_frame:
    each frame's summary and the pipeline's whole result (batch reports read its indices).
    Raises ReplayError.
    """
    bag = Path(bag)
    out_path = _output_path(bag, out)
    reader = open_bag(bag)
    try:
        conns = pick_topic(reader, bag, topic)
        total = sum(c.msgcount for c in conns)
    finally:
        reader.close()
    pipeline = FramePipeline(config or PipelineConfig())
    summary = ReplaySummary(bag=bag, topic=conns[0].topic, output=out_path)
    with BagRecorder(out_path, conns[0].topic, node_name, output_storage(bag, storage)) as recorder, \
            _progress(total, progress) as bar:
        for index, (_, timestamp, cloud) in enumerate(read_clouds(bag, conns[0].topic)):
            msg = to_rclpy_cloud(cloud)
            result = pipeline.process_cloud(msg, tune_inline=False)
            extra = node_values(index + 1, 0, False)
            recorder.write('input', timestamp, cloud)  # as read: not converted back from rclpy
            outputs = frame_messages(msg.header, result, status_name(node_name), extra)
            for key, out_msg in outputs.items():
                recorder.write(key, timestamp, out_msg)
            summary.last_segmented = outputs['segmented']
            stamp_ns = header_stamp_ns(msg.header)
            if result.segmentation is not None and pipeline.retune_due(result.clock):
                # as the node's background sweep: its t applies from the next frame
                with contextlib.suppress(*TUNE_FAILURES):
                    points, shape = result.sweep_cloud
                    pipeline.retune(points, result.clock, stamp_ns, shape=shape)
            frame = FrameSummary.from_diagnostic(index, timestamp, result.diagnostic)
            summary.frames.append(frame)
            if on_frame is not None:
                on_frame(frame, result)
            bar.update(1)
            if echo is not None:
                bar.write(frame.line(), file=sys.stdout) if not bar.disable else echo(frame.line())
        if not summary.frames:
            raise ReplayError(f'{bag}: topic {conns[0].topic} has no messages')
    return summary


def first_sweep(node, pairing: OutputPairing, timeout: float) -> None:
    """Wait until ``node`` answered the first frame and ended the sweep it started (up to ``timeout`` s each;
    a frame lost on the way is not waited for longer)."""
    end = time.monotonic() + timeout
    while not pairing.answered(0) and time.monotonic() < end:
        time.sleep(0.02)
    node.wait_for_sweep(max(end - time.monotonic(), 0.0))


def replay_live(bag: str | Path, *, topic: str | None = None, out: str | Path | None = None, rate: float = 1.0,
                start_node: bool = True, config: PipelineConfig | None = None, node_name: str = 'plane_validation',
                echo: Callable[[str], None] | None = print, discovery_timeout: float = 15.0,
                drain_timeout: float = 60.0, storage: str | None = None) -> ReplaySummary:
    """Publish the bag's clouds on their topic at the recorded timing / ``rate``, like
    ``ros2 bag play``, and record what the node publishes into ``out``.

    start_node: run :class:`~plane_validation.ros.node.PlaneValidationNode` (named ``node_name``,
    configured from ``config``) in this process, subscribed to the bag's topic; otherwise a node
    must already be running; the node started here tunes t on the first frame before the second is played
    (a short bag would otherwise end before the first sweep does), so every later frame is answered with the
    tuned t, as offline replay answers it. Uses its own rclpy context. Returns one FrameSummary per frame the
    node answered (frames it dropped under load have none; ``dropped`` counts them).
    """
    if not rate > 0:
        raise ReplayError(f'rate must be > 0, got {rate}')
    bag = Path(bag)
    out_path = _output_path(bag, out)
    frames = [(t, ts, to_rclpy_cloud(c)) for t, ts, c in read_clouds(bag, topic)]
    if not frames:
        raise ReplayError(f'{bag}: no PointCloud2 messages to play')
    cloud_topic = frames[0][0]
    stamps = [header_stamp_ns(msg.header) for _, _, msg in frames]
    pairing = OutputPairing(node_name, stamps, [ts for _, ts, _ in frames],
                            on_frame=(lambda f: echo(f.line())) if echo else None)

    def node_factory(context):
        from rclpy.parameter import Parameter

        from .node import PlaneValidationNode
        cfg = config or PipelineConfig()
        overrides = [Parameter(name, value=getattr(cfg, name)) for name in cfg.__dataclass_fields__]
        return PlaneValidationNode(node_name, context=context, parameter_overrides=overrides,
                                   cli_args=['--ros-args', '-r', f'cloud:={cloud_topic}'])

    def write_received() -> None:  # in this thread only: sqlite3 is single-threaded
        for key, ts, msg in pairing.take():
            recorder.write(key, ts, msg)

    played = iter(range(len(frames)))
    sent = []

    def publish(ts: int, msg) -> None:
        recorder.write('input', ts, msg)
        sent.append(next(played))
        pairing.published(sent[-1])
        session.publisher.publish(msg)

    def before_each() -> None:
        write_received()
        if sent == [0] and start_node and (config or PipelineConfig()).auto_tune:
            first_sweep(session.nodes[-1], pairing, drain_timeout)

    with BagRecorder(out_path, cloud_topic, node_name, output_storage(bag, storage)) as recorder:
        session = LiveSession(cloud_topic, node_name, pairing.receive, node_factory if start_node else None)
        try:
            wait_for(session.connected, discovery_timeout,
                     f'a node subscribed to {cloud_topic} and publishing {", ".join(session.topics.values())}',
                     ReplayError)
            play([(ts, msg) for _, ts, msg in frames], publish, rate, before_each=before_each)
            wait_for(lambda: pairing.answered_last(quiet=DRAIN_QUIET_S), drain_timeout,
                     'the node to answer the last frame', ReplayError)
            time.sleep(0.2)  # let the other outputs of the last frame arrive
        finally:
            session.close()
        write_received()
    frames_answered = sorted(pairing.frames, key=lambda f: f.index)
    return ReplaySummary(bag=bag, topic=cloud_topic, output=out_path, frames=frames_answered, dropped=pairing.dropped,
                         last_segmented=pairing.last_segmented, sent=len(frames))
