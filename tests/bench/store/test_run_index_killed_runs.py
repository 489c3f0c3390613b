"""A run whose process died (kill -9, power loss) is marked killed in its run.json when the
store (the run index) is next opened, with the last sample time on disk; a live run and a
finished run are left alone."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from analysis.run_record import read_run
from bench.engine.recorder import RunRecorder
from bench.store.run_index import RunIndex

DIES = """
import os, sys
from pathlib import Path
import numpy as np
from bench.engine.recorder import RunRecorder
from bench.store.run_index import RunIndex

root = Path(sys.argv[1])
rec = RunRecorder(root / "dead", {"id": "dead", "sequence": {"name": "step1"}})
t = np.arange(0.0, 2.5, 0.001)
rec.append({"t_s": t, **{c: np.zeros(t.size) for c in rec.base_columns if c != "t_s"}})
RunIndex(root).upsert(rec.meta, root / "dead")
os._exit(0)  # dies like kill -9: no finish, 2.0-2.5 s never written
"""


def _run_that_dies(root) -> None:
    repo = Path(__file__).resolve().parents[3]
    subprocess.run([sys.executable, "-c", DIES, str(root)], check=True, cwd=repo,
                   env={**os.environ, "PYTHONPATH": str(repo)}, timeout=120)


def _run(root, name, seconds):
    rec = RunRecorder(root / name, {"id": name, "sequence": {"name": "step1"}})
    t = np.arange(0.0, seconds, 0.001)
    rec.append({"t_s": t, **{c: np.zeros(t.size) for c in rec.base_columns if c != "t_s"}})
    RunIndex(root).upsert(rec.meta, root / name)
    return rec


def test_store_open_marks_a_dead_run_killed_in_run_json(tmp_path):
    root = tmp_path / "runs"
    _run_that_dies(root)  # parts of 0-1 s and 1-2 s on disk, 2-2.5 s were buffered
    assert json.loads((root / "dead" / "run.json").read_text())["status"] == "running"
    live = _run(root, "live", 1.5)  # this process: alive
    done = _run(root, "done", 1.5)
    done.finish("success", "")
    RunIndex(root).upsert(done.meta, root / "done")

    index = RunIndex(root)  # opening the store
    marked = json.loads((root / "dead" / "run.json").read_text())
    assert marked["status"] == "killed" and "kill -9" in marked["reason"]
    assert marked["last_sample_t_s"] == 1.999 and marked["rows"] == 2000
    assert read_run(root / "dead").meta["status"] == "killed"  # analysis sees the same
    rows = {r.id: r for r in index.list()}
    assert rows["dead"].status == "killed" and rows["dead"].reason == marked["reason"]
    assert json.loads((root / "live" / "run.json").read_text())["status"] == "running"
    assert rows["live"].status == "running"
    assert rows["done"].status == "success"
    assert index.mark_killed() == []  # once marked, never again
    live.finish("success", "")
