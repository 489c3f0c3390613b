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
