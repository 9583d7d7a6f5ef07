"""Event rates over a sliding window (frames received or answered per second). No ROS import."""
from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable

__all__ = ['RateMeter']


class RateMeter:
    """Events per second over the last ``window_s`` seconds of ``clock`` (monotonic seconds).
    Thread-safe: a subscription callback may tick while the worker reads."""

    def __init__(self, window_s: float = 5.0, clock: Callable[[], float] = time.monotonic) -> None:
        if not window_s > 0:
            raise ValueError(f'window_s must be > 0, got {window_s}')
        self.window_s = window_s
        self._clock = clock
        self._times: deque[float] = deque()
        self._lock = threading.Lock()

    def tick(self) -> None:
        """One event now."""
        now = self._clock()
        with self._lock:
            self._times.append(now)
            self._forget(now)

    def rate(self) -> float:
        """Events per second: (n - 1) / (newest - oldest) over the events in the window; NaN with fewer
        than two (no rate is known yet, or the stream stopped for a whole window)."""
        with self._lock:
            self._forget(self._clock())
            if len(self._times) < 2 or self._times[-1] <= self._times[0]:
                return math.nan
            return (len(self._times) - 1) / (self._times[-1] - self._times[0])

    def _forget(self, now: float) -> None:
        while self._times and self._times[0] < now - self.window_s:
            self._times.popleft()
