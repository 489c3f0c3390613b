"""One suite, both stores: the folder default and the lab catalog (PostgreSQL + S3)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

from bench.cli import main
from bench.store.constants_fit import fit_for_store
from bench.store.lab_catalog import StoredConstants
from bench.store.run_summary import RunFilter
from bench.store.stores import open_store


@pytest.fixture(params=["folder", "lab"])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[object]:
    if request.param == "folder":
        yield open_store(str(tmp_path / "runs"))
        return
    pg_url = request.getfixturevalue("pg_url")
    s3 = request.getfixturevalue("s3_env")
    assert main(["store", "init", pg_url]) == 0
    yield open_store(pg_url, data=f"s3://{s3.bucket}/runs", spool=tmp_path / "spool")


def _record(store: object, *args: str) -> Path:
    root = store.record_root()
    before = set(root.glob("*/run.json"))
    assert main(["step", "--repeats", "2", "--out", str(root), *args]) == 0
    (new,) = set(root.glob("*/run.json")) - before
    store.after_run(new.parent)
    return new.parent


def test_record_list_and_read_back(store: object, tmp_path: Path,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    store.check_can_record()
    a = _record(store)
    b = _record(store, "--esc-mode", "diode")
    runs = store.list_runs()
    assert [r.run_id for r in runs] == [b.name, a.name]  # newest first
    assert {r.status for r in runs} == {"success"} and {r.sequence for r in runs} == {"step1"}
    assert all(r.samples == len(pd.read_parquet(d / "samples.parquet"))
               for r, d in zip(runs, (b, a), strict=True))
    assert [r.run_id for r in store.list_runs(limit=1, offset=1)] == [a.name]
    assert store.list_runs(RunFilter(status="trip")) == []
    folder = store.run_folder(a.name)
    pd.testing.assert_frame_equal(pd.read_parquet(folder / "samples.parquet"),
                                  pd.read_parquet(a / "samples.parquet"))
    with pytest.raises(Exception, match="not in the store"):
        store.run_folder("20990101T000000_000000Z-nothing")


def test_constants_round_trip(store: object) -> None:
    row = StoredConstants("M3", "P4", "F30A", "plain", "3S", "step", "thesis-e", "r1",
                          "runs/r1", "", {"latency_s": 0.02, "tau_up_s": 0.15,
                                          "tau_down_s": 0.12})
    assert store.add_constants([row]) == 1
    (back,) = store.constants()
    assert (back.motor, back.kind, back.run_id, back.data) == ("M3", "step", "r1", row.data)
    newer = StoredConstants(*[*row.__dict__.values()][:7], "r2", "runs/r2", "",
                            {**row.data, "tau_up_s": 0.14})
    store.add_constants([newer])
    (back,) = store.constants()  # the newest per actuator and kind
    assert back.run_id == "r2" and back.data["tau_up_s"] == 0.14


def test_a_fitted_step_runs_spreads_round_trip(store: object) -> None:
    """The spread of one edge (time constants and latency) travels in the constants' JSON
    (a jsonb column in the lab catalog: no migration) and comes back as it was stored."""
    run = _record(store)
    key, kind, run_id, data = fit_for_store(run)
    assert all(data[k] > 0 for k in ("tau_up_std_s", "tau_down_std_s", "latency_std_s"))
    store.add_constants([StoredConstants(key.motor, key.propeller, key.esc, key.esc_mode,
                                         key.battery, kind, key.catalog, run_id, str(run), "",
                                         data)])
    (back,) = store.constants()
    assert {k: back.data[k] for k in ("tau_up_std_s", "tau_down_std_s", "latency_std_s")} == \
        {k: data[k] for k in ("tau_up_std_s", "tau_down_std_s", "latency_std_s")}
