"""The web view is read-only, loopback by default, token-guarded beyond it, and answers
junk with 4xx: never a traceback, never a 500."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.cli import main
from bench.serve.app import create_app
from bench.serve.security import CSP
from bench.store.stores import open_store

TOKEN = "lab-token-0123456789"


@pytest.fixture(scope="module")
def folder_client(recorded: Path) -> TestClient:
    return TestClient(create_app(open_store(str(recorded))))


def test_other_host_needs_a_token(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "--host", "0.0.0.0", "--store", "nowhere"]) == 2
    err = capsys.readouterr().err
    assert "needs --token" in err and "Traceback" not in err
    assert main(["serve", "--host", "0.0.0.0", "--token", "short"]) == 2
    assert "at least 12" in capsys.readouterr().err
    assert main(["serve", "--port", "70000"]) == 2


def test_token_required_on_every_request(recorded: Path) -> None:
    app = create_app(open_store(str(recorded)), token=TOKEN)
    with TestClient(app) as c:
        for path in ("/", "/api/runs", "/static/plotly.min.js", "/openapi.json"):
            assert c.get(path).status_code == 401
        assert c.get("/api/runs", headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert c.get("/api/runs", headers={"Authorization": f"Bearer {TOKEN}"}).status_code \
            == 200
        assert c.get("/api/runs", headers={"X-Rotorbench-Token": TOKEN}).status_code == 200
        r = c.get(f"/login?token={TOKEN}", follow_redirects=False)
        assert r.status_code == 303 and "httponly" in r.headers["set-cookie"].lower()
        assert c.get("/api/runs").status_code == 200  # the cookie now


def test_headers_and_read_only(folder_client: TestClient) -> None:
    r = folder_client.get("/")
    assert r.headers["content-security-policy"] == CSP
    assert "script-src 'self'" in CSP and "http" not in CSP  # no CDN
    assert r.headers["x-content-type-options"] == "nosniff"
    assert "<script src=\"/static/" in folder_client.get(
        f"/runs/{folder_client.get('/api/runs').json()[0]['run_id']}").text
    for method in ("post", "put", "delete", "patch"):
        assert getattr(folder_client, method)("/api/runs").status_code == 405


def test_huge_query_strings_are_414(folder_client: TestClient) -> None:
    assert folder_client.get("/api/runs?bench=" + "x" * 5000).status_code == 414
    assert folder_client.get("/" + "a" * 3000).status_code == 414
    assert folder_client.get("/api/runs?bench=" + "x" * 500).status_code == 422


junk = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)),
               max_size=300)


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(["/api/runs", "/", "/api/compare", "/compare", "/api/constants",
                             "/api/live", "/constants", "/api/runs/{id}/series",
                             "/api/runs/{id}", "/runs/{id}"]),
       params=st.dictionaries(st.sampled_from(["bench", "motor", "status", "since", "until",
                                               "limit", "offset", "page", "per_page", "runs",
                                               "columns", "junk", "esc_mode"]), junk,
                              max_size=5),
       run_id=junk)
def test_fuzzed_requests_never_500(folder_client: TestClient, path: str,
                                   params: dict[str, str], run_id: str) -> None:
    from urllib.parse import quote

    url = path.replace("{id}", quote(run_id, safe="") or "x")
    r = folder_client.get(url, params=params)
    assert r.status_code < 500, (url, params, r.status_code, r.text[:300])
    assert "Traceback" not in r.text


@pytest.mark.parametrize("header", [f"bearer {TOKEN}", f"BEARER {TOKEN}", f"Bearer  {TOKEN} ",
                                    f"bEaReR {TOKEN}"])
def test_the_bearer_scheme_is_case_insensitive(recorded: Path, header: str) -> None:
    with TestClient(create_app(open_store(str(recorded)), token=TOKEN)) as c:
        assert c.get("/api/runs", headers={"Authorization": header}).status_code == 200


@pytest.mark.parametrize("header", [f"Basic {TOKEN}", f"Bearer{TOKEN}", f"{TOKEN}",
                                    f"Bearer {TOKEN}x", "Bearer", f"Token {TOKEN}"])
def test_other_schemes_and_wrong_tokens_are_refused(recorded: Path, header: str) -> None:
    with TestClient(create_app(open_store(str(recorded)), token=TOKEN)) as c:
        assert c.get("/api/runs", headers={"Authorization": header}).status_code == 401


@pytest.mark.parametrize("wrong", ["wrong", "", TOKEN[:-1], TOKEN + "x", TOKEN.upper()])
def test_login_with_a_wrong_token_sets_no_cookie(recorded: Path, wrong: str) -> None:
    with TestClient(create_app(open_store(str(recorded)), token=TOKEN)) as c:
        r = c.get("/login", params={"token": wrong}, follow_redirects=False)
        assert r.status_code == 401 and "set-cookie" not in r.headers
        assert c.get("/api/runs").status_code == 401
        assert "rotorbench_token" not in c.cookies


def test_login_without_a_server_token_sets_no_cookie(folder_client: TestClient) -> None:
    r = folder_client.get("/login", params={"token": "anything"}, follow_redirects=False)
    assert r.status_code == 303 and "set-cookie" not in r.headers
