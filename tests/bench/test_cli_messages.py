"""What a new user read: numbers print as numbers in every
error message, a free-form option is named by its flag, and SIGTERM exits 143. Each test
runs the command as a user types it."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import bench.cli
from bench.cli import main
from bench.errors import RigError


def run_bad(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run the CLI in-process; one line on stderr, exit 2; return that line."""
    code = main(list(argv))
    raw = capsys.readouterr().err
    assert code == 2, raw
    assert raw.count("\n") == 1 and raw.startswith("rotorbench: error: "), repr(raw)
    return raw.strip()


def _imu_log(path: Path, **change: object) -> Path:
    n = 50
    t = np.arange(n) * 0.01
    df = pd.DataFrame({"t_s": t, **{f"gyro_{a}_rad_s": np.zeros(n) for a in "xyz"},
                       **{f"acc_{a}_m_s2": np.r_[0.0, 0.0, 9.81][i] * np.ones(n)
                          for i, a in enumerate("xyz")}})
    for key, (row, value) in change.items():
        df.loc[row, key] = value
    df.to_csv(path, index=False)
    return path


def test_error_messages_print_numbers_not_numpy_reprs(tmp_path, capsys):
    """A family of messages that quote values read into numpy (time order, a 0/1 column,
    a free-form part): none shows ``np.float64(...)``."""
    back = _imu_log(tmp_path / "back.csv", t_s=(10, 10.0))  # t: 0.09, 10, 0.11: back in time
    messages = [run_bad(capsys, "attitude", str(back))]
    assert messages[0].endswith("column t_s: time must increase, got 0.11 after 10")
    mov = _imu_log(tmp_path / "mov.csv", movement=(3, 2.5))
    mov_df = pd.read_csv(mov).fillna({"movement": 1.0})
    mov_df.to_csv(mov, index=False)
    messages.append(run_bad(capsys, "attitude", str(mov)))
    assert "expected 0 or 1, got 2.5" in messages[-1]
    for m in messages:
        assert "np." not in m, m


def test_every_command_message_formats_numpy_scalars_plainly(monkeypatch, capsys):
    """The common place: a message built anywhere under ``main`` with ``!r`` or inside a
    list of numpy scalars still prints plain numbers."""
    def bad_command(_args: argparse.Namespace) -> int:
        v = np.float64(9.99)
        raise RigError(f"limits.voltage_min_v: got {v!r}, range {[v, np.int64(3)]}")

    parser = argparse.ArgumentParser()
    parser.set_defaults(func=bad_command)
    monkeypatch.setattr(bench.cli, "_parser_for", lambda argv: parser)
    assert run_bad(capsys) == "rotorbench: error: limits.voltage_min_v: got 9.99, range [9.99, 3]"
    assert repr(np.float64(9.99)) == "np.float64(9.99)"  # only while a command runs


FREE_FORM = ["evaluate", "--actuators", "4", "--prop-diameter-m", "0.254", "--prop-ct", "0.11",
             "--prop-cp", "0.045", "--motor-kv", "920", "--motor-resistance", "0.1",
             "--motor-mass-g", "55", "--battery-cells", "3", "--battery-mah", "5000",
             "--battery-mass-g", "400"]


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_evaluate_battery_c_not_finite_names_the_option(capsys, value):
    err = run_bad(capsys, *FREE_FORM, "--battery-c", value)
    assert err.startswith(f"rotorbench: error: --battery-c: expected a finite number, "
                          f"got {value}")
    assert "<free-form>" not in err and "batteries.csv" not in err


@pytest.mark.parametrize(("fmt", "text"), [
    ("rcbenchmark", "Time (s);ESC signal (µs);Thrust (gf);Voltage (V);Current (A)\n"
                    "0,0;1000;0,5;16,1;0,2\n0,1;1100;10,5;16,0;1,2\n0,2;1200;20,5;15,9;2,25\n"),
    ("csv", "t_s;thrust_n;current_a\n0,0;0,5;0,2\n0,1;1,5;1,2\n0,2;2,5;2,25\n"),
    ("csv", "t_s\tthrust_n\tcurrent_a\n0.0\t0.5\t0.2\n0.1\t1.5\t1.2\n0.2\t2.5\t2.25\n"),
])
def test_import_reads_a_semicolon_or_tab_separated_log(tmp_path, capsys, fmt, text):
    """A log saved by a comma-decimal spreadsheet got pandas' 'Expected N fields' or 'the
    header is one field'; it is read, and the import says how."""
    log = tmp_path / "log.csv"
    log.write_text(text, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["import", str(log), "--format", fmt, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    sep = "';'" if ";" in text else "tab"
    assert "-separated, decimal" in said and sep in said
    samples = pd.read_parquet(out / "samples.parquet")
    assert samples["t_s"].tolist() == pytest.approx([0.0, 0.1, 0.2])
    assert samples["current_a"].tolist() == pytest.approx([0.2, 1.2, 2.25])
