"""The live view, offscreen: ring buffer, timer-driven redraws, a run shown live."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest

os.environ["QT_QPA_PLATFORM"] = "offscreen"
pytest.importorskip("pyqtgraph")

from bench.live import LiveView, RingBuffer, run_with_live_view


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


def test_a_run_is_shown_live_and_the_window_closes(fakes, tmp_path):
    from bench.recorder import RunRecorder
    from bench.runner import Runner
    from bench.sequences import EscRange, compile_plan, step1

    esc = EscRange(1000.0, 1050.0, 2000.0)
    rig = fakes.FakeRig()
    plan = compile_plan(step1(repeats=2), esc, lambda f: 1050.0 + (f / 1e-7) ** 0.5 / 12.0)
    stop = threading.Event()
    seen = {}

    def work(on_rows):
        def spy(rows):
            on_rows(rows)
            seen["n"] = seen.get("n", 0) + len(rows["t_s"])

        runner = Runner(rig, plan, esc, {"thrust_n": 10.0},
                        RunRecorder(tmp_path / "r", {}), on_rows=spy, stop_event=stop)
        return runner.run()

    result = run_with_live_view(work, stop, rate_hint_hz=2500.0, close_when_done=True)
    assert result.status == "success"
    assert seen["n"] == result.rows > 0
    assert rig.esc.armed is False
