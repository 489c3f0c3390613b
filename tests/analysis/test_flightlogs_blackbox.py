"""Blackbox logs in, by round trip: logs written by the test encoder (blackbox_writer,
from the format's documentation) decode to the values that went in, in SI units; each
encoding alone on random values; several logs in one file; damaged logs."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from analysis.flightlogs import blackbox as bb
from analysis.flightlogs import detect_flight_format, read_flight_log
from analysis.flightlogs.blackbox_encodings import decode_group
from analysis.flightlogs.blackbox_frames import frame_body, frame_regex
from analysis.run_record import read_run
from bench.cli import main

w = sys.modules["rotorbench_tests_blackbox_writer"]  # blackbox_writer.py, loaded by conftest.py

DEG = math.pi / 180


def _log(tmp_path, n=3000, seed=0, **kw):
    lay, s = w.quad_layout(), w.Settings(**kw)
    rows = w.flight_rows(n, lay, s, seed)
    path = tmp_path / "LOG00001.BFL"
    path.write_bytes(w.blackbox_log(rows, lay, s))
    return path, rows, {name: k for k, name in enumerate(lay.names)}


def test_every_kept_field_round_trips_in_si_units(tmp_path):
    path, rows, col = _log(tmp_path)
    assert detect_flight_format(path) == "blackbox"
    (log,) = read_flight_log(path, "blackbox")
    c = log.columns
    assert log.rows == len(rows) and log.meta["log_end"] and log.meta["notes"] == []
    np.testing.assert_array_equal(c["t_s"], (rows[:, 1] - rows[0, 1]) * 1e-6)
    for k, axis in enumerate("xyz"):
        np.testing.assert_allclose(c[f"gyro_{axis}_rad_s"], rows[:, col[f"gyroADC[{k}]"]] * DEG)
        np.testing.assert_allclose(c[f"rate_sp_{axis}_rad_s"],
                                   rows[:, col[f"setpoint[{k}]"]] * DEG)
    np.testing.assert_allclose(c["throttle_norm"], rows[:, col["setpoint[3]"]] / 1000)
    for m in range(4):
        raw = rows[:, col[f"motor[{m}]"]]
        np.testing.assert_array_equal(c[f"motor{m + 1}_dshot"], raw)
        np.testing.assert_allclose(c[f"motor{m + 1}_norm"], (raw - 158) / (2047 - 158))
        np.testing.assert_allclose(c[f"motor{m + 1}_rpm"], rows[:, col[f"eRPM[{m}]"]] * 200 / 14)
    np.testing.assert_allclose(c["voltage_v"], rows[:, col["vbatLatest"]] * 0.01)
    np.testing.assert_allclose(c["current_a"], rows[:, col["amperageLatest"]] * 0.01)
    assert log.units["motor1_dshot"] == "DShot command"
    assert log.meta["events"] == {"SYNC_BEEP": 1, "LOG_END": 1}


def test_the_full_betaflight_field_set_round_trips(tmp_path):
    """A 4-field tag8_8svb group, average-2 fields of any sign (gyroUnfilt, accSmooth,
    debug), 8 motors."""
    lay, s = w.quad_layout(8, full=True), w.Settings()
    rows = w.flight_rows(2500, lay, s, seed=7)
    path = tmp_path / "LOG00004.BFL"
    path.write_bytes(w.blackbox_log(rows, lay, s))
    (log,) = read_flight_log(path, "blackbox")
    col = {name: k for k, name in enumerate(lay.names)}
    assert log.rows == 2500 and log.meta["notes"] == []
    for m in range(8):
        np.testing.assert_array_equal(log.columns[f"motor{m + 1}_dshot"],
                                      rows[:, col[f"motor[{m}]"]])
    np.testing.assert_allclose(log.columns["gyro_z_rad_s"], rows[:, col["gyroADC[2]"]] * DEG)
    np.testing.assert_allclose(log.columns["current_a"], rows[:, col["amperageLatest"]] * 0.01)


def test_an_inav_log_with_its_field_names_and_minthrottle(tmp_path):
    """INAV names the battery fields vbat/amperage and predicts motor[0] from minthrottle
    (its predictor list ends before minmotor); analog outputs are µs."""
    lay, s = w.quad_layout(), w.Settings(firmware="INAV 7.1.2 (a1b2c3d) MATEKF405",
                                          motor_output=(1070, 2000))
    rows = w.flight_rows(700, lay, s, seed=3)
    lay.names = [{"vbatLatest": "vbat", "amperageLatest": "amperage"}.get(n, n)
                 for n in lay.names]
    lay.i_pred = [4 if p == 11 else p for p in lay.i_pred]
    rows[:, lay.names.index("motor[0]")] += 400  # analog: 1070..2000 µs
    path = tmp_path / "LOG00005.TXT"
    path.write_bytes(w.blackbox_log(rows, lay, s))
    (log,) = read_flight_log(path, "blackbox")
    assert log.meta["firmware"].startswith("INAV")
    np.testing.assert_allclose(log.columns["voltage_v"], rows[:, lay.names.index("vbat")] * 0.01)
    np.testing.assert_array_equal(log.columns["motor1_us"], rows[:, lay.names.index("motor[0]")])
    assert log.sources["voltage_v"].startswith("vbat ")


def test_high_resolution_and_analog_motors(tmp_path):
    path, rows, col = _log(tmp_path, n=400, high_resolution=1, motor_output=(1070, 2000))
    (log,) = read_flight_log(path, "blackbox")
    np.testing.assert_allclose(log.columns["gyro_x_rad_s"], rows[:, col["gyroADC[0]"]] * DEG / 10)
    np.testing.assert_array_equal(log.columns["motor1_us"], rows[:, col["motor[0]"]])
    assert "motor1_dshot" not in log.columns and log.units["motor1_us"] == "µs"


def test_a_window_boundary_changes_nothing(tmp_path, monkeypatch):
    path, rows, _ = _log(tmp_path, n=6000)
    (whole,) = read_flight_log(path, "blackbox")
    monkeypatch.setattr(bb, "WINDOW", 4096)  # dozens of windows for this log
    (windowed,) = read_flight_log(path, "blackbox")
    assert windowed.rows == len(rows)
    for name, v in whole.columns.items():
        np.testing.assert_array_equal(windowed.columns[name], v, err_msg=name)


@pytest.mark.parametrize("enc", [0, 1, 3, 6, 7, 8, 10])
def test_each_encoding_decodes_what_the_encoder_wrote(enc):
    rng = np.random.default_rng(enc)
    n = {6: 5, 7: 3, 8: 4, 10: 3}.get(enc, 1)
    frames = []
    for _ in range(400):
        scale = rng.choice([1, 7, 100, 3000, 2**20, 2**30])
        v = rng.integers(-scale, scale, n)
        v[rng.random(n) < 0.3] = 0
        if enc == 1:
            v = np.abs(v)
        if enc == 3:
            v = np.clip(v, -8191, 8191)
        if enc == 8:
            v = np.clip(v, -32768, 32767)
        frames.append(v.tolist())
    blob = b"".join(b"P" + w.encode_fields(v, [enc] * n) for v in frames)
    rx = frame_regex({b"P": frame_body([enc] * n)})
    items = rx.findall(blob)
    assert [len(x) for x in items] == [1 + len(w.encode_fields(v, [enc] * n)) for v in frames]
    starts = np.cumsum([0] + [len(x) for x in items[:-1]]) + 1
    buf = np.frombuffer(blob + bytes(16), np.uint8)
    values, end = decode_group(buf, starts, enc, n)
    np.testing.assert_array_equal(values[:, :n], np.array(frames))
    np.testing.assert_array_equal(end - starts + 1, [len(x) for x in items])


def test_several_logs_in_one_file_become_several_runs(tmp_path, capsys):
    lay, s = w.quad_layout(), w.Settings()
    a = w.blackbox_log(w.flight_rows(300, lay, s, 1), lay, s)
    b = w.blackbox_log(w.flight_rows(500, lay, s, 2), lay, s)
    path = tmp_path / "LOG00002.BBL"
    path.write_bytes(b"\xff" * 100 + a + b"\x00" * 50 + b)  # bytes between logs are ignored
    out = tmp_path / "flight"
    assert main(["import", str(path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "log 1 of 2" in text and "log 2 of 2" in text
    assert len(read_run(out).samples) == 300
    rec = read_run(tmp_path / "flight-2")
    assert len(rec.samples) == 500 and rec.meta["kind"] == "flight"
    assert main(["import", str(path), "--log", "2", "--out", str(tmp_path / "only")]) == 0
    assert len(read_run(tmp_path / "only").samples) == 500


def test_a_truncated_log_keeps_what_decodes_and_says_so(tmp_path, capsys):
    lay, s = w.quad_layout(), w.Settings()
    rows = w.flight_rows(2000, lay, s)
    data = w.blackbox_log(rows, lay, s, end=False)
    path = tmp_path / "cut.bbl"
    path.write_bytes(data[:-7])  # the logger stopped mid-frame, no LOG_END
    out = tmp_path / "r"
    assert main(["import", str(path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "no LOG_END" in text
    kept = len(read_run(out).samples)
    assert 1990 <= kept < 2000
    np.testing.assert_allclose(read_run(out).column("voltage_v"),
                               rows[:kept, lay.names.index("vbatLatest")] * 0.01)


def test_corrupt_bytes_mid_log_drop_frames_until_the_next_i_frame(tmp_path):
    path, rows, col = _log(tmp_path, n=2000)
    data = bytearray(path.read_bytes())
    mid = len(data) // 2
    data[mid:mid + 40] = b"\xfe" * 40
    path.write_bytes(bytes(data))
    (log,) = read_flight_log(path, "blackbox")
    assert 1900 < log.rows < 2000
    assert any("skipped" in n for n in log.meta["notes"])
    # every kept row is a row that was written (no frame decoded against a wrong history)
    t_in = (rows[:, 1] - rows[0, 1]) * 1e-6
    k = np.searchsorted(t_in, log.columns["t_s"])
    np.testing.assert_array_equal(t_in[k], log.columns["t_s"])
    np.testing.assert_allclose(log.columns["gyro_y_rad_s"], rows[k, col["gyroADC[1]"]] * DEG)


def test_max_rows_keeps_the_first_rows_and_says_so(tmp_path, capsys):
    path, _, _ = _log(tmp_path, n=1000)
    assert main(["import", str(path), "--max-rows", "100", "--out", str(tmp_path / "r")]) == 0
    assert "kept the first 100 frames" in capsys.readouterr().out
    assert len(read_run(tmp_path / "r").samples) == 100


def _one_line_exit_2(tmp_path, capsys, path, *extra):
    code = main(["import", str(path), *extra, "--out", str(tmp_path / "r")])
    out, err = capsys.readouterr()
    assert code == 2, out + err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "r").exists()
    return err


def test_random_bytes_are_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / "LOG00003.BFL"
    path.write_bytes(np.random.default_rng(3).bytes(20000))
    _one_line_exit_2(tmp_path, capsys, path)
    err = _one_line_exit_2(tmp_path, capsys, path, "--format", "blackbox")
    assert "no blackbox log" in err


def test_random_bytes_after_a_header_are_refused_in_one_line(tmp_path, capsys):
    lay, s = w.quad_layout(), w.Settings()
    path = tmp_path / "h.bbl"
    path.write_bytes(w.header(lay, s) + np.random.default_rng(4).bytes(20000))
    err = _one_line_exit_2(tmp_path, capsys, path)
    assert "no main frame decodes" in err


def test_another_firmwares_field_set_is_refused_naming_what(tmp_path, capsys):
    path = tmp_path / "other.bbl"
    path.write_bytes(w.MARKER + b"H Data version:2\nH Field I name:iteration,clock\n"
                     b"H Field I signed:0,0\nH Field I predictor:0,0\nH Field I encoding:1,1\n"
                     b"H Field P predictor:6,2\nH Field P encoding:9,0\nI\x00\x01")
    err = _one_line_exit_2(tmp_path, capsys, path)
    assert "not a Betaflight/INAV flight log" in err
    path.write_bytes(w.MARKER + b"H Data version:2\nH Field I name:loopIteration,time\n"
                     b"H Field I signed:0,0\nH Field I predictor:0,0\nH Field I encoding:4,1\n"
                     b"H Field P predictor:6,2\nH Field P encoding:9,0\nI\x00\x01")
    err = _one_line_exit_2(tmp_path, capsys, path)
    assert "encoding 4 (Elias delta u32)" in err


def test_a_dataflash_file_forced_as_blackbox_is_refused(tmp_path, capsys):
    path = tmp_path / "x.bin"
    path.write_bytes(b"\xa3\x95\x80" + bytes(200))
    err = _one_line_exit_2(tmp_path, capsys, path, "--format", "blackbox")
    assert "no blackbox log" in err


def test_log_and_max_rows_must_be_at_least_one(tmp_path, capsys):
    path, _, _ = _log(tmp_path, n=200)
    err = _one_line_exit_2(tmp_path, capsys, path, "--max-rows", "0")
    assert "--max-rows 0: expected a whole number of at least 1" in err
    err = _one_line_exit_2(tmp_path, capsys, path, "--log", "2")
    assert "--log 2: " in err and "holds 1 log" in err
    csv = tmp_path / "s.csv"
    csv.write_text("t_s,thrust_n\n0,1\n0.01,1.1\n", encoding="utf-8")
    err = _one_line_exit_2(tmp_path, capsys, csv, "--log", "1")
    assert "apply to flight logs only" in err


def test_an_i_frame_far_ahead_in_time_drops_its_segment_only(tmp_path, capsys):
    lay, s = w.quad_layout(), w.Settings()
    rows = w.flight_rows(800, lay, s)
    seg = s.i_interval // s.p_interval  # frames per I-frame segment
    bad = slice(10 * seg, 11 * seg)
    written = rows.copy()
    written[bad, 1] += 60_000_000  # one segment 60 s ahead: its I frame and P frames
    path = tmp_path / "jump.bbl"
    path.write_bytes(w.blackbox_log(written, lay, s))
    (log,) = read_flight_log(path, "blackbox")
    kept = np.delete(rows, np.arange(800)[bad], axis=0)
    assert log.rows == 800 - seg
    np.testing.assert_array_equal(log.columns["t_s"], (kept[:, 1] - kept[0, 1]) * 1e-6)
    assert any("jumped" in n for n in log.meta["notes"])


def test_time_wraps_past_32_bits_without_a_jump(tmp_path):
    lay, s = w.quad_layout(), w.Settings()
    rows = w.flight_rows(600, lay, s)
    rows[:, 1] += (1 << 32) - 1_000_000 - rows[300, 1]  # the µs clock wraps at row ~300
    written = rows.copy()
    written[:, 1] &= 0xFFFFFFFF
    path = tmp_path / "wrap.bbl"
    path.write_bytes(w.blackbox_log(written, lay, s))
    (log,) = read_flight_log(path, "blackbox")
    assert log.rows == 600
    np.testing.assert_array_equal(log.columns["t_s"], (rows[:, 1] - rows[0, 1]) * 1e-6)


def test_map_with_a_flight_log_is_refused_in_one_line(tmp_path, capsys):
    path, _, _ = _log(tmp_path, n=100)
    err = _one_line_exit_2(tmp_path, capsys, path, "--format", "blackbox", "--map", "t_s=x")
    assert "--map applies to --format csv only" in err
