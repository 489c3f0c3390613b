"""Sequence files and limits: checked on load and before anything runs, one line naming
the file and the field, exit code 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import run_bad

_RECIPE = """name = "two-steps"
limits = {limits}
[[steps]]
kind = "arm"
[[steps]]
kind = "ramp"
end_us = 1400.0
duration_s = 1.0
[[steps]]
kind = "disarm"
"""


@pytest.mark.parametrize(("limits", "expected"), [
    ('{ current_a = "x" }', "limits.current_a: expected a finite number, got 'x'"),
    ("{ warp = 2.0 }", "limits.warp: unknown limit"),
    ("5", "limits: expected a table"),
    ("{ current_a = nan }", "limits.current_a: expected a finite number"),
])
def test_sequence_file_limits_are_checked_on_load(tmp_path: Path, capsys, limits: str,
                                                  expected: str) -> None:
    seq = tmp_path / "recipe.toml"
    seq.write_text(_RECIPE.format(limits=limits))
    err = run_bad(capsys, "step", "--sequence", str(seq), "--dry-run")
    assert f"{seq}: {expected}" in err


def test_sequence_step_that_is_not_a_table(tmp_path: Path, capsys) -> None:
    seq = tmp_path / "recipe.json"
    seq.write_text('{"name": "x", "steps": [1, 2]}')
    err = run_bad(capsys, "step", "--sequence", str(seq), "--dry-run")
    assert "recipe.json: steps[0]: expected a table" in err


@pytest.mark.parametrize("dry", [True, False])
def test_looser_limits_are_refused_before_anything_runs(tmp_path: Path, capsys,
                                                        dry: bool) -> None:
    seq = tmp_path / "recipe.toml"
    seq.write_text(_RECIPE.format(limits="{ current_a = 200.0 }"))
    out = tmp_path / "runs"
    extra = ["--dry-run"] if dry else ["--out", str(out)]
    err = run_bad(capsys, "step", "--sequence", str(seq), *extra)
    assert "current_a: a sequence may only tighten limits" in err
    err = run_bad(capsys, "step", "--limit", "thrust_n=30", *extra)
    assert "thrust_n: a sequence may only tighten limits" in err
    assert not out.exists()


def test_limit_option_must_be_finite(capsys) -> None:
    err = run_bad(capsys, "step", "--limit", "thrust_n=nan", "--dry-run")
    assert "--limit 'thrust_n=nan': expected a finite number" in err


def test_step_table_with_an_unknown_key(tmp_path: Path, capsys) -> None:
    seq = tmp_path / "recipe.toml"
    text = _RECIPE.format(limits="{}").replace("end_us = 1400.0", "end_us = 1400.0\nwobble = 1")
    seq.write_text(text)
    err = run_bad(capsys, "step", "--sequence", str(seq), "--dry-run")
    assert "recipe.toml: steps[1].wobble: unknown key for a ramp step; expected end_us" in err


@pytest.mark.parametrize("argv", [["sweep", "--duration", "0"], ["sweep", "--duration", "nan"],
                                  ["step", "--hold", "0"]])
def test_zero_length_ramp_or_hold_is_refused(argv: list[str], capsys) -> None:
    """`sweep --duration 0` planned a 1100 -> 1900 us step as a 'sweep'."""
    err = run_bad(capsys, *argv, "--dry-run")
    assert "expected a time > 0 s" in err or "must be a time > 0 s" in err


def test_negative_limit_is_refused_before_the_run(tmp_path: Path, capsys) -> None:
    """--limit thrust_n=-1 'tightened' the rig and tripped at t = 0 with a recorded run."""
    out = tmp_path / "runs"
    err = run_bad(capsys, "step", "--limit", "thrust_n=-1", "--out", str(out))
    assert "limits.thrust_n: -1 is below 0" in err
    assert not out.exists()


@pytest.mark.parametrize(("value", "expected"), [
    ("-1.0", "steps[1].duration_s: expected a time >= 0 s, got -1.0"),
    ("inf", "steps[1].duration_s: expected a finite number, got inf"),
    ("nan", "steps[1].duration_s: expected a finite number, got nan"),
])
def test_sequence_step_times_name_the_file(tmp_path: Path, capsys, value: str,
                                           expected: str) -> None:
    """These were reported as "sequence 'two-steps': steps[1]: ..." without the file."""
    seq = tmp_path / "recipe.toml"
    seq.write_text(_RECIPE.format(limits="{}").replace("duration_s = 1.0",
                                                       f"duration_s = {value}"))
    err = run_bad(capsys, "step", "--sequence", str(seq), "--dry-run")
    assert f"{seq}: {expected}" in err
