"""A lab run that ends early (a full spool disk, SIGTERM) ends as one line and an exit
code: the trailing upload is stopped and joined before Python shuts down (pyarrow work in
flight at shutdown crashed the process), and the run left in the spool is named with how
to deliver it. Real PostgreSQL and S3 (moto); the full disk is a real one, a tmpfs of
300 KB in a mount namespace of its own (root only)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.cli import main

pytestmark = pytest.mark.slow(wall_s=40)

ROTORBENCH = [sys.executable, "-m", "bench.cli"]


def _env(s3: object, tmp_path: Path) -> dict[str, str]:
    env = {**os.environ, **s3.env, "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "XDG_DATA_HOME": str(tmp_path / "data")}
    env.pop("ROTORBENCH_STORE", None)
    return env


def _small_disk_command(mount: Path, args: list[str]) -> list[str]:
    """``args`` run with ``mount`` a 300 KB tmpfs that only this process sees."""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        pytest.skip("a real full disk needs root (unshare -m, mount -t tmpfs)")
    mount.mkdir()
    quoted = " ".join(f"'{a}'" for a in [*ROTORBENCH, *args])
    return ["unshare", "-m", "sh", "-c",
            f"mount -t tmpfs -o size=300k tmpfs '{mount}' && exec {quoted}"]


def test_a_full_spool_disk_ends_in_one_line_never_a_crash(pg_url: str, s3_env: object,
                                                          tmp_path: Path) -> None:
    """Before, the process died by SIGSEGV in 4 of 11 tries; eight tries here."""
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    for i in range(8):
        mount = tmp_path / f"disk{i}"
        cmd = _small_disk_command(mount, ["step", "--repeats", "3", "--store", pg_url,
                                          "--spool", str(mount / "spool")])
        run = subprocess.run(cmd, env=_env(s3_env, tmp_path), capture_output=True,
                             text=True, timeout=180)
        text = run.stdout + run.stderr
        assert run.returncode == 2, (run.returncode, text)
        assert "No space left on device" in text and "Traceback" not in text
        assert "spooled:" in run.stderr and "rotorbench store sync --store" in run.stderr


def test_a_sigtermed_lab_run_says_how_to_deliver_it(
        pg_url: str, s3_env: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["store", "init", pg_url, "--data", f"s3://{s3_env.bucket}/runs"]) == 0
    spool = tmp_path / "spool"
    bench = subprocess.Popen([*ROTORBENCH, "step", "--repeats", "3", "--realtime", "--store",
                              pg_url, "--spool", str(spool)], env=_env(s3_env, tmp_path),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 60
    while not list(spool.glob("*/samples.parquet/part-*.parquet")):
        assert time.monotonic() < end and bench.poll() is None
        time.sleep(0.1)
    bench.send_signal(signal.SIGTERM)
    out, err = bench.communicate(timeout=60)
    assert bench.returncode == 143, out + err
    assert "terminated" in err and "spooled:" in err and "rotorbench store sync" in err
    assert "Traceback" not in out + err
    # the delivery it names, in this process (test_lab_secrets runs it as one of its own)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    monkeypatch.delenv("ROTORBENCH_STORE", raising=False)
    capsys.readouterr()
    code = main(["store", "sync", "--store", pg_url, "--spool", str(spool)])
    sync = capsys.readouterr()
    assert code == 0 and "synced 1 of 1" in sync.out, sync.out + sync.err
