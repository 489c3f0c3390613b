"""Fixtures of the web-view tests: a small lab of recorded runs, as a folder store and as
the lab catalog (PostgreSQL + S3), and the app over each."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench.cli import main


@pytest.fixture(scope="session")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder store: a short sweep, two step runs (two ESC modes), stored constants."""
    out = tmp_path_factory.mktemp("served") / "runs"
    assert main(["sweep", "--duration", "10", "--out", str(out), "--no-save-map"]) == 0
    assert main(["step", "--repeats", "2", "--out", str(out)]) == 0
    assert main(["step", "--repeats", "2", "--esc-mode", "diode", "--out", str(out)]) == 0
    steps = sorted(p.parent for p in out.glob("*-step1/run.json"))
    assert main(["constants", "--out", str(out), "--add", str(steps[0])]) == 0
    return out


@pytest.fixture(scope="session")
def recorded_lab(recorded: Path, pg_cluster: object, s3: object,
                 tmp_path_factory: pytest.TempPathFactory) -> str:
    """The recorded runs pushed into a lab catalog (a database of the session's cluster,
    a bucket of its S3), once per test process: the web view only reads, so every test
    over it sees the same catalog, through its own spool and download cache."""
    import os

    import psycopg

    name = f"served_{os.getpid()}"
    with psycopg.connect(pg_cluster.url(), autocommit=True) as con:
        con.execute(f"DROP DATABASE IF EXISTS {name}")
        con.execute(f"CREATE DATABASE {name}")
    url = pg_cluster.url(db=name)
    bucket = name.replace("_", "-")
    s3.create_bucket(bucket)
    with pytest.MonkeyPatch.context() as mp:
        for k, v in s3.env.items():
            mp.setenv(k, v)
        mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("lab-cache")))
        assert main(["store", "init", url, "--data", f"s3://{bucket}/runs"]) == 0
        assert main(["store", "push", str(recorded), "--store", url]) == 0
    return url


@pytest.fixture(params=["folder", "lab"])
def store(request: pytest.FixtureRequest, recorded: Path, tmp_path: Path,
          monkeypatch: pytest.MonkeyPatch) -> Iterator[object]:
    """The recorded runs behind either store."""
    from bench.store.stores import open_store

    if request.param == "folder":
        copy = tmp_path / "runs"
        shutil.copytree(recorded, copy)
        yield open_store(str(copy))
        return
    url = request.getfixturevalue("recorded_lab")
    for k, v in request.getfixturevalue("s3").env.items():
        monkeypatch.setenv(k, v)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))  # each test downloads
    yield open_store(url, spool=tmp_path / "spool")


@pytest.fixture
def client(store: object) -> Iterator[object]:
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app

    with TestClient(create_app(store)) as c:
        yield c


@pytest.fixture(scope="session")
def flight_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder store holding one flight run, as ``rotorbench fly --controller betaflight``
    stores the firmware's log: rates and setpoints, motor outputs, eRPM (2 s at 1 kHz)."""
    import numpy as np
    import pandas as pd

    from analysis.run_paths import read_run_json
    from bench.store.imported_run import write_run
    from bench.store.run_index import RunIndex

    root = tmp_path_factory.mktemp("flight") / "runs"
    t = np.arange(0.0, 2.0, 1e-3)
    sp = np.where((t % 0.6) < 0.25, 1.745, 0.0)
    cols: dict[str, np.ndarray] = {"t_s": t}
    for a in ("x", "y", "z"):
        cols[f"rate_sp_{a}_rad_s"] = sp if a != "z" else 0 * t
        cols[f"gyro_{a}_rad_s"] = np.convolve(cols[f"rate_sp_{a}_rad_s"],
                                              np.full(40, 1 / 40))[:t.size]
    for k in range(1, 5):
        cols[f"motor{k}_norm"] = 0.6 + 0.05 * np.sin(2 * np.pi * (k + t))
        cols[f"motor{k}_rpm"] = 3400 + 300 * np.sin(2 * np.pi * (k + t))
    meta = {"kind": "flight", "components": {}, "import": {"source_file": "LOG00001.BF"},
            "flight": {"synthesized": {"columns": [f"motor{k}_rpm" for k in range(1, 5)]}},
            "flown_by": {"controller": "betaflight"}}
    run = write_run(root / "20260101T000000_000000Z-00000000-betaflight-flight",
                    pd.DataFrame(cols), meta)
    RunIndex(root).upsert(read_run_json(run), run)
    return root
