"""Paper A's calibration through the real PI GCS backend over loopback TCP (sim-imu-tcp.toml):
the same accuracy as on the plain simulated bench, and the hexapod stopped on every
failure path, including the controller dropping the connection mid-run."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.imu_calibration import load_calibration
from bench.cli import main
from bench.plan_runner.runner import HexapodRunOptions
from bench.plan_runner.session import run_stage
from bench.plans.calibration_sequences import Move, Rest, SetPivot, compile_plan
from bench.plans.sequences import Sequence
from bench.rig.rig import load_imu_rig
from drivers.backends.pi_hexapod import PiHexapod
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.hexapod_motions import gyro_sines

pytestmark = pytest.mark.slow(wall_s=20)  # a calibration through the PI GCS wire: started first

REPO = Path(__file__).resolve().parents[3]
TCP_RIG_PATH = REPO / "bench" / "data" / "rigs" / "sim-imu-tcp.toml"
RIG = load_imu_rig(TCP_RIG_PATH)
SEQ = Sequence("cal_test", (SetPivot(), Rest(0.5, "gyro"),
                                       Move(gyro_sines(beats=1), "gyro"), Rest(0.5, "gyro")))


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("cal_tcp")
    out = root / "cal.json"
    code = main(["calibrate", "--quick", "--tick", "0.1", "--rig", str(TCP_RIG_PATH),
                 "--runs", str(root / "runs"), "--out", str(out)])
    metas = [json.loads(p.read_text()) for p in sorted((root / "runs").glob("*/run.json"))]
    return code, out, sorted(metas, key=lambda m: m["stage"])


def test_every_stage_runs_through_the_tcp_backend(calibrated) -> None:
    code, out, metas = calibrated
    assert code == 0 and out.is_file()
    assert [m["kind"] for m in metas] == ["cal_bias", "cal_gyro", "cal_acc", "cal_lever",
                                          "cal_verify"]
    assert all(m["status"] == "success" for m in metas)
    assert all(m["rig"]["devices"]["hexapod"]["url"] == "tcp://sim" for m in metas)


def test_calibration_over_tcp_meets_the_plain_sim_targets(calibrated) -> None:
    """The targets test_calibration_end_to_end.py holds the plain simulated bench to."""
    _, out, metas = calibrated
    cal = load_calibration(out)
    truth = metas[0]["sim_truth"]
    assert _rel(cal.k_gyro, truth["k_gyro"]) < 0.002
    assert _rel(cal.k_acc, truth["k_acc"]) < 0.002
    assert np.abs(np.asarray(cal.lever_arm_m) - truth["lever_arm_from_pivot_m"]).max() < 0.002
    assert abs(cal.time_offset_s - truth["clock_offset_s"]) < 0.5e-3


# ---------------------------------------------------------------------------- failure paths


def _bench(tmp_path: Path, options: str = ""):
    path = TCP_RIG_PATH
    if options:
        path = tmp_path / "tcp.toml"
        path.write_text(TCP_RIG_PATH.read_text(encoding="utf-8").replace(
            'url = "tcp://sim"', f'url = "tcp://sim"\noptions = {{ {options} }}'),
            encoding="utf-8")
    return open_rig(load_imu_rig(path))


def _at(bench, t_s: float, action) -> None:
    """Run ``action`` once the rig clock passes ``t_s`` (a fault on the controller)."""
    done = []

    def listener(now_ns: int) -> None:
        if not done and now_ns * 1e-9 >= t_s:
            done.append(now_ns)
            action()

    bench.clock.on_advance(listener)


def _run(bench, tmp_path: Path, options: HexapodRunOptions | None = None, **kwargs):
    plan = compile_plan(SEQ, RIG.hexapod.hexapod_limits())
    return run_stage(bench, RIG, plan, tmp_path / "runs",
                     options=options or HexapodRunOptions(tick_s=0.1), **kwargs)


def _record(tmp_path: Path) -> tuple[dict, list[dict], pd.DataFrame]:
    (run_dir,) = [p for p in (tmp_path / "runs").iterdir() if p.is_dir()]
    meta = json.loads((run_dir / "run.json").read_text())
    with open(run_dir / "events.csv", newline="") as fh:
        events = list(csv.DictReader(fh))
    return meta, events, pd.read_parquet(run_dir / "samples.parquet")


def _assert_stopped_mid_motion(bench, meta: dict, events: list[dict], df: pd.DataFrame
                               ) -> None:
    plant = bench.sim.hexapod
    assert isinstance(bench.hexapod, PiHexapod) and bench.hexapod.stop_calls >= 1
    assert not plant.is_moving()
    assert meta["duration_s"] < 6.0  # the 22 s motion was cut short ...
    run = plant._runs[-1]
    assert run.stopped_at < run.t0 + run.duration  # ... by a stop
    assert [e["kind"] for e in events][-2:] == ["safe_stop", "run_end"]
    assert len(df) > 200 and df["t_s"].max() > 2.5  # the data up to the failure is kept


def test_controller_dropping_the_connection_fails_the_run_and_stops(tmp_path: Path) -> None:
    with _bench(tmp_path) as bench:
        _at(bench, 3.0, bench.wire.drop_connections)
        with pytest.raises(DeviceError, match="closed the connection"):
            _run(bench, tmp_path)
        meta, events, df = _record(tmp_path)
        assert meta["status"] == "fail" and "closed the connection" in meta["reason"]
        _assert_stopped_mid_motion(bench, meta, events, df)
        assert any("#24" in names for names in bench.wire.by_connection[2:])  # reconnected


def test_silent_controller_fails_the_run_and_the_stop_still_goes_out(tmp_path: Path) -> None:
    with _bench(tmp_path, "timeout_s = 0.5") as bench:
        _at(bench, 3.0, bench.wire.disconnect)
        with pytest.raises(DeviceError, match=r"no reply within 0\.5 s"):
            _run(bench, tmp_path)
        meta, events, df = _record(tmp_path)
        assert meta["status"] == "fail"
        assert "stop not confirmed" in " ".join(meta["safe_stop_errors"])  # honest about it
        _assert_stopped_mid_motion(bench, meta, events, df)  # the #24 arrived nonetheless


def test_watchdog_stops_while_the_main_conversation_hangs(tmp_path: Path) -> None:
    with _bench(tmp_path) as bench:
        _at(bench, 3.0, lambda: bench.wire.stall(1.5, connection=0))
        out = _run(bench, tmp_path, HexapodRunOptions(tick_s=0.1, watchdog_timeout_s=0.5))
        meta, events, df = _record(tmp_path)
        assert out.result.status == "abort" and "watchdog" in meta["reason"]
        _assert_stopped_mid_motion(bench, meta, events, df)
        assert "#24" in bench.wire.by_connection[1]  # over the stop connection
        run = bench.sim.hexapod._runs[-1]
        assert run.stopped_at - run.t0 < 3.5  # stopped while the reply was still pending


@pytest.mark.parametrize("how", ["bug", "ctrl_c"])
def test_host_side_failures_stop_the_platform(tmp_path: Path, how: str) -> None:
    def on_rows(rows):
        if rows["t_s"][-1] > 3.0:
            raise RuntimeError("plotting bug") if how == "bug" else KeyboardInterrupt

    with _bench(tmp_path) as bench:
        with pytest.raises(RuntimeError if how == "bug" else KeyboardInterrupt):
            _run(bench, tmp_path, on_rows=on_rows)
        meta, events, df = _record(tmp_path)
        assert meta["status"] == ("fail" if how == "bug" else "abort")
        _assert_stopped_mid_motion(bench, meta, events, df)


def test_closing_the_bench_stops_the_controller(tmp_path: Path) -> None:
    bench = _bench(tmp_path)
    host, port = bench.wire.address
    bench.close()
    assert bench.close_errors == [] and bench.hexapod.closed
    with pytest.raises(OSError):
        import socket

        socket.create_connection((host, port), timeout=0.5).close()
