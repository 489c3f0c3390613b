"""Ctrl-C or SIGTERM on a running bench command says where the aborted run was recorded
and with which status (it used to print only 'rotorbench: interrupted'), then exits 130
(Ctrl-C) or 143 (SIGTERM: 128 + 15, as a shell reports `kill`; it used to exit 130 too)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.store.indexed_run import RunInterrupted, indexed_run


@pytest.mark.parametrize(("sig", "how", "code", "last"), [
    (signal.SIGINT, "Ctrl-C", 130, "rotorbench: interrupted"),
    (signal.SIGTERM, "SIGTERM", 143, "rotorbench: terminated")])
def test_an_interrupted_step_names_its_run_folder_and_status(sim_rig_mapped_path, tmp_path,
                                                             sig, how, code, last):
    out = tmp_path / "runs"
    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    child = subprocess.Popen([sys.executable, "-m", "bench.cli", "step", "--rig",
                              str(sim_rig_mapped_path), "--out", str(out), "--realtime"],
                             env=env, cwd=repo, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and not list(out.glob("*/samples.parquet/part-*")):
            time.sleep(0.05)
            assert child.poll() is None, "the step ended before it could be interrupted"
        child.send_signal(sig)
        _, err = child.communicate(timeout=20)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    assert child.returncode == code, err
    (run_dir,) = out.glob("*-step1")
    status = json.loads((run_dir / "run.json").read_text())["status"]
    assert status == "abort"
    assert err.strip().splitlines()[-2:] == [
        f"rotorbench: run aborted by operator ({how}): ESC idle and disarmed; "
        f"recorded in {run_dir} (status abort)",
        last,
    ]


def test_an_interrupt_before_the_runner_started_is_recorded_as_fail(tmp_path):
    with pytest.raises(RunInterrupted) as info, indexed_run(tmp_path, "step1", {"kind": "x"}):
        raise KeyboardInterrupt
    exc = info.value
    assert isinstance(exc, KeyboardInterrupt)  # the CLI still exits 130
    assert exc.run_dir.parent == tmp_path and exc.status == "fail"
    assert json.loads((exc.run_dir / "run.json").read_text())["status"] == "fail"
    assert exc.summary("run", "ESC idle and disarmed") == (
        f"run aborted by operator (Ctrl-C): ESC idle and disarmed; recorded in {exc.run_dir} "
        "(status fail)")
