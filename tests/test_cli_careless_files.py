"""Careless files a new user hands the CLI (issue 21, part 3): bytes that are not UTF-8,
damaged BROAD files, a log cut mid-line, a log with one enormous line. Each answer is one
line on stderr naming the file, exit code 2, no traceback, nothing half-written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.test_cli_errors import run_bad

NOT_UTF8 = b"# caf\xe9 \xff\xfe\n"


# --- row 10: a catalog's catalog.toml (and every other TOML file) that is not UTF-8 --------


def test_catalog_toml_not_utf8(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """`optimize` on a catalog whose catalog.toml holds a Latin-1 byte: a traceback."""
    cat = tmp_path / "cat"
    shutil.copytree(fixtures_dir / "catalogs" / "thesis-e", cat)
    with (cat / "catalog.toml").open("ab") as fh:
        fh.write(NOT_UTF8)
    for argv in (["optimize"], ["pareto"]):  # every sizing command shares the loader
        err = run_bad(capsys, *argv, "--catalog", str(cat))
        assert f"{cat / 'catalog.toml'}: invalid TOML: 'utf-8' codec can't decode" in err


def test_robot_toml_and_csv_not_utf8(tmp_path: Path, fixtures_dir: Path) -> None:
    """The mobile-robot example's robot.toml and batteries.csv read the locale's encoding."""
    from optimizer.errors import CatalogError
    from optimizer.robot import load_robot

    robot = tmp_path / "robot"
    shutil.copytree(fixtures_dir / "catalogs" / "thesis-robot", robot)
    with (robot / "robot.toml").open("ab") as fh:
        fh.write(NOT_UTF8)
    with pytest.raises(CatalogError, match=r"robot\.toml: not valid TOML"):
        load_robot(robot)
    shutil.copy(fixtures_dir / "catalogs" / "thesis-robot" / "robot.toml", robot)
    with (robot / "batteries.csv").open("ab") as fh:
        fh.write(NOT_UTF8)
    with pytest.raises(CatalogError, match=r"batteries\.csv: not UTF-8 text"):
        load_robot(robot)


def test_sequence_toml_not_utf8(tmp_path: Path, capsys) -> None:
    seq = tmp_path / "seq.toml"
    seq.write_bytes(b'name = "x"\n' + NOT_UTF8)
    err = run_bad(capsys, "step", "--sequence", str(seq), "--dry-run")
    assert f"{seq}: not a readable JSON/TOML sequence" in err


# --- row 11: a run.json that is not UTF-8 --------------------------------------------------


def _bad_run(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "run.json").write_bytes(b'\xff\xfe{"id": "x"}')
    return folder


@pytest.mark.parametrize("argv", [
    ["fit", "{run}"], ["report", "{run}", "--out", "{tmp}/rep"],
    ["constants", "--add", "{run}", "--out", "{tmp}/runs"],
    ["export", "gazebo", "{run}"], ["export", "px4", "{run}"], ["export", "ardupilot", "{run}"],
    ["fly", "--actuators", "4", "--propeller", "P4", "--motor", "M1", "--battery", "B3",
     "--step-run", "{run}"],
])
def test_run_json_not_utf8(tmp_path: Path, capsys, argv: list[str]) -> None:
    """Each reader of a run folder ended in a UnicodeDecodeError traceback."""
    run = _bad_run(tmp_path / "bad")
    argv = [a.format(run=run, tmp=tmp_path) for a in argv]
    err = run_bad(capsys, *argv)
    assert f"{run / 'run.json'}: not UTF-8 text (byte 0xff at offset 0)" in err
    assert not (tmp_path / "rep").exists() and not (tmp_path / "runs").exists()


def test_runs_rebuild_skips_a_bad_run_json_and_says_so(tmp_path: Path, capsys) -> None:
    """`runs --rebuild` stopped at the first bad folder; now it indexes the others."""
    from bench.cli import main

    root = tmp_path / "runs"
    log = tmp_path / "stand.csv"
    log.write_text("t_s,throttle_us,thrust_n\n0,1000,0\n0.1,1100,0.5\n0.2,1200,1\n")
    assert main(["import", str(log), "--format", "csv", "--out", str(root / "good")]) == 0
    _bad_run(root / "bad")
    (root / "list").mkdir()
    (root / "list" / "run.json").write_text("[1, 2]")
    capsys.readouterr()
    assert main(["runs", "--rebuild", "--out", str(root)]) == 0
    out, err = capsys.readouterr()
    good_id = json.loads((root / "good" / "run.json").read_text())["id"]
    assert good_id in out
    lines = err.splitlines()
    assert len(lines) == 2, err
    assert f"{root / 'bad' / 'run.json'}: unreadable run.json" in lines[0]
    assert f"{root / 'list' / 'run.json'}: expected a JSON object" in lines[1]


# --- row 12: damaged BROAD trials ----------------------------------------------------------


def _broad(path: Path, **replace: object) -> Path:
    """A small BROAD trial with the shipped trial 07's layout (datasets imu_acc, imu_gyr,
    imu_mag, opt_quat, opt_pos, movement; attribute sampling_rate); ``replace`` swaps a
    dataset's values, or makes it a group with the value "group"."""

    h5py = pytest.importorskip("h5py")
    n = 300
    t = np.arange(n) / 285.7
    data: dict[str, object] = {
        "imu_gyr": np.stack([0.5 * np.sin(t), 0.3 * np.cos(t), np.full(n, 0.1)], axis=1),
        "imu_acc": np.tile([0.0, 0.0, 9.81], (n, 1)),
        "imu_mag": np.tile([20.0, 0.0, -40.0], (n, 1)),
        "opt_quat": np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        "opt_pos": np.zeros((n, 3)),
        "movement": np.ones(n, dtype=bool),
    }
    data.update(replace)
    with h5py.File(path, "w") as f:
        f.attrs["sampling_rate"] = 285.7142857142857
        for name, value in data.items():
            if isinstance(value, str):
                f.create_group(name)
            else:
                f[name] = value
    return path


@pytest.mark.parametrize(("replace", "expected"), [
    ({"movement": np.zeros(300, dtype=bool)},
     "dataset movement: every sample is 0; no sample to score"),
    ({"opt_quat": np.full((300, 4), float("nan"))},
     "dataset opt_quat: no sample has a finite reference quaternion"),
    ({"imu_gyr": "group"}, "imu_gyr: expected a dataset of numbers, got a group"),
    ({"imu_gyr": np.array([[b"a", b"b", b"c"]] * 300)},
     "dataset imu_gyr: expected numbers, got |S1 values"),
])
@pytest.mark.parametrize("extra", [[], ["--compare", "--json"]])
def test_broad_trial_that_cannot_be_scored_or_read(tmp_path: Path, capsys, replace: dict,
                                                   expected: str, extra: list[str]) -> None:
    """ValueError / TypeError tracebacks from the scoring or from numpy."""
    trial = _broad(tmp_path / "trial.hdf5", **replace)
    err = run_bad(capsys, "attitude", str(trial), *extra)
    assert f"{trial}: {expected}" in err


def test_broad_fixture_itself_is_scored(tmp_path: Path, capsys) -> None:
    """The intact fixture goes through (the refusals above are about the damage)."""
    from bench.cli import main

    trial = _broad(tmp_path / "trial.hdf5")
    assert main(["attitude", str(trial), "--json"]) == 0


def test_imu_log_whose_movement_column_is_all_zero(tmp_path: Path, capsys) -> None:
    """The CSV form of the same fault (a project IMU log with ref_q* and movement)."""
    log = tmp_path / "imu.csv"
    rows = [f"{i / 100:.2f},0.01,0,0,0,0,9.81,1,0,0,0,0" for i in range(200)]
    log.write_text("t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,"
                   "acc_z_m_s2,ref_qw,ref_qx,ref_qy,ref_qz,movement\n" + "\n".join(rows) + "\n")
    err = run_bad(capsys, "attitude", str(log))
    assert f"{log}: column movement: every sample is 0" in err
