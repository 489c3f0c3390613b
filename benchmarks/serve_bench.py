"""Web view speed: the first page of 10,000 runs, and the first paint of a 5 M-row run.

Prints measured times (median of repeats) for both stores:
* the runs list (``/``, 50 rows of 10,000) served by the app, folder store and lab
  catalog (a throwaway PostgreSQL cluster from the machine's binaries); targets < 300 ms;
* a 5,000,000-row run (25 kHz x 200 s) opened in headless Chromium on a server that is
  up (``rotorbench serve`` in its own process): time from navigation to every plot
  painted (server-side min/max decimation); target < 2 s, the first look at the run (its
  Parquet read; each on a fresh server, ``--repeats`` times) and again (its plots cached).
Usage: python benchmarks/serve_bench.py [--runs 10000] [--rows 5000000] [--paint-only]
       [--repeats 3]
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import sqlite3
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

REPO = Path(__file__).resolve().parents[1]


def _load(name: str, path: Path) -> object:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def make_folder_store(root: Path, n: int) -> None:
    """``n`` indexed runs (run.json each; samples are not needed for listing)."""
    from bench.store.run_index import RunIndex

    RunIndex(root)  # creates runs.sqlite
    rows = []
    for i in range(n):
        month, day = (i // 28800) % 12 + 1, (i // 960) % 28 + 1
        rid = f"2026{month:02d}{day:02d}T{i % 24:02d}0000_{i:06d}Z-step1"
        run = root / rid
        run.mkdir(parents=True)
        meta = {"id": rid, "rig": {"name": f"bench-{i % 3}"}, "sequence": {"name": "step1"},
                "components": {"motor": f"M{i % 4}", "propeller": f"P{i % 5}",
                               "esc_mode": ("complementary", "diode")[i % 2]},
                "status": "trip" if i % 97 == 0 else "success", "rows": 162500,
                "started_utc": f"2026-01-01T00:00:00.{i:06d}+00:00",
                "ended_utc": "2026-01-01T00:00:07+00:00"}
        (run / "run.json").write_text(json.dumps(meta))
        rows.append((rid, rid, meta["rig"]["name"], json.dumps(meta["components"]), "step1",
                     meta["started_utc"], meta["ended_utc"], meta["status"], "", "h", 1))
    with sqlite3.connect(root / "runs.sqlite") as con:
        con.executemany("INSERT INTO runs VALUES (?,?,?,?,?,?,?,?,?,?,?)", rows)


def fill_catalog(url: str, n: int) -> None:
    import psycopg
    from psycopg.types.json import Jsonb

    from bench.store.lab_catalog import LabCatalog

    LabCatalog(url).init()
    with psycopg.connect(url) as con, con.cursor() as cur:
        cur.executemany(
            "INSERT INTO runs (run_id, bench, operator, sequence, components, status, "
            "started_utc, ended_utc, samples, data) VALUES (%s,%s,%s,%s,%s,%s,%s,%s,%s,%s)",
            [(f"r{i:06d}", f"bench-{i % 3}", "ana", "step1",
              Jsonb({"motor": f"M{i % 4}", "propeller": f"P{i % 5}"}),
              "trip" if i % 97 == 0 else "success", f"2026-01-01T00:00:00.{i:06d}Z",
              "2026-01-01T00:00:07Z", 162500, f"s3://lab/runs/r{i:06d}") for i in range(n)])


def time_get(client: object, path: str, repeats: int = 7) -> float:
    client.get(path)  # warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = client.get(path)
        times.append(time.perf_counter() - t0)
        assert r.status_code == 200, r.text[:200]
    return statistics.median(times)


def make_big_run(root: Path, rows: int) -> str:
    from bench.store.run_index import RunIndex

    rid = "20260101T000000_000000Z-endurance"
    run = root / rid
    (run / "samples.parquet").mkdir(parents=True)
    rng = np.random.default_rng(1)
    t = np.arange(rows) / 25_000.0
    u = 1100 + 400 * (np.floor(t / 2) % 2)
    thrust = 2.0 + 3.0 * (np.floor(t / 2) % 2) + 0.05 * rng.standard_normal(rows)
    cols = {"t_s": t, "throttle_us": u, "thrust_setpoint_n": 2.0 + 3.0 * (np.floor(t / 2) % 2),
            "thrust_n": thrust, "current_a": thrust * 1.8, "voltage_v": 12.0 - thrust * 0.05,
            "rpm": 3000 + thrust * 900, "step": (t // 2).astype(np.int64)}
    part = 25_000 * 20
    for k, start in enumerate(range(0, rows, part)):
        pq.write_table(pa.table({c: v[start:start + part] for c, v in cols.items()}),
                       run / "samples.parquet" / f"part-{k:05d}.parquet", compression="lz4")
    meta = {"id": rid, "rig": {"name": "bench-0"}, "sequence": {"name": "endurance"},
            "components": {}, "status": "success", "rows": rows,
            "started_utc": "2026-01-01T00:00:00+00:00", "ended_utc": "2026-01-01T00:03:20+00:00",
            "samples": "samples.parquet", "events": "events.csv"}
    (run / "run.json").write_text(json.dumps(meta))
    (run / "events.csv").write_text("t_s,utc,kind,step,label,detail\n")
    RunIndex(root).upsert(meta, run)
    return rid


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=10_000)
    ap.add_argument("--rows", type=int, default=5_000_000)
    ap.add_argument("--paint-only", action="store_true",
                    help="only the first paint of the big run (skip the runs lists)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="first looks at the big run, each on a fresh server and browser "
                         "context (medians printed)")
    args = ap.parse_args()
    services = _load("rotorbench_tests_services", REPO / "tests" / "services.py")
    browser = _load("rotorbench_tests_browser", REPO / "tests" / "serve" / "browser.py")
    with tempfile.TemporaryDirectory() as tmp:
        if not args.paint_only:
            time_lists(Path(tmp), args.runs, services)
        big = Path(tmp) / "big"
        rid = make_big_run(big, args.rows)
        why = browser.chromium_missing()
        if why:
            print(f"first paint: skipped ({why})")
            return 0
        time_paint(big, rid, args.rows, args.repeats, services, browser)
    return 0


def time_lists(tmp: Path, runs: int, services: object) -> None:
    """The runs list over a folder store and the lab catalog of ``runs`` runs."""
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import FolderStore, open_store

    root = tmp / "runs"
    t0 = time.perf_counter()
    make_folder_store(root, runs)
    print(f"folder store of {runs} runs made in {time.perf_counter() - t0:.1f} s")
    client = TestClient(create_app(FolderStore(root)))
    print(f"folder store, list page 1 (50 of {runs}): "
          f"{time_get(client, '/') * 1e3:.0f} ms; /api/runs?limit=100: "
          f"{time_get(client, '/api/runs?limit=100') * 1e3:.0f} ms; filtered by motor: "
          f"{time_get(client, '/?motor=M1') * 1e3:.0f} ms")
    with contextlib.ExitStack() as stack:
        try:
            pg = stack.enter_context(services.postgres_cluster())
        except BaseException as exc:  # pytest's skip outside pytest
            print(f"lab catalog: skipped ({exc})")
            return
        fill_catalog(pg.url(), runs)
        lab = open_store(pg.url(), data=str(tmp / "share"))
        lc = TestClient(create_app(lab))
        print(f"lab catalog, list page 1 (50 of {runs}): "
              f"{time_get(lc, '/') * 1e3:.0f} ms; /api/runs?limit=100: "
              f"{time_get(lc, '/api/runs?limit=100') * 1e3:.0f} ms; all "
              f"{runs} rows (list_runs): {_time(lambda: lab.list_runs()) * 1e3:.0f} ms")


#: in the page, after the paint: when the page's HTML had arrived, when the deferred
#: scripts had run (DOMContentLoaded), when the plot data was asked for and when it had
#: arrived, ms after navigation start
_PAGE_TIMES = """() => {
  const nav = performance.getEntriesByType("navigation")[0];
  const data = performance.getEntriesByType("resource")
    .filter(e => e.name.includes("/series"))[0] || {};
  return {html: nav.responseEnd, scripts: nav.domContentLoadedEventStart,
          asked: data.requestStart ?? NaN, data: data.responseEnd ?? NaN};
}"""


def time_paint(big: Path, rid: str, rows: int, repeats: int, services: object,
               browser: object) -> None:
    """First paint of the big run's plots: ``repeats`` first looks, each on a fresh
    ``rotorbench serve`` process (nothing cached) and a fresh browser context that has
    been to ``/`` and holds the page's scripts in its HTTP cache; then, once the page's
    step fit is back, the same page again (its plots cached by the server). Medians, and
    each first look with the times the page took (HTML, scripts, plot data)."""
    import re
    import urllib.request

    first: list[float] = []
    again: list[float] = []
    parts: list[dict[str, float]] = []
    with browser.chromium() as chrome:
        for _ in range(repeats):
            with _server_process(big, services) as base:
                ctx = chrome.new_context(viewport={"width": 1280, "height": 900})
                page = ctx.new_page()
                page.goto(base + "/")  # a server that is up and a browser that has been there
                html = urllib.request.urlopen(f"{base}/runs/{rid}").read().decode()
                for src in re.findall(r'<script src="([^"]+)"', html):
                    page.goto(base + src)  # (the page's scripts in its cache)
                for times in (first, again):
                    t0 = time.perf_counter()
                    page.goto(f"{base}/runs/{rid}")
                    page.wait_for_selector("#plots[data-painted]", timeout=60_000)
                    times.append(time.perf_counter() - t0)
                    if times is first:
                        parts.append(page.evaluate(_PAGE_TIMES))
                        plots = page.get_attribute("#plots", "data-painted")
                        # the page then asks for the step fit of all 5 M rows (seconds of
                        # the server's time): "again" is a look after it, not during it
                        page.wait_for_selector("#fits[data-done], #fits .error",
                                               timeout=300_000)
                ctx.close()
    for i, (dt, p) in enumerate(zip(first, parts, strict=True)):
        print(f"  first look {i + 1}: {dt:.2f} s (page in at {p['html'] / 1e3:.2f} s, scripts "
              f"run at {p['scripts'] / 1e3:.2f} s, plot data asked at {p['asked'] / 1e3:.2f} s, "
              f"in at {p['data'] / 1e3:.2f} s)")
    print(f"{rows:,}-row run page, first paint of {plots} plots, median of {repeats}: "
          f"first look (the run read from Parquet) {statistics.median(first):.2f} s "
          f"(max {max(first):.2f} s); again (its plots cached) "
          f"{statistics.median(again):.2f} s")


@contextlib.contextmanager
def _server_process(store: Path, services: object) -> object:
    """``rotorbench serve`` in its own process, as a lab runs it (the browser's driver in
    this process must not share the server's interpreter)."""
    import subprocess

    port = services.free_port()
    proc = subprocess.Popen([sys.executable, "-m", "bench.cli", "serve", "--store", str(store),
                             "--port", str(port)], stdout=subprocess.DEVNULL)
    try:
        if not services.wait_port(port, 30):
            raise SystemExit("rotorbench serve did not start within 30 s")
        yield f"http://127.0.0.1:{port}"
    finally:  # (a page's step fit of the 5 M-row run may still be running: not waited for)
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


def _time(fn: object, repeats: int = 5) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


if __name__ == "__main__":
    sys.exit(main())
