"""Repeated timing and the summary statistics every figure of the suite reports."""
from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

T = TypeVar('T')


@dataclass(frozen=True)
class Summary:
    """Median, min and max of repeated measurements (any unit; the caller names it)."""

    median: float
    low: float
    high: float
    count: int

    @classmethod
    def of(cls, values: Sequence[float]) -> Summary:
        """Summary of ``values``; NaN everywhere when there are none."""
        vals = [float(v) for v in values if v is not None and math.isfinite(v)]
        if not vals:
            return cls(math.nan, math.nan, math.nan, 0)
        return cls(statistics.median(vals), min(vals), max(vals), len(vals))

    def scaled(self, factor: float) -> Summary:
        """The same summary in another unit (e.g. 1e3 for s -> ms)."""
        return Summary(self.median * factor, self.low * factor, self.high * factor, self.count)


def timed(fn: Callable[[], T]) -> tuple[T, float]:
    """(fn(), wall seconds) measured with time.perf_counter."""
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def loglog_exponent(sizes: Sequence[float], seconds: Sequence[float]) -> float:
    """Least-squares slope b of log(seconds) = a + b log(size)."""
    xs = [math.log(s) for s in sizes]
    ys = [math.log(t) for t in seconds]
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else math.nan
