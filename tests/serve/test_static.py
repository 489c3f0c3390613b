"""The plotly.js the pages load: the "basic" partial bundle shipped in bench/serve/static
with its license and source note, served with a year's cache, and enough for the pages
(they draw only trace types the bundle holds)."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from bench.serve.app import PLOTLY_JS, create_app
from bench.serve.security import CSP
from bench.store.stores import open_store

STATIC = Path(__file__).parents[2] / "bench" / "serve" / "static"
BASIC_TRACES = {"scatter", "bar", "pie"}  # what plotly.js-basic-dist-min holds


@pytest.fixture(scope="module")
def client(recorded: Path) -> TestClient:
    return TestClient(create_app(open_store(str(recorded))))


def test_the_bundle_is_the_npm_package_named_in_its_source_note() -> None:
    version = re.fullmatch(r"plotly-basic-(\d+\.\d+\.\d+)\.min\.js", PLOTLY_JS).group(1)
    bundle = (STATIC / PLOTLY_JS).read_bytes()
    assert bundle.startswith(f"/**\n* plotly.js (basic - minified) v{version}\n".encode())
    source = (STATIC / "plotly-basic-SOURCE.txt").read_text()
    assert f"plotly.js-basic-dist-min {version}" in source
    assert f"plotly.js-basic-dist-min-{version}.tgz" in source
    assert f"sha256 {hashlib.sha256(bundle).hexdigest()}" in source
    license_text = (STATIC / "plotly-basic-LICENSE.txt").read_text()
    assert license_text.startswith("MIT License") and "Plotly" in license_text
    # one bundle only: an old one left behind would be served for a year
    assert sorted(p.name for p in STATIC.glob("plotly*.js")) == [PLOTLY_JS]


def test_the_pages_draw_only_what_the_bundle_holds() -> None:
    app_js = (STATIC / "app.js").read_text()
    used = set(re.findall(r"""\btype:\s*["'](\w+)["']""", app_js))
    assert "scatter" in used and used <= BASIC_TRACES, used


def test_served_with_a_years_cache_from_the_pages(client: TestClient) -> None:
    r = client.get(f"/static/{PLOTLY_JS}")
    assert r.status_code == 200 and r.content == (STATIC / PLOTLY_JS).read_bytes()
    assert r.headers["cache-control"] == "public, max-age=31536000, immutable"
    assert "javascript" in r.headers["content-type"]
    assert r.headers["content-security-policy"] == CSP
    assert "immutable" not in client.get("/static/app.js").headers.get("cache-control", "")
    run_id = client.get("/api/runs").json()[0]["run_id"]
    for page in (f"/runs/{run_id}", f"/compare?runs={run_id}"):
        assert f'<script src="/static/{PLOTLY_JS}" defer>' in client.get(page).text
    assert client.get("/static/plotly.min.js").status_code == 404  # the full bundle is gone
