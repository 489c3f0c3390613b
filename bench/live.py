"""Live view of a run: rolling plots of command, thrust, current and speed.

The runner (in a worker thread) pushes each tick's rows into a :class:`RingBuffer`; a
``QTimer`` in the GUI thread takes a snapshot of the last seconds and redraws. The GUI
never reads run files and the worker never touches Qt. Closing the window asks the run
to stop (an operator action, recorded); the runner still ends with the ESC safe.
pyqtgraph and a Qt binding are the optional ``live`` extra, imported only here.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

import numpy as np

from bench.errors import RigError

__all__ = ["LIVE_CHANNELS", "LiveView", "RingBuffer", "run_with_live_view"]

T = TypeVar("T")

# (column, plot title, unit)
LIVE_CHANNELS = (
    ("throttle_us", "command", "us"),
    ("thrust_n", "thrust", "N"),
    ("current_a", "current", "A"),
    ("rpm", "speed", "rpm"),
)


class RingBuffer:
    """Fixed-size numpy ring of the newest rows; one writer, any number of readers."""

    def __init__(self, names: tuple[str, ...], capacity: int) -> None:
        if capacity < 1:
            raise ValueError("capacity must be positive")
        self.names = tuple(names)
        self.capacity = int(capacity)
        self._data = np.full((len(self.names), self.capacity), np.nan)
        self._total = 0
        self._lock = threading.Lock()

    @property
    def total(self) -> int:
        """Rows pushed since the start (not only those kept)."""
        return self._total

    def push(self, columns: Mapping[str, np.ndarray]) -> None:
        n = len(columns["t_s"])
        if n == 0:
            return
        block = np.vstack([np.asarray(columns.get(c, np.full(n, np.nan)), float)
                           for c in self.names])
        if n > self.capacity:
            block = block[:, -self.capacity:]
        m = block.shape[1]
        with self._lock:
            start = (self._total + (n - m)) % self.capacity
            first = min(m, self.capacity - start)
            self._data[:, start:start + first] = block[:, :first]
            if first < m:
                self._data[:, :m - first] = block[:, first:]
            self._total += n

    def snapshot(self) -> dict[str, np.ndarray]:
        """A copy of the kept rows, oldest first (two slices, no full-buffer roll)."""
        with self._lock:
            kept = min(self._total, self.capacity)
            end = self._total % self.capacity
            if kept < self.capacity:
                data = self._data[:, :kept].copy()
            else:
                data = np.concatenate([self._data[:, end:], self._data[:, :end]], axis=1)
        return {name: data[i] for i, name in enumerate(self.names)}


class LiveView:
    """A pyqtgraph window with one rolling plot per channel, refreshed by a QTimer."""

    def __init__(self, ring: RingBuffer, window_s: float = 10.0, interval_ms: int = 50,
                 title: str = "rotorbench live") -> None:
        import pyqtgraph as pg
        from pyqtgraph.Qt import QtCore

        self.ring = ring
        self.window_s = window_s
        self.app = pg.mkQApp("rotorbench")
        self.win = pg.GraphicsLayoutWidget(title=title)
        self.win.resize(900, 700)
        self.plots: dict[str, Any] = {}
        self.curves: dict[str, Any] = {}
        first = None
        for row, (col, name, unit) in enumerate(LIVE_CHANNELS):
            plot = self.win.addPlot(row=row, col=0)
            plot.setLabel("left", name, units=unit)
            plot.setDownsampling(auto=True, mode="peak")
            plot.setClipToView(True)
            plot.showGrid(x=True, y=True, alpha=0.3)
            if first is None:
                first = plot
            else:
                plot.setXLink(first)
            self.plots[col] = plot
            self.curves[col] = plot.plot(pen=pg.mkPen("y" if col == "throttle_us" else "c"))
        self.plots["rpm"].setLabel("bottom", "time", units="s")
        if "thrust_setpoint_n" in ring.names:
            self.curves["thrust_setpoint_n"] = self.plots["thrust_n"].plot(
                pen=pg.mkPen("m", style=QtCore.Qt.PenStyle.DashLine))
        self.refreshes = 0
        self.timer = QtCore.QTimer()
        self.timer.timeout.connect(self.refresh)
        self.timer.start(interval_ms)

    def refresh(self) -> None:
        snap = self.ring.snapshot()
        t = snap["t_s"]
        if t.size:
            keep = t >= t[-1] - self.window_s
            t = t[keep]
            for col, curve in self.curves.items():
                curve.setData(t, snap[col][keep])
        self.refreshes += 1

    def show(self) -> None:
        self.win.show()

    def close(self) -> None:
        self.timer.stop()
        self.win.close()


def check_display() -> None:
    """Without a display Qt aborts the whole process (SIGABRT, several lines of Qt text):
    say so in one line before anything is opened."""
    if not sys.platform.startswith("linux") or os.environ.get("QT_QPA_PLATFORM"):
        return
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RigError("--live needs a display: neither DISPLAY nor WAYLAND_DISPLAY is set "
                       "(run without --live, or set QT_QPA_PLATFORM=offscreen)")


def run_with_live_view(work: Callable[[Callable[[Mapping[str, np.ndarray]], None]], T],
                       stop_event: threading.Event, rate_hint_hz: float = 25_000.0,
                       window_s: float = 10.0, close_when_done: bool = False,
                       interval_ms: int = 50) -> T:
    """Run ``work(on_rows)`` in a worker thread while a live window shows its rows.

    Closing the window or Ctrl-C sets ``stop_event`` (the runner stops safely); the
    function returns ``work``'s result or re-raises its exception.
    """
    check_display()
    names = ("t_s", *[c for c, _, _ in LIVE_CHANNELS], "thrust_setpoint_n")
    ring = RingBuffer(names, int(rate_hint_hz * window_s))
    view = LiveView(ring, window_s=window_s, interval_ms=interval_ms)
    outcome: dict[str, Any] = {}

    def target() -> None:
        try:
            outcome["value"] = work(ring.push)
        except BaseException as exc:
            outcome["error"] = exc

    worker = threading.Thread(target=target, name="rotorbench-run", daemon=True)
    app = view.app
    app.setQuitOnLastWindowClosed(True)
    app.lastWindowClosed.connect(stop_event.set)
    from pyqtgraph.Qt import QtCore

    def poll() -> None:
        if not worker.is_alive():
            view.refresh()
            status = getattr(getattr(outcome.get("value"), "result", None), "status", None)
            view.win.setWindowTitle(f"rotorbench live - finished ({status or 'error'})")
            if close_when_done or stop_event.is_set():  # stopped by Ctrl-C / SIGTERM
                app.quit()
            done_timer.stop()

    done_timer = QtCore.QTimer()
    done_timer.timeout.connect(poll)
    previous = None
    if threading.current_thread() is threading.main_thread():
        def on_sigint(*_: object) -> None:
            stop_event.set()
        previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        view.show()
        worker.start()
        done_timer.start(50)
        app.exec()
    finally:
        stop_event.set()  # window closed before the end: stop the run safely
        worker.join()
        view.close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]
