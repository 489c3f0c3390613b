"""One sweep per ``--out`` at a time (``bench.jobs.sweep_lock``): a second is refused in
one line, and a killed sweep leaves no lock behind."""

from __future__ import annotations

import os
import signal

import pyarrow.parquet as pq
import pytest

from bench.cli import main
from bench.jobs.sweep_lock import lock_path
from bench.jobs.sweep_parts import parts_folder
from tests.bench.jobs.conftest import SWEEP, run_cli, start_sweep, stop, wait_for_parts

pytestmark = pytest.mark.slow(wall_s=15)  # two sweeps in subprocesses


def test_a_second_sweep_at_the_same_out_is_refused_and_a_killed_one_resumes(
        tmp_path, capsys, reference) -> None:
    """While one ``rotorbench fly --sweep`` writes ``--out``, the same command in another
    process is refused (one line naming the first, exit 2) and touches nothing; the first
    is then SIGKILLed, and the same command takes the lock it held and finishes."""
    out = tmp_path / "sweep.parquet"
    argv = [*SWEEP, "--out", str(out)]
    first = start_sweep([*argv, "--chunk-size", "3"])  # 15 chunks: seconds of flying
    try:
        wait_for_parts(out, first)
        # held still mid-sweep (a stopped process keeps its lock), so the second cannot
        # come too late on a loaded host: the first once finished while it started
        os.killpg(first.pid, signal.SIGSTOP)
        second = run_cli(argv)
        assert first.poll() is None, "the first sweep ended before the second was refused"
        os.killpg(first.pid, signal.SIGKILL)
    finally:
        stop(first)
    assert second.returncode == 2, second.stderr
    assert second.stderr.strip() == (
        f"rotorbench: error: --out {out}: another sweep is writing it (process {first.pid}) "
        f"(lock {lock_path(out)}); wait for it to end or choose another --out")
    kept = sum(pq.read_metadata(p).num_rows for p in parts_folder(out).glob("part-*.parquet"))
    assert kept and not out.exists()
    assert main(argv) == 0  # the dead process's lock is no lock
    assert f"resumed: {kept} of 44 done" in capsys.readouterr().err
    assert pq.read_table(out).equals(reference)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.parquet"]
