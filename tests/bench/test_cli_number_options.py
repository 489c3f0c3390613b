"""Numbers on the command line (seeds, timeouts, weights, payloads, repeats, part sizes) are
checked when parsed: one line, exit code 2, never a numpy or scipy traceback later."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from tests.conftest import run_bad


def test_weights_naming_a_metric_twice(capsys) -> None:
    err = run_bad(capsys, "optimize", "--objective", "weighted", "--weights",
                  "price=1,price=2")
    assert "bad weight 'price=2': price is weighted twice" in err


@pytest.mark.parametrize("value", ["0", "-1", "nan", "1e308"])
def test_check_timeout_must_be_positive(capsys, value: str) -> None:
    err = run_bad(capsys, "check", f"--timeout={value}")
    assert "--timeout: expected seconds > 0 per device" in err


@pytest.mark.parametrize("value", ["-1", "0", "nan", "1e308"])  # 1e308 overflowed time_t
def test_devices_can_timeout_must_be_positive(capsys, value: str) -> None:
    err = run_bad(capsys, "devices", f"--can-timeout={value}")
    assert "--can-timeout: expected seconds > 0" in err


@pytest.mark.parametrize("argv", [
    ["step", "--repeats", "1"], ["sweep", "--duration", "1"], ["demo"],
    ["calibrate", "--simulate-log", "x.csv", "--short"], ["console", "--selftest"],
])
def test_negative_seed_is_refused_when_parsed(tmp_path: Path, capsys, monkeypatch,
                                              argv: list[str]) -> None:
    """--seed -1 ended in numpy's 'ValueError: expected non-negative integer' traceback."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--seed", "-1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "argument --seed: expected a whole number >= 0, got '-1'" in err
    assert "Traceback" not in err and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("flag", "value", "expected"), [
    ("--prop-diameter-m", "-1", "--prop-diameter-m: expected a number > 0"),  # complex mass
    ("--prop-ct", "1e308", "--prop-ct: expected a number <= 1e+09"),  # ZeroDivisionError
    ("--battery-cells", "1e308", "--battery-cells: expected a number <= 1e+09"),
])
def test_free_form_numbers_out_of_range(capsys, flag: str, value: str, expected: str) -> None:
    parts = {"--prop-diameter-m": "0.2", "--prop-ct": "0.1", "--prop-cp": "0.05",
             "--motor-kv": "900", "--motor-resistance": "0.1", "--motor-mass-g": "50",
             "--battery-cells": "3", "--battery-mah": "2200", "--battery-mass-g": "180"}
    parts[flag] = value
    argv = [x for kv in parts.items() for x in kv]
    err = run_bad(capsys, "evaluate", "--actuators", "4", *argv)
    assert expected in err


def test_demo_repeats_beyond_the_cap_is_refused(tmp_path: Path, capsys) -> None:
    """--repeats 1000000 ran for days without a word."""
    err = run_bad(capsys, "demo", "--out", str(tmp_path / "d"), "--repeats", "1000000")
    assert "--repeats: expected a count from 1 to 100" in err
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", [
    ["optimize", "--actuators", "4"],
    ["pareto", "--actuators", "4", "--x", "flight-time", "--y", "price"],
    ["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1", "--battery", "B3"],
])
def test_absurd_payload_is_refused_without_numpy_warnings(capsys, command: list[str]) -> None:
    """1e308 kg passed as finite and overflowed numpy (RuntimeWarning lines, then exit 3)."""
    line = run_bad(capsys, *command, "--payload-kg", "1e308")
    assert "payload" in line and "10000" in line
