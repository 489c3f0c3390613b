"""The only things the console window and the bench process share: the newest rows in a
:class:`bench.live.RingBuffer` in shared memory, a heartbeat cell and a duplex pipe.

The window writes ``time.monotonic()`` (system-wide on Linux, so comparable across
processes) into the heartbeat cell from a timer on its GUI thread. The bench side declares
the console lost when its process has exited, or when the heartbeat is older than
:data:`HEARTBEAT_BOUND_S` (a frozen GUI thread, a stopped process). Messages are small
tuples ``(kind, payload)``; the bench stops sending state once the window stops beating,
so a frozen window can never fill the pipe and block the bench.
"""

from __future__ import annotations

import multiprocessing as mp
import time
from typing import Any

from bench.live import RingBuffer
from bench.live import _exit_text as exit_text

__all__ = ["HEARTBEAT_BOUND_S", "HEARTBEAT_PERIOD_S", "RING_NAMES", "BenchLink", "GuiLink",
           "exit_text"]

# No heartbeat for this long: the console is lost, the run stops. 1 s, not 0.5 s: on the
# shared 2-core machine (load ~10) the window's first paints stalled its GUI thread for up
# to 0.97 s, and a bound it crosses in normal use would stop runs for nothing.
HEARTBEAT_BOUND_S = 1.0
HEARTBEAT_PERIOD_S = 0.05
# columns the window plots; power and efficiency are derived in the window
RING_NAMES = ("t_s", "throttle_us", "thrust_setpoint_n", "thrust_n", "torque_nm", "current_a",
              "voltage_v", "rpm")


def _drain(conn: Any, gone: tuple[str, Any] | None) -> list[tuple[str, Any]]:
    """Every message waiting on ``conn``; ``gone`` is appended if the other end closed."""
    out = []
    try:
        while conn.poll():
            out.append(conn.recv())
    except (EOFError, OSError):
        if gone is not None:
            out.append(gone)
    return out


class GuiLink:
    """The window's end: read rows, beat, send requests, receive state."""

    def __init__(self, names: tuple[str, ...], capacity: int, memory: Any, lock: Any,
                 beat: Any, conn: Any) -> None:
        self.ring = RingBuffer(names, capacity, buffer=memory, lock=lock, fresh=False)
        self._beat = beat
        self.conn = conn

    def beat(self) -> None:
        self._beat.value = time.monotonic()

    def send(self, kind: str, payload: Any = None) -> None:
        try:
            self.conn.send((kind, payload))
        except (BrokenPipeError, OSError):
            pass  # the bench is gone; the window notices through `bench_gone`

    def receive(self) -> list[tuple[str, Any]]:
        return _drain(self.conn, ("bench_gone", None))


class BenchLink:
    """The bench's end: owns the shared memory and knows whether the console still lives.

    ``proc`` is the window's process once started (None while the window runs in this
    process, as in the pytest-qt tests: then only the heartbeat tells).
    """

    def __init__(self, capacity: int, ctx: Any = None,
                 heartbeat_bound_s: float = HEARTBEAT_BOUND_S) -> None:
        ctx = ctx or mp.get_context("spawn")
        self.names = RING_NAMES
        self.capacity = int(capacity)
        self._memory = ctx.RawArray("d", RingBuffer.cells(len(self.names), self.capacity))
        self._lock = ctx.Lock()
        self._beat = ctx.RawValue("d", 0.0)
        self.ring = RingBuffer(self.names, self.capacity, buffer=self._memory, lock=self._lock)
        self.conn, self._gui_conn = ctx.Pipe()
        self.proc: Any = None
        self.bound_s = heartbeat_bound_s
        self.closed_by_operator = False

    def gui_args(self) -> tuple[Any, ...]:
        """What :class:`GuiLink` needs (picklable for a spawned process)."""
        return (self.names, self.capacity, self._memory, self._lock, self._beat,
                self._gui_conn)

    def gui_link(self) -> GuiLink:
        """A window end in this process (tests drive the window with pytest-qt)."""
        return GuiLink(*self.gui_args())

    def heartbeat_age_s(self) -> float | None:
        """Seconds since the window's last beat, None before the first one."""
        last = self._beat.value
        return None if last == 0.0 else time.monotonic() - last

    def lost(self, frozen: bool = True) -> str | None:
        """Why the console is gone (closed, crashed, or frozen unless ``frozen`` is
        False), or None while it lives."""
        if self.closed_by_operator:
            return "console window closed"
        if self.proc is not None and self.proc.exitcode is not None:
            code = self.proc.exitcode
            if code == 0:
                return "console window closed"
            return f"console window crashed ({exit_text(code)})"
        age = self.heartbeat_age_s()
        if frozen and age is not None and age > self.bound_s:
            return (f"console frozen: no heartbeat for {age:.2f} s "
                    f"(bound {self.bound_s:g} s)")
        return None

    def send(self, kind: str, payload: Any = None) -> None:
        """Send unless the window stopped beating (a full pipe would block the bench)."""
        age = self.heartbeat_age_s()
        if age is not None and age > self.bound_s:
            return
        try:
            self.conn.send((kind, payload))
        except (BrokenPipeError, OSError):
            pass

    def receive(self) -> list[tuple[str, Any]]:
        return _drain(self.conn, None)
