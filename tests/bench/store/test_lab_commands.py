"""The lab catalog end to end, typed as a user would: two benches recording at once into
PostgreSQL + S3, listing, fitting a run by id, a reader-only login, an outage mid-run and
`store sync`, and no password anywhere it could leak."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import psycopg
import pytest
from rotorbench_tests_services import SUPERUSER_PASSWORD, Postgres, s3_server

from bench.cli import main
from tests.bench.store.conftest import as_environment

pytestmark = pytest.mark.slow(wall_s=30)  # servers started, stopped and restarted: started first

ROTORBENCH = [sys.executable, "-m", "bench.cli"]


def _env(s3: object, tmp_path: Path, **extra: str) -> dict[str, str]:
    env = {**os.environ, **s3.env, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "XDG_DATA_HOME": str(tmp_path / "data"), **extra}
    env.pop("ROTORBENCH_STORE", None)
    return env


def _cli_here(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """A command run in this process through ``main``, the entry point ``rotorbench`` runs,
    for the steps of a test that are not about a process of their own (a fresh interpreter
    per step was most of this file's CPU); its exit code, stdout and stderr."""
    capsys.readouterr()
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def _runs(url: str, capsys: pytest.CaptureFixture[str]) -> list[dict]:
    """``runs --json`` (in-process; test_lab_secrets runs it as a process of its own)."""
    code, out, err = _cli_here(capsys, "runs", "--store", url, "--json")
    assert code == 0, err
    return json.loads(out)


def _under_way(spool: Path, bench: subprocess.Popen[str] | subprocess.Popen[bytes]) -> None:
    """Returns once the recording ``bench`` has written its first part into ``spool``."""
    end = time.monotonic() + 60
    while not list(spool.glob("*/samples.parquet/part-*.parquet")):
        assert time.monotonic() < end and bench.poll() is None
        time.sleep(0.1)


def test_two_benches_at_once_then_list_fit_and_push(
        pg_url: str, s3_env: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    env = _env(s3_env, tmp_path)
    as_environment(monkeypatch, env)
    data = f"s3://{s3_env.bucket}/runs"
    assert main(["store", "init", pg_url]) == 0
    benches = [subprocess.Popen(
        [*ROTORBENCH, "step", "--repeats", "3", "--store", pg_url, "--out", data, "--bench",
         name, "--spool", str(tmp_path / f"spool-{name}"), "--seed", str(i)], env=env,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for i, name in enumerate(("stand-a", "stand-b"))]
    outs = [p.communicate(timeout=300) for p in benches]
    for p, (out, err) in zip(benches, outs, strict=True):
        assert p.returncode == 0, err
        assert "stored in postgresql://postgres:***@" in out and SUPERUSER_PASSWORD not in out
    runs = _runs(pg_url, capsys)
    assert sorted(r["bench"] for r in runs) == ["stand-a", "stand-b"]
    assert len({r["run_id"] for r in runs}) == 2
    import pandas as pd

    for r in runs:  # the catalog's row count is the recorded one; the data is in the bucket
        (local,) = tmp_path.glob(f"spool-*/{r['run_id']}")
        assert r["samples"] == len(pd.read_parquet(local / "samples.parquet")) > 100_000
        assert r["data"] == f"{data}/{r['run_id']}"
    assert all(r["status"] == "success" and r["sequence"] == "step1" for r in runs)
    fit = subprocess.run([*ROTORBENCH, "fit", runs[0]["run_id"], "--store", pg_url, "--json"],
                         env=env, capture_output=True, text=True, timeout=120)
    assert fit.returncode == 0, fit.stderr
    assert 0.01 < json.loads(fit.stdout)["tau_up_ms"] / 1e3 < 0.5
    # the catalog rows and run.json never hold the password
    with psycopg.connect(pg_url) as con:
        dump = json.dumps(con.execute("SELECT row_to_json(runs) FROM runs").fetchall(),
                          default=str)
    assert SUPERUSER_PASSWORD not in dump and '"operator"' in dump and "sha256" in dump
    for meta in (tmp_path).glob("spool-*/*/run.json"):
        assert SUPERUSER_PASSWORD not in meta.read_text()
    # a laptop pushes the same runs again: nothing duplicated
    push = subprocess.run([*ROTORBENCH, "store", "push", str(tmp_path / "spool-stand-a"),
                           "--store", pg_url, "--out", data], env=env, capture_output=True,
                          text=True, timeout=120)
    assert push.returncode == 0, push.stderr
    assert "pushed 0 runs (1 already there)" in push.stdout
    assert len(_runs(pg_url, capsys)) == 2


def test_reader_only_login_is_refused_before_anything_spins(
        pg_url: str, s3_env: object, tmp_path: Path, capsys: pytest.CaptureFixture[str]
        ) -> None:
    assert main(["store", "init", pg_url]) == 0
    with psycopg.connect(pg_url, autocommit=True) as con:
        con.execute("CREATE ROLE ronja LOGIN PASSWORD 'ronja-pw' IN ROLE rotorbench_reader")
    reader = pg_url.replace(f"postgres:{SUPERUSER_PASSWORD}@", "ronja:ronja-pw@")
    spool = tmp_path / "spool"
    code = main(["step", "--repeats", "1", "--store", reader, "--out",
                 f"s3://{s3_env.bucket}/r", "--spool", str(spool)])
    err = capsys.readouterr().err
    assert code == 2 and "user ronja may not record runs" in err and "rotorbench_writer" in err
    assert "ronja-pw" not in err and not any(spool.glob("*/run.json"))


def test_folder_out_to_s3_without_a_catalog_is_refused(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    assert main(["step", "--repeats", "1", "--out", "s3://lab/runs"]) == 2
    assert "give the catalog with --store postgresql://" in capsys.readouterr().err


def test_outage_mid_run_then_sync(pg_cluster: Postgres, pg_url: str, tmp_path: Path,
                                  monkeypatch: pytest.MonkeyPatch,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Both servers stop while a bench records in real time: the run ends normally,
    says it is spooled, and `store sync` delivers it once the servers are back. (The
    session's cluster stops and starts again, as test_spool_destinations' does; the S3
    server is the test's own.)"""
    with s3_server() as s3:
        env = _env(s3, tmp_path)
        as_environment(monkeypatch, env)
        url = pg_url
        spool = tmp_path / "spool"
        s3.create_bucket("lab")
        assert main(["store", "init", url, "--data", "s3://lab/runs"]) == 0
        bench = subprocess.Popen([*ROTORBENCH, "step", "--repeats", "1", "--realtime",
                                  "--store", url, "--spool", str(spool)],
                                 env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True)
        _under_way(spool, bench)  # (4.5 s in real time)
        with psycopg.connect(url, autocommit=True) as con:  # the test cluster commits
            con.execute("CHECKPOINT")  # asynchronously and stops at once: keep what it has
        pg_cluster.stop()
        try:
            port = s3.port
            s3.stop()
            out, err = bench.communicate(timeout=120)
        finally:
            pg_cluster.start()
        assert bench.returncode == 0, err
        assert "success" in out and "spooled:" in out and "store sync" in out
        assert SUPERUSER_PASSWORD not in out + err
        with s3_server(port) as back:
            back.create_bucket("lab")
            sync = [_cli_here(capsys, "store", "sync", "--store", url, "--spool", str(spool))
                    for _ in range(2)]
            assert "synced 1 of 1 waiting runs" in sync[0][1], sync[0][2]
            assert "synced 0 of 0 waiting runs" in sync[1][1]
            (run,) = _runs(url, capsys)
            assert run["status"] == "success" and run["samples"] > 100_000


def test_kill_9_keeps_the_spooled_run_and_sync_delivers_it(
        pg_url: str, s3_env: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import signal

    env = _env(s3_env, tmp_path)
    as_environment(monkeypatch, env)
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    spool = tmp_path / "spool"
    bench = subprocess.Popen([*ROTORBENCH, "step", "--repeats", "3", "--realtime", "--store",
                              pg_url, "--spool", str(spool)], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _under_way(spool, bench)
    time.sleep(1.5)
    bench.send_signal(signal.SIGKILL)
    bench.communicate(timeout=30)
    _, out, err = _cli_here(capsys, "store", "sync", "--store", pg_url, "--spool", str(spool))
    assert "synced 1 of 1 waiting runs" in out, out + err
    (run,) = _runs(pg_url, capsys)
    assert run["status"] == "killed" and run["samples"] > 0


def test_a_bench_records_with_the_database_away_from_the_start(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No catalog to reach when the run starts: it records into the spool, ends normally
    and says it is spooled (store sync delivers it later; tested above)."""
    from rotorbench_tests_services import free_port

    url = f"postgresql://bench:hidden-pw@127.0.0.1:{free_port()}/lab?connect_timeout=1"
    spool = tmp_path / "spool"
    assert main(["step", "--repeats", "1", "--store", url, "--spool", str(spool)]) == 0
    out = capsys.readouterr().out
    assert "success" in out and "spooled:" in out and "hidden-pw" not in out
    (run,) = spool.glob("*/run.json")
    assert json.loads(run.read_text())["status"] == "success"
