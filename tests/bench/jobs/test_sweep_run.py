"""``rotorbench fly --sweep --out``: the file, resume after Ctrl-C, refusals (exit 2)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from rotorbench_tests_services import free_port

from bench.cli import main
from bench.jobs.sweep_parts import parts_folder
from optimizer.model.grid import METRIC_KEYS
from optimizer.sweep.keys import DESIGN_KEYS, design_id
from optimizer.sweep.rows import columns
from tests.bench.jobs.conftest import SWEEP

pytestmark = pytest.mark.slow(wall_s=20)  # sweeps in subprocesses, one interrupted: started first

REPO = Path(__file__).resolve().parents[3]


def test_the_file_has_a_row_per_design_and_its_spec(reference) -> None:
    assert reference.num_rows == 44
    assert reference.schema.names == [c for c, _ in columns(["roll_step"])]
    assert {"design_id", *DESIGN_KEYS, *METRIC_KEYS, "thrust_to_weight", "can_hover",
            "roll_step_rise_time_ms", "roll_step_overshoot_pct", "roll_step_settling_time_ms",
            "roll_step_saturation_pct", "error"} <= set(reference.schema.names)
    rows = reference.to_pylist()
    assert all(r["design_id"] == design_id(*(r[k] for k in DESIGN_KEYS)) for r in rows)
    assert all(r["error"] is None and r["can_hover"] for r in rows)
    assert min(r["thrust_to_weight"] for r in rows) >= 1.2
    assert str(reference.schema.field("roll_step_rise_time_ms").type) == "double"
    spec = json.loads(reference.schema.metadata[b"rotorbench_sweep"])
    assert spec["maneuvers"] == ["roll_step"] and spec["designs"] == 44
    assert spec["catalog"].endswith("thesis-e")
    options = spec["options"]
    assert options["actuators"] == [4] and options["payload_kg"] == 0.0
    assert options["hover_margin"]["min_thrust_to_weight"] == 1.2
    assert (options["layout"], options["drag_n_s_m"], options["step_run"]) == ("x", 0.0, None)


def test_the_ranking_reads_the_sweeps_rows(capsys, reference) -> None:
    """``fly --sweep`` without --out: the rows of the same engine, as a ranking."""
    assert main(["fly", "--sweep", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    by_key = {(r["propeller"], r["motor"], r["battery"]): r for r in reference.to_pylist()}
    assert len(doc["rows"]) == 44 and doc["spearman_rho"] > 0.99
    for r in doc["rows"]:
        row = by_key[(r["propeller"], r["motor"], r["battery"])]
        assert r["rise_time_ms"] == row["roll_step_rise_time_ms"]
        assert r["time_constant_ms"] == row["time_constant_ms"]


def test_ctrl_c_keeps_the_parts_and_the_same_command_resumes(capsys, tmp_path,
                                                             reference) -> None:
    """Ctrl-C at a terminal (SIGINT to the process group: the command and its LocalCluster
    workers) during a 2-worker sweep: the finished chunks stay, one line each says so, no
    worker prints a traceback; the same command in this process flies the rest."""
    out = tmp_path / "sweep.parquet"
    argv = [*SWEEP, "--out", str(out), "--chunk-size", "4"]  # 11 chunks
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen([sys.executable, "-m", "bench.cli", *argv, "--workers", "2"],
                             env=env, cwd=REPO, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    parts = parts_folder(out)
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not list(parts.glob("part-*.parquet")):
            time.sleep(0.01)
            assert child.poll() is None, "the sweep ended before it could be interrupted"
        os.killpg(child.pid, signal.SIGINT)
        _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
            child.communicate()
    assert child.returncode == 130, err
    kept = sum(pq.read_metadata(p).num_rows for p in parts.glob("part-*.parquet"))
    assert 1 <= kept < 44 and not out.exists()
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert err.strip().splitlines()[-2:] == [
        f"kept {kept} of 44 designs in {parts}; run the same command again to fly the rest",
        "rotorbench: interrupted"]
    # other options at the same --out: refused, the parts untouched
    assert main([*SWEEP, "gust", "--out", str(out)]) == 2
    line = capsys.readouterr().err.strip()
    assert "\n" not in line and f"{parts} holds an unfinished sweep" in line
    assert 'maneuvers: ["roll_step"] there, ["roll_step", "gust"] now' in line
    # the same command flies the rest
    assert main(argv) == 0
    assert f"resumed: {kept} of 44 done" in capsys.readouterr().err
    assert pq.read_table(out).equals(reference)
    assert not parts.exists()


def test_without_dask_the_command_names_the_extra(capsys, monkeypatch, tmp_path) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    out = tmp_path / "s.parquet"
    assert main([*SWEEP, "--workers", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "pip install 'rotorbench[sweep]'" in err
    assert list(tmp_path.iterdir()) == []


def test_an_unreachable_scheduler_is_one_line_within_seconds(capsys, tmp_path) -> None:
    address = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    start = time.monotonic()
    assert main([*SWEEP, "--scheduler", address, "--out", str(tmp_path / "s.parquet")]) == 2
    assert time.monotonic() - start < 15
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert err.startswith(f"rotorbench: error: --scheduler {address}: cannot reach")
    assert list(tmp_path.iterdir()) == []  # nothing half-written


CASE = ["--actuators", "4", "--propeller", "P4", "--motor", "M1", "--battery", "B3"]


@pytest.mark.parametrize("argv, words", [
    ([*SWEEP, "--out", "{tmp}/missing/s.parquet"], "folder {tmp}/missing does not exist"),
    ([*SWEEP, "--out", "{tmp}/s.csv"], "expected a file name ending in .parquet"),
    ([*SWEEP, "--out", "{tmp}/s.parquet", "--workers", "0"], "--workers: expected"),
    ([*SWEEP, "--out", "{tmp}/s.parquet", "--chunk-size", "0"], "--chunk-size: expected"),
    ([*SWEEP, "--out", "{tmp}/s.parquet", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"],
     "give one"),
    (["fly", "--sweep", "--maneuver", "gust"], "--maneuver applies to --sweep --out"),
    (["fly", "--sweep", "--actuators", "4", "6"], "the ranking (--sweep without --out)"),
    ([*SWEEP, "--out", "{tmp}/s.parquet", "--plot", "{tmp}"], "--plot draws the ranking"),
    ([*SWEEP, "--out", "{tmp}/s.parquet", "--parallel", "2"], "--parallel needs --series"),
    ([*SWEEP, "--out", "{tmp}/s.parquet", "--actuators", "5"], "flies 4, 6 or 8, got 5"),
    (["fly", *CASE, "--out", "{tmp}/s.parquet"], "--out has no effect without --sweep"),
    (["fly", *CASE, "--flyable"], "--flyable has no effect without --sweep"),
    (["fly", *CASE, "--actuators", "4", "6"], "one count names one design"),
])
def test_bad_input_is_one_line_exit_2(capsys, tmp_path, argv, words) -> None:
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    assert words.replace("{tmp}", str(tmp_path)) in err
    assert list(tmp_path.iterdir()) == []
