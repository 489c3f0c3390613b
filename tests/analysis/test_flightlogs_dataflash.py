"""ArduPilot DataFlash in, by round trip through a writer from the format (FMT messages,
a lazily defined type), and damaged input: a cut log keeps what is whole, a .bin of
random bytes or with no IMU is refused in one line."""

from __future__ import annotations

import math
import sys

import numpy as np

from analysis.flightlogs import detect_flight_format, read_flight_log
from analysis.run_record import read_run
from bench.cli import main

w = sys.modules["rotorbench_tests_dataflash_writer"]  # dataflash_writer.py, loaded by conftest.py


def _log(tmp_path, n=4000):
    data, truth = w.flight(n)
    path = tmp_path / "00000042.BIN"
    path.write_bytes(data)
    return path, truth


def test_the_kept_messages_round_trip_in_si_units(tmp_path):
    path, truth = _log(tmp_path)
    assert detect_flight_format(path) == "dataflash"
    (log,) = read_flight_log(path, "dataflash")
    c = log.columns
    assert log.rows == len(truth["t_us"])  # IMU instance 0 only
    np.testing.assert_allclose(c["t_s"], (truth["t_us"] - truth["t_us"][0]) * 1e-6)
    for k, axis in enumerate("xyz"):
        np.testing.assert_array_equal(c[f"gyro_{axis}_rad_s"], truth["gyro"][:, k])
    # RATE is logged 50 µs after each IMU sample: held, row k shows RATE k-1
    np.testing.assert_allclose(c["rate_sp_y_rad_s"][1:], truth["sp"][:-1, 1] * math.pi / 180,
                               rtol=1e-6)
    assert np.isnan(c["rate_sp_y_rad_s"][0])
    t_s = c["t_s"]
    t0 = truth["t_us"][0]
    for m in range(4):
        e = truth["esc"][truth["esc"][:, 1] == m]
        k = np.searchsorted((e[:, 0] - t0) * 1e-6, t_s, side="right") - 1
        want = np.where(k >= 0, e[np.clip(k, 0, None), 2], np.nan)
        np.testing.assert_array_equal(c[f"motor{m + 1}_rpm"], want)
    assert np.nanmax(c["voltage_v"]) == np.float32(16.8)
    assert np.nanmax(c["current_a"]) == 12.5  # instance 1 (5 V, 1 A) is not mixed in
    assert set(np.unique(c["output1_us"][np.isfinite(c["output1_us"])])) <= set(
        truth["rcou"][:, 0])
    assert "output5_us" not in c  # channels never driven are left out
    assert log.units["output1_us"] == "µs"


def test_import_writes_a_flight_run(tmp_path, capsys):
    path, _ = _log(tmp_path, n=800)
    assert main(["import", str(path), "--out", str(tmp_path / "ap")]) == 0
    assert "dataflash, detected from its first bytes" in capsys.readouterr().out
    rec = read_run(tmp_path / "ap")
    assert rec.meta["kind"] == "flight" and len(rec.samples) == 800
    assert rec.meta["flight"]["sources"]["motor2_rpm"] == "ESC[1].RPM"


def test_a_cut_log_keeps_the_whole_messages_and_says_so(tmp_path, capsys):
    path, truth = _log(tmp_path, n=1000)
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2 + 17])
    assert main(["import", str(path), "--out", str(tmp_path / "r")]) == 0
    text = capsys.readouterr().out
    assert "skipped" in text
    rec = read_run(tmp_path / "r")
    n = len(rec.samples)
    assert 400 < n < 1000
    np.testing.assert_array_equal(rec.column("gyro_x_rad_s"), truth["gyro"][:n, 0])


def test_random_bytes_forced_as_dataflash_are_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / "x.bin"
    path.write_bytes(np.random.default_rng(5).bytes(30000))
    assert main(["import", str(path), "--format", "dataflash", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "no DataFlash FMT message" in err


def test_a_log_without_imu_is_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / "noimu.bin"
    path.write_bytes(w.fmt_message("FMT") + w.fmt_message("BAT")
                     + w.message("BAT", 1000, 0, 16.0, 16.0, 1.0, 0.0, 0.0, 2500, 0.0))
    assert main(["import", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "no IMU message" in err
