"""`rotorbench calibrate` options and rig files it cannot use: refused in one line before
any work."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.bench.conftest import imu_log
from tests.conftest import run_bad


@pytest.mark.parametrize("flag", ["--gyro-range-dps", "--acc-range-g", "--max-lag"])
def test_calibrate_ranges_must_be_positive(tmp_path: Path, capsys, flag: str) -> None:
    """--gyro-range-dps 0 ended in a ZeroDivisionError after the whole calibration."""
    log = tmp_path / "log.csv"
    log.write_text("t_s\n0\n")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out",
                  str(tmp_path / "cal.json"), flag, "0")
    assert f"{flag}: expected a number > 0, got 0" in err
    assert not (tmp_path / "cal.json").exists()


@pytest.mark.parametrize(("content", "expected"), [
    (b'[rig]\nkind = "imu"\nname = = 1\n', "not valid TOML: Invalid value (at line 3"),
    (b"\xac\x00\xff garbage", "not valid TOML: 'utf-8' codec can't decode"),
])
def test_calibrate_broken_rig_file_is_reported_as_broken(tmp_path: Path, capsys,
                                                         content: bytes, expected: str) -> None:
    """A syntax error was reported as 'not an IMU-bench rig', garbage bytes as a traceback."""
    rig = tmp_path / "imu.toml"
    rig.write_bytes(content)
    err = run_bad(capsys, "calibrate", "--rig", str(rig), "--dry-run")
    assert f"{rig}: {expected}" in err


def test_calibrate_runs_folder_is_a_file(tmp_path: Path, capsys) -> None:
    f = tmp_path / "notes.txt"
    f.write_text("keep me")
    err = run_bad(capsys, "calibrate", "--quick", "--runs", str(f), "--out",
                  str(tmp_path / "cal.json"))
    assert "--runs" in err and "notes.txt: is a file; expected a folder" in err
    assert f.read_text() == "keep me" and not (tmp_path / "cal.json").exists()


@pytest.mark.parametrize("angles", [["nan", "0", "0"], ["0", "inf", "0"]])
def test_calibrate_mounting_angles_must_be_finite(tmp_path: Path, capsys,
                                                  angles: list[str]) -> None:
    """nan ended in scipy's 'Found zero norm quaternions in `quat`' traceback."""
    log = imu_log(tmp_path / "imu.csv")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--mounting-deg", *angles)
    assert "--mounting-deg: expected three finite angles in degrees" in err
