"""`rotorbench import FILE --out DIR` without --format: the format from the header, the
stand's accelerometer columns in SI units, and a header of no known format refused."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.run_record import read_run
from bench.cli import main

RCB = "esc_test/rcbenchmark_Log_2019-11-05_171350.csv"
ESC32 = "esc_test/autoquad_esc32_f40_steps_5-2.csv"
G0 = 9.80665


@pytest.mark.parametrize(("log", "fmt"), [(RCB, "rcbenchmark"), (ESC32, "esc32")])
def test_the_shipped_logs_import_without_format(shared_data, tmp_path, capsys, log, fmt):
    out = tmp_path / "run"
    assert main(["import", str(shared_data / log), "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert line.startswith(f"{out}: imported ") and f"({fmt}, detected from the header)" in line
    rec = read_run(out)
    assert rec.meta["import"]["format"] == fmt
    assert rec.meta["import"]["format_taken"] == "detected from the header"


def test_the_stand_accelerometer_columns_are_imported_in_m_s2(shared_data, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["import", str(shared_data / RCB), "--out", str(out)]) == 0
    capsys.readouterr()
    rec = read_run(out)
    # read the file independently: columns 6-8 AccX/AccY/AccZ (g), 20 Vibration (g)
    raw = np.genfromtxt(shared_data / RCB, delimiter=",", skip_header=1, usecols=(0, 5, 6, 7, 19))
    order = np.argsort(raw[:, 0], kind="stable")  # the import puts rows in time order
    for k, col in enumerate(("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2", "vibration_m_s2"), 1):
        np.testing.assert_allclose(rec.column(col), raw[order, k] * G0, err_msg=col)
    assert rec.meta["import"]["columns"]["vibration_m_s2"] == "Vibration (g)"
    # at rest the board reads gravity on its z axis
    assert np.median(rec.column("acc_z_m_s2")[:20]) == pytest.approx(-G0, abs=0.6)


def test_a_control_board_log_with_a_protocol_line_is_rcbenchmark(tmp_path, capsys):
    log = tmp_path / "b.csv"
    log.write_text("Control protocol: Standard PWM at 50Hz\n"
                   "Time (s),ESC signal (µs),Thrust (gf),Motor Electrical Speed (rad/s)\n"
                   "0,1100,100,0\n0.02,1200,200,100\n", encoding="utf-8")
    assert main(["import", str(log), "--out", str(tmp_path / "r")]) == 0
    assert "(rcbenchmark, detected from the header)" in capsys.readouterr().out


def test_a_csv_of_run_columns_is_csv_and_map_implies_csv(tmp_path, capsys):
    log = tmp_path / "s.csv"
    log.write_text("t_s,thrust_n,acc_x_g\n0,1.0,0.5\n0.01,1.1,-0.5\n", encoding="utf-8")
    assert main(["import", str(log), "--out", str(tmp_path / "a")]) == 0
    assert "(csv, detected from the header)" in capsys.readouterr().out
    other = tmp_path / "o.csv"
    other.write_text("when,force\n0,1.0\n0.01,1.1\n", encoding="utf-8")
    assert main(["import", str(other), "--map", "t_s=when", "--map", "thrust_n=force",
                 "--out", str(tmp_path / "b")]) == 0
    assert "(csv, --map)" in capsys.readouterr().out
    assert read_run(tmp_path / "b").column("thrust_n").tolist() == [1.0, 1.1]


def test_an_acceleration_in_g_is_gravity_not_gram_force(tmp_path, capsys):
    log = tmp_path / "s.csv"
    log.write_text("t_s,acc_x_g\n0,0.5\n0.01,-2\n", encoding="utf-8")
    assert main(["import", str(log), "--format", "csv", "--map", "acc_x_m_s2=acc_x_g",
                 "--out", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert read_run(tmp_path / "a").column("acc_x_m_s2").tolist() == [0.5 * G0, -2 * G0]


def test_a_header_of_no_known_format_exits_2_naming_file_and_formats(tmp_path, capsys):
    log = tmp_path / "mystery.csv"
    log.write_text("a,b\n1,2\n", encoding="utf-8")
    out = tmp_path / "r"
    assert main(["import", str(log), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert str(log) in err and "no known log format" in err and "(columns: a, b)" in err
    assert "tried rcbenchmark" in err and "esc32" in err and "csv" in err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["mystery.csv"]


def test_a_header_that_fits_two_formats_asks_for_format(tmp_path, capsys):
    log = tmp_path / "both.csv"
    log.write_text("Time (s),ESC signal (µs),t_s\n0,1000,0\n", encoding="utf-8")
    assert main(["import", str(log), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "fits rcbenchmark and csv" in err and "--format" in err


def test_a_generic_time_and_thrust_csv_is_not_taken_for_a_stand_log(tmp_path, capsys):
    """'Time (s)' and 'Thrust (N)' are anyone's columns: no RCbenchmark marker, no guess."""
    log = tmp_path / "x.csv"
    log.write_text("Time (s),Thrust (N)\n0,1\n0.1,2\n", encoding="utf-8")
    assert main(["import", str(log), "--out", str(tmp_path / "r")]) == 2
    assert "no known log format" in capsys.readouterr().err


def test_a_one_line_huge_header_is_quoted_short(tmp_path, capsys):
    log = tmp_path / "long.csv"
    log.write_text("x" * 200_000 + "\n1\n", encoding="utf-8")
    assert main(["import", str(log), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "no known log format" in err and len(err) < 800
