"""How long a command takes from the bench to the firmware's motor output.

On a bench whose ESC is a flight controller's motor test, the motor sees the firmware's
output, not the bench's request; the time between the two (the MSP request in flight,
the firmware's serial task, its next motor update) is part of the measured step delay and
could not be measured on the thesis bench. :class:`OutputTimedEsc` wraps the ESC: it
notes when each new value is sent (host monotonic clock, just before the request is
written) and matches it with the first motor update carrying that value, as seen by the
plant peer (``drivers.wire_sim.sitl_plant``) on the same clock. ``run_figures()`` gives
the delays of the commands since the last ``arm()`` for the run's ``run.json``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from drivers.contracts import DeviceInfo

__all__ = ["OutputTimedEsc", "delay_summary", "match_delays"]

FIGURE = "command_to_output_delay_s"
PENDING_WAIT_S = 0.25  # how long run_figures waits for the last command's output


def match_delays(commands: Sequence[tuple[float, float]],
                 outputs: Sequence[tuple[float, float]]) -> tuple[list[float], int]:
    """Delay of each command (send time, value) to the first output change (arrival
    time, value) after it, if that change carries its value; returns the delays and how
    many commands never reached the output (superseded by the next one before the
    firmware applied them, or lost). A command asking for the value the output already
    has changes nothing and counts neither way."""
    delays: list[float] = []
    missed = 0
    j = 0
    for t_cmd, value in commands:
        while j < len(outputs) and outputs[j][0] < t_cmd:
            j += 1
        if j < len(outputs) and outputs[j][1] == value:
            delays.append(outputs[j][0] - t_cmd)
            j += 1
        elif not (j > 0 and outputs[j - 1][1] == value):
            missed += 1
    return delays, missed


def delay_summary(delays: Sequence[float], missed: int) -> dict[str, Any]:
    """Median, 95th percentile and extremes in seconds (None when no command was seen)."""
    d = np.asarray(delays, float)
    stats = {k: None for k in ("median", "p95", "min", "max")} if d.size == 0 else {
        "median": float(np.median(d)), "p95": float(np.percentile(d, 95)),
        "min": float(d.min()), "max": float(d.max())}
    return {"commands": int(d.size + missed), "seen": int(d.size), "missed": int(missed),
            **stats, "from": "MSP_SET_MOTOR sent", "to": "first motor update carrying the "
            "value (the firmware's UDP output), host monotonic clock"}


class OutputTimedEsc:
    """An ``Esc`` whose commands are timed against the firmware's motor output."""

    def __init__(self, esc: Any, peer: Any, firmware: str) -> None:
        self.esc = esc
        self.peer = peer  # changes() -> [(arrival time, us)]; check() raises if deaf
        self.firmware = firmware
        self._commands: list[tuple[float, float]] = []
        self._last = math.nan
        self._armed = False

    def __getattr__(self, name: str) -> Any:
        return getattr(self.esc, name)  # client, motor_index... of the wrapped ESC

    def describe(self) -> DeviceInfo:
        info = self.esc.describe()
        extra = {**info.extra, "firmware": self.firmware,
                 "motor_output": "the firmware's UDP motor updates drive the simulated plant"}
        return DeviceInfo(info.kind, f"{info.model}, {self.firmware}", info.url, info.channels,
                          extra)

    def _sent(self, t: float, pulse_us: float) -> None:
        value = float(round(min(self.esc.max_us, max(self.esc.min_us, pulse_us))))
        if value != self._last:
            self._commands.append((t, value))
            self._last = value

    def arm(self) -> None:
        self._commands = []
        self._last = math.nan
        t = time.monotonic()
        self.esc.arm()  # sends every motor to 1000
        self._armed = True
        self._sent(t, self.esc.min_us)

    def set_pulse_us(self, pulse_us: float) -> None:
        self.peer.check()  # the firmware's output still reaches the plant
        t = time.monotonic()
        self.esc.set_pulse_us(pulse_us)
        if self._armed and math.isfinite(float(pulse_us)):
            self._sent(t, float(pulse_us))

    def disarm(self) -> None:
        t = time.monotonic()
        was = self._armed
        self._armed = False
        self.esc.disarm()  # never raises
        if was:
            self._sent(t, self.esc.min_us)

    def close(self) -> None:
        self.disarm()
        self.esc.close()

    def run_figures(self) -> dict[str, Any]:
        """``command_to_output_delay_s`` of the commands since the last ``arm()``; waits
        up to ``PENDING_WAIT_S`` for the output of the last one (the disarm's idle)."""
        commands = list(self._commands)
        if not commands:
            return {}
        deadline = time.monotonic() + PENDING_WAIT_S
        while True:
            delays, missed = match_delays(commands, self.peer.changes())
            if not missed or time.monotonic() > deadline:
                break
            time.sleep(0.01)
        return {FIGURE: {**delay_summary(delays, missed), "fdm_packets_sent":
                         self.peer.fdm_sent, "motor_updates_received": self.peer.updates}}
