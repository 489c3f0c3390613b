"""`rotorbench report`: it replaces only a report folder, and refuses bad motor numbers."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.cli import main
from tests.bench.conftest import imported_run
from tests.conftest import run_bad


@pytest.mark.parametrize("kind", ["file", "folder"])
def test_report_never_replaces_what_is_not_a_report(tmp_path: Path, capsys, kind: str) -> None:
    """`report --out runs` used to move the whole run root away and delete it."""
    run = imported_run(tmp_path)
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
    run = imported_run(tmp_path)
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
    run = imported_run(tmp_path)
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


@pytest.mark.parametrize("bad", [("--kv", "nan"), ("--r-ohm", "0"), ("--j-kg-m2", "-1")])
def test_report_motor_parameters_must_be_positive(tmp_path: Path, capsys,
                                                  bad: tuple[str, str]) -> None:
    """--kv nan ended in a ValueError traceback."""
    run = imported_run(tmp_path)
    capsys.readouterr()
    given = {"--kv": "920", "--r-ohm": "0.1", "--j-kg-m2": "1e-5"} | {bad[0]: bad[1]}
    argv = [x for kv in given.items() for x in kv]
    err = run_bad(capsys, "report", str(run), *argv, "--out", str(tmp_path / "rep"))
    assert f"{bad[0]}: expected a number > 0, got {bad[1]}" in err
    assert not (tmp_path / "rep").exists()
    assert not (tmp_path / ".rep.tmp").exists()
