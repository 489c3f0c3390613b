"""Bad input through the CLI: one line on stderr naming the file, exit code 2, nothing
half-written. Each test is the regression test of a fix found by running the commands."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main


def run_bad(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run the CLI in-process; assert the user-error contract; return the stderr line."""
    code = main(list(argv))
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert err.startswith("rotorbench: error: "), err
    return err


# --- rotorbench import ---------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["rcbenchmark", "esc32", "csv"])
def test_import_missing_file_or_folder(tmp_path: Path, capsys, fmt: str) -> None:
    missing = tmp_path / "nope.csv"
    err = run_bad(capsys, "import", str(missing), "--format", fmt, "--out", str(tmp_path / "o"))
    assert "nope.csv: file not found" in err
    err = run_bad(capsys, "import", str(tmp_path), "--format", fmt, "--out",
                  str(tmp_path / "o"))
    assert f"{tmp_path}: not a file" in err
    assert not (tmp_path / "o").exists()


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
    assert "cannot create its folder" in err


def test_import_long_time_gap_writes_few_parts(tmp_path: Path, capsys) -> None:
    """A log whose clock jumps by 1e12 s imports (parts only where there are rows)."""
    import pandas as pd

    f = tmp_path / "gap.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.5,1.5\n1e12,2\n")
    assert main(["import", str(f), "--format", "csv", "--out", str(tmp_path / "o")]) == 0
    df = pd.read_parquet(tmp_path / "o" / "samples.parquet")
    assert df["t_s"].tolist() == [0.0, 0.5, 1e12]
    assert len(list((tmp_path / "o" / "samples.parquet").glob("*.parquet"))) == 2
