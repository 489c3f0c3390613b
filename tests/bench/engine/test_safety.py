"""Safety: every limit trips, every way a run ends leaves the ESC at idle and disarmed,
and sequences can only tighten the rig's limits. Unit level, on the fake rig."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from bench.engine.recorder import RunRecorder
from bench.engine.safety import SafetySupervisor, effective_limits
from bench.errors import RigError
from bench.plan_runner.runner import Runner, RunOptions
from bench.plans.sequences import EscRange, Sequence, compile_plan
from bench.plans.stand_sequences import step1
from bench.rig.rig import Limits
from drivers.contracts import Block
from drivers.errors import DeviceError

ESC = EscRange(1000.0, 1050.0, 2000.0)
LIMITS = {"thrust_n": 5.0, "current_a": 10.0, "rpm": 9000.0, "voltage_min_v": 9.0,
          "voltage_max_v": 13.0}


def fake_map(thrust_n: float) -> float:  # inverse of the fake plant's steady state
    return 1050.0 + math.sqrt(thrust_n / 1.0e-7) / 12.0


def make_runner(rig, tmp_path, limits=LIMITS, seq=None, **opts):
    seq = seq or step1(repeats=3)
    plan = compile_plan(seq, ESC, fake_map)
    rec = RunRecorder(tmp_path / "run", {"sequence": seq.to_dict()})
    return Runner(rig, plan, ESC, limits, rec, RunOptions(**opts)), rec


def assert_safe(rig):
    assert rig.esc.armed is False
    assert rig.esc.pulse_us == 1000.0
    kinds = [k for _, k, _ in rig.esc.history]
    assert kinds[-1] == "disarm"


def run_json(tmp_path):
    return json.loads((tmp_path / "run" / "run.json").read_text())


def events(tmp_path):
    return pd.read_csv(tmp_path / "run" / "events.csv")


# -- limits only tighten ----------------------------------------------------------------


def test_sequence_may_tighten_limits():
    rig = Limits(thrust_n=7.0, current_a=25.0, rpm=12000.0, voltage_min_v=9.0,
                 voltage_max_v=12.8)
    eff = effective_limits(rig, {"thrust_n": 4.0, "voltage_min_v": 10.0})
    assert eff["thrust_n"] == 4.0 and eff["voltage_min_v"] == 10.0
    assert eff["current_a"] == 25.0


@pytest.mark.parametrize("looser", [{"thrust_n": 8.0}, {"current_a": 30.0}, {"rpm": 15000.0},
                                    {"voltage_min_v": 8.0}, {"voltage_max_v": 14.0}])
def test_sequence_can_never_loosen_limits(looser):
    rig = Limits(thrust_n=7.0, current_a=25.0, rpm=12000.0, voltage_min_v=9.0,
                 voltage_max_v=12.8)
    with pytest.raises(RigError, match="only tighten"):
        effective_limits(rig, looser)
    with pytest.raises(RigError, match="only tighten"):  # plain mapping, our own check
        effective_limits(rig.as_dict(), looser)


def test_unknown_limit_is_refused():
    with pytest.raises(RigError, match=r"limits\.torque_nm"):
        effective_limits(LIMITS, {"torque_nm": 1.0})


def test_supervisor_reports_the_earliest_violation_with_its_sample():
    sup = SafetySupervisor(LIMITS)
    blocks = {
        "load_cell": Block(np.array([1.0, 2.0, 3.0]), {"thrust_n": np.array([1.0, 6.0, 7.0])}),
        "power": Block(np.array([0.5, 1.5]), {"current_a": np.array([1.0, 11.0]),
                                              "voltage_v": np.array([12.0, 11.9])}),
    }
    trip = sup.check(blocks)
    assert trip.limit == "current_a" and trip.t_s == 1.5 and trip.value == 11.0
    assert trip.sample == {"t_s": 1.5, "current_a": 11.0, "voltage_v": 11.9}
    assert sup.check({"rpm": Block(np.array([0.0]), {"rpm": np.array([np.nan])})}) is None


# -- every limit trips and the run ends safe --------------------------------------------


@pytest.mark.parametrize(
    ("channel", "value", "limit"),
    [("thrust_n", 9.0, "thrust_n"), ("current_a", 50.0, "current_a"), ("rpm", 20000.0, "rpm"),
     ("voltage_v", 5.0, "voltage_min_v"), ("voltage_v", 20.0, "voltage_max_v")],
)
def test_each_limit_trips_and_ends_idle_disarmed(fakes, tmp_path, channel, value, limit):
    rig = fakes.FakeRig()
    t_spike = rig.clock.t + 3.2004  # while spinning at the high level
    rig.faults.spike[channel] = (t_spike, value)
    runner, _ = make_runner(rig, tmp_path)
    result = runner.run()
    assert result.status == "abort"
    expected = value - rig.thrust_offset_n if channel == "thrust_n" else value  # tared
    assert result.trip.limit == limit and result.trip.value == pytest.approx(expected)
    assert_safe(rig)
    meta = run_json(tmp_path)
    assert meta["status"] == "abort" and limit in meta["reason"]
    assert meta["trip"]["limit"] == limit
    assert meta["trip"]["sample"][channel] == pytest.approx(expected)
    t_trip = meta["trip"]["t_s"]
    assert t_trip == pytest.approx(t_spike - 100.0, abs=3e-3)  # rig time from run start
    ev = events(tmp_path)
    assert "trip" in set(ev["kind"]) and ev["kind"].iloc[-1] == "run_end"
    samples = pd.read_parquet(tmp_path / "run" / "samples.parquet")
    assert samples["t_s"].iloc[-1] >= t_trip  # the triggering sample is in the record
    # the motor was not commanded again after the trip
    last_set = max(t for t, k, _ in rig.esc.history if k == "set" and _ > 1000.0)
    assert last_set - 100.0 <= t_trip + 0.02


def test_thrust_limit_uses_the_tared_force(fakes, tmp_path):
    rig = fakes.FakeRig()
    rig.thrust_offset_n = 4.0  # a big zero offset: untared, 4 N + 3.2 N would trip at 5 N
    runner, _ = make_runner(rig, tmp_path, limits={**LIMITS, "thrust_n": 5.0})
    assert runner.run().status == "success"
    assert runner.tare_offset_n == pytest.approx(4.0)


# -- every other ending -----------------------------------------------------------------


def test_normal_end_is_idle_and_disarmed(fakes, tmp_path):
    rig = fakes.FakeRig()
    runner, _ = make_runner(rig, tmp_path)
    result = runner.run()
    assert result.status == "success" and result.reason == "sequence complete"
    assert_safe(rig)
    assert run_json(tmp_path)["status"] == "success"


def test_device_error_mid_run_ends_disarmed_and_is_reraised(fakes, tmp_path):
    rig = fakes.FakeRig()
    rig.faults.device_error_at_s = rig.clock.t + 3.3
    runner, _ = make_runner(rig, tmp_path)
    with pytest.raises(DeviceError):
        runner.run()
    assert_safe(rig)
    meta = run_json(tmp_path)
    assert meta["status"] == "fail" and "device error" in meta["reason"]


def test_esc_error_mid_run_still_disarms(fakes, tmp_path):
    rig = fakes.FakeRig()
    rig.esc.fail_set_after_s = rig.clock.t + 3.0  # commands fail; disarm still works
    runner, _ = make_runner(rig, tmp_path)
    with pytest.raises(DeviceError):
        runner.run()
    assert rig.esc.armed is False
    assert runner.result.safe_stop_errors  # the failed idle command is on record
    assert run_json(tmp_path)["safe_stop_errors"]


def test_keyboard_interrupt_mid_run_ends_disarmed(fakes, tmp_path):
    rig = fakes.FakeRig()
    rig.faults.interrupt_at_s = rig.clock.t + 3.3
    runner, _ = make_runner(rig, tmp_path)
    with pytest.raises(KeyboardInterrupt):
        runner.run()
    assert_safe(rig)
    meta = run_json(tmp_path)
    assert meta["status"] == "abort" and "Ctrl-C" in meta["reason"]


def test_bug_mid_run_ends_disarmed_and_keeps_its_traceback(fakes, tmp_path):
    rig = fakes.FakeRig()
    rig.faults.bug_at_s = rig.clock.t + 3.3
    runner, _ = make_runner(rig, tmp_path)
    with pytest.raises(ZeroDivisionError):
        runner.run()
    assert_safe(rig)
    assert run_json(tmp_path)["status"] == "fail"
    assert "ZeroDivisionError" in run_json(tmp_path)["reason"]


def test_operator_stop_ends_disarmed(fakes, tmp_path):
    rig = fakes.FakeRig()
    runner, _ = make_runner(rig, tmp_path)

    def stop_at_3s(t, total, seg):
        if t > 3.0:
            runner.request_stop()

    runner.on_progress = stop_at_3s
    result = runner.run()
    assert result.status == "abort" and "operator" in result.reason
    assert_safe(rig)
    assert "operator_stop" in set(events(tmp_path)["kind"])


def test_esc_gets_a_command_every_tick_for_its_failsafe(fakes, tmp_path):
    rig = fakes.FakeRig()
    seq = step1(repeats=1, hold_s=2.0)
    runner, _ = make_runner(rig, tmp_path, seq=seq, tick_s=0.02)
    runner.run()
    sets = np.array([t for t, k, _ in rig.esc.history if k == "set"])
    assert np.max(np.diff(sets)) <= 0.02 + 1e-9


def test_commands_never_exceed_the_esc_range(fakes, tmp_path):
    rig = fakes.FakeRig()
    seq = Sequence("s", step1(repeats=1).steps)
    runner, _ = make_runner(rig, tmp_path, seq=seq)
    runner.run()
    pulses = [p for _, k, p in rig.esc.history if k == "set"]
    assert all(p == 1000.0 or 1050.0 <= p <= 2000.0 for p in pulses)


@pytest.mark.parametrize("role", ["load_cell", "power", "rpm"])
def test_a_silent_sensor_ends_the_run_disarmed(fakes, tmp_path, role):
    rig = fakes.FakeRig()
    rig.faults.silent_role, rig.faults.silent_at_s = role, rig.clock.t + 3.1
    runner, _ = make_runner(rig, tmp_path)
    with pytest.raises(DeviceError, match=f"{role}: no samples"):
        runner.run()
    assert_safe(rig)
    assert runner.result.t_end_s < 3.1 + 0.25 + 0.05  # within stale_s (+ one tick)


def test_bad_tick_is_refused():
    with pytest.raises(RigError, match="--tick"):
        RunOptions(tick_s=0.0)
    with pytest.raises(RigError, match="--tick"):
        RunOptions(tick_s=0.5)  # slower than the ESC failsafe wants its heartbeat


def test_a_second_ctrl_c_during_the_safe_stop_does_not_cut_it_short(fakes, tmp_path):
    import signal

    rig = fakes.FakeRig()
    rig.faults.interrupt_at_s = rig.clock.t + 3.3  # first Ctrl-C: ends the run
    original = rig.esc.set_pulse_us
    fired = []

    def set_pulse(us):
        if us == 1000.0 and not fired and rig.clock.t >= 103.3:  # the safe stop's idle
            fired.append(True)
            signal.raise_signal(signal.SIGINT)  # second Ctrl-C, while stopping
        original(us)

    rig.esc.set_pulse_us = set_pulse
    runner, _ = make_runner(rig, tmp_path)
    with pytest.raises(KeyboardInterrupt):
        runner.run()
    assert fired
    assert_safe(rig)
    assert run_json(tmp_path)["status"] == "abort"


def test_temperature_limit_trips_when_a_sensor_reports_it():
    sup = SafetySupervisor({**LIMITS, "temperature_c": 80.0})
    block = Block(np.array([0.0, 0.1]), {"temperature_c": np.array([79.0, 81.0])})
    trip = sup.check({"thermo": block})
    assert trip.limit == "temperature_c" and trip.t_s == 0.1 and trip.sensor == "thermo"
