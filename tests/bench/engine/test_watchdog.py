"""The host watchdog: a stalled command loop stops the motor, and stays stopped."""

from __future__ import annotations

import json
import time

import pytest

from bench.engine.watchdog import GuardedEsc, HostWatchdog, WatchdogTrip
from bench.plan_runner.runner import Runner, RunOptions
from bench.plans.sequences import EscRange, compile_plan
from bench.plans.stand_sequences import step1

ESC = EscRange(1000.0, 1050.0, 2000.0)


class Esc:
    def __init__(self):
        self.armed = False
        self.pulse = 1000.0

    def arm(self):
        self.armed = True

    def set_pulse_us(self, us):
        self.pulse = us

    def disarm(self):
        self.armed, self.pulse = False, 1000.0


def test_watchdog_disarms_when_the_loop_stops_checking_in():
    esc = Esc()
    guarded = GuardedEsc(esc, 1050.0, 2000.0, 1000.0)
    guarded.arm()
    guarded.set_pulse_us(1500.0)
    with HostWatchdog(guarded, timeout_s=0.3) as wd:
        for _ in range(10):  # a healthy loop: no trip
            wd.kick()
            time.sleep(0.02)
        assert esc.armed and not wd.tripped
        time.sleep(0.8)  # the loop stalls
        assert wd.tripped
        assert esc.armed is False and esc.pulse == 1000.0
        with pytest.raises(WatchdogTrip):  # the loop wakes up: no more commands
            guarded.set_pulse_us(1500.0)
        with pytest.raises(WatchdogTrip):
            wd.kick()
    assert esc.armed is False and esc.pulse == 1000.0


def test_a_conversation_at_rest_is_not_a_stall_but_a_stall_around_it_is():
    """``at_rest`` (a hexapod's trajectory upload) excuses the time inside the block only:
    the timeout starts again on the way out, and a stall before it trips on the way in."""
    esc = Esc()
    guarded = GuardedEsc(esc, 1050.0, 2000.0, 1000.0)
    guarded.arm()
    with HostWatchdog(guarded, timeout_s=0.2, stops="hexapod stopped") as wd:
        with wd.at_rest():
            time.sleep(0.5)  # the controller takes its time
        assert not wd.tripped and esc.armed
        wd.kick()  # the next tick: not late
        time.sleep(0.5)  # a real stall after the block
        assert wd.tripped and not esc.armed
        assert wd.reason.endswith("; hexapod stopped")
    esc = Esc()
    guarded = GuardedEsc(esc, 1050.0, 2000.0, 1000.0)
    guarded.arm()
    with HostWatchdog(guarded, timeout_s=0.2, poll_s=10.0) as wd:  # the thread sleeps on
        time.sleep(0.4)  # the loop stalled before the conversation
        stalled = r"stalled \d\.\d+ s \(timeout 0\.2 s\); ESC disarmed"
        with pytest.raises(WatchdogTrip, match=stalled), wd.at_rest():
            pass
    assert not esc.armed


def test_guarded_esc_clamps_commands_to_the_rig_range():
    esc = Esc()
    guarded = GuardedEsc(esc, 1050.0, 1800.0, 1000.0)
    guarded.set_pulse_us(2500.0)
    assert esc.pulse == 1800.0
    guarded.set_pulse_us(1010.0)
    assert esc.pulse == 1050.0
    guarded.set_pulse_us(1000.0)  # idle is allowed below min
    assert esc.pulse == 1000.0


def test_stalled_runner_is_stopped_by_the_watchdog(fakes, tmp_path):
    from bench.engine.recorder import RunRecorder

    rig = fakes.FakeRig()
    rig.faults.stall_at_s = rig.clock.t + 3.3  # spinning at the high level
    rig.faults.stall_wall_s = 0.9
    seq = step1(repeats=3)
    plan = compile_plan(seq, ESC, lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)
    rec = RunRecorder(tmp_path / "run", {})
    runner = Runner(rig, plan, ESC, {"thrust_n": 10.0}, rec,
                    RunOptions(watchdog_timeout_s=0.3))
    result = runner.run()
    # checked inside the stalled read, before the loop could do anything
    assert rig.faults.seen_during_stall == [False]
    assert result.status == "abort" and "watchdog" in result.reason
    assert rig.esc.armed is False
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["status"] == "abort" and "stalled" in meta["reason"]


def test_a_signal_inside_the_watchdogs_start_still_ends_safely_and_recorded(
        fakes, tmp_path, monkeypatch):
    """SIGTERM (or Ctrl-C) landing while the watchdog thread starts: the ESC is made safe,
    the run is recorded as aborted and the interrupt goes on to the command. It once
    ended in 'RuntimeError: cannot join thread before it is started' from the run's
    finally, and the run was never recorded (seen with `kill` on `rotorbench demo`)."""
    import threading

    from bench.engine.recorder import RunRecorder

    real_start = threading.Thread.start

    def start(thread: threading.Thread) -> None:
        if thread.name == "rotorbench-watchdog":
            raise KeyboardInterrupt("SIGTERM")  # the signal handler ran inside start()
        real_start(thread)

    monkeypatch.setattr(threading.Thread, "start", start)
    rig = fakes.FakeRig()
    plan = compile_plan(step1(repeats=1), ESC, lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)
    rec = RunRecorder(tmp_path / "run", {})
    runner = Runner(rig, plan, ESC, {"thrust_n": 10.0}, rec, RunOptions())
    with pytest.raises(KeyboardInterrupt):
        runner.run()
    assert rig.esc.armed is False
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["status"] == "abort" and "interrupted" in meta["reason"]


def test_stop_of_a_watchdog_whose_start_was_interrupted(monkeypatch) -> None:
    import threading

    def start(thread: threading.Thread) -> None:
        raise KeyboardInterrupt

    wd = HostWatchdog(GuardedEsc(Esc(), 1050.0, 2000.0, 1000.0))
    monkeypatch.setattr(threading.Thread, "start", start)
    with pytest.raises(KeyboardInterrupt):
        wd.start()
    wd.stop()  # nothing to join, no error
