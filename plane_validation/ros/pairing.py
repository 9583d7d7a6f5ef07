"""Match what a live node publishes to the bag frames it answers (for live replay).

Outputs are matched to frames by header stamp. Float64MultiArray has no header: the node publishes
one coefficients message right before each frame's diagnostics and DDS keeps each topic in order,
so the n-th coefficients message belongs to the n-th diagnostics message of the node.
"""
from __future__ import annotations

import math
import threading
from collections.abc import Callable

from ..app.pipeline import header_stamp_ns
from ..app.summary import FrameSummary
from .messages import diagnostic_from_status, status_name

__all__ = ['OutputPairing']


class OutputPairing:
    """Thread-safe: :meth:`receive` runs in executor callbacks, :meth:`take` in the writer thread.

    bag_time: header stamp (ns) -> bag timestamp (ns) of each frame played; order: header stamp
    -> frame index. on_frame: called with each FrameSummary as its diagnostics arrive.
    """

    def __init__(self, node_name: str, bag_time: dict[int, int], order: dict[int, int],
                 on_frame: Callable[[FrameSummary], None] | None = None) -> None:
        self.node_name, self.bag_time, self.order, self.on_frame = node_name, bag_time, order, on_frame
        self.frames: list[FrameSummary] = []
        self.dropped = 0
        self.last_segmented = None
        self._pending: list[tuple[str, int, object]] = []
        self._coefficients: list = []
        self._diag_stamps: list[int] = []
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
            if stamp not in self.bag_time:
                return  # not a frame of this bag
            self._pending.append((key, self.bag_time[stamp], msg))
            if key == 'segmented':
                self.last_segmented = msg
            if key == 'diagnostics':
                self._diag_stamps.append(stamp)
                self._pair()
                diagnostic = diagnostic_from_status(msg.status[0])
                frame = FrameSummary.from_diagnostic(self.order[stamp], self.bag_time[stamp], diagnostic)
                self.frames.append(frame)
                dropped = diagnostic.number('frames_dropped_since_last')  # this run's drops only
                self.dropped += 0 if math.isnan(dropped) else int(dropped)
                if self.on_frame is not None:
                    self.on_frame(frame)

    def answered(self, stamp_ns: int) -> bool:
        """Whether the frame with header stamp ``stamp_ns`` has been answered."""
        with self._lock:
            return any(f.timestamp == self.bag_time[stamp_ns] for f in self.frames)

    def take(self) -> list[tuple[str, int, object]]:
        """(key, bag timestamp, message) received since the last call, to be written."""
        with self._lock:
            batch, self._pending = self._pending, []
        return batch

    def _pair(self) -> None:
        while self._coefficients and self._diag_stamps:
            stamp = self._diag_stamps.pop(0)
            self._pending.append(('plane_coefficients', self.bag_time[stamp], self._coefficients.pop(0)))
