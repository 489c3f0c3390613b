"""The face every simulated serial device shows: a pty path to open, start and stop.

A simulator builds its :class:`~drivers.wire_sim.pty_port.PtyDevice` as ``self.port``
with its own ``handle`` (and ``tick`` for continuous streams); this base gives the driver
side ``path`` and the lifecycle. :class:`PtyStream` is the whole simulator of a device that
only streams (telemetry wires): the bytes of ``next_frame()`` every ``period_s``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Self

from drivers.wire_sim.pty_port import PtyDevice

__all__ = ["PtySimulator", "PtyStream"]


class PtySimulator:
    """Base of the simulators on a pseudo-terminal (``port`` set by the subclass)."""

    port: PtyDevice

    @property
    def path(self) -> str:
        """What the driver opens, like a real serial port."""
        return self.port.path

    def start(self) -> Self:
        self.port.start()
        return self

    def stop(self) -> None:
        self.port.stop()


class PtyStream(PtySimulator):
    """A device that writes ``next_frame()`` every ``period_s`` and ignores what it hears
    (a late wakeup sends one frame, not the backlog: a UART device does not queue)."""

    def __init__(self, next_frame: Callable[[], bytes], period_s: float) -> None:
        self.next_frame = next_frame
        self.period_s = period_s
        self.frames = 0
        self._next = time.monotonic()
        self.port = PtyDevice(lambda _data: b"", tick=self.tick, tick_s=period_s / 4)

    def tick(self) -> bytes:
        now = time.monotonic()
        if now < self._next:
            return b""
        self._next = max(self._next + self.period_s, now - self.period_s)
        self.frames += 1
        return self.next_frame()
