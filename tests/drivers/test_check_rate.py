"""``check``'s sensor rate comes from the samples' stamps, not the host's scheduling."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.check import RATE_MIN_SAMPLES, sensor_answer
from drivers.contracts import Block
from drivers.sim.clock import SimClock


class _LateStartSensor:
    """A 100 Hz sensor whose poller starts 0.08 s late (what a busy host makes of a polled
    flight controller): the check's window holds less time of samples than of clock."""

    def __init__(self, clock: SimClock) -> None:
        self._clock = clock
        self._start = self._next = clock.now() + 0.08

    def read_block(self) -> Block:
        now = self._clock.now()
        if now < self._start:
            return Block.empty(("gyro_x",))
        t = np.arange(self._next, now, 0.01)
        self._next = float(t[-1]) + 0.01 if t.size else self._next
        return Block(t, {"gyro_x": np.zeros(t.size)})


def test_rate_is_the_stamps_rate_after_a_late_start() -> None:
    clock = SimClock()
    answer = sensor_answer(_LateStartSensor(clock), clock, timeout_s=5.0)
    rate = float(answer.split(" samples/s")[0])
    assert rate == pytest.approx(100.0, rel=0.03), answer


def test_a_sensor_with_fewer_samples_than_the_window_still_answers() -> None:
    clock = SimClock()

    class _Once:
        sent = False

        def read_block(self) -> Block:
            if self.sent or clock.now() < 0.05:
                return Block.empty(("x",))
            self.sent = True
            return Block(np.array([clock.now()]), {"x": np.array([1.0])})

    answer = sensor_answer(_Once(), clock, timeout_s=1.0)
    assert answer.endswith("x=1") and RATE_MIN_SAMPLES > 1
