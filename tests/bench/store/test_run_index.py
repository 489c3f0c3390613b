"""The folder store's index: a damaged or hand-edited run.json lists as a row, never a
traceback; a reader that must not write sees a dead run as killed without marking it;
a row cannot name a folder outside the store."""

from __future__ import annotations

import json
import socket
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cli import main
from bench.errors import RigError
from bench.store.run_index import INDEX_NAME, RunIndex
from bench.store.stores import FolderStore


@pytest.fixture
def root(tmp_path: Path) -> Path:
    """A folder store holding one small imported run, indexed."""
    root = tmp_path / "runs"
    log = tmp_path / "stand.csv"
    log.write_text("t_s,throttle_us,thrust_n\n0,1000,0\n0.1,1100,0.5\n0.2,1200,1\n")
    assert main(["import", str(log), "--format", "csv", "--out", str(root / "good")]) == 0
    assert main(["runs", "--rebuild", "--out", str(root)]) == 0
    return root


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.mark.parametrize("text", ["[1, 2]", '"a string"', "3", "null",
                                  '{"dropped_samples": 3, "longest_gap_s": "long"}',
                                  '{"dropped_samples": "many", "link_errors": [1]}',
                                  '{"rows": "lots", "operator": 5}', "not json", ""])
@pytest.mark.parametrize("listing", [[], ["--json"], ["--status", "success"]])
def test_a_run_json_of_any_shape_lists_without_a_traceback(
        root: Path, capsys: pytest.CaptureFixture[str], text: str, listing: list[str]) -> None:
    (root / "good" / "run.json").write_text(text)
    capsys.readouterr()
    assert main(["runs", "--out", str(root), *listing]) == 0
    out, err = capsys.readouterr()
    assert "good" in out and "Traceback" not in out + err


@pytest.mark.parametrize("meta", [{"started_utc": {"a": 1}}, {"status": ["x"]},
                                  {"pid": "12"}, {"host": 5, "reason": None},
                                  {"rig": ["x"], "sequence": 3, "components": "motor"}])
def test_rebuild_stores_fields_of_the_wrong_type(root: Path, meta: dict,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = root / "good" / "run.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), **meta}))
    assert main(["runs", "--rebuild", "--out", str(root)]) == 0
    assert [r.id for r in RunIndex(root).list()] == ["good"]


def _killed_run(root: Path) -> Path:
    """The run as a process that died (kill -9) left it: running, its pid gone."""
    run = root / "good"
    meta = json.loads((run / "run.json").read_text())
    meta.update(status="running", pid=_dead_pid(), host=socket.gethostname(), ended_utc=None)
    (run / "run.json").write_text(json.dumps(meta))
    with sqlite3.connect(root / INDEX_NAME) as con:
        con.execute("UPDATE runs SET status = 'running', host = ?, pid = ? WHERE id = 'good'",
                    (meta["host"], meta["pid"]))
    return run


def _stamp(path: Path) -> tuple[bytes, int]:
    return path.read_bytes(), path.stat().st_mtime_ns


def test_read_only_reports_a_dead_run_killed_and_writes_nothing(root: Path) -> None:
    run = _killed_run(root)
    before = [_stamp(run / "run.json"), _stamp(root / INDEX_NAME), sorted(root.rglob("*"))]
    store = FolderStore(root, read_only=True)
    (row,) = store.list_runs()
    assert row.status == "killed" and "gone" in row.reason
    assert store.count_runs() == 1 and store.run_folder("good") == run
    assert RunIndex(root, read_only=True).select()[0].status == "killed"
    assert [_stamp(run / "run.json"), _stamp(root / INDEX_NAME),
            sorted(root.rglob("*"))] == before
    (row,) = FolderStore(root).list_runs()  # a command marks it, as documented
    assert row.status == "killed"
    assert json.loads((run / "run.json").read_text())["status"] == "killed"


@pytest.mark.parametrize("path", ["../outside", "/etc", "good/../../outside", "a\\..\\b"])
def test_an_index_row_cannot_name_a_folder_outside_the_store(root: Path, tmp_path: Path,
                                                             path: str) -> None:
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "run.json").write_text('{"id": "evil", "operator": "SECRET"}')
    with sqlite3.connect(root / INDEX_NAME) as con:
        con.execute("INSERT INTO runs (id, path, status) VALUES ('evil', ?, 'success')",
                    (path,))
    with pytest.raises(RigError, match="is not a file name inside the run folder"):
        RunIndex(root).path_of("evil")
    for store in (FolderStore(root), FolderStore(root, read_only=True)):
        with pytest.raises(RigError):
            store.run_folder("evil")
        rows = {r.run_id: r for r in store.list_runs()}
        assert rows["evil"].data == "" and rows["evil"].operator == ""
