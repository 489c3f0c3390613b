"""A run reaches its own catalog and data location, once: two catalogs (two databases of
the one test cluster) and one spool, on real PostgreSQL and S3 (moto), typed as a user
types the commands."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from psycopg.conninfo import conninfo_to_dict
from rotorbench_tests_services import SUPERUSER_PASSWORD, free_port

from bench.cli import main
from bench.store.lab_catalog import LabCatalog
from bench.store.spool_destinations import LEDGER
from tests.bench.store.conftest import cli_in_process

pytestmark = pytest.mark.slow(wall_s=30)

ROTORBENCH = [sys.executable, "-m", "bench.cli"]


def _env(s3: object, tmp_path: Path, **extra: str) -> dict[str, str]:
    env = {**os.environ, **s3.env, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "XDG_DATA_HOME": str(tmp_path / "data"), **extra}
    env.pop("ROTORBENCH_STORE", None)
    return env


def _cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """A recording command, a process of its own: the ledger tells runs by their process."""
    return subprocess.run([*ROTORBENCH, *args], env=env, capture_output=True, text=True,
                          timeout=180)


def _sync(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return cli_in_process(["store", "sync", *args], env)


def _spelled_otherwise(url: str) -> str:
    """The same catalog as another URL names it: localhost, not 127.0.0.1, and a libpq
    option more."""
    return url.replace("@127.0.0.1:", "@localhost:") + "?connect_timeout=5"


def _second_catalog(pg_url: str) -> str:
    import psycopg

    name = conninfo_to_dict(pg_url)["dbname"] + "_b"
    with psycopg.connect(pg_url, autocommit=True) as con:
        con.execute(f"CREATE DATABASE {name}")
    return pg_url.rsplit("/", 1)[0] + f"/{name}"


def test_two_catalogs_one_spool_each_run_goes_where_it_was_going(
        pg_url: str, s3_env: object, tmp_path: Path) -> None:
    a_url, b_url = pg_url, _second_catalog(pg_url)
    env = _env(s3_env, tmp_path)
    spool = tmp_path / "spool"
    a_data = f"s3://{s3_env.bucket}/a-runs"  # given with --out only: no catalog default
    assert main(["store", "init", a_url]) == 0
    assert main(["store", "init", b_url, "--data", f"s3://{s3_env.bucket}/b-runs"]) == 0
    # A's run: its catalog is there, its object store is not: it waits in the spool
    away = _env(s3_env, tmp_path, AWS_ENDPOINT_URL=f"http://127.0.0.1:{free_port()}")
    a_run = _cli(["step", "--repeats", "1", "--store", a_url, "--out", a_data, "--spool",
                  str(spool)], away)
    assert a_run.returncode == 0 and "spooled:" in a_run.stdout, a_run.stdout + a_run.stderr
    # B's run publishes B's run only
    b_run = _cli(["step", "--repeats", "1", "--store", b_url, "--spool", str(spool)], env)
    assert b_run.returncode == 0 and b_run.stdout.count("stored in") == 1, b_run.stdout
    ids = {json.loads(p.read_text())["id"] for p in spool.glob("*/run.json")}
    assert len(ids) == 2
    b_ids = {r.run_id for r in LabCatalog(b_url).list_runs()}
    (a_id,) = ids - b_ids
    assert len(b_ids) == 1  # B lists B's run; A at most A's own, announced as it ran
    assert {r.run_id for r in LabCatalog(a_url).list_runs()} <= {a_id}
    # syncing B leaves A's run alone and says so
    b_sync = _sync(["--store", b_url, "--spool", str(spool)], env)
    assert b_sync.returncode == 0 and "synced 0 of 0" in b_sync.stdout
    assert "1 runs going to other catalogs" in b_sync.stdout
    # `store sync` alone: each run to its own catalog and data location (the password
    # from PGPASSWORD, as libpq takes it; the spool kept none)
    alone = _sync(["--spool", str(spool)], {**env, "PGPASSWORD": SUPERUSER_PASSWORD})
    assert alone.returncode == 0, alone.stdout + alone.stderr
    assert "synced 1 of 1 waiting runs" in alone.stdout
    (a_row,) = LabCatalog(a_url).list_runs()
    assert a_row.run_id == a_id and a_row.status == "success"
    assert a_row.data.startswith(a_data + "/") and LabCatalog(b_url).count_runs() == 1
    # the same catalog spelled otherwise publishes nothing again
    again = _sync(["--store", _spelled_otherwise(a_url), "--spool", str(spool)], env)
    assert again.returncode == 0 and "synced 0 of 0" in again.stdout, again.stderr
    assert LabCatalog(a_url).count_runs() == 1 and LabCatalog(b_url).count_runs() == 1
    for ledger in (spool / LEDGER).glob("*.json"):  # no secret kept for the way there
        assert SUPERUSER_PASSWORD not in ledger.read_text()


def test_a_run_recorded_with_its_catalog_away_is_resolved_at_sync(
        pg_cluster: object, pg_url: str, s3_env: object, tmp_path: Path) -> None:
    """The catalog is down when the run starts: the ledger keeps host, port and database;
    with it still down, sync says the catalog is unreachable (not "no data location");
    once it is back, the catalog spelled otherwise resolves it to its UUID and takes it."""
    env = _env(s3_env, tmp_path)
    spool = tmp_path / "spool"
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    url = pg_url + "?connect_timeout=2"
    import psycopg

    with psycopg.connect(pg_url, autocommit=True) as con:  # the test cluster commits
        con.execute("CHECKPOINT")  # asynchronously and stops at once: keep what init wrote
    pg_cluster.stop()
    try:
        run = _cli(["step", "--repeats", "1", "--store", url, "--spool", str(spool)], env)
        assert run.returncode == 0 and "spooled:" in run.stdout, run.stdout + run.stderr
        down = _sync(["--store", url, "--spool", str(spool)], env)
        assert down.returncode == 2 and "cannot connect" in down.stderr, down.stderr
        assert "no data location" not in down.stderr
        assert len(down.stderr.strip().splitlines()) == 1
    finally:
        pg_cluster.start()
    (entry,) = [json.loads(p.read_text()) for p in (spool / LEDGER).glob("*.json")]
    assert entry["catalog_id"] is None and entry["params"]["dbname"] in pg_url
    sync = _sync(["--store", _spelled_otherwise(pg_url), "--spool", str(spool)], env)
    assert sync.returncode == 0 and "synced 1 of 1" in sync.stdout, sync.stdout + sync.stderr
    (entry,) = [json.loads(p.read_text()) for p in (spool / LEDGER).glob("*.json")]
    assert entry["catalog_id"] == LabCatalog(pg_url).identity().catalog_id
    (row,) = LabCatalog(pg_url).list_runs()
    assert row.status == "success" and row.data.startswith(f"s3://{s3_env.bucket}/runs/")
