"""Run folders: chunked Parquet parts (complete or absent), events, atomic run.json, index."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.run.recorder import BASE_COLUMNS, SAMPLES_DIR, RunRecorder
from bench.store.run_index import RunIndex


def rows(t):
    n = len(t)
    ones = {c: np.full(n, 1.0) for c in BASE_COLUMNS[1:]}
    return {"t_s": t, **ones, "step": np.zeros(n, np.int32)}


def test_parts_hold_at_most_one_second_and_nothing_is_lost(tmp_path):
    rec = RunRecorder(tmp_path / "r", {"note": "x"})
    t = np.arange(0, 3.7, 1 / 1000.0)
    for chunk in np.array_split(t, 37):
        rec.append(rows(chunk))
    meta = rec.finish("success", "done")
    parts = sorted((tmp_path / "r" / SAMPLES_DIR).glob("part-*.parquet"))
    assert len(parts) == 4 and meta["parts"] == 4 and meta["rows"] == len(t)
    for p in parts:
        tp = pd.read_parquet(p)["t_s"]
        assert tp.iloc[-1] - tp.iloc[0] < 1.0
    df = pd.read_parquet(tmp_path / "r" / SAMPLES_DIR)
    np.testing.assert_array_equal(df["t_s"].to_numpy(), t)
    assert list(df.columns[:7]) == list(BASE_COLUMNS)


@settings(max_examples=25, deadline=None)
@given(sizes=st.lists(st.integers(1, 3000), min_size=1, max_size=30),
       chunk=st.sampled_from([0.1, 0.5, 1.0]))
def test_any_block_sizes_give_the_same_samples(tmp_path_factory, sizes, chunk):
    d = tmp_path_factory.mktemp("h") / "r"
    rec = RunRecorder(d, {}, chunk_s=chunk)
    t = np.arange(sum(sizes)) / 2500.0
    start = 0
    for n in sizes:
        rec.append(rows(t[start:start + n]))
        start += n
    rec.finish("success", "")
    got = pd.read_parquet(d / SAMPLES_DIR)["t_s"].to_numpy()
    np.testing.assert_array_equal(got, t)


def test_temporary_part_names_are_invisible_to_readers(tmp_path):
    rec = RunRecorder(tmp_path / "r", {})
    rec.append(rows(np.arange(0, 1.5, 0.001)))
    (tmp_path / "r" / SAMPLES_DIR / ".part-000009.parquet.tmp").write_bytes(b"half a file")
    df = pd.read_parquet(tmp_path / "r" / SAMPLES_DIR)
    assert len(df) == 1000  # only the complete first second
    rec.finish("success", "")  # closes events.csv (an open file is a ResourceWarning)


def test_run_json_says_running_until_finished(tmp_path):
    rec = RunRecorder(tmp_path / "r", {"sequence": {"name": "s"}})
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    assert meta["status"] == "running" and meta["ended_utc"] is None
    assert meta["software_version"] and meta["started_utc"]
    rec.event(0.5, "step_start", 1, "hold", {"x": float("nan")})
    rec.finish("abort", "limit trip", trip={"limit": "rpm"})
    rec.finish("success", "ignored: finish is idempotent")
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    assert meta["status"] == "abort" and meta["trip"] == {"limit": "rpm"}
    assert not list((tmp_path / "r").glob(".*tmp"))
    ev = pd.read_csv(tmp_path / "r" / "events.csv")
    assert ev["kind"].tolist() == ["step_start"] and json.loads(ev["detail"][0]) == {"x": None}


def test_existing_run_folder_is_refused(tmp_path):
    from bench.errors import RigError

    (tmp_path / "r").mkdir()
    with pytest.raises(RigError, match="cannot create"):
        RunRecorder(tmp_path / "r", {})


def test_index_lists_runs_and_flags_killed_ones(tmp_path):
    index = RunIndex(tmp_path)
    rec = RunRecorder(tmp_path / "a", {"sequence": {"name": "step1"}, "rig": {"name": "sim"},
                                       "components": {"esc_mode": "diode"}})
    index.upsert(rec.meta, rec.run_dir)
    rec.finish("success", "sequence complete")
    index.upsert(rec.meta, rec.run_dir)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    index.upsert({"id": "b", "status": "running", "pid": dead.pid, "host": os.uname().nodename,
                  "started_utc": "9999"}, tmp_path / "b")
    listed = {r.id: r for r in index.list()}
    assert listed["a"].status == "success" and listed["a"].sequence == "step1"
    assert listed["a"].components == {"esc_mode": "diode"} and listed["a"].rig == "sim"
    assert listed["b"].status == "killed"
    (tmp_path / "runs.sqlite").unlink()
    assert RunIndex(tmp_path).rebuild().indexed == 1


def test_run_json_text_is_the_indented_dump_and_reuses_unchanged_values(tmp_path):
    """run.json is built one top-level value at a time (the plan's text is kept from the
    first write for the last): byte for byte what ``json.dump(indent=2)`` writes."""
    from pathlib import Path

    from bench.run.recorder import _json_text, _jsonable, atomic_write_json

    plan = {"segments": [{"index": i, "label": "step\nup", "us": 1000.0 + i, "sp": None,
                          "nan": float("nan"), "x": np.float64(1.5), "e": [], "d": {}}
                         for i in range(3)], "duration_s": 2.5}
    meta = {"kind": "step1", "plan": plan, "empty": {}, "none": None, 3: (1, "é"),
            "path": Path("/x"), "n": np.int32(7)}
    want = json.dumps(_jsonable(meta), indent=2, allow_nan=False)
    assert _json_text(meta, None) == want
    assert _json_text({}, None) == json.dumps({}, indent=2)
    cache: dict = {}
    path = tmp_path / "run.json"
    atomic_write_json(path, meta, cache)
    assert path.read_text(encoding="utf-8") == want + "\n"
    assert cache["plan"][0] is plan
    meta = {**meta, "kind": "changed", "plan": plan}
    atomic_write_json(path, meta, cache)  # the plan's text again from the cache
    assert path.read_text(encoding="utf-8") == json.dumps(_jsonable(meta), indent=2) + "\n"
    meta["plan"] = {**plan, "duration_s": 3.0}  # a new object is converted again
    atomic_write_json(path, meta, cache)
    assert json.loads(path.read_text(encoding="utf-8"))["plan"]["duration_s"] == 3.0
