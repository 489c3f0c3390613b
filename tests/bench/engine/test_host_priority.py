"""A run on the wall clock raises every thread of the bench's process, behind the devices,
and hands the niceness back at its end; a run on a simulated clock is left alone."""

from __future__ import annotations

import os
import threading
from types import SimpleNamespace

import pytest

from bench.engine.host_priority import HOST_LOOP_NICE, HostPriority
from bench.engine.run_loop import SafeRunLoop
from drivers.contracts import MonotonicClock
from drivers.device_priority import DEVICE_NICE
from drivers.sim.clock import SimClock
from drivers.wire_sim.paced_clock import PacedClock


def _nice(tid: int) -> int:
    return os.getpriority(os.PRIO_PROCESS, tid)


@pytest.mark.parametrize("clock, realtime, on_wall", [
    (MonotonicClock(), False, True),  # a real rig
    (PacedClock(3.0), False, True),  # a paced simulated bench
    (SimClock(), True, True),  # a simulated rig paced to real time
    (SimClock(), False, False),  # a simulated rig run flat out
])
def test_a_run_is_on_the_wall_clock_when_it_keeps_time_with_it(clock, realtime, on_wall):
    loop = SimpleNamespace(options=SimpleNamespace(realtime=realtime),
                           rig=SimpleNamespace(clock=clock))
    assert SafeRunLoop.on_wall_clock.fget(loop) is on_wall


def test_the_host_runs_behind_the_devices_and_ahead_of_the_default():
    assert DEVICE_NICE < HOST_LOOP_NICE < 0


def test_every_thread_is_raised_for_the_run_and_handed_back_after():
    if os.geteuid() != 0:
        pytest.skip("raising a thread's priority needs root (CAP_SYS_NICE)")
    before = _nice(threading.get_native_id())
    if before <= HOST_LOOP_NICE:
        pytest.skip(f"this process already runs at nice {before}")
    seen: dict[str, int] = {}
    release = threading.Event()
    old = threading.Thread(target=lambda: (release.wait(5), seen.update(old=_nice(
        threading.get_native_id()))))
    old.start()  # a thread from before the run (a window's, a reader's)
    try:
        with HostPriority(True), HostPriority(True):  # two overlapping runs
            seen["loop"] = _nice(threading.get_native_id())
            t = threading.Thread(target=lambda: seen.update(new=_nice(threading.get_native_id())))
            t.start()
            t.join()
            release.set()
            old.join()
        seen["after"] = _nice(threading.get_native_id())
    finally:
        release.set()
        old.join()
    assert seen == {"loop": HOST_LOOP_NICE, "new": HOST_LOOP_NICE, "old": HOST_LOOP_NICE,
                    "after": before}


def test_a_run_on_a_simulated_clock_leaves_the_niceness_alone():
    before = _nice(threading.get_native_id())
    with HostPriority(False):
        assert _nice(threading.get_native_id()) == before


_GROUPS = """
import json, os
from bench.engine.host_priority import HostPriority
from drivers.device_priority import session_group_nice
seen = [session_group_nice(os.getpid())]
with HostPriority(True), HostPriority(True):
    seen.append(session_group_nice(os.getpid()))
seen.append(session_group_nice(os.getpid()))
print(json.dumps(seen))
"""


@pytest.mark.parametrize("own_session", [True, False])
def test_a_bench_leading_its_session_raises_its_group_for_the_run(own_session):
    """Its own group only: a bench in a terminal's (here: the suite's) session leaves it."""
    import json
    import subprocess
    import sys

    from drivers.device_priority import session_group_nice

    if os.geteuid() != 0 or session_group_nice(os.getpid()) is None:
        pytest.skip("needs root and a kernel with scheduling groups per session (autogroup)")
    res = subprocess.run([sys.executable, "-c", _GROUPS], capture_output=True, text=True,
                         timeout=60, start_new_session=own_session, check=True)
    before, during, after = json.loads(res.stdout)
    if own_session:
        assert before == 0  # a new session's group starts at the default
    assert during == (HOST_LOOP_NICE if own_session else before)
    assert after == before
