"""KISS / BLHeli_32 ESC serial telemetry as a ``Sensor``.

:class:`KissTelemetry` listens on the ESC's telemetry wire (115 200 baud, the host sends
nothing: the ESC answers DShot telemetry requests of whoever drives its signal line, or
streams on its own) and hands out one row per frame (``drivers.codecs.kiss``): bus current
and voltage (the ``power`` role), mechanical speed = eRPM / ``pole_pairs`` (the ``rpm``
role), ESC temperature and consumed charge. Rows are stamped with the rig clock when
their bytes arrive; silence longer than ``stale_s`` is a ``DeviceError``.

The simulated ESC of ``serial://sim/kiss`` is a ``drivers.wire_sim.pty_sim.PtyStream``
writing the codec's frames of the plant's state (its registry entry builds it).
"""

from __future__ import annotations

from typing import Any

from drivers.backends.row_stream import SerialStreamSensor
from drivers.codecs import kiss
from drivers.contracts import ChannelInfo, Clock, DeviceInfo
from drivers.errors import DeviceError

__all__ = ["CHANNELS", "KissTelemetry", "kiss"]

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
