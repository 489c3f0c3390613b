"""The web view's JSON and pages over both stores (TestClient: real app, no server)."""

from __future__ import annotations

import io
import itertools

import pandas as pd
import pytest


def _ids(client: object, **params: str) -> list[str]:
    r = client.get("/api/runs", params=params)
    assert r.status_code == 200, r.text
    return [row["run_id"] for row in r.json()]


def test_runs_list_filters_and_pages(client: object) -> None:
    r = client.get("/api/runs")
    rows = r.json()
    assert r.headers["x-total-count"] == "3" and len(rows) == 3
    assert {"run_id", "bench", "sequence", "status", "samples", "data"} <= set(rows[0])
    assert [x["sequence"] for x in rows] == ["step1", "step1", "sweep"]  # newest first
    assert all(x["samples"] > 0 and x["status"] == "success" for x in rows)
    assert len(_ids(client, sequence="step1")) == 2
    assert len(_ids(client, esc_mode="diode")) == 1
    assert _ids(client, motor="no-such-motor") == []
    assert _ids(client, since="2999-01-01") == []
    assert len(_ids(client, since="2000-01-01", until="2999-01-01")) == 3
    assert _ids(client, limit="1", offset="1") == _ids(client)[1:2]


def test_run_page_series_fits_and_downloads(client: object) -> None:
    step, _, sweep = _ids(client)
    html = client.get(f"/runs/{step}")
    assert html.status_code == 200 and step in html.text and "samples.parquet" in html.text
    series = client.get(f"/api/runs/{step}/series", params={"columns": 200}).json()
    keys = {p["key"] for p in series["plots"]}
    assert {"throttle_us", "thrust_n", "current_a", "voltage_v", "rpm",
            "efficiency_g_w"} <= keys
    assert all(len(p["t"]) <= 400 for p in series["plots"]) and series["rows"] > 10_000
    fits = client.get(f"/api/runs/{step}/fits").json()
    assert 0.01 < fits["step"]["tau_up_ms"] / 1e3 < 1.0
    assert "static" in client.get(f"/api/runs/{sweep}/fits").json()
    pq = client.get(f"/runs/{step}/samples.parquet")
    df = pd.read_parquet(io.BytesIO(pq.content))
    assert len(df) == series["rows"] and "thrust_n" in df.columns
    csv = client.get(f"/runs/{step}/samples.csv")
    assert csv.text.splitlines()[0].startswith("t_s,")
    assert len(csv.text.splitlines()) == series["rows"] + 1
    ardu = client.get(f"/runs/{sweep}/export/ardupilot").json()
    assert 0.0 <= ardu["MOT_THST_EXPO"] <= 1.0
    gz = client.get(f"/runs/{sweep}/export/gazebo").json()
    assert gz["motorConstant"] > 0
    assert client.get(f"/runs/{sweep}/export/betaflight").status_code == 404


def test_compare_and_constants(client: object) -> None:
    a, b, sweep = _ids(client)
    d = client.get("/api/compare", params={"runs": f"{a},{sweep}"}).json()
    assert [s["run_id"] for s in d["static"]] == [a, sweep]
    assert len(d["static"][1]["thrust_vs_rpm"]["x"]) > 10
    assert d["steps"][0]["up_edges"] >= 2 and d["steps"][0]["down_edges"] >= 2
    assert "why" in d["steps"][1]  # a sweep has no steps
    # a step run's static points are its plateaus: current rises with thrust there
    cur = d["static"][0]["current_a_vs_thrust"]["y"]
    assert all(hi >= lo - 0.05 for lo, hi in itertools.pairwise(cur))
    assert client.get(f"/compare?runs={a},{b}").status_code == 200
    (c,) = client.get("/api/constants").json()
    assert c["kind"] == "step" and c["data"]["tau_up_s"] > 0
    page = client.get("/constants").text
    assert c["run_id"] in page


@pytest.mark.parametrize("path", [
    "/runs/does-not-exist", "/runs/..%2f..%2fetc%2fpasswd", "/api/runs/%2e%2e%2fetc",
    "/runs/%2fetc%2fpasswd", "/api/runs/..%5c..%5cwindows/series", "/runs/a/../../x",
    "/api/compare?runs=..%2f..%2f", "/static/..%2fapp.py", "/static/%2e%2e%2fapp.py",
])
def test_unknown_runs_and_path_tricks_are_404(client: object, path: str) -> None:
    r = client.get(path)
    assert r.status_code == 404, (path, r.status_code, r.text[:200])
    assert "root:" not in r.text and "import" not in r.text


def test_live_lists_a_running_run(recorded: object, tmp_path: object) -> None:
    """A run whose process still records shows up in /api/live (status, elapsed, values)."""
    import json
    import os
    import shutil

    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.run_index import RunIndex
    from bench.store.stores import open_store

    root = tmp_path / "runs"
    shutil.copytree(recorded, root)
    run = sorted(root.glob("*-step1"))[0]
    meta = json.loads((run / "run.json").read_text())
    meta.update(status="running", pid=os.getpid(), ended_utc=None)
    (run / "run.json").write_text(json.dumps(meta))
    RunIndex(root).upsert(meta, run)
    with TestClient(create_app(open_store(str(root)))) as client:
        (row,) = client.get("/api/live").json()
    assert row["run_id"] == meta["id"] and row["status"] == "running"
    assert row["elapsed_s"] > 0 and row["latest"]["thrust_n"] is not None
