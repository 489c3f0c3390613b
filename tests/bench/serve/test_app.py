"""The web view's JSON and pages over both stores (TestClient: real app, no server)."""

from __future__ import annotations

import io
import itertools
from pathlib import Path

import pandas as pd
import pytest

from bench.cli import main


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


@pytest.mark.parametrize("bad", ["2024-13-45", "2024-02-30", "yesterday", "2024-01-01T99:00"])
@pytest.mark.parametrize("name", ["since", "until"])
def test_a_bad_date_filter_is_422_in_both_stores(client: object, bad: str, name: str) -> None:
    for path in ("/api/runs", "/"):
        r = client.get(path, params={name: bad})
        assert r.status_code == 422, (path, r.status_code, r.text[:200])
        assert "expected a date" in r.text


SECRET = "SECRET-hunter2-do-not-show"


def _folder_client(recorded: object, tmp_path: object) -> tuple[object, object]:
    import shutil

    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    root = tmp_path / "runs"
    shutil.copytree(recorded, root)
    return root, TestClient(create_app(open_store(str(root))))


def test_a_get_never_writes_a_killed_run(recorded: object, tmp_path: object) -> None:
    """A run whose process died: the view says killed and leaves run.json and the index
    as they are (a command marks it)."""
    import json
    import socket
    import sqlite3
    import subprocess
    import sys

    root, client = _folder_client(recorded, tmp_path)
    run = sorted(root.glob("*-step1"))[0]
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    meta = json.loads((run / "run.json").read_text())
    meta.update(status="running", pid=proc.pid, host=socket.gethostname(), ended_utc=None)
    (run / "run.json").write_text(json.dumps(meta))
    with sqlite3.connect(root / "runs.sqlite") as con:
        con.execute("UPDATE runs SET status = 'running', host = ?, pid = ? WHERE id = ?",
                    (meta["host"], proc.pid, meta["id"]))

    def files() -> dict[str, tuple[bytes, int]]:
        return {str(p): (p.read_bytes(), p.stat().st_mtime_ns) for p in root.rglob("*")
                if p.is_file()}

    before = files()
    with client:
        rows = {r["run_id"]: r for r in client.get("/api/runs").json()}
        assert rows[meta["id"]]["status"] == "killed"
        for path in ("/", "/api/live", f"/runs/{meta['id']}", f"/api/runs/{meta['id']}",
                     f"/runs/{meta['id']}/run.json", "/constants"):
            assert client.get(path).status_code == 200, path
    assert files() == before


def test_run_json_naming_files_outside_is_refused_and_not_quoted(recorded: object,
                                                                 tmp_path: object) -> None:
    import json
    import os

    root, client = _folder_client(recorded, tmp_path)
    step, other = sorted(root.glob("*-step1"))
    outside = tmp_path / "outside"
    outside.mkdir()
    os.rename(other / "samples.parquet", outside / "samples.parquet")
    (outside / "secret.csv").write_text(f"{SECRET},x\n1,2\n")
    (outside / "secret.json").write_text(json.dumps({"id": "x", "key": SECRET}))
    meta = json.loads((step / "run.json").read_text())
    rid = meta["id"]
    hostile = [{"samples": str(outside / "samples.parquet")},
               {"samples": "../../outside/samples.parquet"},
               {"events": str(outside / "secret.csv")},
               {"events": "../../outside/secret.csv"}]
    with client:
        for change in hostile:
            (step / "run.json").write_text(json.dumps({**meta, **change}))
            for path in (f"/api/runs/{rid}", f"/api/runs/{rid}/series",
                         f"/runs/{rid}/samples.parquet", f"/runs/{rid}/samples.csv",
                         f"/api/runs/{rid}/fits", f"/runs/{rid}/export/gazebo"):
                if "events" in change and path.endswith("/series"):
                    continue  # the plots do not read the events
                r = client.get(path)
                assert r.status_code == 422 and "inside the run folder" in r.text, (path, r.text)
                assert SECRET not in r.text
        (step / "run.json").unlink()
        os.symlink(outside / "secret.json", step / "run.json")
        for path in (f"/runs/{rid}/run.json", f"/runs/{rid}", f"/api/runs/{rid}"):
            r = client.get(path)
            assert r.status_code == 422 and SECRET not in r.text, (path, r.text)


def test_hostile_catalog_rows_reach_nothing_outside(recorded: object, tmp_path: object,
                                                    pg_url: str, s3_env: object,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Rows another bench (or anyone with a writer login) could write: ids with '..', data
    locations elsewhere. The view reads none of them and writes nothing outside its cache."""
    import json
    import shutil

    import psycopg
    from fastapi.testclient import TestClient

    from bench.cli import main
    from bench.serve.app import create_app
    from bench.store.stores import open_store

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    data = f"s3://{s3_env.bucket}/runs"
    assert main(["store", "init", pg_url, "--data", data]) == 0
    other = tmp_path / "elsewhere" / "r-other"
    shutil.copytree(sorted(recorded.glob("*-step1"))[0], other)
    meta = json.loads((other / "run.json").read_text())
    (other / "run.json").write_text(json.dumps({**meta, "id": "r-other", "operator": SECRET}))
    with psycopg.connect(pg_url) as con:
        for rid, where, status in [("r-other", str(other), "success"),
                                   ("r-file", f"file://{other}", "running"),
                                   ("../../escape", f"{data}/../../escape", "running"),
                                   ("..\\..\\escape", "", "running"),
                                   ("../rotorbench/runs/x", f"{data}/x", "running"),
                                   ("x" * 300, f"{data}/{'x' * 300}", "running")]:
            con.execute("INSERT INTO runs (run_id, bench, operator, status, data, started_utc) "
                        "VALUES (%s, 'hostile', 'x', %s, %s, now())", (rid, status, where))
    before = {str(p) for p in tmp_path.rglob("*")}
    with TestClient(create_app(open_store(pg_url, spool=tmp_path / "spool"))) as client:
        live = client.get("/api/live")
        assert live.status_code == 200 and all(r["latest"] == {} for r in live.json())
        assert len(live.json()) == 5
        for rid in ("r-other", "r-file"):
            for path in (f"/api/runs/{rid}", f"/runs/{rid}", f"/runs/{rid}/run.json"):
                r = client.get(path)
                assert r.status_code == 404 and SECRET not in r.text, (path, r.text)
        assert client.get("/api/runs").status_code == 200
    assert {str(p) for p in tmp_path.rglob("*")} == before


def test_the_run_page_shows_its_run_log_and_serves_it(client: object) -> None:
    """The run's diagnostic log is on its page (its end) and downloadable whole, from
    either store (the lab's copy came through the object store)."""
    step, _, _ = _ids(client)
    html = client.get(f"/runs/{step}").text
    assert 'id="run-log"' in html and "run ended: success: sequence complete" in html
    log = client.get(f"/runs/{step}/run.log")
    assert log.status_code == 200 and log.headers["content-type"].startswith("text/plain")
    assert "answered" in log.text and "run started" in log.text


def test_a_run_log_that_links_out_is_not_served(tmp_path: Path) -> None:
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    out = tmp_path / "runs"
    assert main(["step", "--repeats", "1", "--out", str(out)]) == 0
    (run_dir,) = out.glob("*-step1")
    secret = tmp_path / "secret.txt"
    secret.write_text("the content of another file\n")
    (run_dir / "run.log").unlink()
    (run_dir / "run.log").symlink_to(secret)
    with TestClient(create_app(open_store(str(out)))) as c:
        page = c.get(f"/runs/{run_dir.name}")
        assert page.status_code == 200 and "the content of another file" not in page.text
        assert "outside the run folder" in page.text
        got = c.get(f"/runs/{run_dir.name}/run.log")
        assert got.status_code == 422 and "another file" not in got.text
        (run_dir / "run.log").unlink()
        assert c.get(f"/runs/{run_dir.name}/run.log").status_code == 404
        assert "no run.log" in c.get(f"/runs/{run_dir.name}").text


def test_a_flight_run_is_listed_and_its_page_plots_the_flight_columns(flight_runs: Path
                                                                     ) -> None:
    """A Betaflight flight run (``fly --controller betaflight``): gyro vs setpoint per axis,
    the motor outputs and their eRPM, several traces a plot."""
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    client = TestClient(create_app(open_store(str(flight_runs))))
    (run_id,) = _ids(client)
    assert client.get(f"/runs/{run_id}").status_code == 200
    series = client.get(f"/api/runs/{run_id}/series", params={"columns": 200}).json()
    plots = {p["key"]: p for p in series["plots"]}
    assert list(plots) == ["rate_x", "rate_y", "rate_z", "motor_norm", "motor_rpm"]
    assert [tr["name"] for tr in plots["rate_x"]["traces"]] == ["gyro", "setpoint"]
    assert [tr["name"] for tr in plots["motor_rpm"]["traces"]] == [
        f"motor {k}" for k in range(1, 5)]
    assert plots["motor_rpm"]["unit"] == "rpm" and plots["rate_x"]["t"] == \
        plots["rate_x"]["traces"][0]["t"]
    assert all(len(tr["t"]) <= 400 for p in plots.values() for tr in p["traces"])
