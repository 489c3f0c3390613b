"""A silent device's limit in rig time: ``stale_s`` on a real rig; on a simulated bench
paced by the wall clock, ``stale_s`` of wall time scaled by its pace (never less than
``stale_s``)."""

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
    (PacedClock(3.0), 1.5),  # 3x real time: a 0.5 s wall stall is 1.5 s of rig time
    (PacedClock(1.0), 0.5),  # a paced simulation at real time: the wall clock's
    (PacedClock(0.5), 0.5),  # slower than real time: never less than stale_s
])
def test_the_stale_limit_follows_the_pace_of_the_rig_clock(clock, limit) -> None:
    loop = SimpleNamespace(options=SimpleNamespace(stale_s=0.5), rig=SimpleNamespace(clock=clock))
    assert SafeRunLoop.stale_limit_s.fget(loop) == pytest.approx(limit)
