"""End to end on the real simulated rig: runs, trips of every limit, device errors,
Ctrl-C, bugs and a stalled host all end with the ESC at idle and disarmed."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.engine.recorder import BASE_COLUMNS, RunRecorder
from bench.engine.safety import effective_limits
from bench.plan_runner.runner import Runner, RunOptions
from bench.plan_runner.session import esc_range_of, plan_for, run_sequence
from bench.plans.stand_sequences import step1
from bench.rig.rig import load_rig
from bench.store.run_index import RunIndex
from drivers.contracts import Fault
from drivers.errors import DeviceError
from drivers.factory import open_rig


def disarmed(devices, rig) -> bool:
    devices.clock.sleep(0.05)  # let the ESC latch the last frame (input latency ~15-20 ms)
    truth = devices.truth()
    return (not truth.armed) and devices.esc.last_pulse_us == rig.esc.idle_us


def _mapped_rig(tmp: Path, fakes):
    from bench.rig.rig import default_rig_path

    path = tmp / "sim.toml"
    path.write_text(default_rig_path().read_text(encoding="utf-8"), encoding="utf-8")
    fakes.write_truth_map(path)
    return load_rig(path)


@pytest.fixture(scope="module")
def mapped(tmp_path_factory, fakes):
    tmp = tmp_path_factory.mktemp("simrig")
    rig = _mapped_rig(tmp, fakes)
    outcome = run_sequence(rig, step1(repeats=2), tmp / "runs", open_rig)
    samples = pd.read_parquet(outcome.run_dir / "samples.parquet")
    return rig, outcome, samples


def test_step1_on_the_sim_rig_records_everything(mapped):
    rig, outcome, samples = mapped
    assert outcome.result.status == "success"
    assert list(samples.columns[: len(BASE_COLUMNS)]) == list(BASE_COLUMNS)
    dt = np.diff(samples["t_s"].to_numpy())
    assert np.all(dt > 0) and np.median(dt) == pytest.approx(1 / 25_000, rel=0.01)
    assert samples["t_s"].iloc[-1] == pytest.approx(outcome.plan.duration_s, abs=0.01)
    # settled thrust at each level matches the setpoint through the static map
    for seg in outcome.plan.segments:
        if seg.kind != "thrust_step":
            continue
        late = samples[(samples["t_s"] > seg.t_end_s - 0.1) & (samples["t_s"] < seg.t_end_s)]
        assert late["thrust_n"].mean() == pytest.approx(seg.setpoint_n, rel=0.05)
        assert np.all(late["thrust_setpoint_n"] == seg.setpoint_n)
    meta = json.loads((outcome.run_dir / "run.json").read_text())
    assert meta["status"] == "success" and meta["ended_utc"] and meta["software_version"]
    assert meta["components"]["motor"] == rig.components.motor
    assert meta["sequence"]["name"] == "step1" and meta["rig"]["name"] == rig.name
    events = pd.read_csv(outcome.run_dir / "events.csv")
    assert (events["kind"] == "step_start").sum() == len(outcome.plan.segments)
    rows = RunIndex(outcome.run_dir.parent).list()
    assert [(r.id, r.status) for r in rows] == [(outcome.run_dir.name, "success")]


def _run(rig, seq, tmp_path, wrap=None, inject=None, **opts):
    """Run on the sim rig, keeping the devices open to inspect the ESC afterwards."""
    devices = open_rig(rig)
    if inject:
        inject(devices)
    if wrap:
        devices.sensors["load_cell"] = wrap(devices.sensors["load_cell"], devices)
    limits = effective_limits(rig.limits, seq.limits)
    rec = RunRecorder(tmp_path / "run", {"sequence": seq.to_dict()})
    runner = Runner(devices, plan_for(rig, seq), esc_range_of(rig), limits, rec,
                    RunOptions(**opts))
    return runner, devices


def _level(samples, col, t0, t1):
    part = samples[(samples["t_s"] > t0) & (samples["t_s"] < t1)][col]
    return float(part.mean())


@pytest.fixture(scope="module")
def weak_supply(mapped, tmp_path_factory):
    """The mapped rig on a weak supply (0.3 ohm): sag far above the voltage noise."""
    rig = mapped[0]
    rig = dataclasses.replace(rig, sim=dataclasses.replace(rig.sim, plant={"supply_r_ohm": 0.3}))
    outcome = run_sequence(rig, step1(repeats=2), tmp_path_factory.mktemp("weak"), open_rig)
    return rig, outcome, pd.read_parquet(outcome.run_dir / "samples.parquet")


@pytest.mark.parametrize("limit", ["thrust_n", "current_a", "rpm", "voltage_min_v",
                                   "voltage_max_v"])
def test_every_limit_trips_on_the_sim_rig(mapped, weak_supply, tmp_path, limit):
    rig, outcome, samples = weak_supply if limit.startswith("voltage") else mapped
    segs = [s for s in outcome.plan.segments if s.kind == "thrust_step"]
    low, high = segs[0], segs[1]  # settled low level, then the first high level
    col = {"thrust_n": "thrust_n", "current_a": "current_a", "rpm": "rpm",
           "voltage_min_v": "voltage_v", "voltage_max_v": "voltage_v"}[limit]
    at_low = _level(samples, col, low.t_end_s - 0.2, low.t_end_s)
    at_high = _level(samples, col, high.t_end_s - 0.2, high.t_end_s)
    at_rest = _level(samples, col, 0.55, 0.95)  # tare window, motor stopped
    if limit == "voltage_max_v":
        value = 0.5 * (at_rest + at_high)  # below the resting voltage: trips at once
    else:
        value = 0.5 * (at_low + at_high)  # between the two levels: trips on the up-step
    seq = dataclasses.replace(step1(repeats=2), limits={limit: value})
    runner, devices = _run(rig, seq, tmp_path)
    result = runner.run()
    assert result.status == "abort", result.reason
    assert result.trip.limit == limit and result.trip.channel == col
    if limit == "voltage_max_v":
        assert result.trip.t_s < 0.1
    else:
        assert high.t_start_s < result.trip.t_s < high.t_end_s
    assert disarmed(devices, rig)
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["trip"]["limit"] == limit and meta["trip"]["sample"][col] == result.trip.value
    devices.close()


def test_device_disconnect_mid_run_ends_disarmed(mapped, tmp_path):
    rig = mapped[0]
    runner, devices = _run(rig, step1(repeats=2), tmp_path, inject=lambda d: d.sensors[
        "load_cell"].inject(Fault.DISCONNECT, at_s=3.4))
    with pytest.raises(DeviceError):
        runner.run()
    assert disarmed(devices, rig)
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["status"] == "fail" and "device error" in meta["reason"]


class _Raising:
    """Wraps a sensor: raises ``exc`` on the first read at or after rig time ``at_s``."""

    def __init__(self, sensor, devices, at_s, exc=None, stall_s=0.0):
        self.sensor, self.devices, self.at_s = sensor, devices, at_s
        self.exc, self.stall_s = exc, stall_s
        self.seen: list[bool] = []

    def describe(self):
        return self.sensor.describe()

    def close(self):
        self.sensor.close()

    def read_block(self):
        if self.at_s is not None and self.devices.clock.now() >= self.at_s:
            self.at_s = None
            if self.exc is not None:
                raise self.exc
            time.sleep(self.stall_s)  # the host stalls (no rig time passes)
            esc = self.devices.esc
            self.seen.append(esc.last_pulse_us == 1000.0 and esc.model.events[-1][1] == "disarm")
        return self.sensor.read_block()


@pytest.mark.parametrize("exc", [KeyboardInterrupt(), RuntimeError("a bug")])
def test_ctrl_c_and_bugs_mid_run_end_disarmed(mapped, tmp_path, exc):
    rig = mapped[0]
    runner, devices = _run(rig, step1(repeats=2), tmp_path,
                           wrap=lambda s, d: _Raising(s, d, 3.3, exc))
    with pytest.raises(type(exc)):
        runner.run()
    assert disarmed(devices, rig)
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["status"] == ("abort" if isinstance(exc, KeyboardInterrupt) else "fail")


def test_stalled_host_is_stopped_by_the_watchdog_on_the_sim_rig(mapped, tmp_path):
    rig = mapped[0]
    holder = {}

    def wrap(sensor, devices):
        holder["w"] = _Raising(sensor, devices, 3.3, stall_s=0.9)
        return holder["w"]

    runner, devices = _run(rig, step1(repeats=2), tmp_path, wrap=wrap, watchdog_timeout_s=0.3)
    result = runner.run()
    assert holder["w"].seen == [True]  # disarmed while the loop was still stalled
    assert result.status == "abort" and "watchdog" in result.reason
    assert disarmed(devices, rig)


class _LossyLink:
    """Wraps a sensor as a backend whose decoder saw damaged frames on its link."""

    def __init__(self, sensor):
        self.sensor = sensor

    def describe(self):
        return self.sensor.describe()

    def read_block(self):
        return self.sensor.read_block()

    def close(self):
        self.sensor.close()

    def link_errors(self):
        return {"bad_checksums": 3, "truncated": 1}


def test_link_errors_are_recorded_and_mark_the_run(mapped, tmp_path):
    from bench.commands.runs import drops_text

    rig = mapped[0]
    runner, _ = _run(rig, step1(repeats=1), tmp_path,
                           wrap=lambda sensor, _devices: _LossyLink(sensor))
    runner.run()
    meta = json.loads((tmp_path / "run" / "run.json").read_text())
    assert meta["status"] == "success" and meta["dropped_samples"] == 0
    assert meta["drops"]["load_cell"]["link_errors"] == {"bad_checksums": 3, "truncated": 1}
    assert meta["link_errors"] == 4 and "drops" in meta["marks"]
    assert drops_text(tmp_path / "run") == "0, ! 4 link errors"


def test_the_tare_zeroes_thrust_and_torque_and_records_each_zero_with_its_uncertainty(
        mapped, tmp_path):
    """Both force channels are referred to their zero at rest; run.json keeps each zero,
    its standard uncertainty (the scatter of block means) and its sample count, which the
    budgets of k_f, k_q and the thrust curve read."""
    from analysis.metrology.constant_budgets import tare_uncertainty

    rig = mapped[0]
    rig = dataclasses.replace(rig, sim=dataclasses.replace(
        rig.sim, sensors={"torque_cell_range_nm": 0.5}))
    outcome = run_sequence(rig, step1(repeats=1), tmp_path / "runs", open_rig)
    meta = json.loads((outcome.run_dir / "run.json").read_text())
    tare = meta["tare"]
    assert set(tare) == {"thrust_n", "torque_nm"}
    assert "tare_offset_n" not in meta  # one home for the offset: tare.thrust_n.offset
    for ch, z in tare.items():
        assert z["samples"] > 1000 and 0.0 < z["u"] < 1e-3, (ch, z)
    assert tare_uncertainty(meta) == {ch: z["u"] for ch, z in tare.items()}
    # the tare window is recorded raw (its zero is known at its end): its mean is the zero
    samples = pd.read_parquet(outcome.run_dir / "samples.parquet")
    seg = next(s for s in outcome.plan.segments if s.kind == "tare")
    window = samples[samples["step"] == seg.index]
    for ch, z in tare.items():
        assert abs(len(window) - z["samples"]) <= 1  # the rows delivered during the tare
        assert window[ch].mean() == pytest.approx(z["offset"], abs=z["u"]), ch
    # later samples are referred to the zero: the spinning rotor's torque and thrust
    # over the last repeat's high step have the signs of (E.1) and (E.2)
    last = outcome.plan.segments[5]
    high = samples[(samples["t_s"] > last.t_end_s - 0.1) & (samples["t_s"] < last.t_end_s)]
    assert high["thrust_n"].mean() == pytest.approx(last.setpoint_n, rel=0.05)
    assert abs(high["torque_nm"].mean()) > 20 * tare["torque_nm"]["u"]
