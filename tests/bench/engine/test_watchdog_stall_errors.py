"""A frozen process (suspend, SIGSTOP) freezes the watchdog thread too: the loop that wakes
first must see the stall itself, or the run goes on as if nothing happened."""

from __future__ import annotations

import time

import pytest

from bench.engine.watchdog import GuardedEsc, HostWatchdog, WatchdogTrip


class Esc:
    def __init__(self) -> None:
        self.armed = False
        self.pulse = 1000.0

    def arm(self) -> None:
        self.armed = True

    def set_pulse_us(self, us: float) -> None:
        self.pulse = us

    def disarm(self) -> None:
        self.armed, self.pulse = False, 1000.0


def test_loop_waking_first_after_a_stall_trips_the_watchdog() -> None:
    esc = Esc()
    guarded = GuardedEsc(esc, 1050.0, 2000.0, 1000.0)
    guarded.arm()
    guarded.set_pulse_us(1500.0)
    # the watching thread polls every 60 s: it stands for a thread frozen with the loop
    with HostWatchdog(guarded, timeout_s=0.1, poll_s=60.0) as wd:
        wd.kick()
        time.sleep(0.25)  # the whole process is "frozen"; the loop wakes first
        with pytest.raises(WatchdogTrip, match=r"command loop stalled"):
            wd.kick()
        assert wd.tripped and esc.armed is False and esc.pulse == 1000.0
        with pytest.raises(WatchdogTrip):
            guarded.set_pulse_us(1500.0)


def test_healthy_loop_and_unstarted_watchdog_do_not_trip() -> None:
    esc = Esc()
    guarded = GuardedEsc(esc, 1050.0, 2000.0, 1000.0)
    wd = HostWatchdog(guarded, timeout_s=0.1, poll_s=60.0)
    time.sleep(0.15)
    wd.kick()  # not started: kicks are free
    assert not wd.tripped
    with wd:
        for _ in range(5):
            wd.kick()
            time.sleep(0.01)
    assert not wd.tripped
