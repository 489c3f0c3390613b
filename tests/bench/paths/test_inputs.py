"""Input paths that are not files (bench.paths.inputs): a symlink loop, a device, a FIFO,
refused in one line before any read."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.bench.conftest import imported_run
from tests.conftest import CATALOGS, RIGS, run_bad

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

    run = imported_run(tmp_path)
    (run / "run.json").unlink()
    os.mkfifo(run / "run.json")
    capsys.readouterr()
    err = run_bad(capsys, *command, str(run))
    assert f"{run / 'run.json'}: not a regular file" in err
