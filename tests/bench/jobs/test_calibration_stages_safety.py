"""The hexapod is stopped at the end of every calibration run, whatever ends it."""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import numpy as np
import pytest

from bench.plan_runner.runner import HexapodRunOptions
from bench.plan_runner.session import run_stage
from bench.plans.calibration_sequences import Move, Rest, SetPivot, compile_plan
from bench.plans.sequences import Sequence
from bench.rig.rig import default_imu_rig_path, load_imu_rig
from drivers.contracts import Fault, HexapodLimits
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.hexapod_motions import gyro_sines

RIG = load_imu_rig(default_imu_rig_path())
SEQ = Sequence("cal_test", (SetPivot(), Rest(0.5, "gyro"),
                                       Move(gyro_sines(beats=1), "gyro"), Rest(0.5, "gyro")))
OPTIONS = HexapodRunOptions(tick_s=0.1)


@pytest.fixture
def bench():
    b = open_rig(RIG)
    yield b
    b.close()


def _run(bench, tmp_path: Path, **kwargs):
    plan = compile_plan(SEQ, RIG.hexapod.hexapod_limits())
    return run_stage(bench, RIG, plan, tmp_path / "runs", options=OPTIONS, **kwargs)


def _record(tmp_path: Path) -> tuple[dict, list[dict]]:
    (run_dir,) = [p for p in (tmp_path / "runs").iterdir() if p.is_dir()]
    meta = json.loads((run_dir / "run.json").read_text())
    with open(run_dir / "events.csv", newline="") as fh:
        events = list(csv.DictReader(fh))
    return meta, events


def _assert_stopped_mid_motion(bench, meta: dict, events: list[dict]) -> None:
    hx = bench.hexapod
    assert hx.stop_calls >= 1
    assert not hx.is_moving()
    assert meta["duration_s"] < 10.0  # the 22 s motion was cut short ...
    bench.clock.sleep(1.0)  # ... and the platform stays where it stopped
    log = hx.read_log()
    assert np.allclose(log.values["ref_omega_x_rad_s"], 0.0)
    assert np.allclose(log.values["hex_vroll_rad_s"], 0.0)
    kinds = [e["kind"] for e in events]
    assert kinds[-2:] == ["safe_stop", "run_end"]


def test_normal_end_stops_the_hexapod_and_records_success(bench, tmp_path: Path) -> None:
    out = _run(bench, tmp_path)
    meta, events = _record(tmp_path)
    assert out.result.status == meta["status"] == "success"
    assert bench.hexapod.stop_calls >= 1 and not bench.hexapod.is_moving()
    assert meta["rows"] == out.result.rows > 2000
    assert [e["kind"] for e in events][-2:] == ["safe_stop", "run_end"]
    assert "rig_t0_s" in meta and meta["limits"]["rate_rad_s"] == RIG.hexapod.limits["rate_rad_s"]
    # rows: the IMU's stamps with the hexapod's truth interpolated onto them
    import pandas as pd

    df = pd.read_parquet(out.run_dir / "samples.parquet")
    assert np.allclose(np.diff(df["t_s"]), 0.01)
    truth = bench.hexapod.state_at(df["t_s"].to_numpy() + meta["rig_t0_s"])
    for i, a in enumerate("xyz"):
        assert np.abs(df[f"ref_omega_{a}_rad_s"] - truth.omega_b_rad_s[:, i]).max() < 1e-4
        assert np.abs(df[f"ref_acc_{a}_m_s2"] - truth.specific_force_b_m_s2[:, i]).max() < 1e-3
    q = df[["ref_qw", "ref_qx", "ref_qy", "ref_qz"]].to_numpy()
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-3)
    assert set(df["phase"]) == {"gyro"}


def test_limit_trip_aborts_and_stops(bench, tmp_path: Path) -> None:
    bench.hexapod.inject(Fault.SPIKES, at_s=3.0, probability=1.0)
    out = _run(bench, tmp_path)
    meta, events = _record(tmp_path)
    assert out.result.status == meta["status"] == "abort"
    assert "limit trip" in meta["reason"] and meta["trip"]["sensor"] == "hexapod"
    assert meta["trip"]["t_s"] >= 3.0 - 1e-6
    assert "trip" in [e["kind"] for e in events]
    bench.hexapod.faults.clear()  # read the true log from here on
    _assert_stopped_mid_motion(bench, meta, events)


def test_device_error_fails_the_run_and_stops(bench, tmp_path: Path) -> None:
    bench.imu.inject(Fault.DISCONNECT, at_s=3.0)
    with pytest.raises(DeviceError, match="disconnected"):
        _run(bench, tmp_path)
    meta, events = _record(tmp_path)
    assert meta["status"] == "fail" and "device error" in meta["reason"]
    _assert_stopped_mid_motion(bench, meta, events)


def test_silent_imu_ends_the_run(bench, tmp_path: Path) -> None:
    bench.imu.inject(Fault.DROPOUT, at_s=3.0, probability=1.0)
    with pytest.raises(DeviceError, match="imu: no samples"):
        _run(bench, tmp_path)
    meta, events = _record(tmp_path)
    assert meta["status"] == "fail"
    _assert_stopped_mid_motion(bench, meta, events)


def test_refused_upload_fails_and_stops(bench, tmp_path: Path) -> None:
    bench.hexapod._limits = HexapodLimits(rate_rad_s=0.1)  # the device is stricter than the rig
    with pytest.raises(DeviceError, match="rate_rad_s"):
        _run(bench, tmp_path)
    meta, _ = _record(tmp_path)
    assert meta["status"] == "fail"
    assert bench.hexapod.stop_calls >= 1 and not bench.hexapod.is_moving()


def test_ctrl_c_aborts_stops_and_reraises(bench, tmp_path: Path) -> None:
    def on_progress(t, total, seg):
        if t > 3.0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _run(bench, tmp_path, on_progress=on_progress)
    meta, events = _record(tmp_path)
    assert meta["status"] == "abort" and "Ctrl-C" in meta["reason"]
    _assert_stopped_mid_motion(bench, meta, events)


def test_a_bug_fails_the_run_and_stops(bench, tmp_path: Path) -> None:
    def on_rows(rows):
        if rows["t_s"][-1] > 3.0:
            raise RuntimeError("plotting bug")

    with pytest.raises(RuntimeError, match="plotting bug"):
        _run(bench, tmp_path, on_rows=on_rows)
    meta, events = _record(tmp_path)
    assert meta["status"] == "fail" and "RuntimeError" in meta["reason"]
    _assert_stopped_mid_motion(bench, meta, events)


def test_operator_stop_aborts_and_stops(bench, tmp_path: Path) -> None:
    import threading

    stop = threading.Event()

    def on_progress(t, total, seg):
        if t > 3.0:
            stop.set()

    out = _run(bench, tmp_path, on_progress=on_progress, stop_event=stop)
    meta, events = _record(tmp_path)
    assert out.result.status == "abort" and "operator" in meta["reason"]
    _assert_stopped_mid_motion(bench, meta, events)


def test_stalled_host_is_stopped_by_the_watchdog(bench, tmp_path: Path) -> None:
    stalled = []

    def on_progress(t, total, seg):
        if t > 3.0 and not stalled:
            stalled.append(t)
            time.sleep(0.5)  # the loop hangs longer than the watchdog timeout

    plan = compile_plan(SEQ, RIG.hexapod.hexapod_limits())
    out = run_stage(bench, RIG, plan, tmp_path / "runs", on_progress=on_progress,
                    options=HexapodRunOptions(tick_s=0.1, watchdog_timeout_s=0.1))
    meta, events = _record(tmp_path)
    assert out.result.status == "abort" and "watchdog" in meta["reason"]
    _assert_stopped_mid_motion(bench, meta, events)


def test_calibration_session_stops_at_a_failed_stage_and_closes(tmp_path: Path) -> None:
    from bench.jobs.calibration_stages import run_calibration

    opened = []

    def open_bench(rig, seed=None):
        b = open_rig(rig, seed=seed)
        b.hexapod.inject(Fault.SPIKES, at_s=1.0, probability=1.0)
        opened.append(b)
        return b

    seqs = [SEQ, SEQ]
    run = run_calibration(RIG, tmp_path / "runs", sequences=seqs, options=OPTIONS,
                          open_bench=open_bench)
    assert not run.complete and len(run.stages) == 1
    assert run.stages[0].result.status == "abort"
    (b,) = opened
    assert b.hexapod.closed and not b.hexapod.is_moving()


def test_sigint_on_the_command_stops_records_and_exits_130(tmp_path: Path) -> None:
    """Ctrl-C on `rotorbench calibrate` (realtime, so it is still moving): the stage run is
    recorded as aborted with its safe stop, no calibration is written, exit code 130."""
    import os
    import signal
    import subprocess
    import sys

    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    runs = tmp_path / "runs"
    child = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "calibrate", "--quick", "--realtime", "--runs",
         str(runs), "--out", str(tmp_path / "cal.json")],
        env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and not list(runs.glob("*/samples.parquet/part-*")):
            time.sleep(0.05)
            assert child.poll() is None, "the calibration ended before it could be stopped"
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=20)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    assert child.returncode == 130, err.decode()
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["status"] == "abort" and "Ctrl-C" in meta["reason"]
    assert meta["safe_stop_errors"] == []
    with open(run_dir / "events.csv", newline="") as fh:
        kinds = [e["kind"] for e in csv.DictReader(fh)]
    assert kinds[-2:] == ["safe_stop", "run_end"]
    assert not (tmp_path / "cal.json").exists()
