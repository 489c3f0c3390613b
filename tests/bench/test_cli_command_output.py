"""What a new user tripped over in the commands' output:
each test types the command as the user did."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.cli import build_parser, main
from tests.conftest import RIGS

h5py = pytest.importorskip("h5py")
pytest.importorskip("vqf")


@pytest.fixture(scope="module")
def tumble() -> dict:
    from drivers.sim.imu_tumble import simulate_tumble

    return simulate_tumble(duration_s=6.0, rate_hz=100.0, seed=4)


def _trial(path: Path, c: dict, *, mag: bool) -> Path:
    with h5py.File(path, "w") as f:
        f.create_dataset("imu_gyr", data=c["gyro"])
        f.create_dataset("imu_acc", data=c["acc"])
        if mag:
            f.create_dataset("imu_mag", data=c["mag"])
        f.create_dataset("opt_quat", data=c["quat"])
        f.create_dataset("movement", data=c["movement"].astype(np.uint8))
        f.attrs["sampling_rate"] = 100.0
    return path


def test_attitude_compare_json_writes_no_png_unasked(tumble, tmp_path, monkeypatch, capsys):
    trial = _trial(tmp_path / "t.hdf5", tumble, mag=True)
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["attitude", str(trial), "--compare", "--json", "--peers", "vqf-6d"]) == 0
    assert "wrote" not in capsys.readouterr().err
    assert list(work.iterdir()) == [] and sorted(p.name for p in tmp_path.iterdir()) == [
        "cwd", "t.hdf5"]


def test_attitude_named_9d_peer_without_magnetometer_is_refused(tumble, tmp_path, capsys):
    trial = _trial(tmp_path / "t.hdf5", tumble, mag=False)
    assert main(["attitude", str(trial), "--compare", "--peers", "vqf-6d,vqf-9d"]) == 2
    err = capsys.readouterr().err
    assert err == (f"rotorbench: error: --peers vqf-9d: a 9D peer needs a magnetometer and "
                   f"{trial} has none (mag_x_ut..mag_z_ut or imu_mag); use vqf-6d\n")


def test_calibrate_attitude_and_apply_create_the_out_folder(tumble, tmp_path, capsys):
    """They said 'folder nodir does not exist' where the other commands create it."""
    log = tmp_path / "sim" / "log.csv"  # --simulate-log into a missing folder, too
    assert main(["calibrate", "--simulate-log", str(log), "--short", "--seed", "1"]) == 0
    cal = tmp_path / "nodir" / "deeper" / "cal.json"
    assert main(["calibrate", "--from-log", str(log), "--out", str(cal)]) == 0
    fixed = tmp_path / "nodir2" / "corrected.csv"
    assert main(["calibrate", "apply", "--cal", str(cal), str(log), "--out", str(fixed)]) == 0
    est = tmp_path / "nodir3" / "est.csv"
    assert main(["attitude", str(fixed), "--out", str(est)]) == 0
    trial = _trial(tmp_path / "t.hdf5", tumble, mag=True)
    png = tmp_path / "nodir4" / "e.png"
    assert main(["attitude", str(trial), "--compare", "--peers", "vqf-6d", "--png",
                 str(png)]) == 0
    capsys.readouterr()
    for path in (log, cal, fixed, est, png):
        assert path.stat().st_size > 0, path


def test_calibrate_usage_shows_the_action_as_optional():
    """``calibrate`` alone runs on the rig; the usage line said ACTION was required."""
    sub = build_parser(only="calibrate")._subparsers._group_actions[0]
    usage = sub.choices["calibrate"].format_usage()
    assert usage.rstrip().endswith("[ACTION ...]"), usage


def test_step_dry_run_of_a_refused_plan_prints_only_the_refusal(capsys, fixtures_dir):
    """It printed 300 000 plan lines (3 M with a larger count) and no refusal; the run
    itself refuses the plan: the dry run says so first, and prints nothing else."""
    rig = str(RIGS / "sim.toml")
    assert main(["step", "--rig", rig, "--dry-run", "--repeats", "100000"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("rotorbench: error: sequence 'step1'")  # says the count
    assert "projected 27.8 h of rig time" in err
    assert err.count("\n") == 1 and "longer than the 24 h a run may last" in err
    assert main(["step", "--rig", rig, "--dry-run", "--repeats", "2"]) == 0
    out = capsys.readouterr().out
    assert "projected" in out.splitlines()[-1]
