"""Importers: the shipped real logs (read in place), any CSV, and the import command."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import LogError
from analysis.importers import import_csv, import_esc32, import_rcbenchmark, parse_header
from analysis.run_record import read_run
from bench.cli import main

RCB = "esc_test/rcbenchmark_Log_2019-11-05_171350.csv"
ESC32 = "esc_test/autoquad_esc32_f40_steps_5-2.csv"


def test_parse_header():
    assert parse_header("Thrust (gf)") == ("Thrust", "gf")
    assert parse_header("Torque (N·m)") == ("Torque", "N·m")
    assert parse_header("rpm") == ("rpm", None)
    assert parse_header("speed [rad/s]") == ("speed", "rad/s")


def test_rcbenchmark_real_log(shared_data):
    df, meta = import_rcbenchmark(shared_data / RCB)
    raw = np.genfromtxt(shared_data / RCB, delimiter=",", skip_header=1, usecols=9)
    assert len(df) == raw.size
    # gram-force -> newtons by the header's unit; sparse load-cell rows stay NaN
    np.testing.assert_allclose(df["thrust_n"].to_numpy(), raw * 9.80665e-3, equal_nan=True)
    assert np.isnan(df["thrust_n"]).sum() == np.isnan(raw).sum() > 0
    assert meta["columns"]["thrust_n"] == "Thrust (gf)"
    assert "throttle_us" not in df.columns  # the ESC signal column is empty in this test
    assert df["rpm"].max() == pytest.approx(15957.0)
    assert df["t_s"].is_monotonic_increasing


def test_esc32_real_log(shared_data):
    df, meta = import_esc32(shared_data / ESC32)
    assert df["t_s"].iloc[0] == 0.0
    assert df["t_s"].iloc[-1] == pytest.approx(115.033, abs=1e-3)  # 17:14:08.947 -> 17:16:03.980
    assert set(df.columns) >= {"current_a", "voltage_v", "rpm", "duty_pct"}
    assert df["duty_pct"].max() == 100.0
    assert meta["start_time"].startswith("2019-11-05 17:14:08")


def test_csv_with_run_names_needs_no_mapping(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text("t_s,throttle_us,thrust_setpoint_n,thrust_n,rpm,extra\n"
                 "0,1000,,0,0,1\n0.1,1500,2.0,1.9,6000,2\n", encoding="utf-8")
    df, _meta = import_csv(p)
    assert list(df.columns) == ["t_s", "throttle_us", "thrust_setpoint_n", "thrust_n", "rpm"]
    assert df["thrust_n"].iloc[1] == 1.9 and np.isnan(df["thrust_setpoint_n"].iloc[0])


def test_csv_mapping_converts_units_by_name(tmp_path):
    p = tmp_path / "stand.csv"
    p.write_text("time (ms),pwm (us),lift (kgf),speed [rad/s],amps\n"
                 "0,1100,0.1,100,1\n500,1200,0.2,200,2\n", encoding="utf-8")
    df, _ = import_csv(p, {"t_s": "time (ms)", "throttle_us": "pwm (us)",
                           "thrust_n": "lift (kgf)", "rpm": "speed [rad/s]",
                           "current_a": "amps"})
    assert df["t_s"].tolist() == [0.0, 0.5]
    assert df["throttle_us"].tolist() == [1100.0, 1200.0]
    np.testing.assert_allclose(df["thrust_n"], [0.980665, 1.96133])
    np.testing.assert_allclose(df["rpm"], [100 * 60 / (2 * np.pi), 200 * 60 / (2 * np.pi)])
    assert df["current_a"].tolist() == [1.0, 2.0]


def test_csv_errors_name_file_row_and_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t_s,thrust (V)\n0,1\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"column 'thrust \(V\)'.*not a force unit"):
        import_csv(p, {"thrust_n": "thrust (V)"})
    with pytest.raises(LogError, match="no column 'nope'"):
        import_csv(p, {"thrust_n": "nope"})
    with pytest.raises(LogError, match="unknown run column 'speed'"):
        import_csv(p, {"speed": "t_s"})
    p.write_text("t_s,thrust_n\n0,1\n0.1,abc\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"bad\.csv: row 3, column 'thrust_n'"):
        import_csv(p)
    p.write_text("t_s,thrust_n\n1,1\n0.5,1\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"row 3, column 't_s': time jumps back 0\.5 s"):
        import_csv(p)
    with pytest.raises(LogError, match="not an ESC32"):
        import_esc32(p)


def test_import_command_writes_a_run_folder(shared_data, tmp_path, capsys):
    out = tmp_path / "runs" / "f40"
    assert main(["import", str(shared_data / RCB), "--format", "rcbenchmark",
                 "--out", str(out)]) == 0
    rec = read_run(out)
    assert rec.meta["status"] == "success" and rec.meta["kind"] == "import"
    assert rec.meta["import"]["format"] == "rcbenchmark"
    assert np.isfinite(rec.column("thrust_n")).sum() == 831
    assert np.isnan(rec.column("throttle_us")).all()  # schema column, no data
    assert [p.name for p in out.parent.iterdir()] == ["f40"]  # no temp folder left
    # refuses to overwrite; bad input is one line and exit code 2
    assert main(["import", str(shared_data / RCB), "--format", "rcbenchmark",
                 "--out", str(out)]) == 2
    assert main(["import", str(shared_data / RCB), "--format", "esc32",
                 "--out", str(tmp_path / "x")]) == 2
    assert main(["import", str(shared_data / RCB), "--format", "csv", "--map", "thrust_n",
                 "--out", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert "already exists" in err and "not an ESC32" in err and "RUNCOL=FILECOL" in err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_an_imported_run_is_listed_with_the_file_it_came_from(tmp_path, capsys):
    """`runs` showed an import's reason as 'imported from None'."""
    import json

    log = tmp_path / "stand.csv"
    log.write_text("t_s,throttle_us,thrust_n\n0,1000,0\n0.1,1100,0.5\n0.2,1200,1\n")
    assert main(["import", str(log), "--out", str(tmp_path / "runs" / "a")]) == 0
    capsys.readouterr()
    assert main(["runs", "--out", str(tmp_path / "runs"), "--rebuild", "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["reason"] == f"imported from {log}"


def test_imported_csv_steps_fit_end_to_end(tmp_path, capsys):
    import json

    # a stand at 1 kHz: 1200 <-> 1400 us steps, delay 15 ms, tau 40 ms, no mapping needed
    t = np.arange(0, 4.0, 0.001)
    u = np.where((t // 0.5) % 2 == 1, 1400.0, 1200.0)
    y = np.full(t.size, 2.0)
    for k in range(1, 8):
        t0 = 0.5 * k
        sel = t >= t0
        a, b = (2.0, 3.0) if k % 2 == 1 else (3.0, 2.0)
        s = np.clip(t[sel] - t0 - 0.015, 0, None)
        y[sel] = a + (b - a) * (1 - np.exp(-s / 0.040))
    src = tmp_path / "stand.csv"
    np.savetxt(src, np.c_[t, u, y], delimiter=",", header="t_s,throttle_us,thrust_n",
               comments="", fmt="%.6f")
    run = tmp_path / "run"
    assert main(["import", str(src), "--format", "csv", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["fit", str(run), "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert fit["tau_up_ms"] == pytest.approx(40.0, rel=0.02)
    assert fit["tau_down_ms"] == pytest.approx(40.0, rel=0.02)
    assert fit["latency_ms"] == pytest.approx(15.0, abs=1.0)
    assert fit["gain_unit"] == "N/us" and fit["gain"] == pytest.approx(1 / 200, rel=0.01)
    assert fit["repeats_up"] == 4 and fit["repeats_down"] == 3


def test_rcbenchmark_header_variants(tmp_path):
    # 2021 (HeinzGerhard) headers: thrust already in newtons, "ESC (µs)", optical speed
    a = tmp_path / "a.csv"
    a.write_text("Time (s),ESC (µs),Servo (µs),Torque (N·m),Thrust (N),Voltage (V),"
                 "Current (A),Motor Optical Speed (RPM),App message,\n"
                 "0,1000,,0.0,0.0,16,0.1,0,,\n0.1,1500,,0.05,4.0,15.8,8.0,9000,,\n",
                 encoding="utf-8")
    df, meta = import_rcbenchmark(a)
    assert df["throttle_us"].tolist() == [1000.0, 1500.0]
    assert df["thrust_n"].tolist() == [0.0, 4.0]
    assert df["rpm"].tolist() == [0.0, 9000.0] and meta["columns"]["rpm"].startswith("Motor Opt")
    # control-board logs: a protocol line first, speeds in rad/s, thrust in gf
    b = tmp_path / "b.csv"
    b.write_text("Control protocol: Standard PWM at 50Hz\n"
                 "Time (s),ESC signal (µs),Thrust (gf),Motor Electrical Speed (rad/s)\n"
                 "0,1100,100,0\n0.02,1200,200,100\n", encoding="utf-8")
    df, meta = import_rcbenchmark(b)
    assert meta["control_protocol"] == "Control protocol: Standard PWM at 50Hz"
    np.testing.assert_allclose(df["thrust_n"], [0.980665, 1.96133])
    np.testing.assert_allclose(df["rpm"], [0.0, 100 * 60 / (2 * np.pi)])
