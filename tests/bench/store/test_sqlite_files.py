"""The SQLite stores beside the runs and the folders listed: a damaged index or constants
store, or a file where the folder should be, is one line with exit code 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import run_bad


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


@pytest.mark.parametrize("command", ["runs", "constants"])
def test_a_file_given_as_the_folder_to_list_is_refused(tmp_path: Path, capsys,
                                                       command: str) -> None:
    """`runs --out FILE` said "no runs recorded under FILE" with exit 0."""
    afile = tmp_path / "runs.txt"
    afile.write_text("not a folder")
    line = run_bad(capsys, command, "--out", str(afile))
    assert str(afile) in line and "is a file" in line
