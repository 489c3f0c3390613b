"""Live view of a run: rolling plots of command, thrust, current and speed.

The window lives in a process of its own. The run loop (in the calling process, on its own
thread) pushes each tick's rows into a :class:`RingBuffer` in shared memory; the window process
takes a snapshot of the last seconds on a ``QTimer`` and redraws. Nothing but that memory and a
pipe joins the two, so a crash of Qt, of the binding or of the plotting library ends the window,
never the run: the run loop sees the window gone at its next tick and stops the run safely (ESC
idle and disarmed), recording why. This is not hypothetical: PySide6 6.12.0 releases ``None``
once too often in every void ``QPainter`` call, and on Python 3.11 (where ``None`` is not
immortal) the process aborts with ``none_dealloc`` after a few thousand redraws
(docs/live.md). :func:`binding_fault` detects such a binding before a run starts.

Closing the window asks the run to stop (an operator action, recorded). pyqtgraph and a Qt
binding are the optional ``live`` extra, imported only in the window process.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing as mp
import os
import signal
import sys
import time
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

import numpy as np

from bench.engine.run_loop import OperatorStop
from bench.errors import RigError

__all__ = ["LIVE_CHANNELS", "LiveView", "RingBuffer", "WindowLost", "binding_fault",
           "run_with_live_view"]

T = TypeVar("T")
_log = logging.getLogger(__name__)

# (column, plot title, unit)
LIVE_CHANNELS = (
    ("throttle_us", "command", "us"),
    ("thrust_n", "thrust", "N"),
    ("current_a", "current", "A"),
    ("rpm", "speed", "rpm"),
)
LIVE_EXTRA = "rotorbench[live]"


class RingBuffer:
    """Fixed-size numpy ring of the newest rows; one writer, any number of readers.

    ``buffer`` (optional) is the memory to use, e.g. a ``multiprocessing`` ``RawArray`` of
    :meth:`cells` doubles shared with another process (``fresh`` says whether to clear it).
    The writer never waits for a reader: cell 0 is a sequence number the writer makes odd
    before and even after each push (a seqlock), cell 1 the number of rows pushed so far;
    a reader copies and retries if a push overlapped its copy. So a reader that freezes
    (a window process stopped mid-copy) can never block the run loop that writes. ``lock``
    is accepted for callers that still pass one and is not used.
    """

    _RETRIES = 100

    def __init__(self, names: tuple[str, ...], capacity: int, buffer: Any = None,
                 lock: Any = None, fresh: bool = True) -> None:
        if capacity < 1:
            raise ValueError("capacity must be positive")
        self.names = tuple(names)
        self.capacity = int(capacity)
        cells = self.cells(len(self.names), self.capacity)
        memory = np.frombuffer(buffer, dtype=float) if buffer is not None else np.empty(cells)
        if memory.size != cells:
            raise ValueError(f"ring memory holds {memory.size} cells, needs {cells}")
        self._seq = memory[:1]
        self._count = memory[1:2]
        self._data = memory[2:].reshape(len(self.names), self.capacity)
        if fresh:
            self._seq[0] = 0.0
            self._count[0] = 0.0
            self._data[:] = np.nan

    @staticmethod
    def cells(n_names: int, capacity: int) -> int:
        """Doubles of memory a ring of ``n_names`` columns and ``capacity`` rows needs."""
        return 2 + n_names * capacity

    @property
    def total(self) -> int:
        """Rows pushed since the start (not only those kept)."""
        return int(self._count[0])

    def push(self, columns: Mapping[str, np.ndarray]) -> None:
        n = len(columns["t_s"])
        if n == 0:
            return
        block = np.vstack([np.asarray(columns.get(c, np.full(n, np.nan)), float)
                           for c in self.names])
        if n > self.capacity:
            block = block[:, -self.capacity:]
        m = block.shape[1]
        total = int(self._count[0])
        start = (total + (n - m)) % self.capacity
        first = min(m, self.capacity - start)
        self._seq[0] += 1.0  # odd: a push is under way
        self._data[:, start:start + first] = block[:, :first]
        if first < m:
            self._data[:, :m - first] = block[:, first:]
        self._count[0] = total + n
        self._seq[0] += 1.0  # even: consistent again

    def _read(self, copy: Callable[[int], np.ndarray]) -> tuple[int, np.ndarray]:
        """``copy(total)`` under the seqlock: retried while a push overlaps it (after
        :attr:`_RETRIES` tries the last copy is returned: a display can live with it)."""
        for _ in range(self._RETRIES):
            seq = self._seq[0]
            if seq % 2:
                time.sleep(0)
                continue
            total = int(self._count[0])
            data = copy(total)
            if self._seq[0] == seq:
                return total, data
        total = int(self._count[0])
        return total, copy(total)

    def tail(self, n: int) -> tuple[int, dict[str, np.ndarray]]:
        """The rows pushed total and a copy of the newest ``min(n, kept)`` rows, oldest
        first: a reader that remembers ``total`` copies only what is new."""

        def copy(total: int) -> np.ndarray:
            m = max(min(int(n), total, self.capacity), 0)
            end = total % self.capacity
            start = end - m
            if start >= 0:
                return self._data[:, start:end].copy()
            return np.concatenate([self._data[:, start:], self._data[:, :end]], axis=1)

        total, data = self._read(copy)
        return total, {name: data[i] for i, name in enumerate(self.names)}

    def snapshot(self) -> dict[str, np.ndarray]:
        """A copy of the kept rows, oldest first (two slices, no full-buffer roll)."""

        def copy(total: int) -> np.ndarray:
            kept = min(total, self.capacity)
            end = total % self.capacity
            if kept < self.capacity:
                return self._data[:, :kept].copy()
            return np.concatenate([self._data[:, end:], self._data[:, :end]], axis=1)

        _total, data = self._read(copy)
        return {name: data[i] for i, name in enumerate(self.names)}


class LiveView:
    """A pyqtgraph window with one rolling plot per channel, refreshed by a QTimer."""

    def __init__(self, ring: RingBuffer, window_s: float = 10.0, interval_ms: int = 50,
                 title: str = "rotorbench live") -> None:
        import pyqtgraph as pg
        from pyqtgraph.Qt import QtCore

        from bench.qt.qt_messages import filter_qt_messages
        from bench.qt.stacked_axes import stacked_axes

        self.ring = ring
        self.window_s = window_s
        filter_qt_messages()
        self.app = pg.mkQApp("rotorbench")
        self.win = pg.GraphicsLayoutWidget(title=title)
        self.win.resize(900, 700)
        self.plots: dict[str, Any] = {}
        self.curves: dict[str, Any] = {}
        first = None
        for row, (col, name, unit) in enumerate(LIVE_CHANNELS):
            # a PlotItem hands its ViewBox's methods on at run time, which its stubs omit
            plot: Any = self.win.ci.addPlot(row=row, col=0)
            plot.setLabel("left", name, units=unit)
            plot.setDownsampling(auto=True, mode="peak")
            plot.setClipToView(True)
            plot.showGrid(x=True, y=True, alpha=0.3)
            last = row == len(LIVE_CHANNELS) - 1
            stacked_axes(plot, ("time", "s") if last else None)  # one time axis, under it
            if first is None:
                first = plot
            else:
                plot.setXLink(first)
            self.plots[col] = plot
            self.curves[col] = plot.plot(pen=pg.mkPen("y" if col == "throttle_us" else "c"))
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


def check_display(what: str = "--live", instead: str = "run without --live, or ") -> None:
    """Without a display Qt aborts the whole process (SIGABRT, several lines of Qt text):
    say so in one line before anything is opened."""
    if not sys.platform.startswith("linux") or os.environ.get("QT_QPA_PLATFORM"):
        return
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RigError(f"{what} needs a display: neither DISPLAY nor WAYLAND_DISPLAY is set "
                       f"({instead}set QT_QPA_PLATFORM=offscreen)")


def none_refs_per_call(call: Callable[[], object], calls: int = 2000) -> float:
    """How ``None``'s reference count changes per call of ``call``: 0 for a sound binding,
    about -1 for one that returns ``None`` without taking a reference (on Python >= 3.12
    ``None`` is immortal, its count never moves and such a bug is harmless)."""
    for _ in range(50):  # warm-up: caches and first-call allocations
        call()
    before = sys.getrefcount(None)
    for _ in range(calls):
        call()
    return (sys.getrefcount(None) - before) / calls


def binding_fault() -> str | None:
    """Why the installed Qt binding cannot draw for a whole run, or None if it can.

    Draws lines with a ``QPainter`` on an image (as pyqtgraph does every frame) and watches
    ``None``'s reference count: a binding that releases ``None`` once too often per call
    (PySide6 6.12.0) would abort the process after a few thousand redraws.
    """
    import pyqtgraph as pg
    from pyqtgraph.Qt import QT_LIB, QtCore, QtGui

    pg.mkQApp("rotorbench")
    image = QtGui.QImage(64, 64, QtGui.QImage.Format.Format_ARGB32)
    painter = QtGui.QPainter(image)
    pen = QtGui.QPen()
    a, b = QtCore.QPointF(0.0, 0.0), QtCore.QPointF(10.0, 10.0)

    def draw() -> None:
        painter.setPen(pen)
        painter.drawLine(a, b)

    try:
        drift = none_refs_per_call(draw)
    finally:
        painter.end()
    if drift > -0.5:
        return None
    version = getattr(QtCore, "__version__", None) or QtCore.qVersion()
    return (f"the Qt binding {QT_LIB} {version} on Python {sys.version.split()[0]} releases "
            f"None {-drift:.1f} times too often per QPainter call (the window would abort after "
            f"a few thousand redraws); install the tested versions: pip install '{LIVE_EXTRA}'")


def _qt_binding_missing() -> str | None:
    try:
        import pyqtgraph  # noqa: F401
    except ImportError as exc:
        return f"--live needs the live extra ({exc}); install it: pip install '{LIVE_EXTRA}'"
    return None


class WindowLost(OperatorStop):
    """The live window went away during a run: closed by the operator, or crashed."""

    def reason(self) -> str:
        return str(self)


def _window_main(names: tuple[str, ...], capacity: int, memory: Any, lock: Any, conn: Any,
                 window_s: float, interval_ms: int, title: str, close_when_done: bool) -> None:
    """The window process: show the ring until the operator closes the window (or the run
    is over and ``close_when_done``, or the run's process is gone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is for the run's process
    problem = _qt_binding_missing() or binding_fault()
    if problem is not None:
        conn.send(("error", problem))
        return
    from pyqtgraph.Qt import QtCore

    ring = RingBuffer(names, capacity, buffer=memory, lock=lock, fresh=False)
    view = LiveView(ring, window_s=window_s, interval_ms=interval_ms, title=title)
    app = view.app
    app.setQuitOnLastWindowClosed(True)
    parent = mp.parent_process()
    started = time.monotonic()

    def poll() -> None:
        try:
            while conn.poll():
                kind, *rest = conn.recv()
                if kind == "finished":
                    view.refresh()
                    view.win.setWindowTitle(f"{title} - finished ({rest[0]})")
                    if close_when_done:
                        app.quit()
                elif kind == "quit":
                    app.quit()
        except (EOFError, OSError):  # the run's process is gone (its end of the pipe
            app.quit()  # closed): raised here on every tick, it kept an orphan window
            return  # redrawing, a core's worth, until someone killed it
        if parent is not None and not parent.is_alive():
            app.quit()

    messages = QtCore.QTimer()
    messages.timeout.connect(poll)
    view.show()
    messages.start(50)
    conn.send(("ready", title))
    app.exec()
    view.close()
    with contextlib.suppress(OSError):  # the run's process may be gone
        conn.send(("frames", view.refreshes, time.monotonic() - started))


class _Window:
    """The parent's handle on the window process."""

    def __init__(self, names: tuple[str, ...], capacity: int, window_s: float,
                 interval_ms: int, title: str, close_when_done: bool) -> None:
        ctx = mp.get_context("spawn")  # never fork a process that may hold Qt or device state
        memory = ctx.RawArray("d", RingBuffer.cells(len(names), capacity))
        lock = None  # the ring is a seqlock: no lock is shared with the window
        self.ring = RingBuffer(names, capacity, buffer=memory, lock=lock)
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_window_main, name="rotorbench-live", daemon=True,
                                args=(names, capacity, memory, lock, child, window_s,
                                      interval_ms, title, close_when_done))
        self.proc.start()
        child.close()
        self.frames: tuple[int, float] | None = None

    def wait_ready(self, timeout_s: float) -> None:
        """Block until the window shows, or raise :class:`RigError` with the reason."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.conn.poll(0.05):
                kind, *rest = self._recv()
                if kind == "ready":
                    return
                if kind == "error":
                    self.proc.join(5)
                    raise RigError(f"--live: {rest[0]}")
            elif self.proc.exitcode is not None:
                raise RigError(f"--live: the live window could not start "
                               f"({_exit_text(self.proc.exitcode)})")
        self.close()
        raise RigError(f"--live: the live window did not open within {timeout_s:g} s")

    def check(self) -> None:
        """Called on every tick of the run: raise :class:`WindowLost` once the window is gone."""
        code = self.proc.exitcode
        if code is None:
            return
        if code == 0:
            raise WindowLost("stopped by operator: live window closed")
        raise WindowLost(f"live window crashed ({_exit_text(code)}); the run was stopped safely")

    def finished(self, status: str) -> None:
        self._send(("finished", status))

    def wait_closed(self) -> None:
        """After the run: wait for the operator to close the window (Ctrl-C closes it)."""
        try:
            while self.proc.is_alive():
                self.proc.join(0.2)
        except KeyboardInterrupt:
            pass
        self.close()

    def close(self) -> None:
        if self.proc.is_alive():
            self._send(("quit",))
            self.proc.join(3)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(3)
        self._drain()
        self.conn.close()

    def _send(self, message: tuple) -> None:
        try:
            self.conn.send(message)
        except (BrokenPipeError, OSError):
            pass  # the window is gone already

    def _recv(self) -> tuple:
        message = self.conn.recv()
        if message[0] == "frames":
            self.frames = (message[1], message[2])
        return message

    def _drain(self) -> None:
        try:
            while self.conn.poll():
                self._recv()
        except (EOFError, OSError):
            pass


def _how_to_exit() -> str:
    """What ends the wait for the window: over SSH or offscreen there is none to close."""
    platform = os.environ.get("QT_QPA_PLATFORM", "").split(":")[0]
    if platform in ("offscreen", "minimal", "vnc"):
        return (f"the window is not on this screen (QT_QPA_PLATFORM={platform}): "
                "press Ctrl-C to exit")
    return "close the window to exit (or press Ctrl-C)"


def _exit_text(code: int) -> str:
    if code < 0:
        try:
            return f"signal {signal.Signals(-code).name}"
        except ValueError:
            return f"signal {-code}"
    return f"exit code {code}"


def run_with_live_view(work: Callable[[Callable[[Mapping[str, np.ndarray]], None]], T],
                       rate_hint_hz: float = 25_000.0,
                       window_s: float = 10.0, close_when_done: bool = False,
                       interval_ms: int = 50, ready_timeout_s: float = 60.0,
                       stats: dict[str, Any] | None = None,
                       tell: Callable[[str], None] | None = None) -> T:
    """Run ``work(on_rows)`` here while a live window in its own process shows its rows.

    The window opens (and its binding is checked) before ``work`` starts; a window that
    cannot open is a :class:`RigError` and nothing runs. Closing the window or its crash
    ends the run safely at the next tick (:class:`WindowLost`); Ctrl-C and SIGTERM act on
    the run as without ``--live``. After the run the window stays open with the final
    rows until the operator closes it (at once with ``close_when_done``). ``stats``, if
    given, receives the window's ``frames`` and ``seconds`` and its ``exitcode``;
    ``tell`` (the command's stderr; else the log) hears how to close the finished window.
    """
    check_display()
    problem = _qt_binding_missing()
    if problem is not None:
        raise RigError(problem)
    names = ("t_s", *[c for c, _, _ in LIVE_CHANNELS], "thrust_setpoint_n")
    window = _Window(names, int(rate_hint_hz * window_s), window_s, interval_ms,
                     "rotorbench live", close_when_done)
    try:
        window.wait_ready(ready_timeout_s)

        def on_rows(rows: Mapping[str, np.ndarray]) -> None:
            window.ring.push(rows)
            window.check()

        value = work(on_rows)
        status = getattr(getattr(value, "result", value), "status", None)
        window.finished(str(status or "done"))
        if not close_when_done:
            (tell or _log.warning)(f"live view: run finished; {_how_to_exit()}")
        window.wait_closed()
    finally:
        window.close()
        if stats is not None:
            frames, seconds = window.frames or (0, 0.0)
            stats.update(frames=frames, seconds=seconds, exitcode=window.proc.exitcode)
    return value
