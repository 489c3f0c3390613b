"""Options that would be silently ignored are refused, one line, exit 2; one
mechanism for all (``bench.cli_args.option_values.refuse_unused``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.cli import main
from tests.conftest import run_bad


@pytest.mark.parametrize(("argv", "expected"), [
    (["optimize", "--paper-e-cases", "--objective", "price"],
     "--objective has no effect with --paper-e-cases"),
    (["optimize", "--paper-e-cases", "--payload-kg", "1"],
     "--payload-kg has no effect with --paper-e-cases"),
    (["optimize", "--paper-e-cases", "--flyable"], "--flyable has no effect with --paper-e-cases"),
    (["optimize", "--tip-speed-max", "200"], "--tip-speed-max has no effect without --flyable"),
    (["optimize", "--max-wheelbase-m", "0.5", "--hover-throttle", "20", "80"],
     "--max-wheelbase-m, --hover-throttle have no effect without --flyable"),
    (["pareto", "--rule-max-time-constant-ms", "90"],
     "--rule-max-time-constant-ms has no effect without --flyable"),
    (["calibrate", "--short"], "--short has no effect without --simulate-log"),
    (["calibrate", "--short", "--from-log", "x.csv"], "--short has no effect without"),
    (["step", "--sequence", "{seq}", "--repeats", "5", "--dry-run"],
     "--repeats has no effect with --sequence"),
    (["step", "--sequence", "{seq}", "--hold", "2", "--dry-run"],
     "--hold has no effect with --sequence"),
    (["decode", "--protocol", "msp", "--side", "host", "{bin}"],
     "--side has no effect for --protocol msp (only gcs has sides)"),
    (["decode", "--protocol", "vesc-can", "--side", "host", "{bin}"],
     "--side has no effect for --protocol vesc-can"),
])
def test_option_without_effect_is_refused(tmp_path: Path, capsys, argv: list[str],
                                          expected: str) -> None:
    seq = tmp_path / "seq.json"
    seq.write_text(json.dumps({"name": "mine", "steps": [
        {"kind": "arm"}, {"kind": "thrust_step", "thrust_n": 2.0, "hold_s": 1.0},
        {"kind": "disarm"}]}))
    (tmp_path / "x.bin").write_bytes(b"abc")
    argv = [a.format(seq=seq, bin=tmp_path / "x.bin") for a in argv]
    assert expected in run_bad(capsys, *argv)


def test_calibrate_from_log_with_simulate_log(tmp_path: Path, capsys) -> None:
    """`--from-log X --simulate-log Y` wrote Y and never read X."""
    log = tmp_path / "given.csv"
    log.write_text("t_s\n0\n")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--simulate-log",
                  str(tmp_path / "sim.csv"))
    assert "--from-log has no effect with --simulate-log" in err
    assert not (tmp_path / "sim.csv").exists()


def _sweep_and_step(root: Path) -> tuple[Path, Path]:
    """Two imported runs stand in for a sweep and a step run (the options are refused
    before either is read)."""
    log = root / "stand.csv"
    log.write_text("t_s,throttle_us,thrust_n\n" + "\n".join(
        f"{i * 0.1:.1f},{1000 + 10 * i},{0.01 * i * i}" for i in range(40)) + "\n")
    for name in ("sweep", "step"):
        assert main(["import", str(log), "--format", "csv", "--out", str(root / name)]) == 0
    return root / "sweep", root / "step"


@pytest.mark.parametrize(("target", "extra", "expected"), [
    ("px4", ["--auw-kg", "1.2", "--motors", "4"],
     "--auw-kg, --motors have no effect for export px4 (only ardupilot uses a hover thrust)"),
    ("gazebo", ["--hover-thrust", "3"], "--hover-thrust has no effect for export gazebo"),
    ("ardupilot", ["--step-run", "{step}"],
     "--step-run has no effect for export ardupilot (only gazebo uses time constants)"),
    ("px4", ["--step-run", "{step}"], "--step-run has no effect for export px4"),
])
def test_export_option_of_another_target(tmp_path: Path, capsys, target: str,
                                         extra: list[str], expected: str) -> None:
    sweep, step = _sweep_and_step(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "export", target, str(sweep), *[e.format(step=step) for e in extra])
    assert expected in err


def test_export_options_of_their_own_target_still_work(tmp_path: Path, capsys) -> None:
    assert main(["sweep", "--out", str(tmp_path)]) == 0
    (sweep,) = tmp_path.glob("*-sweep")
    assert main(["export", "ardupilot", str(sweep), "--auw-kg", "1.2", "--motors", "4"]) == 0
    assert "MOT_THST_HOVER" in capsys.readouterr().out


FREE_FORM = ["evaluate", "--actuators", "4", "--prop-diameter-m", "0.254", "--prop-ct", "0.1",
             "--prop-cp", "0.04", "--motor-kv", "920", "--motor-resistance", "0.1",
             "--motor-mass-g", "60", "--battery-cells", "3", "--battery-mah", "3000",
             "--battery-mass-g", "250", "--json"]


@pytest.mark.parametrize("flag", ["--prop-pitch-in", "--motor-io", "--battery-burst-c",
                                  "--battery-resistance-mohm", "--battery-c"])
@pytest.mark.parametrize("value", ["nan", "inf"])
def test_evaluate_nan_is_not_not_given(capsys, flag: str, value: str) -> None:
    """`--motor-io nan` evaluated the design as if the option were absent."""
    err = run_bad(capsys, *FREE_FORM, flag, value)
    assert f"{flag}: expected a finite number, got {value}" in err


def test_an_option_given_with_its_default_value_or_in_its_mode_passes(capsys) -> None:
    """The check compares with argparse's defaults: the flyable rules work with --flyable."""
    assert main(["optimize", "--actuators", "4", "--flyable", "--tip-speed-max", "200"]) == 0
