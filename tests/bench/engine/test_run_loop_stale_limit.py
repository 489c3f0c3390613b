"""A silent device's limit in rig time: ``stale_s`` on a real rig; on a simulated bench
paced by the wall clock, scaled by its pace and at least two seconds of wall time."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from bench.engine.run_loop import SafeRunLoop
from drivers.contracts import MonotonicClock
from drivers.sim.clock import SimClock
from drivers.wire_sim.paced_clock import PacedClock


@pytest.mark.parametrize("clock, limit", [
    (MonotonicClock(), 0.5),  # a real rig: the wall clock
    (SimClock(), 0.5),  # a simulated rig run flat out: no wall clock to hiccup against
    (PacedClock(3.0), 6.0),  # 3x real time: a 2 s wall stall is 6 s of rig time
    (PacedClock(1.0), 2.0),  # a paced simulation at real time: 2 s of wall time
    (PacedClock(0.5), 1.0),  # slower than real time: 2 s of wall time is 1 s of rig time
])
def test_the_stale_limit_follows_the_pace_of_the_rig_clock(clock, limit) -> None:
    loop = SimpleNamespace(options=SimpleNamespace(stale_s=0.5), rig=SimpleNamespace(clock=clock))
    assert SafeRunLoop.stale_limit_s.fget(loop) == pytest.approx(limit)


def _stamping(clock):
    """A run loop's bookkeeping alone (its ``_stamp``), ticking every 10 ms, limit 0.25 s."""
    import numpy as np

    from bench.engine.drops import DropCounter
    from drivers.contracts import Block

    loop = SafeRunLoop.__new__(SafeRunLoop)
    loop.options = SimpleNamespace(stale_s=0.25, tick_s=0.01, realtime=False)
    loop.rig = SimpleNamespace(clock=clock)
    loop.drops, loop._t0, loop._heard = DropCounter(), 0.0, {}
    loop._away_s, loop._last_stamp = 0.0, None

    def read(now: float, samples: bool) -> None:
        t = np.array([now - 0.005, now]) if samples else np.array([])
        loop._stamp("load_cell", Block(t, {"thrust_n": np.zeros(t.size)}), now)
    return read


def _ticks(a: float, b: float) -> list[float]:
    return [round(a + 0.01 * k, 3) for k in range(round((b - a) / 0.01) + 1)]


def test_a_loop_held_up_does_not_blame_the_device_whose_samples_waited() -> None:
    """The loop itself away for 0.35 s (a loaded host), its first read after that empty
    (the reader thread not yet caught up): the device was not silent."""
    from drivers.errors import DeviceError

    read = _stamping(MonotonicClock())
    for now in _ticks(0.0, 0.1):
        read(now, True)
    read(0.45, False)  # 0.35 s after the last tick
    for now in _ticks(0.46, 0.6):
        read(now, True)
    # a device silent while the loop runs is caught after the limit of the loop's time,
    # held-up time not counted
    for now in _ticks(0.61, 0.8):  # 0.2 s of the loop's own time
        read(now, False)
    read(1.15, False)  # held up again: 0.34 s not counted
    with pytest.raises(DeviceError, match=r"load_cell: no samples for 0\.2[56] s"):
        for now in _ticks(1.16, 1.5):
            last = now
            read(now, False)
    assert 1.19 <= last <= 1.2  # 0.6 + 0.34 away + 0.25 of silence


def test_on_a_simulated_clock_a_jump_is_silence() -> None:
    """No wall clock, no held-up loop: rig time without samples is silence."""
    from drivers.errors import DeviceError

    read = _stamping(SimClock())
    for now in _ticks(0.0, 0.1):
        read(now, True)
    with pytest.raises(DeviceError, match=r"no samples for 0\.35 s"):
        read(0.45, False)
