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


def test_a_paced_rig_is_read_for_half_a_second_of_wall_time_too() -> None:
    """At 6x, 0.5 s of rig time is 0.08 s of wall time: a host stall that costs the poller
    0.3 s of rig time (0.05 s of wall time) would take 60 % of such a window's samples."""
    from drivers.wire_sim.paced_clock import PacedClock

    clock = PacedClock(6.0, max_gap_s=float("inf"))
    start = clock.now()

    class _Stalled:
        """100 Hz of rig time, none in the 0.3 s a stall took just after the check began."""

        def __init__(self) -> None:
            self._next = start

        def read_block(self) -> Block:
            t = np.arange(self._next, clock.now(), 0.01)
            self._next = float(t[-1]) + 0.01 if t.size else self._next
            t = t[(t < start + 0.05) | (t > start + 0.35)]
            return Block(t, {"gyro_x": np.zeros(t.size)})

    answer = sensor_answer(_Stalled(), clock, timeout_s=5.0)
    rate = float(answer.split(" samples/s")[0])
    assert clock.now() - start >= 6.0 * 0.5  # half a second of wall time
    assert rate > 85.0, answer  # over 3 s of rig time the stall costs a tenth
