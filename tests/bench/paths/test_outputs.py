"""Outputs that cannot be written: every writing command refuses them before any work, in
one line with exit code 2, and leaves nothing behind.

Two kinds of unwritable place: a regular file where a folder must be, and a read-only
folder. Root ignores a folder's mode bits, so as root the folder is made immutable
(``chattr +i``) instead; where neither works the read-only cases are skipped.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from bench.errors import RigError
from bench.paths.outputs import check_writable
from tests.bench.conftest import imported_run
from tests.conftest import run_bad


def _can_write(folder: Path) -> bool:
    try:
        (folder / ".probe").write_text("x")
    except OSError:
        return False
    (folder / ".probe").unlink()
    return True


@contextlib.contextmanager
def unwritable(*folders: Path) -> Iterator[None]:
    """``folders`` nobody may write in for the block (mode 0555, or immutable as root);
    skips the test where neither works."""
    immutable: list[Path] = []
    try:
        for folder in folders:
            folder.chmod(0o555)
            if _can_write(folder):  # root: mode bits do not apply
                if subprocess.run(["chattr", "+i", str(folder)],
                                  capture_output=True).returncode == 0:
                    immutable.append(folder)
            if _can_write(folder):
                pytest.skip("cannot make a read-only folder here (root without chattr)")
        yield
    finally:
        for folder in immutable:
            subprocess.run(["chattr", "-i", str(folder)], check=True)
        for folder in folders:
            folder.chmod(0o755)


@pytest.fixture
def read_only(tmp_path: Path) -> Iterator[Path]:
    """An existing folder nobody may write in (mode 0555, or immutable as root)."""
    folder = tmp_path / "ro"
    folder.mkdir()
    with unwritable(folder):
        yield folder


#: command line with the output at OUT (a folder or file that cannot be created)
Argv = Callable[[Path, Path], list[str]]
COMMANDS: dict[str, Argv] = {
    "report": lambda tmp, out: ["report", str(imported_run(tmp)), "--out", str(out / "rep")],
    "calibrate apply": lambda tmp, out: ["calibrate", "apply", "--cal", str(tmp / "cal.json"),
                                         str(tmp / "imu.csv"), "--out", str(out / "c.csv")],
    "import-sizinglab": lambda tmp, out: ["import-sizinglab", "--source", str(tmp),
                                          "--out", str(out / "cat")],
    "demo": lambda tmp, out: ["demo", "--combos", "1", "--repeats", "1",
                              "--out", str(out / "demo")],
    "calibrate --quick": lambda tmp, out: ["calibrate", "--quick", "--runs", str(out / "runs")],
    "calibrate --out": lambda tmp, out: ["calibrate", "--quick", "--runs", str(tmp / "runs"),
                                         "--out", str(out / "cal.json")],
    "calibrate --simulate-log": lambda tmp, out: ["calibrate", "--simulate-log",
                                                  str(out / "sim.csv"), "--short"],
    "step": lambda tmp, out: ["step", "--repeats", "1", "--out", str(out / "runs")],
    "sweep": lambda tmp, out: ["sweep", "--duration", "1", "--out", str(out)],
    "import": lambda tmp, out: ["import", str(tmp / "stand.csv"), "--format", "csv",
                                "--out", str(out / "run")],
    "attitude": lambda tmp, out: ["attitude", str(tmp / "imu.csv"), "--out", str(out / "q.csv")],
    "constants --add": lambda tmp, out: ["constants", "--out", str(out), "--add",
                                         str(tmp / "run")],
    "runs --rebuild": lambda tmp, out: ["runs", "--out", str(out), "--rebuild"],
}


def _tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.mark.parametrize("name", COMMANDS)
def test_output_below_a_regular_file(tmp_path: Path, capsys, name: str) -> None:
    argv = COMMANDS[name](tmp_path, tmp_path / "notes.txt" / "sub")
    notes = tmp_path / "notes.txt"
    notes.write_text("keep me")
    before = _tree(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, *argv)
    assert "notes.txt is a file, not a folder" in err
    assert notes.read_text() == "keep me"
    assert _tree(tmp_path) == before  # nothing written, no temporary left


@pytest.mark.parametrize("name", COMMANDS)
def test_output_in_a_read_only_folder(tmp_path: Path, capsys, read_only: Path,
                                      name: str) -> None:
    argv = COMMANDS[name](tmp_path, read_only)
    before = _tree(tmp_path)
    capsys.readouterr()
    err = run_bad(capsys, *argv)
    assert f"cannot write in {read_only}" in err
    assert _tree(tmp_path) == before
    assert os.listdir(read_only) == []


def test_a_folder_output_given_as_a_file_and_the_reverse(tmp_path: Path) -> None:
    (tmp_path / "f.txt").write_text("x")
    with pytest.raises(RigError, match=r"--out .*f.txt: is a file; expected a folder"):
        check_writable(tmp_path / "f.txt", "--out", folder=True)
    with pytest.raises(RigError, match="is a folder; expected the name of the file"):
        check_writable(tmp_path, "--out", folder=False)
    with pytest.raises(RigError, match=r"folder .*missing does not exist"):
        check_writable(tmp_path / "missing" / "a.csv", "--out", folder=False,
                       make_parents=False)
    # a new folder several levels down is fine: the command creates the parents
    assert check_writable(tmp_path / "a" / "b" / "c", "--out", folder=True)
    assert not (tmp_path / "a").exists() and not list(tmp_path.glob(".rotorbench-probe*"))
