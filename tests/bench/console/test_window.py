"""The console window, offscreen, against the bench side that runs the rig.

Two set-ups, each for what it can show:
- pytest-qt drives the window in this process while :class:`ConsoleBench` serves it on a
  thread (same pipe, shared ring and heartbeat as across processes): the operator's clicks
  and keys, what the window shows (banner, plans, history) and what got recorded.
- The window in a spawned process of its own, as ``rotorbench console`` runs it, with the
  bench here: only then can the test kill it or stop it (SIGKILL, SIGSTOP) mid-run and
  measure the time from its death to the ESC made safe.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import re
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

os.environ["QT_QPA_PLATFORM"] = "offscreen"
pytest.importorskip("pyqtgraph")
pytest.importorskip("pytestqt")

from pyqtgraph.Qt import QtCore

from bench.console.link import HEARTBEAT_BOUND_S, BenchLink
from bench.console.server import ConsoleBench
from bench.rig.rig import default_rig_path, load_rig
from drivers.factory import open_rig

pytestmark = pytest.mark.slow(wall_s=60)  # windows on paced benches in real time: started first

Key = QtCore.Qt.Key
LEFT = QtCore.Qt.MouseButton.LeftButton
IDLE = 1000.0
# window and bench share one interpreter in the served set-up: a long paint or collection
# holding the GIL can stall the run loop past its 0.5 s watchdog, or the window's beat
# past its 1 s bound, on a loaded machine (a safe stop, but not what those tests look at;
# one fresh-clone run saw a 1.07 s beat). Both bounds have their own tests, with the
# window in a process apart (below, as `rotorbench console` runs it) at the shipped bounds.
SHARED_INTERPRETER_BOUND_S = 2.0
# what the served windows here look at is what they do, not how often they paint: 25
# frames a second instead of the shipped 100 (measured alone: 65 s of CPU time for this file
# instead of 71); the selftest holds a window to its frame-rate floor (test_window_options.py)
FRAME_MS = 40


class _Opener:
    """open_rig that keeps the devices it opened, to look at the ESC afterwards."""

    def __init__(self) -> None:
        self.rigs: list = []

    def __call__(self, rig, seed=None):
        self.rigs.append(open_rig(rig, seed=seed))
        return self.rigs[-1]

    def esc_safe(self) -> bool:
        esc = self.rigs[-1].esc
        return esc.last_pulse_us == IDLE and esc.model.events[-1][1] == "disarm"


def _throttle(run_dir) -> np.ndarray:
    return pd.read_parquet(run_dir / "samples.parquet", columns=["throttle_us"]
                           )["throttle_us"].to_numpy()


def _served_window(qtbot, tmp_path, rig, capacity, **kwargs):
    """The window here, its bench serving it on a thread; a generator: yields both, then
    closes the window and checks the bench ended with it."""
    from bench.console.window import ConsoleWindow

    link = BenchLink(capacity=capacity, heartbeat_bound_s=SHARED_INTERPRETER_BOUND_S)
    bench = ConsoleBench(rig, tmp_path, link, **kwargs)
    win = ConsoleWindow(link.gui_link(), tmp_path, frame_ms=FRAME_MS)
    qtbot.addWidget(win)
    win.show()
    serving = threading.Thread(target=bench.serve, daemon=True)
    serving.start()
    qtbot.waitUntil(lambda: bool(win.rig), timeout=30_000)
    yield win, bench
    win.close()
    serving.join(60)
    assert not serving.is_alive()


@pytest.fixture
def console(qtbot, tmp_path):
    from bench.plan_runner.runner import RunOptions

    opener = _Opener()
    options = RunOptions(realtime=True, watchdog_timeout_s=SHARED_INTERPRETER_BOUND_S)
    for win, bench in _served_window(qtbot, tmp_path, load_rig(default_rig_path()),
                                     25_000 * 6, open_rig=opener, options=options):
        yield win, bench, opener


def _arm_and_throttle(qtbot, win, presses=3):
    qtbot.mouseClick(win.arm_button, LEFT)
    qtbot.waitUntil(lambda: bool(win.state.get("manual")), timeout=20_000)
    for _ in range(presses):  # keyboard control: Page Up = +10 %
        qtbot.keyClick(win.control.slider, Key.Key_PageUp)
    assert win.control.fraction == pytest.approx(presses / 10)
    target = IDLE + presses * 100.0
    qtbot.waitUntil(lambda: win.state.get("command_us") == target or bool(win.finished),
                    timeout=15_000)
    assert not win.finished, win.finished[-1]["reason"]


def test_arm_throttle_and_space_record_a_run_that_ends_at_idle(qtbot, console):
    win, _bench, opener = console
    _arm_and_throttle(qtbot, win)
    qtbot.keyClick(win.control.slider, Key.Key_Space)  # Space is stop, even on the slider
    qtbot.waitUntil(lambda: bool(win.finished), timeout=15_000)
    info = win.finished[-1]
    assert info["kind"] == "manual" and info["status"] == "success"
    cmd = _throttle(__import__("pathlib").Path(info["run_dir"]))
    assert cmd.max() == 1300.0 and cmd[-1] == IDLE
    assert opener.esc_safe()
    assert not win.banner.isVisible()


def test_closing_the_window_mid_run_ends_with_the_esc_idle(qtbot, console):
    win, bench, opener = console
    _arm_and_throttle(qtbot, win, presses=2)
    win.close()
    qtbot.waitUntil(lambda: bool(bench.finished), timeout=15_000)
    info = bench.finished[-1]
    assert info["status"] == "abort" and "console window closed" in info["reason"]
    assert opener.esc_safe()


def test_a_limit_trip_shows_a_banner_with_the_cause_and_the_tripping_sample(qtbot, console):
    win, _bench, opener = console
    label, box = win.control.limits.rows["thrust_n"]
    box.setValue(9.0)  # the box cannot loosen: it stops at the rig's 7 N
    assert box.value() == 7.0
    box.setValue(0.3)
    buttons = win.control.limits.findChildren(type(win.arm_button))
    tighten = next(b for b in buttons if b.text() == "Tighten")  # the first row: thrust_n
    qtbot.mouseClick(tighten, LEFT)
    qtbot.waitUntil(lambda: win.state.get("limits", {}).get("thrust_n") == 0.3, timeout=5000)
    assert "rig 7" in label.text() and box.maximum() == 0.3
    qtbot.mouseClick(win.arm_button, LEFT)
    qtbot.waitUntil(lambda: bool(win.state.get("manual")), timeout=20_000)
    win.control.set_fraction(0.3)
    qtbot.waitUntil(lambda: bool(win.finished), timeout=20_000)
    info = win.finished[-1]
    assert info["status"] == "abort" and info["trip"]["limit"] == "thrust_n"
    assert win.banner.isVisible()
    text = win.banner.text()
    assert text.startswith("LIMIT TRIP") and "thrust_n" in text and "0.3" in text
    assert f"thrust_n={info['trip']['sample']['thrust_n']:.4g}" in text  # the sample
    assert opener.esc_safe()


def test_a_plan_shows_its_steps_and_progress_and_esc_aborts_it(qtbot, console):
    win, _bench, opener = console
    plans = win.plans
    plans.repeats.setValue(1)
    plans.hold.setValue(0.2)
    qtbot.waitUntil(lambda: "1 repeats" in plans.description.text(), timeout=5000)
    assert plans.table.rowCount() > 8 and plans.table.item(0, 3).text() == "arm"
    qtbot.mouseClick(plans.start_button, LEFT)
    qtbot.waitUntil(lambda: plans.progress.value() > 10, timeout=20_000)
    assert "step1: step" in plans.step_label.text()
    qtbot.keyClick(win, Key.Key_Escape)
    qtbot.waitUntil(lambda: bool(win.finished), timeout=10_000)
    info = win.finished[-1]
    assert info["kind"] == "step1" and info["status"] == "abort"
    assert "stopped by operator" in info["reason"]
    assert opener.esc_safe()


def test_a_bad_plan_file_is_refused_in_one_line(qtbot, console, tmp_path):
    win, _bench, _ = console
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nsteps = [{ kind = "spin" }]\n')
    win.plans.set_file(str(bad))
    qtbot.waitUntil(lambda: bool(win.errors), timeout=5000)
    assert "steps[0].kind" in win.errors[-1] and "\n" not in win.errors[-1]


def test_tare_then_history_opens_and_overlays_runs(qtbot, console):
    win, _bench, _ = console
    for n in (1, 2):
        qtbot.mouseClick(win.devices.tare_button, LEFT)
        qtbot.waitUntil(lambda n=n: len(win.finished) == n, timeout=20_000)
    assert "tare: offset" in win.devices.info.text()
    hist = win.history
    assert hist.table.rowCount() == 2
    statuses = [hist.filters["status"].itemText(i) for i in range(hist.filters["status"].count())]
    assert "success" in statuses
    hist.select(0)
    hist.open_selected()
    assert hist.opened == [hist.shown[0].id]
    hist.select(0, 1)
    hist.open_selected()
    assert len(hist.opened) == 2 and len(hist.plot.getPlotItem().listDataItems()) == 2
    hist.filters["rig"].setCurrentIndex(1)  # "sim"
    assert hist.table.rowCount() == 2


# -- the window in its own process --------------------------------------------------------


@pytest.fixture
def window_process(tmp_path):
    from bench.console.gui_main import window_main

    ctx = mp.get_context("spawn")
    opener = _Opener()
    link = BenchLink(capacity=25_000 * 6, ctx=ctx)
    bench = ConsoleBench(load_rig(default_rig_path()), tmp_path, link, open_rig=opener)
    proc = ctx.Process(target=window_main, daemon=True,
                       args=(link.gui_args(), str(tmp_path), None, 5.0))
    proc.start()
    link.proc = proc
    serving = threading.Thread(target=bench.serve, daemon=True)
    serving.start()
    deadline = time.monotonic() + 90
    while link.heartbeat_age_s() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert link.heartbeat_age_s() is not None, "the window process did not start"
    time.sleep(1.0)  # its first paints
    yield bench, proc, opener
    if proc.is_alive():
        os.kill(proc.pid, signal.SIGCONT)
        proc.terminate()
    proc.join(10)
    serving.join(30)


def _spin(bench):
    bench.handle("arm", None)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not (bench.run and bench.run.runner
                                               and bench.run.runner.in_manual):
        time.sleep(0.02)
    bench.handle("throttle", 0.3)
    while time.monotonic() < deadline and bench.run.runner.esc.last_us != 1300.0:
        time.sleep(0.02)
    assert bench.run.runner.esc.last_us == 1300.0 and bench.busy


def _wait_end(bench, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while bench.busy and time.monotonic() < deadline:
        time.sleep(0.005)
    assert not bench.busy


def _signal_mid_run(window_process, sig, what):
    """Spin at 30 %, send ``sig`` to the window process; the run's record and the time
    from the signal to the ESC made safe."""
    bench, proc, opener = window_process
    _spin(bench)
    sent = time.monotonic()
    os.kill(proc.pid, sig)
    _wait_end(bench)
    delay = bench.run.runner.safe_at - sent
    print(f"window {what} -> ESC idle and disarmed in {delay * 1e3:.0f} ms "
          f"(heartbeat bound {HEARTBEAT_BOUND_S:g} s)")
    assert opener.esc_safe()
    return bench.finished[-1], delay


def test_killing_the_window_process_mid_run_makes_the_esc_safe_at_once(window_process):
    info, delay = _signal_mid_run(window_process, signal.SIGKILL, "killed")
    assert info["status"] == "abort" and "crashed (signal SIGKILL)" in info["reason"]
    assert _throttle(__import__("pathlib").Path(info["run_dir"])).max() == 1300.0
    assert delay < 0.5  # the next tick sees the process gone (20 ms ticks)


def test_a_frozen_window_stops_the_run_within_the_heartbeat_bound(window_process):
    bench, proc, _ = window_process
    info, delay = _signal_mid_run(window_process, signal.SIGSTOP, "frozen (SIGSTOP)")
    assert info["status"] == "abort" and "console frozen" in info["reason"]
    # the window's last beat may predate the SIGSTOP (a long paint): the run stops once the
    # beat is older than the bound, never before, and within a tick or two after
    age = float(re.search(r"no heartbeat for ([0-9.]+) s", info["reason"]).group(1))
    assert HEARTBEAT_BOUND_S <= age < HEARTBEAT_BOUND_S + 0.2
    assert delay < HEARTBEAT_BOUND_S + 0.5
    os.kill(proc.pid, signal.SIGCONT)  # the window recovers: the console goes on
    time.sleep(0.5)
    assert proc.is_alive() and bench.lost_reason is None


def test_the_selftest_runs_headless_and_records_a_run_that_ends_at_idle(tmp_path):
    """The whole ``rotorbench console --selftest`` (its frame rate is measured, printed and
    checked by the command; here any rate is accepted: no timed test in the suite)."""
    import subprocess
    import sys

    from PIL import Image

    shot = tmp_path / "shot.png"
    proc = subprocess.run([sys.executable, "-m", "bench.cli", "console", "--selftest",
                           "--out", str(tmp_path), "--screenshot", str(shot), "--min-fps", "0"],
                          capture_output=True, text=True, timeout=240, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert re.search(r"^\d+ frames/s$", proc.stdout, re.M)
    assert "recorded throttle: up to 1300 us, last 1000 us" in proc.stdout
    with Image.open(shot) as img:
        assert img.size[0] >= 800 and img.size[1] >= 500
    from bench.store.run_index import RunIndex

    rows = RunIndex(tmp_path).list()
    assert [(r.sequence, r.status) for r in rows] == [("manual", "success")]


@pytest.fixture
def imu_console(qtbot, tmp_path):
    from bench.rig.rig import default_imu_rig_path, load_imu_rig

    yield from _served_window(qtbot, tmp_path, load_imu_rig(default_imu_rig_path()), 1000)


def test_the_imu_tab_calibrates_an_imu_rig_stage_by_stage(qtbot, imu_console, tmp_path):
    win, bench = imu_console
    assert win.tabs.currentWidget() is win.imu and not win.arm_button.isEnabled()
    qtbot.mouseClick(win.arm_button, LEFT)  # disabled: nothing happens
    qtbot.mouseClick(win.imu.quick_button, LEFT)
    qtbot.waitUntil(lambda: bool(win.finished), timeout=300_000)
    info = win.finished[-1]
    assert info["kind"] == "calibration" and info["status"] == "success", info["reason"]
    assert len(info["stages"]) == 5
    assert "calibration success: 5/5 stages" in win.imu.stage_label.text()
    import json as _json
    from pathlib import Path

    cal = _json.loads(Path(info["calibration"]).read_text())
    assert cal["format"] == "rotorbench-imu-calibration/1"
    assert np.asarray(cal["k_gyro"]).shape == (3, 3)
    assert '"format": "rotorbench-imu-calibration/1"' in win.imu.result.toPlainText()
    assert win.imu.table.rowCount() == 5  # one recorded run per stage, from the index
    bench.handle("arm", None)  # the bench refuses propulsion requests on an IMU rig
    assert bench.run.kind == "calibration"


def test_aborting_a_calibration_stops_the_hexapod_and_records_the_stage(qtbot, imu_console):
    import json as _json
    from pathlib import Path

    win, _bench = imu_console
    qtbot.mouseClick(win.imu.quick_button, LEFT)
    qtbot.waitUntil(lambda: (win.state.get("imu") or {}).get("t", 0) > 0, timeout=60_000)
    assert "stage 1/5" in win.imu.stage_label.text()
    qtbot.keyClick(win, Key.Key_Space)
    qtbot.waitUntil(lambda: bool(win.finished), timeout=60_000)
    info = win.finished[-1]
    assert info["status"] == "abort" and "stopped by operator" in info["reason"]
    meta = _json.loads((Path(info["run_dir"]) / "run.json").read_text())
    assert meta["status"] == "abort" and not meta.get("safe_stop_errors")


def test_history_fits_the_last_step_run_and_exports_through_the_cli(qtbot, console):
    win, _bench, _ = console
    win.plans.repeats.setValue(2)
    win.plans.hold.setValue(0.3)
    qtbot.waitUntil(lambda: "2 repeats" in win.plans.description.text(), timeout=5000)
    qtbot.mouseClick(win.plans.start_button, LEFT)
    qtbot.waitUntil(lambda: bool(win.finished), timeout=60_000)
    assert win.finished[-1]["status"] == "success", win.finished[-1]["reason"]
    hist = win.history
    hist.fit_last()  # `rotorbench fit RUN --json` in a child process; the window goes on
    qtbot.waitUntil(lambda: hist.process.state() == QtCore.QProcess.ProcessState.NotRunning,
                    timeout=60_000)
    qtbot.wait(200)
    text = hist.fit_label.text()
    assert text.startswith("last fit ("), hist.output.toPlainText()
    assert "step1" in text and "tau up" in text and "gain" in text
    assert re.search(r"tau up \d", text), text  # a number was fitted, not '-'
    hist.select(0)
    hist.export("px4")  # `rotorbench export px4 RUN`: its output (or one-line error) shown
    qtbot.waitUntil(lambda: hist.process.state() == QtCore.QProcess.ProcessState.NotRunning,
                    timeout=60_000)
    qtbot.wait(200)
    lines = hist.output.toPlainText().splitlines()
    assert lines[0].startswith("$ ") and "export px4" in lines[0] and len(lines) >= 2


def test_the_devices_tab_calibrates_the_load_cell_step_by_step(qtbot, console, tmp_path):
    """Each weight is asked for in the tab and confirmed with Weight placed; the
    calibration is recorded like the CLI's, the ESC never armed; a second one with the
    fixture needs no answer."""
    import json

    win, _bench, opener = console
    win.tabs.setCurrentWidget(win.devices)
    win.devices.masses.setText("0,500,1000")
    qtbot.mouseClick(win.devices.calibrate_button, LEFT)
    for step in range(1, 6):  # 0, 500, 1000 up; 500, 0 down
        qtbot.waitUntil(lambda s=step: win.devices.placed_button.isEnabled()
                        and f"[{s}/5]" in win.devices.prompt.text(), timeout=20_000)
        qtbot.mouseClick(win.devices.placed_button, LEFT)
    qtbot.waitUntil(lambda: bool(win.finished), timeout=30_000)
    info = win.finished[-1]
    assert info["kind"] == "cell calibration" and info["status"] == "success", info
    assert "gain" in win.devices.info.text() and "accepted" in win.devices.info.text()
    meta = json.loads((Path(info["run_dir"]) / "run.json").read_text())
    assert meta["kind"] == "calibration" and meta["calibration"]["plan"]["masses_kg"] == [
        0.0, 0.5, 1.0]
    events = [e[1] for e in opener.rigs[-1].esc.model.events]
    assert "disarm" in events and "arm" not in events  # made safe at close, never armed
    win.devices.automatic.setChecked(True)
    qtbot.mouseClick(win.devices.calibrate_button, LEFT)
    qtbot.waitUntil(lambda: len(win.finished) == 2, timeout=30_000)
    assert win.finished[-1]["status"] == "success"
    assert not win.devices.placed_button.isEnabled()


def test_stop_at_a_weight_prompt_ends_the_calibration_recorded_as_failed(qtbot, console):
    win, _bench, _opener = console
    qtbot.mouseClick(win.devices.calibrate_button, LEFT)
    qtbot.waitUntil(win.devices.placed_button.isEnabled, timeout=20_000)
    win.stop()
    qtbot.waitUntil(lambda: bool(win.finished), timeout=20_000)
    info = win.finished[-1]
    assert info["status"] == "fail" and "stopped by the operator" in info["reason"]
    assert "calibration failed" in win.devices.info.text()
