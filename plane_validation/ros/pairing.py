"""Match what a live node publishes to the bag frames it answers (for live replay).

Outputs are matched to frames by header stamp. Where several frames share a stamp (a driver that
leaves it unset), the node's answers come in the order the frames were played, each topic in order:
a frame's diagnostics say how many frames the node dropped before it, which tells which of the
frames with that stamp it answered, and the n-th message of another topic with that stamp belongs to
the n-th answered frame with it. A cloud lost before the node (its sensor-data subscription keeps one)
is counted nowhere: the answers after it then go to a frame before their own (which one cannot be
known: how long a cloud takes to reach the node is not), never to a frame not yet played.

Float64MultiArray has no header: the node publishes one coefficients message right before each
frame's diagnostics and DDS keeps each topic in order, so the n-th coefficients message belongs to the
n-th diagnostics message of the node.
"""
from __future__ import annotations

import math
import threading
import time
from collections import defaultdict
from collections.abc import Callable

from ..app.pipeline import header_stamp_ns
from ..app.summary import FrameSummary
from .messages import diagnostic_from_status, status_name

__all__ = ['OutputPairing']


class OutputPairing:
    """Thread-safe: :meth:`receive` runs in executor callbacks, :meth:`take` in the writer thread.

    stamps: (n,) header stamp (ns) of each frame played, in play order; bag_times: (n,) its bag
    timestamp (ns). on_frame: called with each FrameSummary as its diagnostics arrive.
    """

    def __init__(self, node_name: str, stamps: list[int], bag_times: list[int],
                 on_frame: Callable[[FrameSummary], None] | None = None) -> None:
        self.node_name, self.stamps, self.bag_times, self.on_frame = node_name, stamps, bag_times, on_frame
        self.frames: list[FrameSummary] = []
        self.dropped = 0
        self.last_segmented = None
        self._played: dict[int, list[int]] = defaultdict(list)  # stamp -> frame indices, in play order
        for index, stamp in enumerate(stamps):
            self._played[stamp].append(index)
        self._answered: dict[int, list[int]] = defaultdict(list)  # stamp -> frame indices answered, in order
        self._last = -1  # the last frame answered
        self._frontier = -1  # the last frame played (published())
        self._slowest = 0.0  # the longest processing_ms of an answer, s
        self._final_sent: float | None = None  # when the last frame was played (time.monotonic)
        self._final_answered: float | None = None  # when the latest answer with the last frame's stamp came
        self._quiet_since = time.monotonic()  # the latest diagnostics
        self._seen: dict[tuple[str, int], int] = defaultdict(int)  # (topic, stamp) -> messages received
        self._waiting: list[tuple[str, int, int, object]] = []  # (key, stamp, n-th, msg) not yet placed
        self._pending: list[tuple[str, int, object]] = []
        self._coefficients: list = []
        self._diag_frames: list[int] = []
        self._lock = threading.Lock()

    def receive(self, key: str, msg) -> None:
        """One message of output ``key`` from the node."""
        with self._lock:
            if key == 'plane_coefficients':
                self._coefficients.append(msg)
                self._pair()
                return
            if key == 'planes' and not msg.markers:
                return
            if key == 'diagnostics' and not any(s.name == status_name(self.node_name) for s in msg.status):
                return  # another node's diagnostics
            stamp = header_stamp_ns(msg.markers[0].header if key == 'planes' else msg.header)
            if not any(i <= self._frontier for i in self._played.get(stamp, ())):
                return  # not a frame of this bag played so far (another publisher's cloud)
            if key == 'segmented':
                self.last_segmented = msg
            if key == 'diagnostics':
                diagnostic = diagnostic_from_status(msg.status[0])
                dropped = diagnostic.number('frames_dropped_since_last')  # this run's drops only
                dropped = 0 if math.isnan(dropped) else int(dropped)
                index = self._answered_frame(stamp, dropped)
                self._quiet_since = time.monotonic()
                seconds = diagnostic.number('processing_ms') / 1000
                self._slowest = self._slowest if math.isnan(seconds) else max(self._slowest, seconds)
                if stamp == self.stamps[-1]:
                    self._final_answered = self._quiet_since
                self._answered[stamp].append(index)
                self._diag_frames.append(index)
                self._pair()
                frame = FrameSummary.from_diagnostic(index, self.bag_times[index], diagnostic)
                self.frames.append(frame)
                self.dropped += dropped
                if self.on_frame is not None:
                    self.on_frame(frame)
            self._waiting.append((key, stamp, self._seen[key, stamp], msg))
            self._seen[key, stamp] += 1
            self._place()

    def answered(self, index: int) -> bool:
        """Whether frame ``index``'s diagnostics have come."""
        with self._lock:
            return any(frame.index == index for frame in self.frames)

    def published(self, index: int) -> None:
        """Frame ``index`` is about to be played (frames are played in order)."""
        with self._lock:
            self._frontier = index
            if index == len(self.stamps) - 1:
                self._final_sent = time.monotonic()

    def _answered_frame(self, stamp: int, dropped: int) -> int:
        """The frame a diagnostics message with ``stamp`` (of a frame played so far) answers: the first
        frame with that stamp played so far that is at least ``dropped`` frames after the last answered;
        else the first one after the last answered (the node dropped clouds of another publisher); else
        (more answers than frames played: a node answering such clouds with that stamp too) the last
        frame with it played."""
        played = [i for i in self._played[stamp] if i <= self._frontier]
        later = [i for i in played if i > self._last]
        expected = self._last + 1 + dropped
        index = next((i for i in later if i >= expected), later[0] if later else played[-1])
        self._last = max(self._last, index)
        return index

    def _place(self) -> None:
        """Move the messages whose frame is known (their stamp's n-th answered frame) to the output."""
        still = []
        for key, stamp, nth, msg in self._waiting:
            answered = self._answered[stamp]
            if len(self._played[stamp]) == 1:  # a unique stamp: its frame (played: see receive)
                self._pending.append((key, self.bag_times[self._played[stamp][0]], msg))
            elif nth < len(answered):
                self._pending.append((key, self.bag_times[answered[nth]], msg))
            else:
                still.append((key, stamp, nth, msg))
        self._waiting = still

    def answered_last(self, quiet: float = 0.0) -> bool:
        """Whether the last frame has been answered: an answer was placed on it, or (its stamp shared
        with other frames, which a lost cloud can shift) one with its stamp came after it was played and
        no diagnostics came since for ``quiet`` seconds, or for three times the longest processing time
        an answer reported if that is longer (a slow node is quiet while it works on the last frame)."""
        with self._lock:
            if self._last == len(self.stamps) - 1:
                return True
            return (len(self._played[self.stamps[-1]]) > 1 and self._final_sent is not None
                    and self._final_answered is not None and self._final_answered >= self._final_sent
                    and time.monotonic() - self._quiet_since >= max(quiet, 3 * self._slowest))

    def take(self) -> list[tuple[str, int, object]]:
        """(key, bag timestamp, message) received since the last call, to be written."""
        with self._lock:
            batch, self._pending = self._pending, []
        return batch

    def _pair(self) -> None:
        while self._coefficients and self._diag_frames:
            index = self._diag_frames.pop(0)
            self._pending.append(('plane_coefficients', self.bag_times[index], self._coefficients.pop(0)))
