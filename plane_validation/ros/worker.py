"""The node's data flow, shared by the plain and the managed node: a one-slot mailbox, a worker
thread that runs the shared :class:`~plane_validation.app.pipeline.FramePipeline` and publishes,
background tolerance sweeps, rates, and the node's log lines.

The subscription callback only puts the newest cloud into the mailbox (an older unprocessed cloud is
dropped and counted); the worker takes it, processes and publishes it. Tolerance sweeps (the first,
later ones every ``retune_period``, retries of a failed one) run in a background thread while frames
keep being processed with the current tolerance (a quick estimate until the first sweep ends). A frame
that comes due while a sweep runs is kept and swept when it ends, so the node sweeps the frames offline
replay sweeps (when it drops none).
"""
from __future__ import annotations

import dataclasses
import math
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.serialization import serialize_message
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header

from ..app.diagnostics import Level, fmt
from ..app.frame_result import FrameResult
from ..app.pipeline import FramePipeline, header_stamp_ns, import_first_use_modules
from ..app.rates import RateMeter
from ..core.kernels import Warmup, warm
from .messages import OUTPUTS, cloud_from_cdr, diagnostics, frame_messages, node_values

__all__ = ['FrameWorker', 'input_qos', 'output_publishers', 'subscribe', 'LOG_THROTTLE_S', 'SWEEP_STOP_S',
           'RATE_WINDOW_S']

ERROR, WARN = Level.ERROR, Level.WARN
#: Seconds between two log lines of the same kind.
LOG_THROTTLE_S = 5.0
#: Seconds stop() waits for a running sweep to end (it stops after its current candidate).
SWEEP_STOP_S = 3.0
#: Seconds of wall time input_rate_hz and output_rate_hz are measured over.
RATE_WINDOW_S = 5.0


def input_qos(reliability: str) -> QoSProfile:
    """The cloud subscription's QoS: keep the newest, sensor-data durability, the given reliability."""
    return QoSProfile(depth=1, history=qos_profile_sensor_data.history,
                      durability=qos_profile_sensor_data.durability,
                      reliability=ReliabilityPolicy.RELIABLE if reliability == 'reliable'
                      else ReliabilityPolicy.BEST_EFFORT)


def output_publishers(create) -> dict[str, object]:
    """One publisher per output made by ``create(cls, topic, depth)``: ~/<key>, and /diagnostics."""
    return {key: create(cls, '/diagnostics', 10) if key == 'diagnostics' else create(cls, f'~/{key}', 1)
            for key, cls in OUTPUTS.items()}


def subscribe(node, worker: FrameWorker, reliability: str):
    """``node``'s ``cloud`` subscription, handing each cloud to ``worker``, and a log line naming the topic it
    resolved to and where the outputs go: a node started without ``-r cloud:=...`` waited on /cloud without a word."""
    # serialized: a cloud the mailbox drops is never deserialized, and the worker reads the one it takes without a copy
    subscription = node.create_subscription(PointCloud2, 'cloud', worker.offer, input_qos(reliability), raw=True)
    outputs = ', '.join(f'~/{key}' for key in list(OUTPUTS)[:-1])
    node.get_logger().info(f'listening for PointCloud2 on {subscription.topic_name} ({reliability}); publishing '
                           f'{outputs} (~ = {node.get_fully_qualified_name()}; each while it has a subscriber) and '
                           '/diagnostics')
    return subscription


def warm_kernels(logger, started: Warmup | None = None) -> Warmup:
    """Compile or load the compiled kernels and say how long it took on ``logger`` (an rclpy logger), counting
    ``started``: what ``kernels.warm_probe()`` did before (when it compiled, the cache is cold: the others are
    compiled on every core), then import the modules the frames import on first use and read a cloud (rosbags
    builds its PointCloud2 reader on first use: 0.1 s). A node calls this before it answers its first frame."""
    cold = started is not None and started.compiled
    # in a thread of its own: Ctrl-C raises KeyboardInterrupt in the main thread, which must not be inside numba's
    # loading (a KeyboardInterrupt in llvmlite's ctypes callback crashed the process with SIGSEGV); here it ends
    # the wait and the start, and the loading finishes before the process exits
    with ThreadPoolExecutor(1, thread_name_prefix='plane_validation_warmup') as pool:
        ready = pool.submit(warm, jobs=os.cpu_count() or 1, cold=cold).result()
        pool.submit(import_first_use_modules).result()
        pool.submit(cloud_from_cdr, serialize_message(PointCloud2())).result()
    seconds = ready.seconds + (started.seconds if started is not None else 0.0)
    logger.info(f'compiled kernels ready in {seconds:.2f} s ' + (
        '(compiled now and cached: later starts load them)' if ready.compiled else '(loaded from the cache)'))
    return Warmup(seconds, ready.compiled)


class FrameWorker:
    """Processes the clouds ``node`` receives and hands each frame's messages to ``publish(key, msg)``: the
    diagnostics, and each other output that ``listened(key)`` says has a subscriber (one nobody receives is not
    built: a 640 x 480 frame's two clouds are 10 MB to build and send).

    node: the rclpy node (for its logger and context); min_output_rate_hz: below this output rate a
    frame is WARN (0 = off)."""

    def __init__(self, node, pipeline: FramePipeline, publish: Callable[[str, object], None], status_name: str,
                 *, min_output_rate_hz: float = 0.0, listened: Callable[[str], bool] = lambda key: True) -> None:
        self.node = node
        self.pipeline = pipeline
        self.publish = publish
        self.listened = listened
        self.status_name = status_name
        self.min_output_rate_hz = min_output_rate_hz
        self.input_rate = RateMeter(RATE_WINDOW_S)
        self.output_rate = RateMeter(RATE_WINDOW_S)
        self.frames_dropped = 0
        self._dropped_reported = 0
        self.frames_processed = 0
        self._slot = None
        self._wake = threading.Condition()
        self._stopping = False
        self._sweep_idle = threading.Event()
        self._sweep_idle.set()
        self._sweep_lock = threading.Lock()
        self._sweeping_on: float | None = None  # stamp (s) of the frame the running sweep runs on
        self._next_sweep = None  # (frame, stamp_ns) kept for the sweep after it
        self._thread = threading.Thread(target=self._work, name='plane_validation_worker', daemon=True)
        self._thread.start()

    @property
    def logger(self):
        return self.node.get_logger()

    # -- input: single-slot handoff -------------------------------------------------------------
    def offer(self, msg: bytes) -> None:
        """The subscription callback: keep ``msg`` (a serialized PointCloud2) as the next cloud, dropping an
        unprocessed older one."""
        self.input_rate.tick()
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
                if self._stopping or not self.node.context.ok():
                    return  # shutting down: publishing failed because the context is gone
                self.logger.error(f'frame failed unexpectedly: {exc!r}', throttle_duration_sec=LOG_THROTTLE_S)

    # -- one frame -------------------------------------------------------------------------------
    def process(self, raw: bytes, dropped: int) -> None:
        """Read the serialized cloud ``raw``, run the shared pipeline, publish the outputs listened to, stamped with
        the input header. dropped: frames_dropped when this cloud was taken; the drops since the last frame are
        reported with it (those meanwhile are older than the next frame, not this one)."""
        try:
            msg, header = cloud_from_cdr(raw)
        except ValueError as exc:  # not a PointCloud2 at all: answered with a header of its own
            header = Header()
            result = self.pipeline.reject(f'malformed PointCloud2: {exc}', ERROR)
        else:
            result = self.pipeline.process_cloud(msg, tune_inline=False)
        stamp_ns = header_stamp_ns(header)
        retune = result.segmentation is not None and self._reserve_sweep(result, stamp_ns)
        self.frames_processed += 1
        self.output_rate.tick()
        with self._wake:
            dropped_now, self._dropped_reported = dropped - self._dropped_reported, dropped
        result = self._rated(result)
        extra = node_values(self.frames_processed, dropped, retune or self._tuning(), dropped_now) + (
            ('input_rate_hz', fmt(self.input_rate.rate())), ('output_rate_hz', fmt(self.output_rate.rate())))
        # a message no subscriber has matched reaches no one: not built (it would not be sent either)
        keys = [key for key in OUTPUTS if key != 'diagnostics' and self.listened(key)]
        start = time.perf_counter()
        for topic, out in frame_messages(header, result, self.status_name, keys=keys).items():
            self.publish(topic, out)
        # the diagnostics last, with what the other outputs cost (processing_ms leaves them out)
        extra += (('outputs_ms', f'{1000 * (time.perf_counter() - start):.1f}'),)
        self.publish('diagnostics', diagnostics(header, result.diagnostic.with_values(*extra), self.status_name))
        if retune:  # after publishing: the sweep competes for the GIL; frames go on with the current t
            self._start_retune(result, stamp_ns)

        if not self.node.context.ok():
            return  # shutting down: rosout is gone, a line now would only say it cannot be published
        # rclpy ties a throttled call site to one severity: one call site per level, throttled apart
        if result.level == ERROR:
            self.logger.error(f'ERROR: {result.message}', throttle_duration_sec=LOG_THROTTLE_S)
        elif result.level == WARN:
            self.logger.warning(f'WARN: {result.message}', throttle_duration_sec=LOG_THROTTLE_S)

    def _rated(self, result: FrameResult) -> FrameResult:
        """``result``, WARN when the node answers fewer frames per second than min_output_rate_hz (a frame's
        own level says only what its planes and its input are like: a dropped frame does not change it)."""
        rate, low = self.output_rate.rate(), self.min_output_rate_hz
        if low > 0 and not math.isnan(rate) and rate < low:
            return dataclasses.replace(result, diagnostic=result.diagnostic.escalated(
                WARN, f'output rate {rate:.3g} Hz is below min_output_rate_hz {low:g} '
                      f'(input {fmt(self.input_rate.rate())} Hz, {self.frames_dropped} frame(s) dropped so far)'))
        return result

    # -- tolerance sweeps ------------------------------------------------------------------------
    def _tuning(self) -> bool:
        return not self._sweep_idle.is_set()

    def _reserve_sweep(self, frame: FrameResult, stamp_ns: int) -> bool:
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

    def _start_retune(self, frame: FrameResult, stamp_ns: int) -> None:
        points, shape = frame.sweep_cloud

        def run() -> None:
            try:
                result = self.pipeline.retune(points, frame.clock, stamp_ns, shape=shape,
                                              stop=lambda: self._stopping)
                if result is not None and self.pipeline.last_tuning is result and not self._stopping:
                    # as the frames: WARN when its verdict is not reliable (one call site per severity)
                    if result.reliable:
                        self.logger.info(f'retuned: t = {result.tolerance:.4g} m ({result.verdict})')
                    else:
                        self.logger.warning(f'retuned: t = {result.tolerance:.4g} m ({result.verdict})')
            except KeyboardInterrupt:  # Ctrl-C reached a worker process of a parallel sweep: the node stops
                pass
            except Exception as exc:  # a failed sweep keeps the current tolerance; the node goes on
                if not self._stopping:
                    self.logger.warning(f'retune failed, keeping t: {str(exc) or type(exc).__name__}',
                                        throttle_duration_sec=LOG_THROTTLE_S)
            finally:
                self._sweep_ended()
        threading.Thread(target=run, name='plane_validation_retune', daemon=True).start()

    def wait_for_sweep(self, timeout: float | None = None) -> bool:
        """Wait until no tolerance sweep is running (True) or ``timeout`` seconds pass (False)."""
        return self._sweep_idle.wait(timeout)

    def stop(self) -> None:
        """Stop taking clouds, end the worker thread and (for up to SWEEP_STOP_S) a running sweep."""
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=10)
        # a sweep stops after its current candidate; one that takes longer is left to its daemon thread
        self._sweep_idle.wait(timeout=SWEEP_STOP_S)
