"""run.log: every run keeps what happened on the way (the rig opened, the devices that
answered, each segment, late check-ins and where the loop was, why it stopped); the
terminal shows only what -v / --log-level ask for, and never on stdout."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from pathlib import Path

import pytest

from bench.engine import run_log
from bench.engine.recorder import RunRecorder
from bench.engine.watchdog import where
from bench.plan_runner.runner import Runner, RunOptions
from bench.plans.sequences import EscRange, compile_plan
from bench.plans.stand_sequences import step1

ESC = EscRange(idle_us=1000.0, min_us=1050.0, max_us=1900.0)
CLI = [sys.executable, "-m", "bench.cli"]


def _log_of(run_dir: Path) -> str:
    meta = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
    assert meta["log"] == "run.log"
    return (run_dir / "run.log").read_text(encoding="utf-8")


def test_a_watchdog_stop_says_where_the_loop_was(fakes, tmp_path: Path) -> None:
    rig = fakes.FakeRig()
    rig.faults.stall_at_s = rig.clock.t + 3.3
    rig.faults.stall_wall_s = 0.9  # inside the load cell's read: FakeRig.before_read
    plan = compile_plan(step1(repeats=3), ESC, lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)
    rec = RunRecorder(tmp_path / "run", {})
    result = Runner(rig, plan, ESC, {"thrust_n": 10.0}, rec,
                    RunOptions(watchdog_timeout_s=0.3)).run()
    assert result.status == "abort"
    text = _log_of(tmp_path / "run")
    trip = next(line for line in text.splitlines() if "the loop was at" in line)
    # where the watchdog's thread found the loop: asleep in the stalled read
    assert "stalled" in trip
    assert "before_read" in trip and "_read_devices" in trip
    assert "run ended: abort: watchdog" in text
    assert "safe stop (idle + disarm) done" in text


def test_a_late_check_in_is_logged_with_where_it_came_from(fakes, tmp_path: Path) -> None:
    rig = fakes.FakeRig()
    rig.faults.stall_at_s = rig.clock.t + 3.3
    rig.faults.stall_wall_s = 0.35  # late (over half the timeout) but no trip
    plan = compile_plan(step1(repeats=2), ESC, lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)
    rec = RunRecorder(tmp_path / "run", {})
    result = Runner(rig, plan, ESC, {"thrust_n": 10.0}, rec,
                    RunOptions(watchdog_timeout_s=0.6)).run()
    assert result.status == "success"
    late = [line for line in _log_of(tmp_path / "run").splitlines() if "late check-in" in line]
    assert late, "a 0.35 s stall of a 0.6 s watchdog is a late check-in"
    assert "timeout 0.6 s" in late[0] and "_deliver" in late[0]


def test_where_names_the_projects_frames_innermost_first() -> None:
    def inner() -> str:
        return where(sys._getframe())

    def outer() -> str:
        return inner()

    text = outer()
    first, second = text.split(" < ")[:2]
    assert first.startswith("test_run_log.py:") and first.endswith(" inner")
    assert second.endswith(" outer")
    assert where(None).startswith("unknown")


def test_the_loggers_levels_are_the_programs_again_after_a_run(fakes, tmp_path: Path) -> None:
    """A program using rotorbench as a library keeps its own logging settings: the run
    lowers the project's loggers only while it records."""
    before = {name: logging.getLogger(name).level for name in run_log.PACKAGES}
    rig = fakes.FakeRig()
    plan = compile_plan(step1(repeats=1), ESC, lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)
    Runner(rig, plan, ESC, {"thrust_n": 10.0}, RunRecorder(tmp_path / "run", {}),
           RunOptions()).run()
    assert {name: logging.getLogger(name).level for name in run_log.PACKAGES} == before
    assert not any(isinstance(h, run_log.RunLogCapture)
                   for name in run_log.PACKAGES for h in logging.getLogger(name).handlers)


def test_lines_before_the_run_folder_exists_are_kept_for_it(tmp_path: Path) -> None:
    log = logging.getLogger("drivers.some_device")
    with run_log.capture():
        log.info("the device answered: v1.2")
        rec = RunRecorder(tmp_path / "run", {})
        log.info("during the run")
        rec.finish("success", "done")
        log.info("after the run: not in its log")
    text = (tmp_path / "run" / "run.log").read_text(encoding="utf-8")
    lines = text.splitlines()
    assert "the device answered: v1.2" in lines[0]
    assert "during the run" in text and "after the run" not in text


@pytest.mark.slow(wall_s=8)
def test_cli_step_writes_run_log_and_v_logs_to_stderr_only(sim_rig_path: Path,
                                                            tmp_path: Path) -> None:
    out = tmp_path / "runs"
    quiet = subprocess.run([*CLI, "step", "--rig", str(sim_rig_path), "--out", str(out),
                            "--repeats", "1"], capture_output=True, text=True, timeout=120,
                           cwd=tmp_path)
    assert quiet.returncode == 0, quiet.stderr
    assert "INFO" not in quiet.stderr and "INFO" not in quiet.stdout
    (run_dir,) = out.glob("*-step1")  # (a map sweep ran before it: the rig had no map)
    text = _log_of(run_dir)
    for expected in ("opening esc", "esc answered", "load_cell answered", "segment 0 arm",
                     "run started", "run ended: success: sequence complete", "recorded:"):
        assert expected in text, expected

    loud = subprocess.run([*CLI, "step", "--rig", str(sim_rig_path), "--out", str(out),
                           "--repeats", "1", "-v"], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert loud.returncode == 0, loud.stderr
    assert "rotorbench: INFO: drivers.factory: esc answered" in loud.stderr
    assert "segment 0" not in loud.stderr  # -v: what the bench does; -vv: the details
    assert "INFO" not in loud.stdout

    chatty = subprocess.run([*CLI, "--log-level", "debug", "step", "--rig",
                             str(sim_rig_path), "--out", str(out), "--repeats", "1"],
                            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert chatty.returncode == 0, chatty.stderr
    assert "segment 0 arm" in chatty.stderr and "DEBUG" not in chatty.stdout


def test_cli_refuses_an_unknown_log_level(tmp_path: Path) -> None:
    res = subprocess.run([*CLI, "--log-level", "loud", "runs"], capture_output=True,
                         text=True, timeout=60, cwd=tmp_path)
    assert res.returncode == 2
    assert "--log-level" in res.stderr and "Traceback" not in res.stderr
