"""No secret in any output, page, row or file: a catalog password made of every special
character and a key inside an S3 URI, typed as a user types them, on real PostgreSQL and
S3 (moto)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from urllib.parse import quote

import psycopg
import pytest
from psycopg import sql
from psycopg.conninfo import conninfo_to_dict, make_conninfo

from bench.cli import main

pytestmark = pytest.mark.slow(wall_s=25)

ROTORBENCH = [sys.executable, "-m", "bench.cli"]
PASSWORD = "p#/?@%:&=+ 'q\"\\;~!$w*"  # every character a URL or libpq string treats specially
S3_SECRET = "S3CRET/KEY+with@char"


def _env(s3: object, tmp_path: Path, **extra: str) -> dict[str, str]:
    env = {**os.environ, **s3.env, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "XDG_DATA_HOME": str(tmp_path / "data"), **extra}
    env.pop("ROTORBENCH_STORE", None)
    env.pop("PGPASSWORD", None)
    return env


def _cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*ROTORBENCH, *args], env=env, capture_output=True, text=True,
                          timeout=180)


def _forms(secret: str) -> list[str]:
    """The secret as it could leak: itself, percent-encoded, libpq-quoted."""
    return [secret, quote(secret, safe=""), quote(secret), secret.replace("'", "\\'")]


def _leaks(text: str, secret: str = PASSWORD) -> list[str]:
    return [f for f in _forms(secret) if f in text]


@pytest.fixture
def writer_url(pg_url: str, s3_env: object) -> str:
    """A writer login whose password holds every special character, percent-encoded in
    the URL as libpq wants it; the catalog's data location is saved by store init."""
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    params = conninfo_to_dict(pg_url)
    role = f"wri_{params['dbname']}"  # roles are the cluster's, databases the test's
    with psycopg.connect(pg_url, autocommit=True) as con:
        con.execute(sql.SQL("CREATE ROLE {} LOGIN PASSWORD {} IN ROLE rotorbench_writer")
                    .format(sql.Identifier(role), sql.Literal(PASSWORD)))
    return (f"postgresql://{role}:{quote(PASSWORD, safe='')}@{params['host']}:"
            f"{params['port']}/{params['dbname']}")


def test_a_password_of_every_special_character_appears_nowhere(
        writer_url: str, pg_url: str, s3_env: object, tmp_path: Path) -> None:
    env = _env(s3_env, tmp_path)
    spool = tmp_path / "spool"
    params = conninfo_to_dict(writer_url)
    keywords = make_conninfo("", **params)  # the key=value form docs/lab.md promises
    outputs = []
    step = _cli(["step", "--repeats", "1", "--store", writer_url, "--spool", str(spool)], env)
    assert step.returncode == 0, step.stderr
    assert "stored in postgresql://wri_" in step.stdout and ":***@" in step.stdout
    outputs.append(step)
    runs = _cli(["runs", "--store", keywords, "--json"], env)
    assert runs.returncode == 0, runs.stderr
    assert len(json.loads(runs.stdout)) == 1
    outputs.append(runs)
    outputs.append(_cli(["runs", "--store", writer_url], env))  # the table's title
    sync = _cli(["store", "sync", "--store", writer_url, "--spool", str(spool)], env)
    assert sync.returncode == 0 and ":***@" in sync.stdout, sync.stderr
    outputs.append(sync)
    wrong_port = writer_url.replace(f":{params['port']}/", ":1/")
    refused = _cli(["runs", "--store", wrong_port + "?connect_timeout=2"], env)
    assert refused.returncode == 2 and "cannot connect" in refused.stderr
    outputs.append(refused)
    bad_login = _cli(["runs", "--store", writer_url.replace("//wri_", "//nobody_")], env)
    assert bad_login.returncode == 2
    outputs.append(bad_login)
    raw = (f"postgresql://{params['user']}:{PASSWORD}@{params['host']}:{params['port']}/"
           f"{params['dbname']}")  # not percent-encoded: libpq would misread it
    typed_raw = _cli(["step", "--repeats", "1", "--store", raw, "--spool", str(spool)], env)
    assert typed_raw.returncode == 2 and "percent-encoded" in typed_raw.stderr
    outputs.append(typed_raw)
    for out in outputs:
        text = out.stdout + out.stderr
        assert "Traceback" not in text and not _leaks(text), (out.args, text)
    assert len(typed_raw.stderr.strip().splitlines()) == 1
    for path in spool.rglob("*"):  # the spool: run.json, marker, ledger, index
        if path.is_file():
            assert not _leaks(path.read_bytes().decode("utf-8", "replace")), path
    with psycopg.connect(pg_url) as con:
        dump = json.dumps([con.execute(sql.SQL("SELECT row_to_json(t) FROM {} t").format(
            sql.Identifier(table))).fetchall() for table in ("runs", "settings", "constants")],
            default=str)
    assert not _leaks(dump) and "wri" in dump


def test_the_web_page_header_shows_the_catalog_without_its_password(
        writer_url: str, s3_env: object, tmp_path: Path) -> None:
    from fastapi.testclient import TestClient

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    store = open_store(writer_url, spool=tmp_path / "spool")
    with TestClient(create_app(store)) as client:
        page = client.get("/")
    assert page.status_code == 200
    assert "postgresql://wri_" in page.text and ":***@" in page.text
    assert not _leaks(page.text)


def test_a_key_in_an_s3_data_location_is_refused_and_shown_nowhere(
        pg_url: str, s3_env: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capfd: pytest.CaptureFixture[str]) -> None:
    """Each refused before anything is opened: run in this process (the first test above
    runs the commands as processes of their own), its output read at the file
    descriptors, so what a library writes there is read too."""
    for k, v in _env(s3_env, tmp_path).items():
        if os.environ.get(k) != v:
            monkeypatch.setenv(k, v)
    for k in ("ROTORBENCH_STORE", "PGPASSWORD"):
        monkeypatch.delenv(k, raising=False)
    assert main(["store", "init", pg_url]) == 0
    spool = tmp_path / "spool"
    located = f"s3://AKIALABKEY:{S3_SECRET}@{s3_env.bucket}/runs"
    tries = [["step", "--repeats", "1", "--store", pg_url, "--out", located, "--spool",
              str(spool)],
             ["store", "init", pg_url, "--data", located],
             ["store", "sync", "--store", pg_url, "--out", located, "--spool", str(spool)],
             ["step", "--repeats", "1", "--store", pg_url, "--out",
              f"s3://{s3_env.bucket}/runs?secret_key={quote(S3_SECRET, safe='')}",
              "--spool", str(spool)]]
    for args in tries:
        capfd.readouterr()
        code = main(args)
        out = capfd.readouterr()
        text = out.out + out.err
        assert code == 2, (args, text)
        assert "holds credentials" in out.err and "AWS_ACCESS_KEY_ID" in out.err
        assert len(out.err.strip().splitlines()) == 1 and "Traceback" not in text
        assert not _leaks(text, S3_SECRET) and "AKIALABKEY" not in text, text
    assert not list(spool.glob("*/run.json"))  # nothing recorded
    with psycopg.connect(pg_url) as con:
        dump = json.dumps(con.execute("SELECT row_to_json(s) FROM settings s").fetchall())
    assert "AKIALABKEY" not in dump and not _leaks(dump, S3_SECRET)


def test_a_token_on_the_command_line_is_warned_about(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capfd: pytest.CaptureFixture[str]) -> None:
    """``--token`` is visible in ``ps``: serve says so on stderr and names the variable
    (the port is refused right after, so nothing is served). In this process: what is
    tested is the command's words, not a process."""
    monkeypatch.delenv("ROTORBENCH_TOKEN", raising=False)
    assert main(["serve", "--store", str(tmp_path), "--token", "a-long-enough-token",
                 "--port", "0"]) == 2
    err = capfd.readouterr().err
    assert "--token is visible" in err and "ROTORBENCH_TOKEN" in err
    monkeypatch.setenv("ROTORBENCH_TOKEN", "a-long-enough-token")
    assert main(["serve", "--store", str(tmp_path), "--port", "0"]) == 2
    assert "warning" not in capfd.readouterr().err
