"""The step / sweep / runs commands on the simulated rig, through the real CLI entry."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bench.cli import main
from bench.rig.rig import load_rig


def test_dry_run_prints_every_step_and_touches_no_device(sim_rig_mapped_path, monkeypatch,
                                                         capsys, tmp_path):
    import drivers.factory

    def no_devices(*a, **k):
        raise AssertionError("a dry run opened the rig")

    monkeypatch.setattr(drivers.factory, "open_rig", no_devices)
    assert main(["step", "--rig", str(sim_rig_mapped_path), "--repeats", "3", "--dry-run",
                 "--out", str(tmp_path / "runs")]) == 0
    out = capsys.readouterr().out
    assert "sequence step1" in out and "3.187 N" in out and "disarm" in out
    assert out.count("thrust_step") == 1 + 2 * 3
    assert not (tmp_path / "runs").exists()
    assert main(["sweep", "--rig", str(sim_rig_mapped_path), "--dry-run"]) == 0
    assert "ramp to 1900.0 us" in capsys.readouterr().out


def test_step_without_a_map_sweeps_first_then_steps(sim_rig_path, tmp_path, capsys):
    out_root = tmp_path / "runs"
    assert load_rig(sim_rig_path).thrust_map is None
    code = main(["step", "--rig", str(sim_rig_path), "--repeats", "2", "--out", str(out_root),
                 "--sequence", "step2", "--esc-mode", "diode"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "no static thrust map yet: measuring one with a sweep first" in captured.err
    assert "rig time" in captured.err  # the progress bar is on stderr
    rig = load_rig(sim_rig_path)
    assert rig.thrust_map is not None  # stored with the rig for the next runs
    # the measured map agrees with the plant's own steady state (Paper C section 4.4)
    from drivers.factory import open_rig

    devices = open_rig(rig.with_esc_mode("diode"))
    truth = devices.truth()
    devices.close()
    for us in (1300.0, 1500.0, 1700.0, 1850.0):
        assert rig.thrust_map.thrust_for(us) == pytest.approx(truth.steady_thrust_n(us), rel=0.03)
    sweep_dir, step_dir = sorted(out_root.glob("*-sweep")) + sorted(out_root.glob("*-step2"))
    fig = pd.read_parquet(sweep_dir / "samples.parquet")
    assert {"throttle_us", "thrust_n", "current_a", "rpm"} <= set(fig.columns)
    assert (sweep_dir / "static_map.json").is_file()
    samples = pd.read_parquet(step_dir / "samples.parquet")
    assert np.nanmax(samples["thrust_setpoint_n"]) == pytest.approx(3.187, abs=1e-3)
    assert main(["runs", "--out", str(out_root)]) == 0
    listing = capsys.readouterr().out
    assert "sweep" in listing and "step2" in listing and listing.count("success") == 2
    assert "diode" in listing


def test_a_looser_limit_is_one_line_and_exit_2(sim_rig_mapped_path, tmp_path, capsys):
    code = main(["step", "--rig", str(sim_rig_mapped_path), "--limit", "current_a=100",
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "only tighten" in err and "Traceback" not in err
    assert not list(tmp_path.glob("*-step1"))  # refused before any run folder exists


def test_a_tighter_limit_trips_and_exits_1(sim_rig_mapped_path, tmp_path, capsys):
    # a current limit the step's high level exceeds (a thrust limit below the plan's
    # setpoints is refused before the run: tests/bench/test_refused_before_run.py)
    code = main(["step", "--rig", str(sim_rig_mapped_path), "--limit", "current_a=2",
                 "--repeats", "1", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 1 and "abort: limit trip: current_a" in out


def test_bad_rig_file_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[rig]\nname = 3\n")
    assert main(["step", "--rig", str(bad), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and len(err.strip().splitlines()) == 1


def test_runs_on_an_empty_root(tmp_path, capsys):
    assert main(["runs", "--out", str(tmp_path)]) == 0
    assert "no runs recorded" in capsys.readouterr().out


SEQUENCE_TOML = """
name = "two-steps"
description = "a hand-written recipe"
limits = { current_a = 20.0 }

[[steps]]
kind = "arm"

[[steps]]
kind = "tare"
duration_s = 0.5

[[steps]]
kind = "ramp"
end_us = 1400.0
duration_s = 1.0

[[steps]]
kind = "throttle_step"
us = 1600.0
hold_s = 0.5

[[steps]]
kind = "thrust_step"
thrust_n = 2.0
hold_s = 0.5

[[steps]]
kind = "disarm"
"""


def test_a_sequence_file_runs_and_is_stored(sim_rig_mapped_path, tmp_path, capsys):
    path = tmp_path / "recipe.toml"
    path.write_text(SEQUENCE_TOML)
    assert main(["step", "--rig", str(sim_rig_mapped_path), "--sequence", str(path),
                 "--dry-run"]) == 0
    assert "two-steps" in capsys.readouterr().out
    assert main(["step", "--rig", str(sim_rig_mapped_path), "--sequence", str(path),
                 "--out", str(tmp_path / "runs")]) == 0
    run_dir = next((tmp_path / "runs").glob("*-two-steps"))
    import json

    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["limits"]["current_a"] == 20.0 and meta["sequence"]["name"] == "two-steps"
    samples = pd.read_parquet(run_dir / "samples.parquet")
    assert samples["throttle_us"].max() == pytest.approx(1600.0)


@pytest.mark.parametrize(("text", "match"), [
    ("name = 'x'\n[[steps]]\nkind = 'fly'\n", r"steps\[0\]\.kind"),
    ("name = 'x'\n[[steps]]\nkind = 'hold'\nduration_s = 'long'\n",
     r"steps\[0\]\.duration_s: expected a number"),
    ("name = 'x'\n", "steps: expected a non-empty list"),
    ("name = 'x\n", "not a readable"),
])
def test_a_bad_sequence_file_is_one_line_naming_the_field(sim_rig_mapped_path, tmp_path,
                                                          capsys, text, match):
    import re

    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["step", "--rig", str(sim_rig_mapped_path), "--sequence", str(path),
                 "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and re.search(match, err) and len(err.strip().splitlines()) == 1
