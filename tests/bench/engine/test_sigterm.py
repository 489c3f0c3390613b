"""`kill PID` (SIGTERM) ends every command as Ctrl-C does, the ESC left idle, but with
exit 143 (Ctrl-C exits 130).
`step`, `sweep` and `calibrate` did; `console` and `demo` died by the signal: the console's
manual session stayed 'running' in its run.json with no safe stop, its window lived on for
a minute, and the demo left its temporary folder behind."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[3]


def _terminate_when(argv: list[str], ready: Callable[[], bool]) -> tuple[int, str]:
    """Run ``rotorbench ARGV`` as a user would, `kill` it (SIGTERM) once ``ready()``."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "QT_QPA_PLATFORM": "offscreen"}
    child = subprocess.Popen([sys.executable, "-m", "bench.cli", *argv], env=env, cwd=REPO,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    try:
        deadline = time.monotonic() + 60.0
        while not ready():
            assert child.poll() is None, "the command ended before it could be terminated"
            assert time.monotonic() < deadline, "the command never got going"
            time.sleep(0.05)
        child.send_signal(signal.SIGTERM)
        # the window process shares stderr: communicate returns once it is gone too
        _, err = child.communicate(timeout=30)
    finally:
        if child.poll() is None or not child.stderr.closed:
            with contextlib.suppress(ProcessLookupError):  # the command, a window it left
                os.killpg(child.pid, signal.SIGKILL)
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    return child.returncode, err


def test_sigterm_on_the_console_makes_the_running_session_safe(tmp_path: Path) -> None:
    pytest.importorskip("pyqtgraph")
    out = tmp_path / "runs"
    code, err = _terminate_when(
        ["console", "--rig", str(REPO / "bench" / "data" / "rigs" / "sim.toml"), "--selftest",
         "--out", str(out)],
        lambda: any(out.glob("*-manual/samples.parquet/part-*")))
    assert code == 143, err
    assert err.strip().splitlines()[-1] == "rotorbench: terminated"
    (run,) = out.glob("*-manual")
    meta = json.loads((run / "run.json").read_text())
    assert meta["status"] != "running", meta["status"]  # the run loop ended it and recorded
    throttle = pd.read_parquet(run / "samples.parquet", columns=["throttle_us"])
    assert throttle["throttle_us"].iloc[-1] == 1000.0  # the ESC idle at the end


def test_sigterm_on_the_demo_leaves_nothing_half_written(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    code, err = _terminate_when(["demo", "--out", str(out)],
                                lambda: any(tmp_path.glob(".demo*/runs/*/run.json")))
    assert code == 143, err
    assert err.strip().splitlines()[-1] == "rotorbench: terminated"
    assert list(tmp_path.iterdir()) == []  # no demo folder, no temporary one
