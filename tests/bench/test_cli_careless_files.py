"""Careless files a new user hands the CLI: bytes that are not UTF-8,
damaged BROAD files, a log cut mid-line, a log with one enormous line. Each answer is one
line on stderr naming the file, exit code 2, no traceback, nothing half-written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import CATALOGS, RIGS, run_bad

NOT_UTF8 = b"# caf\xe9 \xff\xfe\n"


# --- row 10: a catalog's catalog.toml (and every other TOML file) that is not UTF-8 --------


def test_catalog_toml_not_utf8(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """`optimize` on a catalog whose catalog.toml holds a Latin-1 byte: a traceback."""
    cat = tmp_path / "cat"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    with (cat / "catalog.toml").open("ab") as fh:
        fh.write(NOT_UTF8)
    for argv in (["optimize"], ["pareto"]):  # every sizing command shares the loader
        err = run_bad(capsys, *argv, "--catalog", str(cat))
        assert f"{cat / 'catalog.toml'}: invalid TOML: 'utf-8' codec can't decode" in err


def test_robot_toml_and_csv_not_utf8(tmp_path: Path, fixtures_dir: Path) -> None:
    """The mobile-robot example's robot.toml and batteries.csv read the locale's encoding."""
    from optimizer.cases.robot import load_robot
    from optimizer.errors import CatalogError

    robot = tmp_path / "robot"
    shutil.copytree(CATALOGS / "thesis-robot", robot)
    with (robot / "robot.toml").open("ab") as fh:
        fh.write(NOT_UTF8)
    with pytest.raises(CatalogError, match=r"robot\.toml: not valid TOML"):
        load_robot(robot)
    shutil.copy(CATALOGS / "thesis-robot" / "robot.toml", robot)
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
    assert f"{run / 'run.json'}: not UTF-8 text (at byte offset 0)" in err
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


# --- row 13: a log cut in the middle of its last line -------------------------------------

RCB_HEADER = ("Time (s),ESC signal (µs),Thrust (gf),Voltage (V),Current (A),"
              "Motor Electrical Speed (RPM),App message,")
RCB_ROWS = [f"{0.1 * i:.1f},{1100 + 10 * i},{50 + i},16.0,{1.5 + 0.1 * i:.4f},{3000 + 100 * i},,"
            for i in range(6)]
ESC32_ROWS = ["Timestamp,Amps,Batt. Volts,RPM"] + [
    f"2019-11-05 17:16:0{i}:000,{0.5 + i:.4f},15.8,{1000 * i}" for i in range(6)]


@pytest.mark.parametrize(("fmt", "lines", "cut_after"), [
    ("rcbenchmark", [RCB_HEADER, *RCB_ROWS], "16.0,"),   # cut before the current's cell
    ("esc32", ESC32_ROWS, ",5."),                          # cut inside the current's cell
    ("csv", ["t_s,thrust_n,current_a"] + [f"{0.1 * i:.1f},{i},{1.5 + i}" for i in range(6)],
     "0.5,5"),                                             # a hand-made CSV: fields missing
])
def test_import_drops_a_last_line_cut_mid_write(tmp_path: Path, capsys, fmt: str,
                                                lines: list[str], cut_after: str) -> None:
    """The partial row was imported (current_a = 0.0 from '0.'); now it is dropped and
    the import says so, on screen and in run.json."""
    import pandas as pd

    from bench.cli import main

    whole = "\n".join(lines)
    text = whole[:whole.rindex(cut_after) + len(cut_after)]
    log = tmp_path / "log.csv"
    log.write_text(text, encoding="utf-8")
    out = tmp_path / "run"
    assert main(["import", str(log), "--format", fmt, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert f"dropped line {len(lines)} (" in said and "the file ends inside it" in said
    df = pd.read_parquet(out / "samples.parquet")
    assert len(df) == len(lines) - 2  # the header and the cut line
    meta = json.loads((out / "run.json").read_text())
    assert meta["import"]["cut_last_line"]["line"] == len(lines)
    # the same log whole (with its final line break) keeps every row and says nothing
    log.write_text(whole + "\n", encoding="utf-8")
    assert main(["import", str(log), "--format", fmt, "--out", str(tmp_path / "whole")]) == 0
    assert "dropped" not in capsys.readouterr().out
    assert len(pd.read_parquet(tmp_path / "whole" / "samples.parquet")) == len(lines) - 1


def test_hand_made_csv_without_a_final_line_break_keeps_its_last_row(tmp_path: Path,
                                                                    capsys) -> None:
    """An editor may omit the last line break: a row with every field is kept (only the
    loggers' formats, which end every line, treat a missing break alone as a cut)."""
    import pandas as pd

    from bench.cli import main

    log = tmp_path / "hand.csv"
    log.write_text("t_s,thrust_n\n0,1\n0.1,2", encoding="utf-8")
    assert main(["import", str(log), "--format", "csv", "--out", str(tmp_path / "r")]) == 0
    assert "dropped" not in capsys.readouterr().out
    assert pd.read_parquet(tmp_path / "r" / "samples.parquet")["thrust_n"].tolist() == [1, 2]


def test_a_log_whose_only_row_is_cut(tmp_path: Path, capsys) -> None:
    log = tmp_path / "log.csv"
    log.write_text(RCB_HEADER + "\n" + RCB_ROWS[0][:12], encoding="utf-8")
    err = run_bad(capsys, "import", str(log), "--format", "rcbenchmark", "--out",
                  str(tmp_path / "r"))
    assert "no data rows (the only one, line 2, is cut" in err
    assert not (tmp_path / "r").exists()


# --- row 16: one enormous line ------------------------------------------------------------

BIG = 20_000_000  # the 20 MB line of the report


@pytest.mark.parametrize(("fmt", "text", "expected"), [
    ("csv", "t_s,thrust_n\n0,1\n0.1,{big}\n0.2,3\n",
     "row 3, column 'thrust_n': expected a number, got 'xxxxx"),
    ("csv", "t_s,thrust_n\n0,1\n{big}\n0.2,3\n", "row 3, column 't_s': expected a number"),
    ("rcbenchmark", "t_s,{big}\n0,1\n", "no 'Time (s)' column: not an RCbenchmark log"),
])
def test_import_quotes_a_short_excerpt_of_a_huge_cell(tmp_path: Path, capsys, fmt: str,
                                                     text: str, expected: str) -> None:
    """The error line held the whole 20 MB cell."""
    log = tmp_path / "big.csv"
    log.write_text(text.format(big="x" * BIG))
    err = run_bad(capsys, "import", str(log), "--format", fmt, "--out", str(tmp_path / "r"))
    assert expected in err and f"({BIG} characters)" in err
    assert len(err) < 400


def test_every_error_line_is_capped(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """The net under the readers that quote a value whole: a rig file's 3 MB URL."""
    text = (RIGS / "sim.toml").read_text(encoding="utf-8")
    rig = tmp_path / "rig.toml"
    rig.write_text(text.replace('url = "sim://esc"', f'url = "sim://esc{"z" * 3_000_000}"'),
                   encoding="utf-8")
    err = run_bad(capsys, "step", "--rig", str(rig), "--dry-run")
    assert err.startswith(f"rotorbench: error: {rig}: [devices.esc] url: ")
    assert "characters left out" in err and len(err) < 1100
