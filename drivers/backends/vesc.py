"""VESC on CAN as the bench ESC and as a telemetry sensor (speed, current, voltage, temperature).

``VescEsc`` fills ``drivers.contracts.Esc``: a pulse width (1000..2000 µs, the bench's
common throttle scale) maps linearly to a duty cycle 0..1 sent as ``SET_DUTY``; idle and
disarm send ``SET_CURRENT 0`` (no torque, the motor coasts). The VESC releases the motor
when commands stop for 1 s (protocols.md §3.2), so a keep-alive thread repeats the last
command every ``keepalive_s`` — but only while the host itself keeps commanding: if the
host has not called ``set_pulse_us`` for ``host_timeout_s`` (a stalled host), the thread
sends ``SET_CURRENT 0`` and stops refreshing, and the motor stops.

``VescTelemetry`` fills ``drivers.contracts.Sensor`` from the status broadcasts
(STATUS 1, 4, 5), which are off by default on a VESC: enable them in the VESC app config
(``can_status_msgs_r1``, e.g. the FOC wizard's STATUS 1-4 plus STATUS 5). Each STATUS 1
makes one row; the other fields hold their latest value (NaN until first seen).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

from drivers.backends.can_esc_guard import DutyEsc
from drivers.backends.can_link import CanLink
from drivers.backends.row_stream import block_from_rows
from drivers.codecs import vesc_can as vc
from drivers.codecs.can_log import CanFrame
from drivers.codecs.stream import link_losses
from drivers.contracts import Block, ChannelInfo, Clock, DeviceInfo, MonotonicClock
from drivers.errors import DeviceError


@dataclass(frozen=True)
class VescEscSettings:
    """How the bench drives one VESC."""

    controller_id: int
    min_us: float = 1000.0
    max_us: float = 2000.0
    keepalive_s: float = 0.1  # resend period, well inside the VESC's 1 s timeout (§3.2)
    host_timeout_s: float = 0.5  # host silent this long -> stop refreshing (motor stops)

    def duty(self, pulse_us: float) -> float:
        """Pulse width -> duty cycle, linear between ``min_us`` and ``max_us``."""
        return min(1.0, max(0.0, (pulse_us - self.min_us) / (self.max_us - self.min_us)))


class VescEsc(DutyEsc):
    """The bench ESC on a VESC (``drivers.contracts.Esc``)."""

    def __init__(self, link: CanLink, settings: VescEscSettings, url: str = "can://vesc") -> None:
        super().__init__(link, settings, url, vc.COMMAND_TIMEOUT_S, f"vesc-keepalive-{url}")

    def describe(self) -> DeviceInfo:
        return self._info("VESC (CAN)", {"controller_id": self.settings.controller_id})

    def _command(self) -> CanFrame:
        duty = self._duty()
        cid = self.settings.controller_id
        if duty <= 0.0:
            return vc.encode(vc.SetCurrent(cid, 0.0))
        return vc.encode(vc.SetDuty(cid, duty))

    def _send_held(self) -> None:
        self.link.send(self._command())

    def _send_stop(self) -> None:
        self.link.send(vc.encode(vc.SetCurrent(self.settings.controller_id, 0.0)))


TELEMETRY_CHANNELS = ("rpm", "current_a", "voltage_v", "motor_current_a", "duty", "temp_fet_c",
                      "temp_motor_c")


class VescTelemetry:
    """Speed, input current, voltage and temperatures of one VESC (``Sensor``).

    ``rpm`` is mechanical (electrical rpm / ``pole_pairs``); ``current_a`` is the input
    (supply) current of STATUS 4, ``motor_current_a`` the motor current of STATUS 1.
    ``read_block`` raises ``DeviceError`` when no STATUS 1 arrived for ``stale_s``.
    """

    def __init__(self, link: CanLink, controller_id: int, pole_pairs: int, *,
                 clock: Clock | None = None, stale_s: float = 0.5, rate_hz: float = 50.0,
                 url: str = "can://vesc") -> None:
        if pole_pairs < 1:
            raise DeviceError(f"{url}: pole_pairs must be >= 1, got {pole_pairs}")
        self.link = link
        self.controller_id = controller_id
        self.pole_pairs = pole_pairs
        self.clock = clock or MonotonicClock()
        self.stale_s = stale_s
        self.rate_hz = rate_hz  # §3.2 default can_status_rate_1 = 50 Hz
        self.url = url
        self.decoder = vc.VescDecoder(controller_ids={controller_id})
        self._lock = threading.Lock()
        self._latest = dict.fromkeys(TELEMETRY_CHANNELS, math.nan)
        self._rows: list[tuple[float, ...]] = []
        self._opened = self.clock.now()
        self._last_status: float | None = None
        self._closed = False
        link.subscribe(self._on_frame)

    def link_errors(self) -> dict[str, int]:
        """Frames of this VESC lost on the bus (malformed status frames)."""
        return link_losses(self.decoder.stats)

    def describe(self) -> DeviceInfo:
        units = {"rpm": "rpm", "current_a": "A", "voltage_v": "V", "motor_current_a": "A",
                 "duty": "1", "temp_fet_c": "degC", "temp_motor_c": "degC"}
        return DeviceInfo(kind="esc_telemetry", model="VESC status broadcasts", url=self.url,
                          channels=tuple(ChannelInfo(n, units[n], self.rate_hz)
                                         for n in TELEMETRY_CHANNELS),
                          extra={"controller_id": self.controller_id,
                                 "pole_pairs": self.pole_pairs})

    def _on_frame(self, frame: CanFrame) -> None:
        for msg in self.decoder.feed(frame):
            now = self.clock.now()
            with self._lock:
                lat = self._latest
                if isinstance(msg, vc.Status1):
                    lat["rpm"] = vc.mech_rpm(msg.erpm, self.pole_pairs)
                    lat["motor_current_a"] = msg.current_a
                    lat["duty"] = msg.duty
                    self._rows.append((now, *(lat[n] for n in TELEMETRY_CHANNELS)))
                    self._last_status = now
                elif isinstance(msg, vc.Status4):
                    lat["temp_fet_c"] = msg.temp_fet_c
                    lat["temp_motor_c"] = msg.temp_motor_c
                    lat["current_a"] = msg.current_in_a
                elif isinstance(msg, vc.Status5):
                    lat["voltage_v"] = msg.voltage_in_v

    def read_block(self) -> Block:
        if self._closed:
            raise DeviceError(f"{self.url}: telemetry is closed")
        now = self.clock.now()
        with self._lock:
            rows, self._rows = self._rows, []
            last = self._last_status
        if last is None and now - self._opened > self.stale_s:
            raise DeviceError(f"{self.url}: no STATUS broadcast from VESC "
                              f"{self.controller_id} within {self.stale_s} s (enable "
                              "STATUS 1/4/5 in can_status_msgs_r1)")
        if last is not None and now - last > self.stale_s:
            raise DeviceError(f"{self.url}: VESC {self.controller_id} silent for "
                              f"{now - last:.3f} s (disconnected?)")
        return block_from_rows(rows, TELEMETRY_CHANNELS)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.link.unsubscribe(self._on_frame)
