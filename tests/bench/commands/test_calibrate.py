"""`rotorbench calibrate --quick` on the simulated IMU bench: every stage recorded, then the
calibration's accuracy against the simulator's hidden truth (the accuracy targets)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.imu_calibration import TABLE_A2, load_calibration
from analysis.imu_log import CALIBRATION_COLUMNS, load_calibration_log
from bench.cli import main
from bench.rig.rig import default_imu_rig_path


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("cal")
    out = root / "cal.json"
    code = main(["calibrate", "--quick", "--tick", "0.1", "--runs", str(root / "runs"),
                 "--out", str(out)])
    return code, root, out


def _runs(root: Path) -> list[dict]:
    metas = [json.loads(p.read_text()) for p in sorted((root / "runs").glob("*/run.json"))]
    return sorted(metas, key=lambda m: m["stage"])


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_every_stage_is_a_successful_recorded_run(calibrated) -> None:
    code, root, out = calibrated
    assert code == 0 and out.is_file()
    metas = _runs(root)
    assert [m["kind"] for m in metas] == ["cal_bias", "cal_gyro", "cal_acc", "cal_lever",
                                          "cal_verify"]
    assert all(m["status"] == "success" for m in metas)
    assert (root / "runs" / "runs.sqlite").is_file()
    # each run's samples are directly a calibration log of its phases
    for m in metas:
        df = pd.read_parquet(root / "runs" / m["id"] / "samples.parquet")
        assert set(CALIBRATION_COLUMNS) <= set(df.columns)
        assert df["t_s"].is_monotonic_increasing


def test_joined_log_reads_as_a_calibration_log(calibrated) -> None:
    _, root, _ = calibrated
    (log,) = (root / "runs").glob("*-calibration.parquet")
    df = load_calibration_log(log)
    sizes = df.groupby("phase").size()
    assert 3000 <= sizes["bias"] <= 3010  # the quick 3000-sample hold
    assert set(sizes.index) == {"bias", "gyro", "acc", "lever_x", "lever_y", "lever_z",
                                "verify"}


def test_accuracy_meets_the_issue_targets(calibrated) -> None:
    _, root, out = calibrated
    cal = load_calibration(out)
    truth = _runs(root)[0]["sim_truth"]
    assert _rel(cal.k_gyro, truth["k_gyro"]) < 0.002
    assert _rel(cal.k_acc, truth["k_acc"]) < 0.002
    r_err = np.asarray(cal.lever_arm_m) - truth["lever_arm_from_pivot_m"]
    assert np.abs(r_err).max() < 0.002
    z = (np.asarray(cal.gyro_bias_rad_s) - truth["gyro_bias_rad_s"]) / \
        np.asarray(cal.gyro_bias_stderr_rad_s)
    assert np.all(np.abs(z) < 3.0)
    assert abs(cal.time_offset_s - truth["clock_offset_s"]) < 0.5e-3
    v = cal.verification_rms
    for kind in ("gyro_rad_s", "acc_m_s2"):
        corrected = np.asarray(v[kind]["corrected"])
        assert np.all(corrected <= np.asarray(TABLE_A2[kind]))
        assert np.all(corrected < np.asarray(v[kind]["raw"]))


def test_json_has_the_required_fields(calibrated) -> None:
    _, _, out = calibrated
    data = json.loads(out.read_text())
    for key in ("gyro_bias_rad_s", "k_gyro", "k_acc", "lever_arm_m", "time_offset_s",
                "verification_rms"):
        assert key in data
    assert data["decomposition"]["gyro"]["rotation_vs_measured_deg"] < 0.2


def test_apply_corrects_the_joined_log(calibrated, tmp_path: Path) -> None:
    _, root, out = calibrated
    (log,) = (root / "runs").glob("*-calibration.parquet")
    corrected = tmp_path / "corrected.parquet"
    assert main(["calibrate", "apply", "--cal", str(out), str(log), "--out",
                 str(corrected)]) == 0
    df = pd.read_parquet(corrected)
    v = df[df["phase"] == "verify"]
    err = v["gyro_z_rad_s"] - v["ref_omega_z_rad_s"]
    assert float(np.sqrt(np.mean(err**2))) < TABLE_A2["gyro_rad_s"][2]


def test_dry_run_touches_no_device(tmp_path: Path, capsys: pytest.CaptureFixture,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["calibrate", "--dry-run"]) == 0
    out = capsys.readouterr().out
    for name in ("cal_bias", "cal_gyro", "cal_acc", "cal_lever", "cal_verify"):
        assert name in out
    assert "10000 samples" in out
    assert not (tmp_path / "runs").exists()


def test_rig_file_errors_are_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture
                                              ) -> None:
    text = default_imu_rig_path().read_text(encoding="utf-8")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("rate_rad_s = 0.7", "rate_rad_s = -1"), encoding="utf-8")
    assert main(["calibrate", "--rig", str(bad), "--dry-run"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.toml" in err[0] and "rate_rad_s" in err[0]
    bad.write_text(text.replace("lever_arm_m = [0.365, -0.235, 0.230]", "lever_arm_m = [1, 2]"),
                   encoding="utf-8")
    assert main(["calibrate", "--rig", str(bad), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "[sim.imu] lever_arm_m" in err and "three finite numbers" in err
    # a sequence the rig's limits cannot run is refused before anything moves
    bad.write_text(text.replace("rate_rad_s = 0.7", "rate_rad_s = 0.2"), encoding="utf-8")
    assert main(["calibrate", "--rig", str(bad), "--dry-run"]) == 2
    assert "exceeds the hexapod limits" in capsys.readouterr().err
