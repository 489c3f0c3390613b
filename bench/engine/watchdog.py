"""Host watchdog: a stalled command loop stops the motor.

The runner checks in (``kick``) on every tick. A separate thread watches the host's
monotonic clock (never the rig clock: a stalled host also stalls a simulated clock);
when the loop has not checked in for ``timeout_s`` it latches and disarms the ESC.
All ESC commands go through :class:`GuardedEsc`, which refuses commands once latched,
so a loop that wakes up again cannot spin the motor back up.

A conversation with an actuator that is at rest and cannot move until the next command
(a hexapod's trajectory upload: the controller refuses it while moving) may take longer
than the timeout on a real controller; ``at_rest`` excuses it instead of stopping a run
that has nothing moving to stop.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
import threading
import time
import traceback
from collections.abc import Iterator
from types import FrameType

from drivers.contracts import Esc

__all__ = ["GuardedEsc", "HostWatchdog", "WatchdogTrip", "where"]

log = logging.getLogger(__name__)

#: a check-in later than this share of the timeout is logged with where the loop was
LATE_SHARE = 0.5


def where(frame: FrameType | None, depth: int = 6) -> str:
    """Where a thread is, innermost first: ``runner.py:245 _tick_until < runner.py:170
    _hold``. The frames shown are the project's own (the watchdog's left out); a library
    call the thread was inside (numpy, pyarrow, a socket) is named in front of them."""
    if frame is None:
        return "unknown (the thread has ended)"
    stack = [f for f in traceback.extract_stack(frame)[::-1]
             if not f.filename.endswith("watchdog.py")]
    ours = [f for f in stack if _PROJECT_PATH.search(f.filename)]
    text = " < ".join(_frame_text(f) for f in (ours or stack)[:depth])
    if ours and stack and stack[0] is not ours[0]:
        text = f"{_frame_text(stack[0])} in {text}"
    return text


_PROJECT_PATH = re.compile(r"[/\\](bench|drivers|analysis|optimizer)[/\\]")


def _frame_text(f: traceback.FrameSummary) -> str:
    return f"{os.path.basename(f.filename)}:{f.lineno} {f.name}"


class WatchdogTrip(Exception):
    """The command loop stalled longer than the watchdog timeout."""


class GuardedEsc:
    """An ESC wrapper shared by the runner and the watchdog: clamps commands, latches kills."""

    def __init__(self, esc: Esc, min_us: float, max_us: float, idle_us: float) -> None:
        self.esc = esc
        self.min_us, self.max_us, self.idle_us = min_us, max_us, idle_us
        self._lock = threading.Lock()
        self.killed_reason: str | None = None
        self.last_us = idle_us

    def arm(self) -> None:
        with self._lock:
            self._refuse_if_killed()
            self.esc.arm()

    def set_pulse_us(self, pulse_us: float) -> None:
        if pulse_us != self.idle_us:
            pulse_us = min(max(pulse_us, self.min_us), self.max_us)
        with self._lock:
            self._refuse_if_killed()
            self.esc.set_pulse_us(pulse_us)
            self.last_us = pulse_us

    def safe_stop(self, lock_timeout_s: float = -1) -> list[str]:
        """Idle then disarm; each attempted even if the other fails. Returns the errors.

        With ``lock_timeout_s`` >= 0 a command stuck in another thread does not block the
        stop for longer than that: the ESC is disarmed anyway (``disarm`` is safe anytime).
        """
        errors = []
        locked = self._lock.acquire(timeout=lock_timeout_s)
        try:
            for action in (lambda: self.esc.set_pulse_us(self.idle_us), self.esc.disarm):
                try:
                    action()
                except Exception as exc:  # the safe stop must try every step
                    errors.append(f"{type(exc).__name__}: {exc}")
            self.last_us = self.idle_us
        finally:
            if locked:
                self._lock.release()
        return errors

    def kill(self, reason: str) -> list[str]:
        """Latch (no more commands) and make the ESC safe."""
        self.killed_reason = reason
        return self.safe_stop(lock_timeout_s=0.1)

    def _refuse_if_killed(self) -> None:
        if self.killed_reason is not None:
            raise WatchdogTrip(self.killed_reason)


class HostWatchdog:
    """A daemon thread that kills the ESC when ``kick`` has not been called for a while.

    ``esc`` is anything with ``kill(reason)`` (the hexapod's guard too); ``stops`` says
    what its kill does, for the run's reason."""

    def __init__(self, esc: GuardedEsc, timeout_s: float = 0.5, poll_s: float | None = None,
                 *, stops: str = "ESC disarmed"):
        if timeout_s <= 0:
            raise ValueError("watchdog timeout must be positive")
        self.esc = esc
        self.timeout_s = timeout_s
        self.stops = stops
        self._at_rest = False  # inside at_rest: a long conversation is not a stall
        self.poll_s = poll_s if poll_s is not None else min(timeout_s / 5.0, 0.05)
        self._last = time.monotonic()
        self._stop = threading.Event()
        self._trip_lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._loop_ident: int | None = None  # the thread that checks in
        self.tripped_at: float | None = None
        self.stall_s: float = 0.0
        self.errors: list[str] = []

    @property
    def tripped(self) -> bool:
        return self.tripped_at is not None

    def kick(self) -> None:
        now = time.monotonic()
        stalled = now - self._last
        self._last = now
        if stalled > LATE_SHARE * self.timeout_s and self._thread is not None \
                and not self.tripped:
            log.info("late check-in: %.3f s since the last (timeout %g s), the loop at %s",
                        stalled, self.timeout_s, where(sys._getframe(1)))
        if not self.tripped and self._thread is not None and stalled > self.timeout_s:
            # the whole process was frozen (suspend, SIGSTOP, swap): the watching thread
            # froze too, and the loop may wake first; it sees the stall itself
            self._trip(stalled)
        if self.tripped:
            raise WatchdogTrip(self.reason)

    @contextlib.contextmanager
    def at_rest(self) -> Iterator[None]:
        """A device conversation with the actuator at rest, which it cannot leave inside
        the block (a trajectory upload): its length is not a stall. The loop checks in on
        the way in (a stall before it still trips) and the timeout starts again on the
        way out."""
        self.kick()
        self._at_rest = True
        try:
            yield
        finally:
            self._last = time.monotonic()
            self._at_rest = False

    @property
    def reason(self) -> str:
        return (f"watchdog: command loop stalled {self.stall_s:.3f} s "
                f"(timeout {self.timeout_s:g} s); {self.stops}")

    def start(self) -> HostWatchdog:
        """Watch the thread that calls this (the command loop's)."""
        self._last = time.monotonic()
        self._loop_ident = threading.get_ident()
        thread = threading.Thread(target=self._watch, name="rotorbench-watchdog", daemon=True)
        thread.start()  # a Ctrl-C or SIGTERM may land in here: then no thread is kept
        self._thread = thread
        return self

    def stop(self) -> None:
        """Stop watching; safe after a start that a signal interrupted (a thread that was
        never started cannot be joined, and a started one sees the stop within poll_s)."""
        self._stop.set()
        if self._thread is not None and self._thread.is_alive():
            self._thread.join(timeout=2.0)

    def _watch(self) -> None:
        while not self._stop.wait(self.poll_s):
            stalled = time.monotonic() - self._last
            if stalled > self.timeout_s and not self._at_rest:
                self._trip(stalled)
                return

    def _trip(self, stalled: float) -> None:
        with self._trip_lock:  # the thread and a waking loop may both see the stall
            if self.tripped:
                return
            self.stall_s = stalled
            self.tripped_at = time.monotonic()
            loop = sys._current_frames().get(self._loop_ident) \
                if self._loop_ident is not None else None
            # INFO: the command says the stop itself; the log adds where the loop was
            log.info("%s; the loop was at %s", self.reason, where(loop))
            self.errors = self.esc.kill(self.reason)
            if self.errors:
                log.info("watchdog: the stop reported %s", "; ".join(self.errors))

    def __enter__(self) -> HostWatchdog:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
