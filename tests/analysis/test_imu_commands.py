"""``rotorbench calibrate`` and ``rotorbench attitude`` end to end on simulated files."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from bench.cli import main
from drivers.sim.imu_attitude_log import simulate_attitude_log


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cal") / "sim.parquet"
    assert main(["calibrate", "--simulate-log", str(path), "--short", "--seed", "4"]) == 0
    return path


def test_calibrate_from_log_writes_json_and_figures(sim_log: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "cal.json"
    rc = main(["calibrate", "--from-log", str(sim_log), "--out", str(out),
               "--mounting-deg", "0", "0", "17", "--figures", str(tmp_path / "figs")])
    assert rc == 0
    text = capsys.readouterr().out
    assert "Table A.1" in text and "Table A.2" in text and "time offset" in text
    cal = json.loads(out.read_text())
    assert abs(cal["time_offset_s"] - 0.0237) < 1e-3
    assert len(list((tmp_path / "figs").glob("fig_a*.png"))) == 4
    assert not list(tmp_path.glob(".*tmp"))  # no temp files left behind


def test_apply_then_attitude_pipeline(sim_log: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture) -> None:
    cal = tmp_path / "cal.json"
    assert main(["calibrate", "--from-log", str(sim_log), "--out", str(cal)]) == 0
    corrected = tmp_path / "corrected.csv"
    assert main(["calibrate", "apply", "--cal", str(cal), str(sim_log),
                 "--out", str(corrected)]) == 0
    df = pd.read_csv(corrected)
    assert {"gyro_x_rad_s", "acc_z_m_s2", "phase", "ref_acc_z_m_s2"} <= set(df.columns)
    assert "imu_gyro_x_rad_s" not in df.columns
    att = tmp_path / "att.parquet"
    assert main(["attitude", str(corrected), "--out", str(att), "--filter", "paper-b",
                 "--bias-seconds", "5"]) == 0
    q = pd.read_parquet(att)
    assert {"qw", "qz", "roll_deg", "yaw_deg"} <= set(q.columns) and len(q) == len(df)


def test_attitude_with_reference_prints_rms(tmp_path: Path,
                                            capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "att.csv"
    pd.DataFrame(simulate_attitude_log()).to_csv(path, index=False)
    assert main(["attitude", str(path), "--filter", "paper-b-printed", "--gain", "0.002",
                 "--yaw-aligned"]) == 0
    out = capsys.readouterr().out
    assert "inclination" in out and "heading" in out and "paper-b-printed (6D)" in out


def test_calibrate_on_a_propulsion_rig_says_what_is_missing(
        capsys: pytest.CaptureFixture) -> None:
    # Without --from-log the command runs on the IMU bench (tests/bench/test_calibration_*);
    # a propulsion rig file is refused with one line naming the file and the field.
    from bench.rig.rig import default_rig_path

    assert main(["calibrate", "--rig", str(default_rig_path())]) == 2
    err = capsys.readouterr().err
    assert "kind" in err and "IMU-bench rig" in err and "sim.toml" in err


@pytest.mark.parametrize("argv", [
    ["calibrate", "--from-log", "missing.csv"],
    ["attitude", "missing.parquet"],
    ["attitude", "x.csv", "--gain", "2"],
    ["calibrate", "apply", "--cal", "nope.json", "log.csv", "--out", "o.csv"],
])
def test_bad_input_is_one_line_exit_2(argv: list[str], tmp_path: Path,
                                      capsys: pytest.CaptureFixture,
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rotorbench: error:")
