"""What the lab store refuses and says, on real PostgreSQL and S3 (moto): a reader writes
nothing, a login is told what it lacks, another writer's runs are named as such, a
spooled run.json that cannot be read is named, and a running run is in the catalog."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import psycopg
import pytest
from psycopg.conninfo import conninfo_to_dict

from bench.cli import main
from bench.store.lab_catalog import LabCatalog
from tests.bench.store.conftest import cli_in_process

pytestmark = pytest.mark.slow(wall_s=30)

ROTORBENCH = [sys.executable, "-m", "bench.cli"]


def _login(pg_url: str, name: str, role: str | None) -> str:
    """A new login (``role``: the group it is in) of the test's database."""
    params = conninfo_to_dict(pg_url)
    user = f"{name}_{params['dbname']}"
    with psycopg.connect(pg_url, autocommit=True) as con:
        con.execute(f"CREATE ROLE {user} LOGIN PASSWORD '{name}-pw'"
                    + (f" IN ROLE {role}" if role else ""))
    return f"postgresql://{user}:{name}-pw@{params['host']}:{params['port']}/{params['dbname']}"


def _env(s3: object, tmp_path: Path) -> dict[str, str]:
    env = {**os.environ, **s3.env, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "XDG_DATA_HOME": str(tmp_path / "data")}
    env.pop("ROTORBENCH_STORE", None)
    return env


def _sync(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return cli_in_process(["store", "sync", *args], env)


def _objects(s3: object) -> list[str]:
    import boto3  # moto's own client library, here to read what the server keeps

    got = boto3.client("s3", endpoint_url=s3.endpoint).list_objects_v2(Bucket=s3.bucket)
    return [o["Key"] for o in got.get("Contents", [])]


@pytest.fixture(scope="module")
def laptop_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("laptop") / "runs"
    assert main(["step", "--repeats", "1", "--out", str(out)]) == 0
    return out


def test_a_reader_push_uploads_nothing(pg_url: str, s3_env: object, laptop_runs: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    reader = _login(pg_url, "ronja", "rotorbench_reader")
    assert main(["store", "push", str(laptop_runs), "--store", reader]) == 2
    err = capsys.readouterr().err
    assert "may not record runs" in err and "ronja-pw" not in err
    assert _objects(s3_env) == [] and LabCatalog(pg_url).count_runs() == 0


def test_init_by_a_login_without_rights_says_what_init_needs(
        pg_url: str, capsys: pytest.CaptureFixture[str]) -> None:
    plain = _login(pg_url, "nora", None)
    assert main(["store", "init", plain]) == 2
    err = capsys.readouterr().err
    assert "store init needs a login that may create tables" in err and "CREATEROLE" in err
    assert "writer" not in err and "nora-pw" not in err


@pytest.mark.parametrize("content", [b"[1, 2]", b"\xff\xfe garbage", b"{not json", b"null"])
def test_an_unreadable_spooled_run_is_named_and_fails_the_sync(
        pg_url: str, s3_env: object, laptop_runs: Path, tmp_path: Path, content: bytes,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    spool = tmp_path / "spool"
    bad = spool / "20261129T000000_000000Z-deadbeef-step1"
    bad.mkdir(parents=True)
    (bad / "run.json").write_bytes(content)
    code = main(["store", "sync", "--store", pg_url, "--spool", str(spool)])
    out = capsys.readouterr()
    assert code == 2 and f"still spooled: {bad.name}:" in out.out and "unreadable" in out.out
    assert "Traceback" not in out.out + out.err


def test_a_running_run_is_listed_live_and_another_writer_may_not_sync_it(
        pg_url: str, s3_env: object, tmp_path: Path) -> None:
    """A run is in the catalog as it starts (the web view's /api/live lists it); the run
    ends while the object store is away; another writer's `store sync` says in one line
    whose run it is; its own login delivers it."""
    from fastapi.testclient import TestClient
    from rotorbench_tests_services import s3_server

    from bench.serve.app import create_app
    from bench.store.stores import open_store

    assert main(["store", "init", pg_url]) == 0
    bench_a, bench_b = (_login(pg_url, n, "rotorbench_writer") for n in ("ba", "bb"))
    spool = tmp_path / "spool"
    with s3_server() as own:
        own.create_bucket("lab")
        env = {**_env(s3_env, tmp_path), "AWS_ENDPOINT_URL": own.endpoint}
        bench = subprocess.Popen([*ROTORBENCH, "step", "--repeats", "1", "--realtime",
                                  "--store", bench_a, "--out", "s3://lab/runs", "--spool",
                                  str(spool)], env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        live: list[dict] = []
        with TestClient(create_app(open_store(pg_url, spool=tmp_path / "web"))) as client:
            end = time.monotonic() + 20
            while not live and time.monotonic() < end and bench.poll() is None:
                live = client.get("/api/live").json()
                time.sleep(0.2)
        assert live and live[0]["status"] == "running", "the run never appeared live"
        port = own.port
        own.stop()  # the object store goes away before the run ends
        out, err = bench.communicate(timeout=120)
        assert bench.returncode == 0 and "spooled:" in out, out + err
    with s3_server(port) as back:
        back.create_bucket("lab")
        other = _sync(["--store", bench_b, "--spool", str(spool)], env)
        assert other.returncode == 2, other.stdout + other.stderr
        (line,) = [x for x in other.stdout.splitlines() if x.startswith("still spooled")]
        assert "by login ba_" in line and "login bb_" in line and "writer role" not in line
        own_sync = _sync(["--store", bench_a, "--spool", str(spool)], env)
        assert own_sync.returncode == 0 and "synced 1 of 1" in own_sync.stdout, own_sync.stderr
    (row,) = LabCatalog(pg_url).list_runs()
    assert row.status == "success"
    shutil.rmtree(spool)
