"""RateMeter: events per second over a sliding window."""
import math

import pytest

from plane_validation.app.rates import RateMeter


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_rate_over_the_window_and_nan_until_two_events_or_after_a_silent_window():
    clock = Clock()
    meter = RateMeter(5.0, clock)
    assert math.isnan(meter.rate())
    meter.tick()
    assert math.isnan(meter.rate())
    for _ in range(20):  # 10 Hz
        clock.now += 0.1
        meter.tick()
    assert meter.rate() == pytest.approx(10.0)
    for _ in range(100):  # then 2 Hz for 50 s: the window holds only those
        clock.now += 0.5
        meter.tick()
    assert meter.rate() == pytest.approx(2.0)
    clock.now += 6.0
    assert math.isnan(meter.rate())  # nothing for a whole window


def test_a_window_must_be_positive():
    with pytest.raises(ValueError, match='window_s'):
        RateMeter(0.0)
