"""``rotorbench store init|sync|push`` as a user types them, on real PostgreSQL and S3."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bench.cli import main
from bench.store.lab_catalog import LabCatalog


@pytest.fixture(scope="module")
def laptop_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A laptop's folder store: two short step runs and their stored constants."""
    out = tmp_path_factory.mktemp("laptop") / "runs"
    for _ in range(2):
        assert main(["step", "--repeats", "2", "--out", str(out)]) == 0
    runs = sorted(p.parent for p in out.glob("*/run.json"))
    assert main(["constants", "--out", str(out), "--add", str(runs[0])]) == 0
    return out


def test_init_twice_then_push_twice(pg_url: str, s3_env: object, laptop_runs: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    data = f"s3://{s3_env.bucket}/runs"
    assert main(["store", "init", pg_url, "--data", data]) == 0
    assert main(["store", "init", pg_url]) == 0
    out = capsys.readouterr().out
    assert "(created)" in out and "(already current)" in out
    assert "s3cret-superuser-pw" not in out and "postgres:***@" in out
    assert main(["store", "push", str(laptop_runs), "--store", pg_url]) == 0
    first = capsys.readouterr().out
    assert "pushed 2 runs (0 already there), 1 constants rows (0 already there)" in first
    assert main(["store", "push", str(laptop_runs), "--store", pg_url]) == 0
    again = capsys.readouterr().out
    assert "pushed 0 runs (2 already there), 0 constants rows (1 already there)" in again
    assert again.count("already in the catalog") == 2
    cat = LabCatalog(pg_url)
    assert cat.count_runs() == 2 and len(cat.constants(history=True)) == 1
    assert all(r.data.startswith(data) for r in cat.list_runs())


def test_sync_delivers_the_spool_once(pg_url: str, s3_env: object, laptop_runs: Path,
                                      tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    spool = tmp_path / "spool"  # runs no lab command recorded: --store names their catalog
    shutil.copytree(laptop_runs, spool, ignore=shutil.ignore_patterns(".published"))
    monkeypatch.setenv("ROTORBENCH_STORE", pg_url)
    assert main(["store", "init", pg_url]) == 0
    assert main(["store", "sync", "--spool", str(spool), "--out",
                 f"s3://{s3_env.bucket}/r"]) == 0
    assert "synced 2 of 2 waiting runs" in capsys.readouterr().out
    assert main(["store", "sync", "--spool", str(spool), "--out",
                 f"s3://{s3_env.bucket}/r"]) == 0
    assert "synced 0 of 0 waiting runs" in capsys.readouterr().out


def test_no_data_location_and_folder_url_are_one_line_errors(
        pg_url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["store", "init", pg_url]) == 0
    assert main(["store", "push", str(tmp_path), "--store", pg_url]) == 2
    err = capsys.readouterr().err
    assert "no data location" in err and "s3cret" not in err
    assert main(["store", "init", str(tmp_path)]) == 2
    assert "needs a postgresql:// URL" in capsys.readouterr().err
    assert main(["store", "sync", "--store", "mysql://x"]) == 2
    assert "unknown kind 'mysql'" in capsys.readouterr().err
