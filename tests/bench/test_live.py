"""The live view, offscreen: ring buffer, timer-driven redraws, a run shown live in a window
process of its own, and the run stopped safely when that window closes or crashes."""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time

import numpy as np
import pytest

from tests.conftest import RIGS

os.environ["QT_QPA_PLATFORM"] = "offscreen"
pytest.importorskip("pyqtgraph")

from bench.live import (
    LiveView,
    RingBuffer,
    WindowLost,
    _Window,
    binding_fault,
    none_refs_per_call,
    run_with_live_view,
)

pytestmark = pytest.mark.slow(wall_s=22)  # paced runs drawn live: started first


def cols(t):
    return {"t_s": t, "throttle_us": 1000 + t, "thrust_n": 2 * t, "current_a": 3 * t,
            "rpm": 4 * t}


def test_ring_buffer_keeps_the_newest_rows_in_order():
    ring = RingBuffer(("t_s", "thrust_n"), capacity=10)
    assert ring.snapshot()["t_s"].size == 0
    ring.push({"t_s": np.arange(4.0), "thrust_n": np.arange(4.0)})
    np.testing.assert_array_equal(ring.snapshot()["t_s"], np.arange(4.0))
    for start in range(4, 40, 7):  # wraps around several times
        ring.push({"t_s": np.arange(start, start + 7.0), "thrust_n": np.zeros(7)})
    np.testing.assert_array_equal(ring.snapshot()["t_s"], np.arange(36.0, 46.0))
    ring.push({"t_s": np.arange(100.0, 125.0), "thrust_n": np.zeros(25)})  # > capacity
    np.testing.assert_array_equal(ring.snapshot()["t_s"], np.arange(115.0, 125.0))
    assert ring.total == 4 + 6 * 7 + 25


def test_ring_readers_never_block_the_writer_and_see_whole_pushes():
    """The writer takes no lock (a frozen reader process cannot stall the run loop); a
    reader racing it still gets a consistent copy: times in order, no torn block."""
    ring = RingBuffer(("t_s", "thrust_n"), capacity=1000)
    done = threading.Event()

    def write():
        t = 0.0
        for _ in range(3000):
            block = np.arange(t, t + 37.0)
            ring.push({"t_s": block, "thrust_n": 2 * block})
            t += 37.0
        done.set()

    writer = threading.Thread(target=write)
    writer.start()
    reads = 0
    while not done.is_set() or reads < 10:
        snap = ring.snapshot()
        if snap["t_s"].size:
            assert np.all(np.diff(snap["t_s"]) == 1.0)
            np.testing.assert_array_equal(snap["thrust_n"], 2 * snap["t_s"])
        reads += 1
    writer.join()
    assert ring.total == 3000 * 37


def test_live_view_redraws_from_the_ring_on_its_timer():
    ring = RingBuffer(("t_s", "throttle_us", "thrust_n", "current_a", "rpm"), 50_000)
    view = LiveView(ring, window_s=2.0, interval_ms=10)
    view.show()
    ring.push(cols(np.arange(0, 5, 1e-4)))
    deadline = threading.Event()
    for _ in range(200):
        view.app.processEvents()
        if view.refreshes >= 2:
            break
        deadline.wait(0.01)
    assert view.refreshes >= 2  # driven by the QTimer, not called by the test
    curve = view.curves["thrust_n"]
    x, y = curve.xData, curve.yData  # the data set on the curve (drawing may downsample)
    assert x[-1] == pytest.approx(5 - 1e-4) and x[0] >= x[-1] - 2.0 - 1e-9  # last 2 s only
    assert x[0] < x[-1] - 1.99
    np.testing.assert_allclose(y, 2 * x)
    assert view.plots["rpm"].getAxis("left").labelText == "speed"
    view.close()


def test_live_view_draws_one_time_axis_and_blits_unchanged_axes():
    """Axis text was most of a frame (43 ms offscreen for 8 axes redrawn every frame;
    benchmarks/live_frame.py): the stacked plots share one time axis, under the last, and
    each axis is kept as a pixmap while its range stands."""
    from pyqtgraph.Qt import QtWidgets

    ring = RingBuffer(("t_s", "throttle_us", "thrust_n", "current_a", "rpm"), 1000)
    view = LiveView(ring, window_s=2.0, interval_ms=10)
    view.show()
    view.app.processEvents()
    assert [k for k, p in view.plots.items() if p.getAxis("bottom").isVisible()] == ["rpm"]
    cached = QtWidgets.QGraphicsItem.CacheMode.DeviceCoordinateCache
    assert all(p.getAxis(side).cacheMode() == cached
               for p in view.plots.values() for side in ("left", "bottom"))
    view.close()


def _step_plan(repeats):
    from bench.plans.sequences import EscRange, compile_plan
    from bench.plans.stand_sequences import step1

    esc = EscRange(1000.0, 1050.0, 2000.0)
    return esc, compile_plan(step1(repeats=repeats), esc,
                             lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)


def _runner(fakes, tmp_path, repeats, spy):
    from bench.engine.recorder import RunRecorder
    from bench.plan_runner.runner import Runner

    esc, plan = _step_plan(repeats)
    rig = fakes.FakeRig()
    return rig, Runner(rig, plan, esc, {"thrust_n": 10.0}, RunRecorder(tmp_path / "r", {}),
                       on_rows=spy)


def test_a_run_is_shown_live_and_the_window_closes(fakes, tmp_path):
    seen = {}

    def work(on_rows):
        def spy(rows):
            on_rows(rows)
            seen["n"] = seen.get("n", 0) + len(rows["t_s"])

        rig, runner = _runner(fakes, tmp_path, 2, spy)
        seen["rig"] = rig
        return runner.run()

    stats = {}
    result = run_with_live_view(work, rate_hint_hz=2500.0, close_when_done=True, stats=stats)
    assert result.status == "success"
    assert seen["n"] == result.rows > 0
    assert seen["rig"].esc.armed is False
    assert stats["exitcode"] == 0  # the window process ended on its own, cleanly


def test_the_window_draws_through_a_whole_paced_run(fakes, tmp_path):
    """Rows arrive at bench pace for several seconds while the window redraws every 10 ms:
    a binding that corrupts the interpreter on drawing (PySide6 6.12.0 on Python 3.11) would
    be refused before the run or abort the window process here."""

    def work(on_rows):
        def paced(rows):
            on_rows(rows)
            time.sleep(0.02)  # one 20 ms tick per tick: the run takes its real 6 s

        _rig, runner = _runner(fakes, tmp_path, 5, paced)
        return runner.run()

    stats = {}
    result = run_with_live_view(work, rate_hint_hz=2500.0, close_when_done=True,
                                interval_ms=10, stats=stats)
    assert result.status == "success"
    assert stats["exitcode"] == 0
    assert stats["frames"] > 20  # it really drew, many times (about 100 on an idle machine)


def test_a_crashed_window_stops_the_run_with_the_esc_safe(fakes, tmp_path):
    seen = {}

    def work(on_rows):
        def spy(rows):
            seen["n"] = seen.get("n", 0) + len(rows["t_s"])
            if seen["n"] > 2000 and "killed" not in seen:
                (child,) = mp.active_children()
                os.kill(child.pid, signal.SIGABRT)  # as Qt's none_dealloc abort does
                seen["killed"] = True
                while mp.active_children():  # reaped: its exit code is known
                    time.sleep(0.01)
            on_rows(rows)

        rig, runner = _runner(fakes, tmp_path, 20, spy)
        seen["rig"] = rig
        return runner.run()

    result = run_with_live_view(work, rate_hint_hz=2500.0)
    assert result.status == "abort"
    assert result.reason == "live window crashed (signal SIGABRT); the run was stopped safely"
    esc = seen["rig"].esc
    assert esc.armed is False and esc.pulse_us == 1000.0
    assert esc.history[-1][1] == "disarm"


def test_closing_the_window_is_an_operator_stop():
    window = _Window(("t_s", "thrust_n"), 100, 1.0, 50, "test", False)
    try:
        window.wait_ready(60)
        window.check()  # open: nothing to say
        window._send(("quit",))  # what closing the last window does: the app quits, exit 0
        window.proc.join(10)
        with pytest.raises(WindowLost, match="stopped by operator: live window closed"):
            window.check()
    finally:
        window.close()


HOST = """
import sys, time
from bench.live import _Window
window = _Window(("t_s", "thrust_n"), 100, 1.0, 50, "orphan", False)
window.wait_ready(60)
print(window.proc.pid, flush=True)
sys.stdin.read()
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_window_ends_with_a_killed_run_process():
    """A bench killed outright (SIGKILL) leaves its window's pipe at end of file: the
    window quits instead of redrawing on, orphaned, at a core's worth of CPU."""
    import subprocess

    host = subprocess.Popen([sys.executable, "-c", HOST], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    window = None
    try:
        assert host.stdout is not None
        window = int(host.stdout.readline())
        host.kill()
        host.wait(10)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and os.path.exists(f"/proc/{window}"):
            time.sleep(0.05)
        assert not os.path.exists(f"/proc/{window}"), "the window outlived its run"
    finally:
        if host.poll() is None:
            host.kill()
        if window is not None and os.path.exists(f"/proc/{window}"):
            os.kill(window, signal.SIGKILL)  # it holds the host's stdout open
        host.communicate(timeout=60)


def test_the_installed_binding_draws_without_corrupting_none():
    assert binding_fault() is None


@pytest.mark.skipif(sys.version_info >= (3, 12), reason="None is immortal from Python 3.12")
def test_a_binding_that_over_releases_none_is_detected():
    decref, incref = ctypes.pythonapi.Py_DecRef, ctypes.pythonapi.Py_IncRef
    decref.argtypes = incref.argtypes = [ctypes.py_object]
    calls = 0

    def leaky():  # what PySide6 6.12.0's void QPainter calls do to None
        nonlocal calls
        calls += 1
        decref(None)

    try:
        assert none_refs_per_call(leaky, calls=500) == pytest.approx(-1.0, abs=0.1)
    finally:
        for _ in range(calls):
            incref(None)
    assert none_refs_per_call(lambda: None, calls=500) == pytest.approx(0.0, abs=0.1)


def _window_processes(pid: int) -> list[int]:
    """The children of ``pid`` that are spawned multiprocessing workers (not the resource
    tracker that multiprocessing starts beside them)."""
    kids: list[int] = []
    for task in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{task}/children") as f:
            for kid in f.read().split():
                try:
                    with open(f"/proc/{kid}/cmdline", "rb") as c:
                        cmdline = c.read()
                except OSError:  # a short-lived child that has ended meanwhile
                    continue
                if b"spawn_main" in cmdline and b"resource_tracker" not in cmdline:
                    kids.append(int(kid))
    return kids


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_step_live_from_the_command_line_runs_to_the_end(tmp_path, fixtures_dir):
    """`rotorbench step --live` as a user runs it: the run completes with the window open,
    then the window is closed (here: its process ended) and the command exits 0."""
    import json
    import subprocess

    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "bench.cli", "step", "--live", "--repeats", "2", "--rig",
         str(RIGS / "sim.toml"), "--out", str(tmp_path)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 120
        status = None
        while time.monotonic() < deadline and proc.poll() is None:
            runs = list(tmp_path.glob("*-step1/run.json"))
            if runs:
                status = json.loads(runs[0].read_text()).get("status")
                if status not in (None, "running"):
                    break
            time.sleep(0.2)
        assert status == "success", proc.stderr.read() if proc.poll() is not None else status
        assert proc.poll() is None  # the finished run is still on screen
        (window,) = _window_processes(proc.pid)
        os.kill(window, signal.SIGTERM)  # the operator closes the window
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            windows = _window_processes(proc.pid)
            proc.kill()
            for window in windows:  # it holds the command's pipes: communicate waits on it
                with contextlib.suppress(ProcessLookupError):
                    os.kill(window, signal.SIGKILL)
            proc.communicate(timeout=60)  # reaped, pipes closed: no leak warning later
    assert proc.returncode == 0, err
    assert "Fatal Python error" not in err
    assert ": success: sequence complete" in out
    # offscreen (or over SSH) there is no window to close: the wait says what ends it
    assert ("live view: run finished; the window is not on this screen "
            "(QT_QPA_PLATFORM=offscreen): press Ctrl-C to exit") in err


def test_the_wait_after_a_live_run_says_how_to_end_it(monkeypatch):
    from bench.live import _how_to_exit

    monkeypatch.setenv("QT_QPA_PLATFORM", "xcb")
    assert _how_to_exit() == "close the window to exit (or press Ctrl-C)"
    monkeypatch.setenv("QT_QPA_PLATFORM", "offscreen")
    assert "press Ctrl-C to exit" in _how_to_exit()
