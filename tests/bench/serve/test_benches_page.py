"""The web view's benches page over a real lab catalog holding two benches' constants of one
motor and propeller: the tables with the flagged pair, the JSON, a request with nothing to
compare answered 422 in words, and in a real Chromium a panel painted per constant."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from bench.serve.app import create_app
from bench.store.lab_catalog import LabCatalog, StoredConstants, run_from_meta
from bench.store.stores import open_store

browser_mod = sys.modules["rotorbench_tests_browser"]  # browser.py, by conftest
M, P = "m-2212", "p-8x45"


@pytest.fixture
def two_benches(pg_url: str, tmp_path: Path) -> object:
    """Benches A and B: step constants that agree, k_f 10 % apart with small spreads."""
    cat = LabCatalog(pg_url)
    cat.init()
    rows = []
    for i, (bench, k_f) in enumerate((("A", 6.4e-6), ("B", 7.0e-6)), start=1):
        run_id = f"20261127T0800{i:02d}_000000Z-sweep-{i:04x}"
        cat.upsert_run(run_from_meta(
            {"id": run_id, "rig": {"name": "sim"}, "status": "success",
             "components": {"motor": M, "propeller": P}, "started_utc": "2026-11-27T08:00Z"},
            data=f"s3://lab/runs/{run_id}", samples=10, bench=bench, operator="ana"))
        rows += [StoredConstants(M, P, "f30a", "complementary", "3s", "static", "", run_id, "",
                                 "", {"k_f_n_s2": k_f, "k_f_std_n_s2": 4e-9, "points": 60}),
                 StoredConstants(M, P, "f30a", "complementary", "3s", "step", "", run_id, "",
                                 "", {"tau_up_s": 0.03, "tau_down_s": 0.05, "latency_s": 0.01,
                                      "tau_up_std_s": 0.002, "tau_down_std_s": 0.002,
                                      "latency_std_s": 0.001, "repeats": 4})]
    cat.add_constants(rows)
    return open_store(pg_url, spool=tmp_path / "spool")


def test_the_page_and_the_json(two_benches: object) -> None:
    from fastapi.testclient import TestClient

    with TestClient(create_app(two_benches)) as client:  # type: ignore[arg-type]
        index = client.get("/benches")
        assert index.status_code == 200 and f"/benches?motor={M}&amp;propeller={P}" in index.text
        page = client.get("/benches", params={"motor": M, "propeller": P})
        assert page.status_code == 200
        assert '<tr class="flagged"><td>k_f_n_s2</td><td>A vs B</td>' in page.text
        assert "tau_up_s</td><td>A vs B</td><td>+0.00</td><td></td>" in page.text
        d = client.get("/api/benches", params={"motor": M, "propeller": P}).json()
        assert [f["constant"] for f in d["flagged"]] == ["k_f_n_s2"]
        assert {c["constant"] for c in d["constants"]} == {"k_f_n_s2", "tau_up_s",
                                                           "tau_down_s", "latency_s"}
        bad = client.get("/api/benches", params={"motor": "nope", "propeller": P})
        assert bad.status_code == 422 and "--motor nope: no constants" in bad.json()["detail"]
        page = client.get("/benches", params={"motor": "nope", "propeller": P})
        assert page.status_code == 422 and 'id="benches-why"' in page.text


@pytest.mark.slow(wall_s=15)  # Chromium started, plotly.js loaded
def test_a_panel_per_constant_in_a_real_browser(two_benches: object) -> None:
    from rotorbench_tests_services import missing

    why = browser_mod.chromium_missing()
    if why:
        missing(why)
    with browser_mod.chromium() as browser, \
            browser_mod.serving(create_app(two_benches)) as base:  # type: ignore[arg-type]
        pg = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
        errors: list[str] = []
        pg.on("pageerror", lambda e: errors.append(str(e)))
        pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        pg.goto(base + "/benches")
        pg.click("#stored-pairs a")
        pg.wait_for_selector("#benches[data-painted]", timeout=30_000)
        assert pg.get_attribute("#benches", "data-painted") == "4"
        # each bench's marker with its error bar, in the k_f panel
        assert pg.locator("#bench-k_f_n_s2 .main-svg g.trace .point").count() == 2
        assert pg.locator("#bench-k_f_n_s2 .main-svg g.errorbar").count() == 2
        assert pg.locator("#bench-pairs tr.flagged").count() == 1
        assert errors == [], errors  # no script error, no CSP violation
