"""PX4 ULog in: the two real PX4 logs shipped in fixtures/data/px4_ulog, imported as runs
of kind flight, checked against the topics read independently with pyulog."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import pyulog

from analysis.flightlogs import detect_flight_format, read_flight_log
from analysis.run_record import read_run
from bench.cli import main

ULOG = Path(__file__).resolve().parents[2] / "fixtures" / "data" / "px4_ulog"
EVENTS = ULOG / "sample_px4_events.ulg"
SMALL = ULOG / "sample_log_small.ulg"


def _topic(path: Path, name: str):
    return pyulog.ULog(str(path), [name]).get_dataset(name, 0).data


def test_both_shipped_logs_are_detected_as_ulog():
    assert detect_flight_format(EVENTS) == "ulog"
    assert detect_flight_format(SMALL) == "ulog"


def test_gyro_is_the_time_base_in_rad_s_from_zero():
    (log,) = read_flight_log(EVENTS, "ulog")
    sc = _topic(EVENTS, "sensor_combined")
    t = log.columns["t_s"]
    assert t[0] == 0.0 and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(t, (sc["timestamp"] - sc["timestamp"][0]) * 1e-6)
    np.testing.assert_allclose(log.columns["gyro_z_rad_s"], sc["gyro_rad[2]"], rtol=1e-6)
    assert log.units["gyro_x_rad_s"] == "rad/s"


def test_esc_rpm_and_battery_are_held_onto_the_gyro_clock():
    (log,) = read_flight_log(EVENTS, "ulog")
    esc = _topic(EVENTS, "esc_status")
    rpm = log.columns["motor1_rpm"]
    # the log flies up to about 3300 rpm; held values are logged values
    assert 3000 < np.nanmax(rpm) <= esc["esc[0].esc_rpm"].max()
    assert set(np.unique(rpm[np.isfinite(rpm)])) <= set(esc["esc[0].esc_rpm"].astype(float))
    # a held value is the last logged at or before the row's time
    sc_t = _topic(EVENTS, "sensor_combined")["timestamp"]
    k = len(sc_t) // 2
    j = np.searchsorted(esc["timestamp"], sc_t[k], side="right") - 1
    assert rpm[k] == esc["esc[0].esc_rpm"][j]
    v = log.columns["voltage_v"]
    assert 10.0 < np.nanmedian(v) < 30.0


def test_setpoint_and_motor_outputs_say_their_units():
    (log,) = read_flight_log(EVENTS, "ulog")
    assert log.units["rate_sp_x_rad_s"] == "rad/s"
    assert log.units["output1_us"] == "µs"
    assert np.nanmax(log.columns["output1_us"]) == pytest.approx(1549.0)
    m = log.columns["motor1_norm"]
    assert 0.5 < np.nanmax(m) <= 1.0


def test_import_writes_a_flight_run(tmp_path, capsys):
    out = tmp_path / "px4"
    assert main(["import", str(SMALL), "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert "(log 1 of 1; ulog, detected from its first bytes)" in line
    rec = read_run(out)
    assert rec.meta["kind"] == "flight"
    assert rec.meta["flight"]["format"] == "ulog"
    assert rec.meta["flight"]["sources"]["voltage_v"] == "battery_status.voltage_v"
    assert len(rec.samples) == len(_topic(SMALL, "sensor_combined")["timestamp"])
    assert np.isfinite(rec.column("gyro_x_rad_s")).all()


def test_a_cut_ulog_keeps_what_it_holds_or_says_why(tmp_path, capsys):
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(EVENTS.read_bytes()[:400_000])
    code = main(["import", str(cut), "--out", str(tmp_path / "r")])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    if code == 0:
        assert 0 < len(read_run(tmp_path / "r").samples) < 7783
    else:
        assert code == 2 and len(err.strip().splitlines()) == 1


def test_a_ulog_header_on_random_bytes_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.ulg"
    rng = np.random.default_rng(1)
    bad.write_bytes(b"ULog\x01\x12\x35\x01" + bytes(8) + rng.bytes(5000))
    assert main(["import", str(bad), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(bad) in err


def test_max_rows_keeps_the_first_rows_and_says_so(tmp_path, capsys):
    out = tmp_path / "px4"
    assert main(["import", str(SMALL), "--max-rows", "100", "--out", str(out)]) == 0
    assert "kept the first 100 of 1298 rows (--max-rows)" in capsys.readouterr().out
    assert len(read_run(out).samples) == 100


def test_without_the_flightlogs_extra_a_ulog_says_which_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyulog", None)  # import pyulog now raises ImportError
    assert main(["import", str(SMALL), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "rotorbench[flightlogs]" in err
    assert not (tmp_path / "r").exists()


def test_a_flight_run_is_indexed_like_a_bench_run(tmp_path, capsys):
    from bench.store.run_index import RunIndex

    assert main(["import", str(EVENTS), "--out", str(tmp_path / "runs" / "px4")]) == 0
    capsys.readouterr()
    index = RunIndex(tmp_path / "runs")
    assert index.rebuild().indexed == 1
    (row,) = index.list()
    assert row.status == "success" and "sample_px4_events.ulg" in row.reason


def test_another_format_forced_as_ulog_is_one_line_exit_2(tmp_path, capsys):
    other = tmp_path / "x.ulg"
    other.write_bytes(b"\xa3\x95\x80" + bytes(300))  # a DataFlash start
    assert main(["import", str(other), "--format", "ulog", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "not a readable ULog" in err
