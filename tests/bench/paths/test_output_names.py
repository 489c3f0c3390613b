"""Output names that cannot be written (bench.paths.outputs): a file where a folder must
be, a folder where a file must be, an output that is also an input."""

from __future__ import annotations

from pathlib import Path

from tests.bench.conftest import imu_log
from tests.conftest import run_bad


def test_step_out_is_a_file(tmp_path: Path, capsys) -> None:
    f = tmp_path / "notes.txt"
    f.write_text("keep me")
    err = run_bad(capsys, "step", "--repeats", "1", "--out", str(f))
    assert "--out" in err and "notes.txt: is a file; expected a folder" in err
    assert f.read_text() == "keep me"


def test_output_named_like_an_existing_folder(tmp_path: Path, capsys) -> None:
    """A folder where the output file should go ended in IsADirectoryError at the rename."""
    log = imu_log(tmp_path / "imu.csv")
    (tmp_path / "est.parquet").mkdir()
    (tmp_path / "cal.json").mkdir()
    err = run_bad(capsys, "attitude", str(log), "--out", str(tmp_path / "est.parquet"))
    assert "est.parquet: is a folder" in err
    err = run_bad(capsys, "calibrate", "--simulate-log", str(tmp_path / "est.parquet"),
                  "--short")
    assert "est.parquet: is a folder" in err
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out",
                  str(tmp_path / "cal.json"))
    assert "cal.json: is a folder" in err
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--figures", str(log))
    assert "--figures" in err and "imu.csv: is a file; expected a folder" in err
    assert not list(tmp_path.glob(".*"))  # no temp file left behind


def test_output_that_is_the_input_is_refused(tmp_path: Path, capsys) -> None:
    """calibrate apply --out LOG LOG replaced the log with its corrected copy (exit 0)."""
    log = imu_log(tmp_path / "imu.csv")
    text = log.read_text()
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    err = run_bad(capsys, "calibrate", "apply", "--cal", str(cal), "--out", str(log), str(log))
    assert f"--out {log}: is also an input" in err
    err = run_bad(capsys, "calibrate", "apply", "--cal", str(cal), "--out",
                  str(tmp_path / ".." / tmp_path.name / "cal.json"), str(log))
    assert "is also an input" in err
    err = run_bad(capsys, "attitude", str(log), "--out", str(log))
    assert "is also an input" in err
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out", str(log))
    assert "is also an input" in err
    assert log.read_text() == text and cal.read_text() == "{}"
