"""KISS / BLHeli_32 ESC serial telemetry as a ``Sensor``, and its simulated ESC on a pty.

:class:`KissTelemetry` listens on the ESC's telemetry wire (115 200 baud, the host sends
nothing: the ESC answers DShot telemetry requests of whoever drives its signal line, or
streams on its own) and hands out one row per frame (``drivers.codecs.kiss``): bus current
and voltage (the ``power`` role), mechanical speed = eRPM / ``pole_pairs`` (the ``rpm``
role), ESC temperature and consumed charge. Rows are stamped with the rig clock when
their bytes arrive; silence longer than ``stale_s`` is a ``DeviceError``.

:class:`SimKissEsc` is the wire-level simulated ESC (``serial://sim/kiss``): a pty that,
once the host has opened it, writes a frame every ``period_s`` from
``model() -> (voltage_v, current_a, rpm)`` (the rig's simulated plant), integrating the
consumption like the firmware.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from drivers.backends.row_stream import SerialStreamSensor
from drivers.codecs import kiss
from drivers.contracts import ChannelInfo, Clock, DeviceInfo
from drivers.errors import DeviceError
from drivers.wire_sim.pty_port import PtyDevice
from drivers.wire_sim.pty_sim import PtySimulator

__all__ = ["CHANNELS", "KissTelemetry", "SimKissEsc"]

CHANNELS = {"current_a": "A", "voltage_v": "V", "rpm": "rpm", "temperature_c": "degC",
            "consumption_mah": "mAh"}


class KissTelemetry(SerialStreamSensor):
    """Frames in, blocks out (the columns of :data:`CHANNELS`)."""

    names = tuple(CHANNELS)

    def __init__(self, port: Any, pole_pairs: int, *, clock: Clock | None = None,
                 stale_s: float = 0.5, url: str = "serial://kiss") -> None:
        if pole_pairs < 1:
            raise DeviceError(f"{url}: pole_pairs must be >= 1, got {pole_pairs}")
        super().__init__(port, clock=clock, stale_s=stale_s, url=url)
        self.pole_pairs = pole_pairs
        self.decoder = kiss.KissDecoder()
        self._start_reader(f"kiss-{url}")

    def describe(self) -> DeviceInfo:
        return DeviceInfo(kind="esc_telemetry", model="KISS/BLHeli_32 ESC telemetry",
                          url=self.url,
                          channels=tuple(ChannelInfo(n, u, 0.0) for n, u in CHANNELS.items()),
                          extra={"pole_pairs": self.pole_pairs})

    def _decode(self, data: bytes, now: float) -> list[tuple[float, ...]]:
        return [(now, t.current_a, t.voltage_v, t.rpm(self.pole_pairs), t.temperature_c,
                 t.consumption_mah) for t in self.decoder.feed(data)]

    def _silence(self, silent_s: float) -> str:
        s = self.decoder.stats
        return (f"{self.url}: no telemetry frame for {silent_s:.3f} s ({s.bad_checksums} "
                f"CRC errors, {s.garbage_bytes} bytes skipped)")


class SimKissEsc(PtySimulator):
    """A simulated ESC streaming telemetry frames on a pty (see module doc)."""

    def __init__(self, model: Callable[[], tuple[float, float, float]], pole_pairs: int, *,
                 period_s: float = 0.01, temperature_c: float = 25.0) -> None:
        self.model = model
        self.pole_pairs = pole_pairs
        self.period_s = period_s
        self.temperature_c = temperature_c
        self.consumption_mah = 0.0
        self.frames = 0
        self._next = time.monotonic()
        self._last = self._next
        self.port = PtyDevice(lambda _data: b"", tick=self.tick, tick_s=period_s / 4)

    def frame(self) -> bytes:
        """The frame of the model's state now (consumption integrated since the last)."""
        voltage, current, rpm = self.model()
        now = time.monotonic()
        self.consumption_mah += max(current, 0.0) * (now - self._last) / 3.6
        self._last = now
        self.frames += 1
        return kiss.encode(kiss.Telemetry(self.temperature_c, voltage, current,
                                          self.consumption_mah, rpm * self.pole_pairs))

    def tick(self) -> bytes:
        now = time.monotonic()
        if now < self._next:
            return b""
        self._next = max(self._next + self.period_s, now - self.period_s)
        return self.frame()
