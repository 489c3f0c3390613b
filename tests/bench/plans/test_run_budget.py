"""Absurd limits and absurd plans are refused before anything spins:
``thrust_n = 1e308`` switched the trip off, a 1e6 s hold wrote 1.1 GB in 30 s."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import bench.plans.run_budget as budget_module
from bench.cli import main
from bench.plans.run_budget import Budget, check_budget, project
from bench.rig.rig import HEXAPOD_LIMIT_MAXIMA, LIMIT_MAXIMA, default_imu_rig_path
from tests.conftest import run_bad


@pytest.mark.parametrize("name", sorted(LIMIT_MAXIMA))
@pytest.mark.parametrize("factor", [1.5, 1e300])
def test_rig_limit_beyond_any_stand_is_refused(sim_rig_mapped_path: Path, capsys, name: str,
                                               factor: float) -> None:
    text = sim_rig_mapped_path.read_text()
    value = LIMIT_MAXIMA[name] * factor
    line = re.compile(rf"^{name} = .*$", re.M)
    text = line.sub(f"{name} = {value!r}", text) if line.search(text) else \
        text.replace("[limits]\n", f"[limits]\n{name} = {value!r}\n")
    if name == "voltage_min_v":  # keep min < max so the bound is what is refused
        text = re.sub(r"^voltage_max_v = .*$", "voltage_max_v = 999.0", text, flags=re.M)
    sim_rig_mapped_path.write_text(text)
    err = run_bad(capsys, "step", "--rig", str(sim_rig_mapped_path), "--dry-run")
    assert f"{sim_rig_mapped_path}: [limits] {name}:" in err
    assert f"-{LIMIT_MAXIMA[name]:g}" in err


def test_hexapod_limit_beyond_any_hexapod_is_refused(tmp_path: Path, capsys) -> None:
    rig = tmp_path / "imu.toml"
    text = default_imu_rig_path().read_text()
    assert re.search(r"^velocity_m_s = ", text, re.M)
    rig.write_text(re.sub(r"^velocity_m_s = .*$", "velocity_m_s = 1e308", text, flags=re.M))
    err = run_bad(capsys, "calibrate", "--rig", str(rig), "--dry-run")
    assert f"{rig}: [hexapod] velocity_m_s:" in err
    assert f"0-{HEXAPOD_LIMIT_MAXIMA['velocity_m_s']:g}" in err


@pytest.mark.parametrize("argv", [
    ["step", "--hold", "1e6"],
    ["step", "--repeats", "100000", "--hold", "1"],
    ["sweep", "--duration", "1e7"],
])
def test_a_plan_longer_than_a_day_is_refused(sim_rig_mapped_path: Path, tmp_path: Path, capsys,
                                             argv: list[str]) -> None:
    out = tmp_path / "runs"
    err = run_bad(capsys, *argv, "--rig", str(sim_rig_mapped_path), "--out", str(out), "--yes")
    assert "of rig time" in err and "longer than the 24 h a run may last" in err
    assert not out.exists()


@pytest.mark.parametrize("sequence", ["step1", "step2"])
def test_a_huge_repeat_count_is_refused_in_constant_memory(sim_rig_mapped_path: Path,
                                                           tmp_path: Path, capsys,
                                                           sequence: str) -> None:
    """`step --repeats 100000000` built 16 GB of steps before the budget
    check; 1e6 repeats took 12.8 s and 1.4 GB to refuse. The length is now projected from
    one repeat."""
    import tracemalloc

    out = tmp_path / "runs"
    tracemalloc.start()
    try:
        err = run_bad(capsys, "step", "--sequence", sequence, "--repeats", "200000",
                      "--rig", str(sim_rig_mapped_path), "--out", str(out))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert f"sequence '{sequence}' (200000 repeats): projected" in err
    assert "longer than the 24 h a run may last" in err
    assert peak < 50e6, f"{peak / 1e6:.0f} MB"
    assert not out.exists()


def test_many_short_repeats_are_refused_by_their_step_count(sim_rig_mapped_path: Path,
                                                            capsys) -> None:
    """A short plan of very many steps (--hold 1e-3): 2.6 GB and no end before."""
    err = run_bad(capsys, "step", "--repeats", "3000000", "--hold", "1e-3", "--dry-run",
                  "--rig", str(sim_rig_mapped_path))
    assert "(3000000 repeats): 9000007 steps, more than the 300000 a plan may hold" in err


def test_a_console_plan_with_a_huge_repeat_count_is_refused() -> None:
    """The console's plans share the sequence builders (bench.plans.plan_specs)."""
    from bench.errors import RigError
    from bench.plans.plan_specs import plan_sequence

    with pytest.raises(RigError, match=r"\(100000000 repeats\): projected .* longer than"):
        plan_sequence({"plan": "step1", "repeats": 100_000_000, "hold_s": 0.5})


def test_a_sequence_file_with_an_absurd_hold(sim_rig_mapped_path: Path, tmp_path: Path,
                                             capsys) -> None:
    seq = tmp_path / "long.json"
    seq.write_text(json.dumps({"name": "soak", "steps": [
        {"kind": "arm"}, {"kind": "throttle_step", "us": 1300.0, "hold_s": 1e6},
        {"kind": "disarm"}]}))
    out = tmp_path / "runs"
    err = run_bad(capsys, "step", "--sequence", str(seq), "--rig", str(sim_rig_mapped_path),
                  "--out", str(out))
    assert err.startswith(f"rotorbench: error: sequence 'soak' ({seq}): projected 278 h of "
                          "rig time and about 430 GB of samples (25000 rows/s)")
    assert not out.exists()


def test_a_long_plan_needs_yes(sim_rig_mapped_path: Path, tmp_path: Path, capsys,
                               monkeypatch) -> None:
    """Above the confirmation bound the plan runs only with --yes (bound lowered to 5 s
    here so the test runs a short plan)."""
    monkeypatch.setattr(budget_module, "CONFIRM_PLAN_S", 5.0)
    out = tmp_path / "runs"
    argv = ["step", "--repeats", "2", "--rig", str(sim_rig_mapped_path), "--out", str(out)]
    err = run_bad(capsys, *argv)
    assert "projected 6.5 s of rig time" in err and "pass --yes to run it" in err
    assert not out.exists()
    assert main([*argv, "--yes"]) == 0
    assert len(list(out.glob("*-step1"))) == 1


def test_the_dry_run_prints_the_projection(sim_rig_mapped_path: Path, capsys) -> None:
    """A plan longer than a run may last is refused by the dry run too, with its
    projection and before any plan line (tests/bench/test_cli_command_output.py); a long one
    that a run may carry out is printed with its projection."""
    assert main(["step", "--hold", "1000", "--rig", str(sim_rig_mapped_path), "--dry-run"]) == 0
    assert "projected 11.1 h of rig time and about 17.2 GB" in capsys.readouterr().out
    assert main(["step", "--hold", "1e6", "--rig", str(sim_rig_mapped_path), "--dry-run"]) == 2
    out, err = capsys.readouterr()
    assert "projected 1.11e+04 h of rig time" in err and out == ""


def test_budget_bounds() -> None:
    day = budget_module.MAX_PLAN_S
    check_budget(project(day, 1.0), "x", yes=True)  # a day at a slow rate is allowed
    with pytest.raises(Exception, match="longer than the 24 h"):
        check_budget(project(day + 1.0, 1.0), "x", yes=True)
    with pytest.raises(Exception, match="pass --yes"):
        check_budget(Budget(10.0, 1.0, 3e9), "x", yes=False)  # too big, though short
    check_budget(Budget(10.0, 1.0, 3e9), "x", yes=True)
