"""One background thread that runs jobs in turn: work that lets go of the GIL (numpy's
random fill, pyarrow's Parquet encoding) overlaps the caller's Python.

Starting a ``threading.Thread`` per job made the caller wait about half a millisecond
each time for the new thread to come up, which on a simulated run (two jobs per second of
rig time, a few milliseconds of wall time apart) ate most of what the overlap saved. The
thread here stays up while jobs keep coming and ends after ``idle_s`` without one, so an
object holding a ``Worker`` leaves no thread behind for long.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["Worker"]


class Worker:
    """Runs ``submit``-ted calls one after the other; ``result`` returns (or raises) what
    the oldest call not yet collected returned (or raised)."""

    def __init__(self, name: str, idle_s: float = 0.5) -> None:
        self.name = name
        self.idle_s = idle_s
        self._jobs: queue.SimpleQueue[tuple[Callable[..., Any], tuple[Any, ...]]] = \
            queue.SimpleQueue()
        self._results: queue.SimpleQueue[tuple[bool, Any]] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self.pending = 0  # calls submitted and not yet collected

    def submit(self, fn: Callable[..., Any], *args: Any) -> None:
        with self._lock:
            self._jobs.put((fn, args))
            self.pending += 1
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
                self._thread.start()

    def result(self) -> Any:
        """Wait for the oldest call not yet collected; its exception is raised here."""
        if not self.pending:
            raise RuntimeError(f"{self.name}: no call to collect")
        ok, value = self._results.get()
        self.pending -= 1
        if not ok:
            raise value
        return value

    def _run(self) -> None:
        while True:
            try:
                fn, args = self._jobs.get(timeout=self.idle_s)
            except queue.Empty:
                with self._lock:  # submit puts and checks under the lock: no job is stranded
                    if self._jobs.empty():
                        self._thread = None
                        return
                continue
            try:
                self._results.put((True, fn(*args)))
            except BaseException as exc:  # handed to the caller by result()
                self._results.put((False, exc))
