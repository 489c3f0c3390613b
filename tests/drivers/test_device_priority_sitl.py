"""A device's stand-in process (a simulated world, the Betaflight SITL) runs ahead of the
host's work, with exact timers: every thread of it, those it has and those it starts
later."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drivers.device_priority import (
    DEVICE_NICE,
    DEVICE_TIMER_SLACK_NS,
    raise_device_priority,
    session_group_nice,
)

ROOT = os.geteuid() == 0

_TWO_THREADS = """
import threading, time, sys
go = threading.Event()
threading.Thread(target=go.wait, daemon=True).start()
print("ready", flush=True)
sys.stdin.readline()  # the test raises the priority meanwhile
late = threading.Thread(target=go.wait, daemon=True); late.start()
print("late", flush=True)
time.sleep(30)
"""


def _nices(pid: int) -> list[int]:
    return [os.getpriority(os.PRIO_PROCESS, int(t)) for t in os.listdir(f"/proc/{pid}/task")]


def _slacks(pid: int) -> list[int]:
    """Each thread's timer slack (ns); readable for a process of the same user."""
    return [int(Path(f"/proc/{t}/timerslack_ns").read_text()) for t in
            os.listdir(f"/proc/{pid}/task")]


def test_every_thread_and_a_later_one_run_at_the_device_niceness() -> None:
    with subprocess.Popen([sys.executable, "-c", _TWO_THREADS], stdin=subprocess.PIPE,
                          stdout=subprocess.PIPE, text=True) as proc:
        try:
            assert proc.stdout and proc.stdin and proc.stdout.readline() == "ready\n"
            raised = raise_device_priority(proc.pid)
            proc.stdin.write("\n")
            proc.stdin.flush()
            assert proc.stdout.readline() == "late\n"
            nices, slacks = _nices(proc.pid), _slacks(proc.pid)
        finally:
            proc.kill()
    assert len(nices) == 3
    if ROOT:
        assert raised and nices == [DEVICE_NICE] * 3
        assert slacks == [DEVICE_TIMER_SLACK_NS] * 3
    else:  # without the privilege: said so, and nothing changed
        assert not raised and set(nices) == {os.getpriority(os.PRIO_PROCESS, 0)}


@pytest.mark.skipif(session_group_nice(os.getpid()) is None, reason="a kernel without autogroup")
def test_a_session_of_its_own_is_raised_and_the_callers_is_left_alone() -> None:
    """Niceness orders threads only within a session's scheduling group: a stand-in in a
    session of its own has that group raised; one in the caller's session leaves the
    caller's group (the terminal's, the suite's) as it was."""
    ours = session_group_nice(os.getpid())
    sleep = [sys.executable, "-c", "import time; time.sleep(30)"]
    with subprocess.Popen(sleep, start_new_session=True) as own, subprocess.Popen(sleep) as shared:
        try:
            raised = raise_device_priority(own.pid), raise_device_priority(shared.pid)
            groups = session_group_nice(own.pid), session_group_nice(shared.pid)
        finally:
            own.kill()
            shared.kill()
    assert groups[1] == ours == session_group_nice(os.getpid())
    if ROOT:
        assert raised == (True, True) and groups[0] == DEVICE_NICE
    else:
        assert raised[0] is False and groups[0] == 0


def test_a_gone_process_is_no_error() -> None:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    time.sleep(0.05)
    assert raise_device_priority(proc.pid) is False


@pytest.mark.skipif(not ROOT, reason="the firmware tests run as root (network namespaces)")
def test_the_firmware_runs_at_the_device_niceness(sitl) -> None:
    assert set(_nices(sitl.proc.pid)) == {DEVICE_NICE}
    assert os.getsid(sitl.proc.pid) == sitl.proc.pid
    assert session_group_nice(sitl.proc.pid) in (DEVICE_NICE, None)
    assert set(_slacks(sitl.proc.pid)) == {DEVICE_TIMER_SLACK_NS}
