"""kill -9 mid-run: every sample up to the last written part (at most one second before the
kill) is readable with pandas.read_parquet, and the record says what is known."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd

from bench.store.run_index import RunIndex

CHILD = """
import sys
from pathlib import Path
from bench.rig.rig import load_rig
from bench.plan_runner.runner import RunOptions
from bench.plans.stand_sequences import step1
from bench.plan_runner.session import run_sequence
from drivers.factory import open_rig

rig = load_rig(sys.argv[1])
run_sequence(rig, step1(repeats=20), Path(sys.argv[2]), open_rig,
             options=RunOptions(realtime=True))
"""


def test_kill_9_mid_run_keeps_everything_up_to_the_last_part(sim_rig_mapped_path, tmp_path):
    out = tmp_path / "runs"
    script = tmp_path / "child.py"
    script.write_text(CHILD, encoding="utf-8")
    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    child = subprocess.Popen([sys.executable, str(script), str(sim_rig_mapped_path), str(out)],
                             env=env, cwd=repo)
    try:
        deadline = time.monotonic() + 30.0
        parts: list[Path] = []
        while time.monotonic() < deadline and len(parts) < 3:
            time.sleep(0.05)
            parts = list(out.glob("*/samples.parquet/part-*.parquet"))
            assert child.poll() is None, "the child run ended before it could be killed"
        assert len(parts) >= 3, "no parts written in time"
        time.sleep(0.4)  # somewhere between two parts
        child.send_signal(signal.SIGKILL)
        killed_at = datetime.now().astimezone()
        child.wait(timeout=10)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    assert child.returncode == -signal.SIGKILL
    run_dir = next(out.glob("*-step1"))
    df = pd.read_parquet(run_dir / "samples.parquet")
    t = df["t_s"].to_numpy()
    assert t[0] < 0.001 and np.all(np.diff(t) > 0)
    assert np.max(np.diff(t)) < 2.0 / 25_000  # no hole: every part complete, in order
    events = pd.read_csv(run_dir / "events.csv")
    started = datetime.fromisoformat(events.loc[events["kind"] == "run_start", "utc"].iloc[0])
    elapsed = (killed_at - started).total_seconds()  # rig time == wall time (realtime pacing)
    assert t[-1] >= elapsed - 1.0 - 0.3, (t[-1], elapsed)  # lost at most ~one second
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["status"] == "running"  # never finished, and no store opened since
    listed = {r.id: r.status for r in RunIndex(out).list()}
    assert listed[run_dir.name] == "killed"
    # opening the store marked run.json too: every reader agrees
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["status"] == "killed" and "kill -9" in meta["reason"]
    assert meta["last_sample_t_s"] == t[-1] and meta["rows"] == t.size


def test_sigterm_mid_run_stops_safely_and_records_it(sim_rig_mapped_path, tmp_path):
    out = tmp_path / "runs"
    repo = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": str(repo)}
    child = subprocess.Popen([sys.executable, "-m", "bench.cli", "step", "--rig",
                              str(sim_rig_mapped_path), "--out", str(out), "--realtime"],
                             env=env, cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and not list(out.glob("*/samples.parquet/part-*")):
            time.sleep(0.05)
        child.send_signal(signal.SIGTERM)
        _, err = child.communicate(timeout=20)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()  # reaped, pipes closed: no leak warning in a later test
    assert child.returncode == 143, err  # 128 + SIGTERM (Ctrl-C is 130)
    run_dir = next(out.glob("*-step1"))
    meta = json.loads((run_dir / "run.json").read_text())
    assert meta["status"] == "abort" and "SIGTERM" in meta["reason"]
    assert meta["safe_stop_errors"] == []
    events = pd.read_csv(run_dir / "events.csv")
    assert events["kind"].tolist()[-2:] == ["safe_stop", "run_end"]
    assert meta["command_line"][:2] == ["rotorbench", "step"]
