"""`rotorbench import` on logs a new user hands it: one line on stderr naming the file,
exit code 2, nothing half-written."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from tests.conftest import run_bad


@pytest.mark.parametrize("fmt", ["rcbenchmark", "esc32", "csv"])
def test_import_missing_file_or_folder(tmp_path: Path, capsys, fmt: str) -> None:
    missing = tmp_path / "nope.csv"
    err = run_bad(capsys, "import", str(missing), "--format", fmt, "--out", str(tmp_path / "o"))
    assert "nope.csv: file not found" in err
    err = run_bad(capsys, "import", str(tmp_path), "--format", fmt, "--out",
                  str(tmp_path / "o"))
    assert f"{tmp_path}: not a file" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", ["my run", "..x", "-x", "a" * 129, "é"])
def test_import_out_whose_name_is_not_a_run_id(tmp_path: Path, capsys, name: str) -> None:
    """The folder's name becomes the run's id; one that is not one was refused only
    later, by the web view and `store push`."""
    f = tmp_path / "log.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1,2\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / name))
    assert "is not a run id" in err and "the folder's name (the run's id)" in err
    assert not (tmp_path / name).exists()


def test_import_ragged_csv_is_one_line(tmp_path: Path, capsys) -> None:
    f = tmp_path / "ragged.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1\n0.2,1,5\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / "o"))
    assert "ragged.csv: not a readable CSV" in err and "line 4" in err


def test_import_header_only(tmp_path: Path, capsys) -> None:
    f = tmp_path / "hdr.csv"
    f.write_text("t_s,thrust_n\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / "o"))
    assert "hdr.csv: no data rows" in err
    assert not (tmp_path / "o").exists()


_RCB_ROWS = "".join(f"{0.1 * i:.1f},{1100 + 10 * i},{100 + 5 * i},16.0,{0.5 * i},{900 * i}\n"
                   for i in range(10))


@pytest.mark.parametrize(("fmt", "header", "twice"), [
    # the case met: 'Thrust (gf)' renamed to 'Voltage (V)'; voltage_v took the thrust
    ("rcbenchmark", "Time (s),ESC signal (µs),Voltage (V),Voltage (V),Current (A),"
                    "Motor Electrical Speed (RPM)", "'Voltage (V)' twice (columns 3 and 4)"),
    ("rcbenchmark", "Time (s),ESC signal (µs),Thrust (gf),Voltage (V),Current (A),"
                    "Thrust (N)", "'Thrust (N)' twice (columns 3 and 6)"),
    ("esc32", "Timestamp,Amps,Batt. Volts,Amps,RPM,Duty", "'Amps' twice (columns 2 and 4)"),
    ("csv", "t_s,throttle_us,thrust_n,voltage_v,current_a,thrust_n",
     "'thrust_n' twice (columns 3 and 6)"),
])
def test_import_refuses_a_column_named_twice(tmp_path: Path, capsys, fmt: str, header: str,
                                             twice: str) -> None:
    """pandas renames a repeated header to 'X.1' and the importer took it."""
    f = tmp_path / "log.csv"
    rows = _RCB_ROWS if fmt != "esc32" else "".join(
        f"2019-11-05 17:14:08:{100 * i:03d},{0.5 * i},16.0,0.1,{900 * i},{10 * i}\n"
        for i in range(10))
    f.write_text(header + "\n" + rows, encoding="utf-8")
    err = run_bad(capsys, "import", str(f), "--format", fmt, "--out", str(tmp_path / "o"))
    assert f"log.csv: the header names column {twice}; rename one" in err
    assert not (tmp_path / "o").exists()


def test_import_map_twice_is_refused(tmp_path: Path, capsys) -> None:
    f = tmp_path / "log.csv"
    f.write_text("a,b\n0,1\n0.1,2\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--map", "t_s=a",
                  "--map", "t_s=b", "--out", str(tmp_path / "o"))
    assert "t_s is mapped twice" in err
    assert not (tmp_path / "o").exists()


def test_import_out_below_a_file(tmp_path: Path, capsys) -> None:
    f = tmp_path / "log.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1,2\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(f / "run"))
    assert "log.csv is a file, not a folder" in err


def test_import_long_time_gap_writes_few_parts(tmp_path: Path, capsys) -> None:
    """A log whose clock jumps by 1e12 s imports (parts only where there are rows)."""
    import pandas as pd

    f = tmp_path / "gap.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.5,1.5\n1e12,2\n")
    assert main(["import", str(f), "--format", "csv", "--out", str(tmp_path / "o")]) == 0
    df = pd.read_parquet(tmp_path / "o" / "samples.parquet")
    assert df["t_s"].tolist() == [0.0, 0.5, 1e12]
    assert len(list((tmp_path / "o" / "samples.parquet").glob("*.parquet"))) == 2


def test_logs_with_semicolons_or_ragged_rows(tmp_path: Path, capsys) -> None:
    """A ';'-separated log said only 'no time column'; a ragged row gave two lines.
    (``import`` reads a ';'-separated log: tests/bench/test_cli_messages.py.)"""
    semi = tmp_path / "semi.csv"
    semi.write_text("t_s;thrust_n\n0;1\n0.1;2\n")
    err = run_bad(capsys, "attitude", str(semi))
    assert "semi.csv: the header is one field" in err
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("t_s,gyro_x_rad_s\n0,1\n0.1\n0.2,1,5\n")
    err = run_bad(capsys, "attitude", str(ragged))
    assert "ragged.csv: cannot be read as csv" in err and "line 4" in err


def test_import_infinite_value(tmp_path: Path, capsys) -> None:
    f = tmp_path / "inf.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1,inf\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / "o"))
    assert "inf.csv: row 3, column 'thrust_n': expected a finite number" in err
    assert not (tmp_path / "o").exists()
