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

from bench.engine.recorder import BASE_COLUMNS, SAMPLES_DIR, RunRecorder
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

    from bench.engine.recorder import _json_text, _jsonable, atomic_write_json

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


def test_parts_are_encoded_losslessly_and_compactly(tmp_path):
    """Quantised channels (ADC counts times a scale) go into a dictionary, time stamps get
    their bytes split, distinct values stay plain: every value reads back bit for bit
    (-0.0, NaN payloads, infinities too) and the part is under half its plain size."""
    import pyarrow.parquet as pq

    rng = np.random.default_rng(7)
    n = 25_000
    t = np.arange(n) / 25_000.0 + rng.uniform(-1.7e-6, 1.7e-6, n)  # a jittered clock
    lsb = 20.0 / 2**16
    odd_nan = np.frombuffer(np.uint64(0x7FF8000000000BAD).tobytes(), np.float64)[0]
    special = np.resize(np.array([0.0, -0.0, np.nan, odd_nan, np.inf, -np.inf, 1.5]), n)
    cols = {"t_s": t, "throttle_us": np.full(n, 1532.5),
            "thrust_setpoint_n": np.full(n, 3.1871612),
            "thrust_n": (np.rint(rng.normal(800, 150, n)) * lsb - 0.012) * 10.0,
            "current_a": np.rint(rng.normal(400, 120, n)) * lsb / 0.0366,
            "voltage_v": np.rint(rng.normal(700, 20, n)) * lsb / 0.06369,
            "rpm": rng.normal(5000.0, 30.0, n), "special": special,
            "step": np.repeat(np.arange(5, dtype=np.int32), n // 5)}
    rec = RunRecorder(tmp_path / "r", {})
    rec.append(cols)
    rec.finish("success", "")
    (part,) = (tmp_path / "r" / SAMPLES_DIR).glob("part-*.parquet")
    back = pq.read_table(part)
    for name, want in cols.items():
        got = back.column(name).to_numpy()
        assert got.dtype == want.dtype
        assert np.array_equal(got.view(f"u{want.itemsize}"), want.view(f"u{want.itemsize}")), name
    plain = tmp_path / "plain.parquet"
    pq.write_table(back, plain, compression="lz4", use_dictionary=False)

    def chunks(path):
        meta = pq.ParquetFile(path).metadata.row_group(0)
        return {meta.column(i).path_in_schema: meta.column(i) for i in range(meta.num_columns)}

    ours, theirs = chunks(part), chunks(plain)
    assert "BYTE_STREAM_SPLIT" in ours["t_s"].encodings
    for name in ("throttle_us", "thrust_n", "current_a", "voltage_v", "special", "step"):
        assert "RLE_DICTIONARY" in ours[name].encodings, name
    assert "RLE_DICTIONARY" not in ours["rpm"].encodings  # distinct values: no dictionary
    for name, most in (("t_s", 0.7), ("thrust_n", 0.5), ("current_a", 0.5), ("voltage_v", 0.5)):
        assert ours[name].total_compressed_size < most * theirs[name].total_compressed_size
    assert part.stat().st_size < 0.7 * plain.stat().st_size


def test_written_behind_parts_hold_ten_seconds(tmp_path):
    """A simulated run written behind (``write_behind``) cuts parts of 10 s of rig time: a
    tenth of the files (and of a lab store's uploads); nothing is lost."""
    from bench.engine.recorder import BEHIND_PART_S

    rec = RunRecorder(tmp_path / "r", {})
    rec.write_behind()
    t = np.arange(0, 25.0, 1 / 1000.0)
    for chunk in np.array_split(t, 25):
        rec.append(rows(chunk))
    meta = rec.finish("success", "")
    parts = sorted((tmp_path / "r" / SAMPLES_DIR).glob("part-*.parquet"))
    spans = [pd.read_parquet(p)["t_s"].agg(["min", "max"]).tolist() for p in parts]
    assert BEHIND_PART_S == 10.0 and meta["parts"] == len(parts) == 3
    assert [round(lo) for lo, _ in spans] == [0, 10, 20]
    assert all(hi - lo < BEHIND_PART_S for lo, hi in spans)
    got = pd.read_parquet(tmp_path / "r" / SAMPLES_DIR)["t_s"].to_numpy()
    np.testing.assert_array_equal(got, t)
    other = RunRecorder(tmp_path / "s", {})
    with pytest.raises(ValueError, match="part_s"):
        other.write_behind(part_s=0)
    other.finish("fail", "")
