"""Damaged flight logs never end in a traceback: seeded random cuts, flipped bytes,
overwritten and deleted runs of a valid blackbox and DataFlash log each either import
(what decodes) or are refused with a LogError; warnings are errors here (pytest config),
so a numpy warning on damaged values fails too. Found: a damaged FMT renaming IMU's
columns, and signalling-NaN floats."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import LogError
from analysis.flightlogs import read_flight_log

bbw = sys.modules["rotorbench_tests_blackbox_writer"]  # blackbox_writer.py, loaded by conftest.py
dfw = sys.modules["rotorbench_tests_dataflash_writer"]  # dataflash_writer.py, loaded by conftest.py


def _valid(fmt: str) -> bytes:
    if fmt == "blackbox":
        lay, s = bbw.quad_layout(), bbw.Settings()
        return bbw.blackbox_log(bbw.flight_rows(600, lay, s), lay, s)
    return dfw.flight(300)[0]


def _damage(data: bytes, rng: np.random.Generator) -> bytes:
    out = bytearray(data)
    op = int(rng.integers(0, 4))
    # half the time in the first kilobyte: the header or FMT messages, which define the rest
    at = int(rng.integers(0, min(1000, len(out)) if rng.random() < 0.5 else len(out)))
    if op == 0:
        return bytes(out[:at])
    if op == 1:
        for _ in range(int(rng.integers(1, 20))):
            out[min(at + int(rng.integers(0, 200)), len(out) - 1)] = int(rng.integers(0, 256))
    elif op == 2:
        n = int(rng.integers(1, 500))
        out[at:at + n] = rng.bytes(n)
    else:
        del out[at:at + int(rng.integers(1, 300))]
    return bytes(out)


@pytest.mark.parametrize("fmt", ["blackbox", "dataflash"])
def test_damaged_logs_import_or_are_refused_never_a_traceback(tmp_path, fmt):
    rng = np.random.default_rng(11)
    valid = _valid(fmt)
    path = tmp_path / "damaged.log"
    outcomes = {"imported": 0, "refused": 0}
    for _ in range(150):
        path.write_bytes(_damage(valid, rng))
        try:
            logs = read_flight_log(path, fmt)
        except LogError as exc:
            assert "\n" not in str(exc)
            outcomes["refused"] += 1
            continue
        for log in logs:
            t = log.columns["t_s"]
            assert len(t) == log.rows and np.all(np.diff(t) > 0)
            assert all(len(v) == len(t) for v in log.columns.values())
        outcomes["imported"] += 1
    assert outcomes["imported"] > 30  # much damage leaves most of the log readable


def test_damaged_ulogs_say_one_line_through_the_command(tmp_path, capsys):
    """pyulog prints its own warnings on a damaged file: the command keeps them to one
    note, so the output stays the import line and notes, or one error line."""
    from bench.cli import main

    valid = (Path(__file__).resolve().parents[2] / "fixtures" / "data" / "px4_ulog"
             / "sample_px4_events.ulg").read_bytes()
    rng = np.random.default_rng(4)
    path = tmp_path / "damaged.ulg"
    codes = set()
    for k in range(8):
        path.write_bytes(_damage(valid, rng))
        out_dir = tmp_path / f"r{k}"
        code = main(["import", str(path), "--out", str(out_dir)])
        out, err = capsys.readouterr()
        codes.add(code)
        assert "Traceback" not in out + err
        if code == 0:
            assert all(line.startswith(f"{out_dir}: ") for line in out.splitlines())
        else:
            assert code == 2 and len(err.strip().splitlines()) == 1 and not out_dir.exists()
    assert 0 in codes
