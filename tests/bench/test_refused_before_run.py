"""Settings under which a run could only fail are refused before anything is written or
armed: a device option misspelt left a failed run folder and an
index row per try; a limit of 0 or a tick of 1e-9 armed the ESC, then tripped at t = 0 or
starved the watchdog."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from tests.conftest import run_bad

FIXTURE_RIGS = Path(__file__).resolve().parents[2] / "bench" / "data" / "rigs"


# --- row 15: a device-option error writes nothing -----------------------------------------


@pytest.mark.parametrize("command", [["step", "--repeats", "1"], ["sweep"]])
def test_device_option_error_leaves_no_run_folder(tmp_path: Path, capsys,
                                                  command: list[str]) -> None:
    text = (FIXTURE_RIGS / "sim-can.toml").read_text(encoding="utf-8")
    assert "pole_pairs = 7, keepalive_s" in text
    rig = tmp_path / "can.toml"
    rig.write_text(text.replace("pole_pairs = 7, keepalive_s", "pole_pairz = 7, keepalive_s"),
                   encoding="utf-8")
    out = tmp_path / "runs"
    for _ in range(2):  # each try left one more failed run
        assert main([*command, "--rig", str(rig), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        # `step` says first that it measures the missing map with a sweep
        assert err.endswith("\n") and "Traceback" not in err
        last = err.splitlines()[-1]
        assert last.startswith(f"rotorbench: error: {rig}: [devices.esc] options.pole_pairz: "
                               "unknown option for this device"), err
    assert not out.exists() or list(out.iterdir()) == [], sorted(out.iterdir())


# --- row 17: limits that leave the plan no room, a tick the loop cannot keep --------------


@pytest.mark.parametrize(("argv", "expected"), [
    (["step", "--limit", "thrust_n=0"], "limits.thrust_n = 0: expected > 0 N"),
    (["step", "--limit", "current_a=0"], "limits.current_a = 0: expected > 0 A"),
    (["sweep", "--limit", "rpm=0"], "limits.rpm = 0: expected > 0 rpm"),
    (["step", "--limit", "thrust_n=1"], "limits.thrust_n = 1 N leaves no room for the plan's "
                                        "thrust setpoint"),
    (["step", "--limit", "voltage_min_v=12.5", "--limit", "voltage_max_v=12"],
     "voltage_min_v = 12.5 V is not below voltage_max_v = 12 V"),
    (["step", "--tick", "1e-9"], "--tick 1e-09: expected 0.001 <= tick <= 0.1 s"),
    (["sweep", "--tick", "0.0005"], "--tick 0.0005: expected 0.001 <= tick"),
    (["console", "--selftest", "--limit", "thrust_n=0"], "--limit: limits.thrust_n = 0"),
    (["console", "--selftest", "--tick", "1e-9"], "--tick 1e-09"),
])
def test_run_that_could_only_trip_is_refused_before_arming(tmp_path: Path, capsys,
                                                           monkeypatch, argv: list[str],
                                                           expected: str) -> None:
    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    out = tmp_path / "runs"
    err = run_bad(capsys, *argv, "--out", str(out))
    assert expected in err
    assert not out.exists()  # no run folder, no index: nothing was opened or armed


def test_limit_and_tick_dry_run_says_the_same(capsys) -> None:
    err = run_bad(capsys, "step", "--limit", "thrust_n=1", "--dry-run")
    assert "leaves no room for the plan's thrust setpoint" in err
    for command in ("step", "sweep"):
        err = run_bad(capsys, command, "--tick", "0.2", "--dry-run")
        assert "--tick 0.2: expected 0.001 <= tick <= 0.1 s" in err


@pytest.mark.parametrize("name", ["thrust_n", "current_a", "rpm", "voltage_max_v"])
def test_rig_file_limit_of_zero(tmp_path: Path, capsys, name: str) -> None:
    import re

    text = (FIXTURE_RIGS / "sim.toml").read_text(encoding="utf-8")
    text, n = re.subn(rf"(?m)^{name} = .*$", f"{name} = 0", text)
    assert n == 1
    if name == "voltage_max_v":
        text = re.sub(r"(?m)^voltage_min_v = .*$", "voltage_min_v = 0", text)
    rig = tmp_path / "rig.toml"
    rig.write_text(text, encoding="utf-8")
    err = run_bad(capsys, "step", "--rig", str(rig), "--out", str(tmp_path / "runs"))
    assert f"{rig}: [limits] {name}: 0: expected a limit > 0" in err
    assert not (tmp_path / "runs").exists()


def test_a_fine_tick_still_runs(tmp_path: Path, capsys) -> None:
    """The bound is not stricter than the loop: 1 ms runs a step to its end."""
    assert main(["step", "--repeats", "1", "--tick", "0.001", "--out", str(tmp_path)]) == 0
