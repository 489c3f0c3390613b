"""VESC over USB/UART (pyserial port) as the bench ESC and as a telemetry sensor.

The way most VESC users connect: the packet protocol of protocols.md §3.3 on the VESC's
USB port (or its UART at 115200 baud). ``VescUartEsc`` sends ``SET_DUTY`` (pulse width
1000..2000 µs -> duty 0..1, as the CAN backend) and ``SET_CURRENT 0`` at idle/disarm; the
VESC releases the motor when no command arrives for 1 s (``APPCONF_TIMEOUT_MSEC``, §3.2),
so the command is repeated every ``keepalive_s``, but only while the host keeps
commanding (``host_timeout_s``, the same guard as the CAN ESCs): a dead or stalled host
lets the VESC's own timeout stop the motor. ``VescUartTelemetry`` polls ``GET_VALUES``
(§3.4) at ``rate_hz`` into rows: ``rpm`` (mechanical), ``current_a`` (input),
``voltage_v``, ``motor_current_a``, ``duty``, ``temp_fet_c``, ``temp_motor_c``.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

from drivers.backends.can_esc_guard import DutyEsc
from drivers.backends.row_stream import block_from_rows
from drivers.backends.serial_link import Deadline, read_some, write_all
from drivers.codecs import vesc_uart as vu
from drivers.codecs.stream import link_losses
from drivers.contracts import Block, ChannelInfo, Clock, DeviceInfo, MonotonicClock
from drivers.errors import DeviceError

COMMAND_TIMEOUT_S = 1.0  # §3.2 APPCONF_TIMEOUT_MSEC 1000
# the columns of the CAN backend's VescTelemetry, so rigs swap the wire without changes
TELEMETRY_UNITS = {"rpm": "rpm", "current_a": "A", "voltage_v": "V", "motor_current_a": "A",
                   "duty": "1", "temp_fet_c": "degC", "temp_motor_c": "degC"}
TELEMETRY_CHANNELS = tuple(TELEMETRY_UNITS)


class VescUartLink:
    """One port shared by the ESC (writes) and the telemetry poller (request/reply)."""

    def __init__(self, port: Any, name: str, timeout_s: float = 0.1) -> None:
        self.port = port
        self.name = name
        self.timeout_s = timeout_s
        self.lock = threading.RLock()
        self.decoder = vu.VescUartDecoder(replies=True)

    def send(self, msg: vu.VescUartMessage) -> None:
        with self.lock:
            write_all(self.port, vu.encode(msg), self.name)

    def values(self) -> vu.Values:
        """``GET_VALUES`` and its reply."""
        with self.lock:
            write_all(self.port, vu.encode(vu.Request(vu.COMM_GET_VALUES)), self.name)
            deadline = Deadline(self.timeout_s)
            while True:
                for m in self.decoder.feed(read_some(self.port, self.name)):
                    if isinstance(m, vu.Values):
                        return m
                if deadline.expired:
                    raise DeviceError(f"{self.name}: no GET_VALUES reply within "
                                      f"{self.timeout_s * 1e3:.0f} ms")


@dataclass(frozen=True)
class VescUartSettings:
    min_us: float = 1000.0
    max_us: float = 2000.0
    keepalive_s: float = 0.1
    host_timeout_s: float = 0.5


class VescUartEsc(DutyEsc):
    """The bench ESC on a VESC's USB/UART port (``drivers.contracts.Esc``)."""

    def __init__(self, link: VescUartLink, settings: VescUartSettings,
                 url: str = "serial://vesc") -> None:
        super().__init__(link, settings, url, COMMAND_TIMEOUT_S, f"vesc-uart-keepalive-{url}")

    def describe(self) -> DeviceInfo:
        return self._info("VESC (USB/UART)", {"dead_host_s": COMMAND_TIMEOUT_S})

    def _send_held(self) -> None:
        duty = self._duty()
        self.link.send(vu.SetDuty(duty) if duty > 0.0 else vu.SetCurrent(0.0))

    def _send_stop(self) -> None:
        self.link.send(vu.SetCurrent(0.0))


class VescUartTelemetry:
    """``GET_VALUES`` polled on a thread (``Sensor``); silence -> ``DeviceError``."""

    def __init__(self, link: VescUartLink, pole_pairs: int, *, rate_hz: float = 100.0,
                 clock: Clock | None = None, stale_s: float = 0.5,
                 url: str = "serial://vesc") -> None:
        if pole_pairs < 1:
            raise DeviceError(f"{url}: pole_pairs must be >= 1, got {pole_pairs}")
        self.link = link
        self.pole_pairs = pole_pairs
        self.rate_hz = rate_hz
        self.clock = clock or MonotonicClock()
        self.stale_s = stale_s
        self.url = url
        self.firmware = link.values()  # fails at open when nothing answers
        self._rows: list[tuple[float, ...]] = []
        self._error: DeviceError | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, name=f"vesc-uart-{url}", daemon=True)
        self._thread.start()

    def describe(self) -> DeviceInfo:
        return DeviceInfo(kind="esc_telemetry", model="VESC GET_VALUES (USB/UART)", url=self.url,
                          channels=tuple(ChannelInfo(n, TELEMETRY_UNITS[n], self.rate_hz)
                                         for n in TELEMETRY_CHANNELS),
                          extra={"pole_pairs": self.pole_pairs,
                                 "controller_id": self.firmware.controller_id})

    def _poll(self) -> None:
        period = 1.0 / self.rate_hz
        due = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due = max(due + period, time.monotonic() - period)
            stamp = self.clock.now()
            try:
                v = self.link.values()
            except DeviceError as exc:
                with self._lock:
                    self._error = exc
                return
            row = (stamp, v.erpm / self.pole_pairs, v.input_current_a, v.voltage_in_v,
                   v.motor_current_a, v.duty, v.temp_fet_c, v.temp_motor_c)
            with self._lock:
                self._rows.append(row)

    def link_errors(self) -> dict[str, int]:
        """Replies lost on the serial link (bad CRC16, truncated, malformed frames)."""
        return link_losses(self.link.decoder.stats)

    def read_block(self) -> Block:
        with self._lock:
            rows, self._rows = self._rows, []
            err = self._error
        if err is not None:
            raise err
        return block_from_rows(rows, TELEMETRY_CHANNELS)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
