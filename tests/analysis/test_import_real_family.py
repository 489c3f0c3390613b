"""The esc_test collection's defects on synthetic logs of the same structure (logfamily.py):
rows that step back in time (two boards interleaving) are reordered and counted, a
concatenated file is refused naming the row; CSV cells NaN / inf / repeated timestamps are
named by row and column with the text as written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.errors import LogError
from analysis.importers import JITTER_MAX_PERIODS, import_csv, import_rcbenchmark
from bench.cli import main


def test_jittery_rcbenchmark_log_imports_in_time_order(logfamily, tmp_path, capsys):
    src = logfamily.rcbenchmark_log(tmp_path / "Log_jitter.csv", steps_back=9, seed=3)
    raw_t = np.genfromtxt(src, delimiter=",", skip_header=1, usecols=0)
    assert int(np.sum(np.diff(raw_t) < 0)) == 9  # the defect is in the file
    df, meta = import_rcbenchmark(src)
    order = meta["time_order"]
    assert order["time_steps_back"] == 9
    assert 9 <= order["reordered_rows"] <= 18  # each step back moves one or two rows
    assert order["max_step_back_s"] <= 0.009 + 1e-9
    assert order["jitter_bound_s"] == pytest.approx(
        JITTER_MAX_PERIODS * np.median(np.diff(raw_t)[np.diff(raw_t) > 0]))
    assert df["t_s"].is_monotonic_increasing and len(df) == raw_t.size
    np.testing.assert_array_equal(np.sort(raw_t, kind="stable"), df["t_s"].to_numpy())

    run = tmp_path / "run"
    assert main(["import", str(src), "--format", "rcbenchmark", "--out", str(run)]) == 0
    out = capsys.readouterr().out
    assert f"time order: {order['reordered_rows']} rows reordered" in out
    assert "(9 places, at most" in out
    stored = json.loads((run / "run.json").read_text())["import"]["time_order"]
    assert stored["reordered_rows"] == order["reordered_rows"]


def test_a_clean_log_reorders_nothing(logfamily, tmp_path, capsys):
    src = logfamily.rcbenchmark_log(tmp_path / "clean.csv", seconds=20)
    _, meta = import_rcbenchmark(src)
    assert meta["time_order"]["reordered_rows"] == 0
    assert main(["import", str(src), "--format", "rcbenchmark", "--out",
                 str(tmp_path / "r")]) == 0
    assert "time order" not in capsys.readouterr().out


def test_concatenated_log_is_refused_naming_the_row(logfamily, tmp_path, capsys):
    src = logfamily.rcbenchmark_log(tmp_path / "two.csv", seconds=20, concatenated=True)
    t = np.genfromtxt(src, delimiter=",", skip_header=1, usecols=0)
    line = int(np.flatnonzero(np.diff(t) < -1.0)[0]) + 3  # header is line 1
    with pytest.raises(LogError, match=rf"two\.csv: row {line}, column 'Time \(s\)': time "
                                       r"jumps back .* jitter bound"):
        import_rcbenchmark(src)
    assert main(["import", str(src), "--format", "rcbenchmark", "--out",
                 str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize(("cell", "what"), [
    ("inf", "expected a finite number"), ("-Infinity", "expected a finite number"),
    ("NaN", "expected a finite number"), ("1,5", None), ("abc", "expected a number")])
def test_csv_bad_cells_are_quoted_as_written(tmp_path, cell, what):
    p = tmp_path / "bad.csv"
    p.write_text(f"t_s,thrust_n\n0,1\n0.1,2\n0.2,{cell}\n", encoding="utf-8")
    if what is None:  # an extra field: pandas' own one-line message
        with pytest.raises(LogError, match=r"bad\.csv: not a readable CSV"):
            import_csv(p)
        return
    with pytest.raises(LogError) as err:
        import_csv(p)
    msg = str(err.value)
    assert msg == f"{p}: row 4, column 'thrust_n': {what}" + (
        " (leave the cell empty for no value)" if "finite" in what else "") + f", got {cell!r}"
    assert "np.float64" not in msg


def test_csv_time_cells_nan_and_repeats_are_named(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("time (ms),thrust_n\n0,1\nnan,2\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"row 3, column 'time \(ms\)': expected a finite "
                                       r"number .*got 'nan'"):
        import_csv(p, {"t_s": "time (ms)"})
    p.write_text("time (ms),thrust_n\n0,1\n,2\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"row 3, column 'time \(ms\)': time is empty"):
        import_csv(p, {"t_s": "time (ms)"})
    p.write_text("time (ms),thrust_n\n0,1\n10.0,2\n20,2\n10,3\n", encoding="utf-8")
    with pytest.raises(LogError, match=r"row 5, column 'time \(ms\)': repeated timestamp "
                                       r"'10' "):
        import_csv(p, {"t_s": "time (ms)"})


def test_the_shipped_jitter_fixture_is_what_the_generator_writes(logfamily, fixtures_dir,
                                                                tmp_path):
    again = logfamily.rcbenchmark_log(tmp_path / "j.csv", seconds=15, steps_back=3, seed=7)
    shipped = fixtures_dir / "logs" / "rcbenchmark_jitter.csv"
    assert shipped.read_bytes() == again.read_bytes()
    _, meta = import_rcbenchmark(shipped)
    assert meta["time_order"]["reordered_rows"] == 6  # as docs/identification.md shows


@pytest.mark.parametrize("doc", ["docs/identification.md"])
def test_the_docs_show_what_importing_the_jittery_log_prints(fixtures_dir, tmp_path, capsys,
                                                             monkeypatch, doc):
    """docs/identification.md shows the import of the jittery fixture and its summary; run
    the shown command verbatim (from the repository root) and compare."""
    root = fixtures_dir.parent
    text = (root / doc).read_text(encoding="utf-8")
    cmd = "$ rotorbench import fixtures/logs/rcbenchmark_jitter.csv " \
          "--out out/real/jitter\n"
    block = text[text.index(cmd) + len(cmd):]
    shown = block[:block.index("```")].rstrip("\n").split("\n")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fixtures").symlink_to(root / "fixtures")
    argv = cmd[2:].split()[1:]
    assert main(argv) == 0
    assert capsys.readouterr().out.rstrip("\n").split("\n") == shown
