"""What every simulated CAN device shares: a bus subscription and a publishing thread.

The node hears the host's frames through ``_on_frame`` (on the bus thread) and calls
``_tick(now)`` every ``period_s`` on its own thread (the status broadcasts).
``disconnect()`` is the fault switch: the node vanishes from the bus (no statuses, frames
ignored) until ``reconnect()``.
"""

from __future__ import annotations

import threading
import time
from typing import Self

from drivers.backends.can_link import CanLink
from drivers.codecs.can_log import CanFrame

__all__ = ["SimCanNode"]


class SimCanNode:
    """Base of the simulated CAN devices. A subclass sets its own state first, then calls
    ``__init__`` (which subscribes to the bus, so frames may arrive at once)."""

    def __init__(self, link: CanLink, period_s: float, thread_name: str) -> None:
        self.link = link
        self.period_s = period_s
        self._t0 = time.monotonic()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._silent = threading.Event()
        self._thread = threading.Thread(target=self._run, name=thread_name, daemon=True)
        link.subscribe(self._on_frame)

    def start(self) -> Self:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self.link.unsubscribe(self._on_frame)
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)

    def disconnect(self) -> None:
        """Fault: the device vanishes from the bus (no statuses, commands ignored)."""
        self._silent.set()

    def reconnect(self) -> None:
        self._silent.clear()

    def _on_frame(self, frame: CanFrame) -> None:
        raise NotImplementedError

    def _tick(self, now: float) -> None:
        """One period: apply the command timeout, publish (unless silent)."""
        raise NotImplementedError

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            self._tick(time.monotonic())
            next_t += self.period_s
            self._stop.wait(max(0.0, next_t - time.monotonic()))
