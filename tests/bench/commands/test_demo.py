"""``rotorbench demo --out``: only a previous demo's output is ever replaced."""

from __future__ import annotations

import os

import pytest

from bench.cli import main
from bench.commands.demo import MARKER


def _snapshot(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("kind", ["user folder", "cwd", "file", "empty folder"])
def test_refuses_what_a_demo_did_not_write(tmp_path, capsys, monkeypatch, kind):
    target = tmp_path / "mine"
    if kind == "file":
        target.write_text("keep me", encoding="utf-8")
    else:
        target.mkdir()
        if kind != "empty folder":
            (target / "notes.txt").write_text("keep me", encoding="utf-8")
            (target / "sub").mkdir()
            (target / "sub" / "data.csv").write_text("1,2\n", encoding="utf-8")
    arg = str(target)
    if kind == "cwd":
        monkeypatch.chdir(target)
        arg = "."
    before = _snapshot(tmp_path)
    assert main(["demo", "--out", arg, "--combos", "1", "--repeats", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rotorbench: error: --out ") and len(err.strip().splitlines()) == 1
    assert ("not written by `rotorbench demo`" in err) or ("not a folder" in err)
    assert _snapshot(tmp_path) == before  # nothing deleted, no temporary folder left


def test_refuses_to_replace_the_folder_it_runs_in(tmp_path, capsys, monkeypatch):
    old = tmp_path / "demo-out"
    old.mkdir()
    (old / MARKER).write_text("rotorbench demo output\n", encoding="utf-8")
    monkeypatch.chdir(old)
    assert main(["demo", "--out", ".", "--combos", "1", "--repeats", "1"]) == 2
    assert "current folder" in capsys.readouterr().err
    assert (old / MARKER).is_file()


def test_replaces_a_previous_demo_output(tmp_path, capsys):
    out = tmp_path / "demo-out"
    out.mkdir()
    (out / MARKER).write_text("rotorbench demo output\n", encoding="utf-8")
    (out / "tables").mkdir()
    (out / "tables" / "stale.csv").write_text("from the last run", encoding="utf-8")
    keep = tmp_path / "neighbour.txt"
    keep.write_text("not the demo's", encoding="utf-8")
    assert main(["demo", "--out", str(out), "--combos", "1", "--repeats", "2"]) == 0
    capsys.readouterr()
    assert not (out / "tables" / "stale.csv").exists()
    assert (out / MARKER).is_file() and (out / "demo.json").is_file()
    assert (out / "tables" / "designs.csv").is_file()
    assert keep.read_text(encoding="utf-8") == "not the demo's"
    assert sorted(os.listdir(tmp_path)) == ["demo-out", "neighbour.txt"]  # no temp folders
    # a file and a folder of the user's in the demo output are not deleted
    (out / "NOTES.txt").write_text("mine", encoding="utf-8")
    (out / "figures" / "mydata").mkdir()
    before = _snapshot(tmp_path)
    assert main(["demo", "--out", str(out), "--combos", "1", "--repeats", "1"]) == 2
    err = capsys.readouterr().err
    assert "did not write (NOTES.txt, figures/mydata/)" in err, err
    assert _snapshot(tmp_path) == before


def test_keeps_a_users_file_in_an_older_demo_output(tmp_path, capsys):
    """A demo folder from before the manifest: only the demo's own top-level names."""
    out = tmp_path / "demo-out"
    out.mkdir()
    (out / MARKER).write_text("rotorbench demo output\n", encoding="utf-8")
    (out / "NOTES.txt").write_text("mine", encoding="utf-8")
    before = _snapshot(tmp_path)
    assert main(["demo", "--out", str(out), "--combos", "1", "--repeats", "1"]) == 2
    assert "did not write (NOTES.txt)" in capsys.readouterr().err
    assert _snapshot(tmp_path) == before
