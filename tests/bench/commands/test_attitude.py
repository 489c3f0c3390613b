"""`rotorbench attitude` options: a bad bias window, no reference to score against."""

from __future__ import annotations

from pathlib import Path

from bench.cli import main
from tests.bench.conftest import imu_log
from tests.conftest import run_bad


def test_attitude_negative_bias_seconds(tmp_path: Path, capsys) -> None:
    log = imu_log(tmp_path / "imu.csv")
    err = run_bad(capsys, "attitude", str(log), "--bias-seconds", "-1")
    assert "--bias-seconds: expected a number of seconds >= 0, got -1" in err


def test_attitude_without_reference_says_how_to_get_the_estimate(tmp_path: Path,
                                                                 capsys) -> None:
    """Without a reference quaternion and without --out the command printed only a header."""
    log = imu_log(tmp_path / "imu.csv")
    assert main(["attitude", str(log)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "no reference attitude in the log" in out and "--out FILE" in out
