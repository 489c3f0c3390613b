"""Bad input through the CLI: one line on stderr naming the file, exit code 2, nothing
half-written. Each test is the regression test of a fix found by running the commands."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from tests.conftest import CATALOGS, RIGS, SIZINGLAB


def run_bad(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run the CLI in-process; assert the user-error contract; return the stderr line."""
    code = main(list(argv))
    raw = capsys.readouterr().err
    assert code == 2, raw
    assert raw.count("\n") == 1 and raw.endswith("\n"), repr(raw)  # one line, no blank
    assert raw.startswith("rotorbench: error: "), repr(raw)
    return raw.strip()


# --- rotorbench import ---------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["rcbenchmark", "esc32", "csv"])
def test_import_missing_file_or_folder(tmp_path: Path, capsys, fmt: str) -> None:
    missing = tmp_path / "nope.csv"
    err = run_bad(capsys, "import", str(missing), "--format", fmt, "--out", str(tmp_path / "o"))
    assert "nope.csv: file not found" in err
    err = run_bad(capsys, "import", str(tmp_path), "--format", fmt, "--out",
                  str(tmp_path / "o"))
    assert f"{tmp_path}: not a file" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", ["my run", "..x", "-x", "a" * 129, "é"])
def test_import_out_whose_name_is_not_a_run_id(tmp_path: Path, capsys, name: str) -> None:
    """The folder's name becomes the run's id; one that is not one was refused only
    later, by the web view and `store push`."""
    f = tmp_path / "log.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1,2\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / name))
    assert "is not a run id" in err and "the folder's name (the run's id)" in err
    assert not (tmp_path / name).exists()


def test_import_ragged_csv_is_one_line(tmp_path: Path, capsys) -> None:
    f = tmp_path / "ragged.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1\n0.2,1,5\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / "o"))
    assert "ragged.csv: not a readable CSV" in err and "line 4" in err


def test_import_header_only(tmp_path: Path, capsys) -> None:
    f = tmp_path / "hdr.csv"
    f.write_text("t_s,thrust_n\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / "o"))
    assert "hdr.csv: no data rows" in err
    assert not (tmp_path / "o").exists()


_RCB_ROWS = "".join(f"{0.1 * i:.1f},{1100 + 10 * i},{100 + 5 * i},16.0,{0.5 * i},{900 * i}\n"
                   for i in range(10))


@pytest.mark.parametrize(("fmt", "header", "twice"), [
    # the case met: 'Thrust (gf)' renamed to 'Voltage (V)'; voltage_v took the thrust
    ("rcbenchmark", "Time (s),ESC signal (µs),Voltage (V),Voltage (V),Current (A),"
                    "Motor Electrical Speed (RPM)", "'Voltage (V)' twice (columns 3 and 4)"),
    ("rcbenchmark", "Time (s),ESC signal (µs),Thrust (gf),Voltage (V),Current (A),"
                    "Thrust (N)", "'Thrust (N)' twice (columns 3 and 6)"),
    ("esc32", "Timestamp,Amps,Batt. Volts,Amps,RPM,Duty", "'Amps' twice (columns 2 and 4)"),
    ("csv", "t_s,throttle_us,thrust_n,voltage_v,current_a,thrust_n",
     "'thrust_n' twice (columns 3 and 6)"),
])
def test_import_refuses_a_column_named_twice(tmp_path: Path, capsys, fmt: str, header: str,
                                             twice: str) -> None:
    """pandas renames a repeated header to 'X.1' and the importer took it."""
    f = tmp_path / "log.csv"
    rows = _RCB_ROWS if fmt != "esc32" else "".join(
        f"2019-11-05 17:14:08:{100 * i:03d},{0.5 * i},16.0,0.1,{900 * i},{10 * i}\n"
        for i in range(10))
    f.write_text(header + "\n" + rows, encoding="utf-8")
    err = run_bad(capsys, "import", str(f), "--format", fmt, "--out", str(tmp_path / "o"))
    assert f"log.csv: the header names column {twice}; rename one" in err
    assert not (tmp_path / "o").exists()


def test_sizinglab_import_refuses_a_column_named_twice(tmp_path: Path, capsys,
                                                      shared_data: Path) -> None:
    """The same in the SizingLab importer: a repeated header is refused."""
    import shutil

    src = tmp_path / "sizinglab"
    shutil.copytree(SIZINGLAB, src)
    motors = src / "Motors_Data.csv"
    motors.write_text(motors.read_text(encoding="utf-8").replace("Pole_number", "Kv_rpm_v", 1),
                      encoding="utf-8")
    err = run_bad(capsys, "import-sizinglab", "--source", str(src), "--out", str(tmp_path / "cat"))
    assert "Motors_Data.csv: the header names column 'Kv_rpm_v' twice" in err
    assert not (tmp_path / "cat").exists()


def test_other_tables_refuse_a_column_named_twice(tmp_path: Path, capsys,
                                                  fixtures_dir: Path) -> None:
    """The same in every other reader of a CSV header (catalog tables, a rig's
    thrust map, an IMU log) refuses a repeated name."""
    import shutil

    cat = tmp_path / "thesis-e"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    motors = cat / "motors.csv"
    motors.write_text(motors.read_text(encoding="utf-8").replace(",price,", ",mass_g,", 1),
                      encoding="utf-8")
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert "motors.csv: the header names column 'mass_g' twice" in err

    rig = tmp_path / "rig" / "sim.toml"
    shutil.copytree(RIGS, rig.parent)
    (rig.parent / "sim.thrust_map.csv").write_text("command_us,thrust_n,thrust_n\n"
                                                   "1000,0,1\n2000,8,9\n", encoding="utf-8")
    err = run_bad(capsys, "step", "--rig", str(rig), "--dry-run")
    assert "sim.thrust_map.csv: the header names column 'thrust_n' twice" in err

    log = tmp_path / "imu.csv"
    log.write_text("t_s,gyr_x,gyr_x\n0,1,2\n", encoding="utf-8")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out", str(tmp_path / "c.json"))
    assert "imu.csv: the header names column 'gyr_x' twice" in err


def test_import_map_twice_is_refused(tmp_path: Path, capsys) -> None:
    f = tmp_path / "log.csv"
    f.write_text("a,b\n0,1\n0.1,2\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--map", "t_s=a",
                  "--map", "t_s=b", "--out", str(tmp_path / "o"))
    assert "t_s is mapped twice" in err
    assert not (tmp_path / "o").exists()


def test_import_out_below_a_file(tmp_path: Path, capsys) -> None:
    f = tmp_path / "log.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1,2\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(f / "run"))
    assert "log.csv is a file, not a folder" in err


def test_import_long_time_gap_writes_few_parts(tmp_path: Path, capsys) -> None:
    """A log whose clock jumps by 1e12 s imports (parts only where there are rows)."""
    import pandas as pd

    f = tmp_path / "gap.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.5,1.5\n1e12,2\n")
    assert main(["import", str(f), "--format", "csv", "--out", str(tmp_path / "o")]) == 0
    df = pd.read_parquet(tmp_path / "o" / "samples.parquet")
    assert df["t_s"].tolist() == [0.0, 0.5, 1e12]
    assert len(list((tmp_path / "o" / "samples.parquet").glob("*.parquet"))) == 2


# --- rotorbench report ---------------------------------------------------------------------


def _imported_run(tmp_path: Path) -> Path:
    f = tmp_path / "stand.csv"
    rows = "\n".join(f"{i * 0.1:.1f},{1000 + 10 * i},{0.01 * i * i}" for i in range(40))
    f.write_text("t_s,throttle_us,thrust_n\n" + rows + "\n")
    run = tmp_path / "run"
    assert main(["import", str(f), "--format", "csv", "--out", str(run)]) == 0
    return run


@pytest.mark.parametrize("kind", ["file", "folder"])
def test_report_never_replaces_what_is_not_a_report(tmp_path: Path, capsys, kind: str) -> None:
    """`report --out runs` used to move the whole run root away and delete it."""
    run = _imported_run(tmp_path)
    target = tmp_path / "precious"
    if kind == "file":
        target.write_text("keep me")
    else:
        target.mkdir()
        (target / "data.txt").write_text("keep me")
    capsys.readouterr()
    err = run_bad(capsys, "report", str(run), "--out", str(target))
    assert "precious: exists and is not a report folder" in err
    kept = target if kind == "file" else target / "data.txt"
    assert kept.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["precious", "run", "stand.csv"]


def test_report_replaces_an_earlier_report(tmp_path: Path, capsys) -> None:
    run = _imported_run(tmp_path)
    out = tmp_path / "rep"
    assert main(["report", str(run), "--out", str(out)]) == 0
    first = sorted(p.name for p in out.iterdir())
    (out / "report.json").write_text("{}")  # its own files are replaced
    assert main(["report", str(run), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == first
    assert (out / "report.json").read_text() != "{}"


@pytest.mark.parametrize("manifest", [True, False], ids=["report", "older report"])
def test_report_keeps_the_users_files_in_its_folder(tmp_path: Path, capsys,
                                                     manifest: bool) -> None:
    """A second `report --out rep` deleted rep/NOTES.txt and rep/mydata/."""
    run = _imported_run(tmp_path)
    out = tmp_path / "rep"
    assert main(["report", str(run), "--out", str(out)]) == 0
    if not manifest:  # a report folder written before the manifest existed
        (out / ".rotorbench-files").unlink()
    (out / "NOTES.txt").write_text("mine")
    (out / "mydata").mkdir()
    (out / "mydata" / "x.csv").write_text("1\n")
    capsys.readouterr()
    err = run_bad(capsys, "report", str(run), "--out", str(out))
    assert "holds files `rotorbench report` did not write (NOTES.txt, mydata/)" in err
    assert (out / "NOTES.txt").read_text() == "mine"
    assert (out / "mydata" / "x.csv").read_text() == "1\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep", "run", "stand.csv"]


# --- the SQLite stores beside the runs -----------------------------------------------------


def test_corrupt_run_index_and_constants_store(tmp_path: Path, capsys) -> None:
    (tmp_path / "runs.sqlite").write_bytes(b"\xac\x00 not a database" * 40)
    (tmp_path / "constants.sqlite").write_bytes(b"\xac\x00 not a database" * 40)
    for argv in (["runs", "--out", str(tmp_path)], ["runs", "--out", str(tmp_path), "--rebuild"]):
        err = run_bad(capsys, *argv)
        assert "runs.sqlite: not a readable run index" in err
    err = run_bad(capsys, "constants", "--out", str(tmp_path))
    assert "constants.sqlite: not a readable constants store" in err
    err = run_bad(capsys, "optimize", "--measured", str(tmp_path))
    assert "constants.sqlite: not a readable constants store" in err


def test_step_out_is_a_file(tmp_path: Path, capsys) -> None:
    f = tmp_path / "notes.txt"
    f.write_text("keep me")
    err = run_bad(capsys, "step", "--repeats", "1", "--out", str(f))
    assert "--out" in err and "notes.txt: is a file; expected a folder" in err
    assert f.read_text() == "keep me"


# --- sequences and limits ------------------------------------------------------------------

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


# --- optimize ------------------------------------------------------------------------------


def test_weights_naming_a_metric_twice(capsys) -> None:
    err = run_bad(capsys, "optimize", "--objective", "weighted", "--weights",
                  "price=1,price=2")
    assert "bad weight 'price=2': price is weighted twice" in err


# --- calibrate -----------------------------------------------------------------------------


@pytest.mark.parametrize("flag", ["--gyro-range-dps", "--acc-range-g", "--max-lag"])
def test_calibrate_ranges_must_be_positive(tmp_path: Path, capsys, flag: str) -> None:
    """--gyro-range-dps 0 ended in a ZeroDivisionError after the whole calibration."""
    log = tmp_path / "log.csv"
    log.write_text("t_s\n0\n")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out",
                  str(tmp_path / "cal.json"), flag, "0")
    assert f"{flag}: expected a number > 0, got 0" in err
    assert not (tmp_path / "cal.json").exists()


# --- default outputs stay out of the repository's status ----------------------------------


def test_default_outputs_are_git_ignored(tmp_path: Path) -> None:
    """Run from a checkout, the commands' default outputs (./runs, ./demo-out of `make demo`,
    ./report-<run id>) must not show up as untracked files."""
    import shutil
    import subprocess

    repo = Path(__file__).resolve().parents[1]
    if shutil.which("git") is None or not (repo / ".git").exists():
        pytest.skip("not a git checkout")
    paths = ["runs/x/run.json", "demo-out/tables/x.csv", "report-20260101T000000Z-step1/x.png"]
    proc = subprocess.run(["git", "-C", str(repo), "check-ignore", "--no-index", *paths],
                          capture_output=True, text=True, check=False)
    assert sorted(proc.stdout.split()) == sorted(paths), proc.stderr


# --- attitude ------------------------------------------------------------------------------


def _imu_log(path: Path) -> Path:
    rows = "\n".join(f"{i * 0.01:.2f},0,0,0,0,0,9.81" for i in range(50))
    path.write_text("t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,"
                    "acc_z_m_s2\n" + rows + "\n")
    return path


def test_attitude_negative_bias_seconds(tmp_path: Path, capsys) -> None:
    log = _imu_log(tmp_path / "imu.csv")
    err = run_bad(capsys, "attitude", str(log), "--bias-seconds", "-1")
    assert "--bias-seconds: expected a number of seconds >= 0, got -1" in err


def test_attitude_without_reference_says_how_to_get_the_estimate(tmp_path: Path,
                                                                 capsys) -> None:
    """Without a reference quaternion and without --out the command printed only a header."""
    log = _imu_log(tmp_path / "imu.csv")
    assert main(["attitude", str(log)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "no reference attitude in the log" in out and "--out FILE" in out


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


@pytest.mark.parametrize(("content", "expected"), [
    (b'[rig]\nkind = "imu"\nname = = 1\n', "not valid TOML: Invalid value (at line 3"),
    (b"\xac\x00\xff garbage", "not valid TOML: 'utf-8' codec can't decode"),
])
def test_calibrate_broken_rig_file_is_reported_as_broken(tmp_path: Path, capsys,
                                                         content: bytes, expected: str) -> None:
    """A syntax error was reported as 'not an IMU-bench rig', garbage bytes as a traceback."""
    rig = tmp_path / "imu.toml"
    rig.write_bytes(content)
    err = run_bad(capsys, "calibrate", "--rig", str(rig), "--dry-run")
    assert f"{rig}: {expected}" in err


def test_calibrate_runs_folder_is_a_file(tmp_path: Path, capsys) -> None:
    f = tmp_path / "notes.txt"
    f.write_text("keep me")
    err = run_bad(capsys, "calibrate", "--quick", "--runs", str(f), "--out",
                  str(tmp_path / "cal.json"))
    assert "--runs" in err and "notes.txt: is a file; expected a folder" in err
    assert f.read_text() == "keep me" and not (tmp_path / "cal.json").exists()


# --- export, fit, report, check options ----------------------------------------------------


@pytest.mark.parametrize("value", ["-1", "0", "nan"])
def test_export_hover_thrust_must_be_positive(tmp_path: Path, capsys, value: str) -> None:
    """--hover-thrust -1 printed MOT_THST_HOVER,-0.0842 (with exit code 0)."""
    run = _imported_run(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "export", "ardupilot", str(run), f"--hover-thrust={value}")
    assert "--hover-thrust: expected a thrust per motor > 0 N" in err


@pytest.mark.parametrize("json_flag", [[], ["--json"]], ids=["lines", "json"])
@pytest.mark.parametrize(("auw", "motors", "says"), [
    ("nan", "4", "--auw-kg: expected an all-up weight > 0 kg, got nan"),
    ("inf", "4", "--auw-kg: expected an all-up weight > 0 kg, got inf"),
    ("-1", "4", "--auw-kg: expected an all-up weight > 0 kg, got -1"),
    ("1.2", "0", "--motors: expected a count >= 1, got 0"),
    ("1.2", "-4", "--motors: expected a count >= 1, got -4"),
])
def test_export_auw_and_motors_are_checked(tmp_path: Path, capsys, auw: str, motors: str,
                                           says: str, json_flag: list[str]) -> None:
    """`--auw-kg nan --motors 4` printed MOT_THST_HOVER,nan (exit 0) and, with
    --json, a ValueError traceback."""
    run = _imported_run(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "export", "ardupilot", str(run), f"--auw-kg={auw}",
                  f"--motors={motors}", *json_flag)
    assert says in err


@pytest.mark.parametrize("value", ["0", "-1", "nan"])
def test_fit_window_must_be_positive(tmp_path: Path, capsys, value: str) -> None:
    """--window nan ended in 'cannot convert float NaN to integer'."""
    run = _imported_run(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, "fit", str(run), f"--window={value}")
    assert "--window: expected seconds > 0 after each edge" in err


@pytest.mark.parametrize("value", ["0", "-1", "nan", "1e308"])
def test_check_timeout_must_be_positive(capsys, value: str) -> None:
    err = run_bad(capsys, "check", f"--timeout={value}")
    assert "--timeout: expected seconds > 0 per device" in err


@pytest.mark.parametrize("bad", [("--kv", "nan"), ("--r-ohm", "0"), ("--j-kg-m2", "-1")])
def test_report_motor_parameters_must_be_positive(tmp_path: Path, capsys,
                                                  bad: tuple[str, str]) -> None:
    """--kv nan ended in a ValueError traceback."""
    run = _imported_run(tmp_path)
    capsys.readouterr()
    given = {"--kv": "920", "--r-ohm": "0.1", "--j-kg-m2": "1e-5"} | {bad[0]: bad[1]}
    argv = [x for kv in given.items() for x in kv]
    err = run_bad(capsys, "report", str(run), *argv, "--out", str(tmp_path / "rep"))
    assert f"{bad[0]}: expected a number > 0, got {bad[1]}" in err
    assert not (tmp_path / "rep").exists()
    assert not (tmp_path / ".rep.tmp").exists()


def test_output_named_like_an_existing_folder(tmp_path: Path, capsys) -> None:
    """A folder where the output file should go ended in IsADirectoryError at the rename."""
    log = _imu_log(tmp_path / "imu.csv")
    (tmp_path / "est.parquet").mkdir()
    (tmp_path / "cal.json").mkdir()
    err = run_bad(capsys, "attitude", str(log), "--out", str(tmp_path / "est.parquet"))
    assert "est.parquet: is a folder" in err
    err = run_bad(capsys, "calibrate", "--simulate-log", str(tmp_path / "est.parquet"),
                  "--short")
    assert "est.parquet: is a folder" in err
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out",
                  str(tmp_path / "cal.json"))
    assert "cal.json: is a folder" in err
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--figures", str(log))
    assert "--figures" in err and "imu.csv: is a file; expected a folder" in err
    assert not list(tmp_path.glob(".*"))  # no temp file left behind


def test_negative_limit_is_refused_before_the_run(tmp_path: Path, capsys) -> None:
    """--limit thrust_n=-1 'tightened' the rig and tripped at t = 0 with a recorded run."""
    out = tmp_path / "runs"
    err = run_bad(capsys, "step", "--limit", "thrust_n=-1", "--out", str(out))
    assert "limits.thrust_n: -1 is below 0" in err
    assert not out.exists()


def test_live_without_a_display(tmp_path: Path, capsys, monkeypatch) -> None:
    """Qt aborted the process (exit 134, Qt's text) when no display was there."""
    import sys

    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM"):
        monkeypatch.delenv(var, raising=False)
    out = tmp_path / "runs"
    err = run_bad(capsys, "step", "--live", "--repeats", "1", "--out", str(out))
    assert "--live needs a display" in err
    assert not out.exists()


# --- rig files -----------------------------------------------------------------------------


def test_rig_file_or_thrust_map_with_garbage_bytes(tmp_path: Path, capsys,
                                                   fixtures_dir: Path) -> None:
    """Bytes that are not UTF-8 ended in a UnicodeDecodeError traceback."""
    garbage = b"\xac\x00\xff\xfe garbage"
    rig = tmp_path / "rig.toml"
    rig.write_bytes(garbage)
    for argv in (["step", "--dry-run"], ["check"]):
        err = run_bad(capsys, *argv, "--rig", str(rig))
        assert f"{rig}: not valid TOML: 'utf-8' codec can't decode" in err
    text = (RIGS / "sim.toml").read_text()
    rig.write_text(text)
    (tmp_path / "sim.thrust_map.csv").write_bytes(garbage)
    err = run_bad(capsys, "step", "--dry-run", "--rig", str(rig))
    assert "sim.thrust_map.csv: cannot read thrust map" in err


@pytest.mark.parametrize("command", ["step", "sweep"])
def test_imu_rig_given_to_a_propulsion_command(capsys, fixtures_dir: Path,
                                               command: str) -> None:
    """It said 'hexapod: unknown key; expected one of rig, devices, ...'. (``check``
    checks IMU-bench rigs: tests/bench/test_check_imu_rig.py.)"""
    rig = RIGS / "sim-imu.toml"
    err = run_bad(capsys, command, "--rig", str(rig), "--dry-run")
    assert 'kind = "imu": an IMU-bench rig' in err and "rotorbench calibrate" in err


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


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_fit_multi_rate_run_prints_no_numpy_warning(tmp_path: Path, capsys) -> None:
    """Load-cell rows at 250 Hz interleaved with telemetry rows (thrust empty) at 100 Hz,
    as the sim-can rig records: fit printed 'RuntimeWarning: Mean of empty slice'."""
    import numpy as np

    def command(t):
        return np.where((t >= 1.0) & (np.floor(t) % 2 == 1), 1700.0, 1500.0)

    fine = np.arange(0.0, 12.0, 0.0005)  # first-order lag, 12 ms delay, tau 30 ms
    target = (command(fine - 0.012) - 1000.0) / 250.0
    resp = np.zeros_like(fine)
    for i in range(1, fine.size):
        resp[i] = resp[i - 1] + (target[i] - resp[i - 1]) * (1 - np.exp(-0.0005 / 0.03))
    cell = np.arange(0.0, 12.0, 0.004)
    tele = np.arange(0.0013, 12.0, 0.01)
    rows = [(a, command(a), f"{np.interp(a, fine, resp):.5f}", "") for a in cell]
    rows += [(a, command(a), "", "5000") for a in tele]
    f = tmp_path / "mixed.csv"
    f.write_text("t_s,throttle_us,thrust_n,rpm\n" + "\n".join(
        f"{a:.4f},{u},{y},{r}" for a, u, y, r in sorted(rows)) + "\n")
    assert main(["import", str(f), "--format", "csv", "--out", str(tmp_path / "run")]) == 0
    assert main(["fit", str(tmp_path / "run"), "--json"]) == 0
    assert "Warning" not in capsys.readouterr().err


def test_check_rig_mixing_sim_and_hardware(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """check listed each sim device as FAIL 'unknown device URL scheme 'sim''; step said
    what is wrong. Both now say it in one line."""
    text = (RIGS / "sim.toml").read_text()
    rig = tmp_path / "mixed.toml"
    rig.write_text(text.replace('url = "sim://power"', 'url = "nidaq://Dev1/ai1,ai2"'))
    (tmp_path / "sim.thrust_map.csv").write_text(
        (RIGS / "sim.thrust_map.csv").read_text())
    for argv in (["check"], ["step", "--repeats", "1", "--out", str(tmp_path / "runs")]):
        err = run_bad(capsys, *argv, "--rig", str(rig))
        assert "[devices.esc] url 'sim://esc': sim:// devices run on the simulated clock" in err


def test_catalog_with_semicolons_says_so(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """A spreadsheet export with ';' listed every column as missing and nothing else."""
    import shutil

    cat = tmp_path / "cat"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    motors = cat / "motors.csv"
    motors.write_text(motors.read_text().replace(",", ";"))
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert "motors.csv: missing column 'id'" in err
    assert "the header is one field: columns must be separated by commas" in err


def test_logs_with_semicolons_or_ragged_rows(tmp_path: Path, capsys) -> None:
    """A ';'-separated log said only 'no time column'; a ragged row gave two lines.
    (``import`` reads a ';'-separated log: tests/test_cli_messages.py.)"""
    semi = tmp_path / "semi.csv"
    semi.write_text("t_s;thrust_n\n0;1\n0.1;2\n")
    err = run_bad(capsys, "attitude", str(semi))
    assert "semi.csv: the header is one field" in err
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("t_s,gyro_x_rad_s\n0,1\n0.1\n0.2,1,5\n")
    err = run_bad(capsys, "attitude", str(ragged))
    assert "ragged.csv: cannot be read as csv" in err and "line 4" in err


def test_import_infinite_value(tmp_path: Path, capsys) -> None:
    f = tmp_path / "inf.csv"
    f.write_text("t_s,thrust_n\n0,1\n0.1,inf\n")
    err = run_bad(capsys, "import", str(f), "--format", "csv", "--out", str(tmp_path / "o"))
    assert "inf.csv: row 3, column 'thrust_n': expected a finite number" in err
    assert not (tmp_path / "o").exists()


def test_catalog_by_shipped_name_and_bad_environment(tmp_path: Path, capsys,
                                                     monkeypatch) -> None:
    """`--catalog thesis-d` (the README names the shipped catalogs) was 'not a catalog
    folder' outside the source tree; a wrong ROTORBENCH_CATALOG blamed the install."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("ROTORBENCH_CATALOG", raising=False)
    assert main(["evaluate", "--catalog", "thesis-d", "--actuators", "4", "--propeller", "P1",
                 "--motor", "M1", "--battery", "B1", "--json"]) == 0
    assert "thesis-d" in capsys.readouterr().out
    monkeypatch.setenv("ROTORBENCH_CATALOG", "nosuch")
    err = run_bad(capsys, "optimize")
    assert "ROTORBENCH_CATALOG=nosuch: not a catalog folder or a shipped catalog name" in err


def test_robot_example_given_as_a_catalog(capsys, fixtures_dir: Path) -> None:
    """It said only 'missing file propellers.csv'."""
    err = run_bad(capsys, "optimize", "--catalog", str(CATALOGS / "thesis-robot"))
    assert "mobile-robot example (robot.toml), not a multirotor catalog" in err


@pytest.mark.parametrize("value", ["-1", "0", "nan", "1e308"])  # 1e308 overflowed time_t
def test_devices_can_timeout_must_be_positive(capsys, value: str) -> None:
    err = run_bad(capsys, "devices", f"--can-timeout={value}")
    assert "--can-timeout: expected seconds > 0" in err


def test_replay_file_that_is_not_a_recording(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    """Garbage bytes said 'This file contains pickled (object) data ... allow_pickle='."""
    text = (RIGS / "sim.toml").read_text()
    rec = tmp_path / "rec.npz"
    rec.write_bytes(b"\xac\x00 garbage" * 20)
    rig = tmp_path / "replay.toml"
    rig.write_text(text.replace('url = "sim://load_cell"', f'url = "replay://{rec}"'))
    (tmp_path / "sim.thrust_map.csv").write_text(
        (RIGS / "sim.thrust_map.csv").read_text())
    err = run_bad(capsys, "check", "--rig", str(rig))
    assert "rec.npz: not a NumPy .npz file (expected an .npz recording" in err
    assert "pickle" not in err
    rec.unlink()
    err = run_bad(capsys, "check", "--rig", str(rig))
    assert "rec.npz not found" in err


SIZING_PLOTS = {
    "evaluate": ["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1",
                 "--battery", "B3"],
    "pareto": ["pareto", "--actuators", "4", "--x", "flight-time", "--y", "time-constant"],
}


@pytest.mark.parametrize("command", sorted(SIZING_PLOTS))
@pytest.mark.parametrize(("name", "expected"), [
    ("in-a-file/x.png", "is a file, not a folder"),  # a file where the folder must be
    ("folder", "expected a file name ending in"),  # would silently become folder.png
    ("bare", "expected a file name ending in"),
    ("table.txt", "expected a file name ending in"),  # matplotlib failed after the work
])
def test_sizing_plot_path_is_checked_before_the_work(tmp_path: Path, capsys, command: str,
                                                     name: str, expected: str) -> None:
    (tmp_path / "in-a-file").write_text("x")
    (tmp_path / "folder").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main([*SIZING_PLOTS[command], "--plot", str(tmp_path / name)])
    err = capsys.readouterr().err
    assert code == 2 and expected in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


@pytest.mark.parametrize("command", sorted(SIZING_PLOTS))
def test_sizing_plot_writes_a_new_folder_and_file(tmp_path: Path, capsys, command: str) -> None:
    out = tmp_path / "new" / "figure.png"
    assert main([*SIZING_PLOTS[command], "--plot", str(out)]) == 0
    capsys.readouterr()
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --- found by the careless-input hunt (negative seeds, --save, same-path outputs, ...) ------


@pytest.mark.parametrize("argv", [
    ["step", "--repeats", "1"], ["sweep", "--duration", "1"], ["demo"],
    ["calibrate", "--simulate-log", "x.csv", "--short"], ["console", "--selftest"],
])
def test_negative_seed_is_refused_when_parsed(tmp_path: Path, capsys, monkeypatch,
                                              argv: list[str]) -> None:
    """--seed -1 ended in numpy's 'ValueError: expected non-negative integer' traceback."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--seed", "-1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "argument --seed: expected a whole number >= 0, got '-1'" in err
    assert "Traceback" not in err and list(tmp_path.iterdir()) == []


def test_check_deep_save_is_checked_before_listening(tmp_path: Path, capsys,
                                                     fixtures_dir: Path) -> None:
    """A folder, a path below a file or the rig itself as --save were tracebacks (or
    replaced the rig file) after the listening."""
    rig = tmp_path / "rig.toml"
    rig.write_text((RIGS / "sim.toml").read_text())
    (tmp_path / "sim.thrust_map.csv").write_text(
        (RIGS / "sim.thrust_map.csv").read_text())
    (tmp_path / "folder").mkdir()
    base = ["check", "--rig", str(rig), "--deep", "--seconds", "0.2", "--save"]
    err = run_bad(capsys, *base, str(tmp_path / "folder"))
    assert "--save" in err and "is a folder; expected the name of the file" in err
    err = run_bad(capsys, *base, str(rig / "report.json"))
    assert "rig.toml is a file, not a folder" in err
    text = rig.read_text()
    err = run_bad(capsys, *base, str(rig))
    assert "is also an input" in err and rig.read_text() == text
    err = run_bad(capsys, "check", "--rig", str(rig), "--save", str(tmp_path / "r.json"))
    assert "--save: only applies with --deep" in err


def test_output_that_is_the_input_is_refused(tmp_path: Path, capsys) -> None:
    """calibrate apply --out LOG LOG replaced the log with its corrected copy (exit 0)."""
    log = _imu_log(tmp_path / "imu.csv")
    text = log.read_text()
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    err = run_bad(capsys, "calibrate", "apply", "--cal", str(cal), "--out", str(log), str(log))
    assert f"--out {log}: is also an input" in err
    err = run_bad(capsys, "calibrate", "apply", "--cal", str(cal), "--out",
                  str(tmp_path / ".." / tmp_path.name / "cal.json"), str(log))
    assert "is also an input" in err
    err = run_bad(capsys, "attitude", str(log), "--out", str(log))
    assert "is also an input" in err
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--out", str(log))
    assert "is also an input" in err
    assert log.read_text() == text and cal.read_text() == "{}"


@pytest.mark.parametrize("angles", [["nan", "0", "0"], ["0", "inf", "0"]])
def test_calibrate_mounting_angles_must_be_finite(tmp_path: Path, capsys,
                                                  angles: list[str]) -> None:
    """nan ended in scipy's 'Found zero norm quaternions in `quat`' traceback."""
    log = _imu_log(tmp_path / "imu.csv")
    err = run_bad(capsys, "calibrate", "--from-log", str(log), "--mounting-deg", *angles)
    assert "--mounting-deg: expected three finite angles in degrees" in err


@pytest.mark.parametrize(("extra", "expected"), [
    (["--window", "nan"], "--window nan: expected 0 < seconds <= 60"),  # NaN to integer
    (["--selftest", "--min-fps", "inf"], "--min-fps inf: expected a refresh rate"),
    (["--selftest", "--min-fps", "-1"], "--min-fps -1: expected a refresh rate"),
    (["--selftest", "--screenshot", "shot.txt"], "expected a file name ending in .png"),
    (["--selftest", "--screenshot", "afile/shot.png"], "afile is a file, not a folder"),
    (["--selftest", "--out", "afile"], "--out afile: is a file; expected a folder"),
    (["--min-fps", "3"], "--min-fps: only applies with --selftest"),  # opened the window
    (["--screenshot", "shot.png"], "--screenshot: only applies with --selftest"),
])
def test_console_options_are_checked_before_the_window(tmp_path: Path, capsys, monkeypatch,
                                                       extra: list[str],
                                                       expected: str) -> None:
    """The self-test reported bad paths as FAIL (exit 1) after running the rig."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("x")
    err = run_bad(capsys, "console", *extra)
    assert expected in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


@pytest.mark.parametrize(("flag", "value", "expected"), [
    ("--prop-diameter-m", "-1", "--prop-diameter-m: expected a number > 0"),  # complex mass
    ("--prop-ct", "1e308", "--prop-ct: expected a number <= 1e+09"),  # ZeroDivisionError
    ("--battery-cells", "1e308", "--battery-cells: expected a number <= 1e+09"),
])
def test_free_form_numbers_out_of_range(capsys, flag: str, value: str, expected: str) -> None:
    parts = {"--prop-diameter-m": "0.2", "--prop-ct": "0.1", "--prop-cp": "0.05",
             "--motor-kv": "900", "--motor-resistance": "0.1", "--motor-mass-g": "50",
             "--battery-cells": "3", "--battery-mah": "2200", "--battery-mass-g": "180"}
    parts[flag] = value
    argv = [x for kv in parts.items() for x in kv]
    err = run_bad(capsys, "evaluate", "--actuators", "4", *argv)
    assert expected in err


def test_catalog_cell_beyond_1e9_is_refused(tmp_path: Path, capsys, fixtures_dir: Path) -> None:
    import shutil

    cat = tmp_path / "cat"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    lines = (cat / "propellers.csv").read_text().splitlines()
    header = lines[0].split(",")
    row = lines[1].split(",")
    row[header.index("ct")] = "1e308"
    (cat / "propellers.csv").write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n")
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert "propellers.csv" in err and "column 'ct': expected a number <= 1e+09" in err


def test_demo_repeats_beyond_the_cap_is_refused(tmp_path: Path, capsys) -> None:
    """--repeats 1000000 ran for days without a word."""
    err = run_bad(capsys, "demo", "--out", str(tmp_path / "d"), "--repeats", "1000000")
    assert "--repeats: expected a count from 1 to 100" in err
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("command", ["runs", "constants"])
def test_a_file_given_as_the_folder_to_list_is_refused(tmp_path: Path, capsys,
                                                       command: str) -> None:
    """`runs --out FILE` said "no runs recorded under FILE" with exit 0."""
    afile = tmp_path / "runs.txt"
    afile.write_text("not a folder")
    line = run_bad(capsys, command, "--out", str(afile))
    assert str(afile) in line and "is a file" in line


@pytest.mark.parametrize("command", [
    ["optimize", "--actuators", "4"],
    ["pareto", "--actuators", "4", "--x", "flight-time", "--y", "price"],
    ["evaluate", "--actuators", "4", "--propeller", "P4", "--motor", "M1", "--battery", "B3"],
])
def test_absurd_payload_is_refused_without_numpy_warnings(capsys, command: list[str]) -> None:
    """1e308 kg passed as finite and overflowed numpy (RuntimeWarning lines, then exit 3)."""
    line = run_bad(capsys, *command, "--payload-kg", "1e308")
    assert "payload" in line and "10000" in line


# --- input paths that are not files: a symlink loop, a device, a FIFO ---------------------


_LOOP_ARGV = [  # every command with an input path; LOOP is replaced by the looping link
    ["step", "--rig", "LOOP", "--dry-run"], ["sweep", "--rig", "LOOP", "--dry-run"],
    ["check", "--rig", "LOOP"], ["calibrate", "--rig", "LOOP", "--dry-run"],
    ["console", "--rig", "LOOP", "--selftest"], ["step", "--sequence", "LOOP", "--dry-run"],
    ["fit", "LOOP"], ["report", "LOOP"], ["export", "ardupilot", "LOOP"],
    ["constants", "--add", "LOOP"], ["import", "LOOP", "--format", "csv", "--out", "o"],
    ["decode", "--protocol", "msp", "LOOP"], ["attitude", "LOOP"],
    ["calibrate", "--from-log", "LOOP", "--out", "c.json"],
    ["optimize", "--catalog", "LOOP"], ["optimize", "--measured", "LOOP"],
    ["import-sizinglab", "--source", "LOOP", "--out", "q"],
    # folders a command lists: a loop read as an empty folder ("no runs", exit 0)
    ["runs", "--out", "LOOP"], ["constants", "--out", "LOOP"],
    ["store", "push", "LOOP", "--store", "postgresql://127.0.0.1:1/lab"],
]


@pytest.mark.parametrize("argv", _LOOP_ARGV, ids=lambda a: " ".join(a[:2]))
def test_a_symlink_loop_as_input_is_one_line(tmp_path: Path, capsys, monkeypatch,
                                             argv: list[str]) -> None:
    """A rig file that is a symlink loop gave a RuntimeError traceback from
    Path.resolve (and 'not found' elsewhere: exists() is False for a loop)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a").symlink_to("b")
    (tmp_path / "b").symlink_to("a")
    argv = [a.replace("LOOP", "a") for a in argv]
    err = run_bad(capsys, *argv)
    assert "a: a loop of symbolic links" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]  # nothing written


def test_a_rigs_thrust_map_that_loops_is_one_line(tmp_path: Path, capsys,
                                                  fixtures_dir: Path) -> None:
    rig = tmp_path / "sim.toml"
    rig.write_text((RIGS / "sim.toml").read_text(encoding="utf-8"))
    map_link = tmp_path / "sim.thrust_map.csv"
    map_link.symlink_to(map_link.name)
    err = run_bad(capsys, "step", "--rig", str(rig), "--dry-run")
    assert "thrust map" in err and "a loop of symbolic links" in err


@pytest.mark.parametrize("argv", [
    ["decode", "--protocol", "msp", "SPECIAL"], ["decode", "--protocol", "gcs", "SPECIAL"],
    ["decode", "--protocol", "vesc-can", "SPECIAL"],
    ["import", "SPECIAL", "--format", "rcbenchmark", "--out", "o"],
    ["calibrate", "--from-log", "SPECIAL", "--out", "c.json"],
    ["step", "--rig", "SPECIAL", "--dry-run"], ["step", "--sequence", "SPECIAL", "--dry-run"],
], ids=lambda a: " ".join(a[:3]))
@pytest.mark.parametrize("special", ["/dev/zero", "fifo"])
def test_a_device_or_fifo_as_input_is_refused(tmp_path: Path, capsys, monkeypatch,
                                              argv: list[str], special: str) -> None:
    """`decode --protocol msp /dev/zero` read 18 GB in 20 s (a FIFO blocks
    forever): a path that is not a regular file is refused before it is opened."""
    import os

    monkeypatch.chdir(tmp_path)
    if special == "fifo":
        os.mkfifo(tmp_path / "fifo")
    argv = [a.replace("SPECIAL", special) for a in argv]
    err = run_bad(capsys, *argv)
    kind = "a character device" if special == "/dev/zero" else "a FIFO (named pipe)"
    assert f"{special}: is {kind}, not a regular file; save the data to a file" in err


@pytest.mark.parametrize(("name", "kind", "says"), [
    ("catalog.toml", "loop", "catalog.toml: cannot read: Too many levels of symbolic links"),
    ("catalog.toml", "fifo", "catalog.toml: not a regular file"),
    ("motors.csv", "loop", "motors.csv: a symbolic link that leads nowhere"),
    ("motors.csv", "fifo", "motors.csv: not a regular file"),
])
def test_a_catalog_file_that_loops_or_blocks(tmp_path: Path, capsys, fixtures_dir: Path,
                                            name: str, kind: str, says: str) -> None:
    """Row 9's sibling inside a catalog folder: a looping catalog.toml was taken as absent
    (the default constants, silently), a looping table as 'missing'; a FIFO blocked."""
    import os
    import shutil

    cat = tmp_path / "cat"
    shutil.copytree(CATALOGS / "thesis-e", cat)
    (cat / name).unlink()
    if kind == "loop":
        (cat / name).symlink_to(name)
    else:
        os.mkfifo(cat / name)
    err = run_bad(capsys, "optimize", "--catalog", str(cat))
    assert says in err


@pytest.mark.parametrize("command", [["fit"], ["report"], ["export", "ardupilot"],
                                     ["constants", "--add"]])
def test_a_run_json_that_is_a_fifo_is_refused(tmp_path: Path, capsys,
                                              command: list[str]) -> None:
    """Row 5's sibling inside a run folder: a FIFO as run.json blocked every reader."""
    import os

    run = _imported_run(tmp_path)
    (run / "run.json").unlink()
    os.mkfifo(run / "run.json")
    capsys.readouterr()
    err = run_bad(capsys, *command, str(run))
    assert f"{run / 'run.json'}: not a regular file" in err
