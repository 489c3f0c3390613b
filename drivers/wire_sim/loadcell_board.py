"""A simulated load-cell board printing lines on a pseudo-terminal.

Prints a greeting and the layout's header once the host sends any byte (bytes written
before the port is opened are lost, protocols.md §9.3), then one line every ``period_s``
with values from ``model(t_s) -> {column: SI value}`` formatted by the ``LineLayout``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from drivers.codecs.loadcell_lines import LineLayout
from drivers.wire_sim.pty_port import PtyDevice
from drivers.wire_sim.pty_sim import PtySimulator

__all__ = ["SimLoadcellBoard", "SteadyReadings"]


@dataclass(frozen=True)
class SteadyReadings:
    """A stand-in model (``model(t_s)``): the same ``readings`` on every line but the board's
    clock column ``clock``, its seconds since start to the microsecond (the firmware's
    ``micros()``). A value, so it crosses to a device process pickled, where a lambda
    cannot."""

    readings: Mapping[str, float]
    clock: str

    def __call__(self, t_s: float) -> dict[str, float]:
        return {**self.readings, self.clock: round(t_s, 6)}


class SimLoadcellBoard(PtySimulator):
    def __init__(self, layout: LineLayout, model: Callable[[float], Mapping[str, float]], *,
                 period_s: float = 0.004, header: str = "", eol: str = "\r\n") -> None:
        self.layout = layout
        self.model = model
        self.period_s = period_s  # 250 Hz like the §8.2 firmware's loop
        self.header = header
        self.eol = eol
        self.started = False
        self._t0 = time.monotonic()
        self._next = 0.0
        self.port = PtyDevice(self.handle, tick=self.tick, tick_s=period_s / 4)

    def handle(self, data: bytes) -> bytes:
        if self.started:
            return b""
        self.started = True
        self._next = time.monotonic()
        text = "Load cell ready" + self.eol + (self.header + self.eol if self.header else "")
        return text.encode()

    def tick(self) -> bytes:
        if not self.started or time.monotonic() < self._next:
            return b""
        self._next += self.period_s
        values = self.model(time.monotonic() - self._t0)
        return (self.layout.format(values) + self.eol).encode()
