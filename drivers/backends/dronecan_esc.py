"""A DroneCAN (UAVCAN v0) ESC on CAN as the bench ``Esc``, and its Status as a ``Sensor``.

``DroneCanEsc`` broadcasts ``uavcan.equipment.esc.RawCommand`` (protocols.md §4.1) every
``period_s`` with this ESC's slot set from the pulse width (1000..2000 µs -> 0..8191,
other slots 0 = stop) and publishes the host's ``NodeStatus`` once a second, as DroneCAN
nodes do (§4.1: publish period 2-1000 ms). ESCs stop when commands stop (the timeout is
ESC firmware specific, not in protocols.md); like the VESC backend, the refresh stops
when the host has not commanded for ``host_timeout_s``, after one all-zero command.

``DroneCanEscTelemetry`` turns ``Status`` messages of one ESC index into rows: ``rpm``,
``current_a``, ``voltage_v``, ``temp_esc_c`` (the wire carries kelvin), ``error_count``.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from drivers.backends.can_esc_guard import HostGuardedCanEsc
from drivers.backends.can_link import CanLink
from drivers.backends.row_stream import block_from_rows
from drivers.codecs import dronecan as dc
from drivers.codecs.can_log import CanFrame
from drivers.codecs.stream import link_losses
from drivers.contracts import Block, ChannelInfo, Clock, DeviceInfo, MonotonicClock
from drivers.errors import DeviceError

KELVIN_AT_0C = 273.15


@dataclass(frozen=True)
class DroneCanEscSettings:
    esc_index: int
    node_id: int = 100  # the bench's own node id (as in the §4.2 example frame)
    min_us: float = 1000.0
    max_us: float = 2000.0
    period_s: float = 0.02  # 50 Hz command stream
    host_timeout_s: float = 0.5
    priority: int = dc.DEFAULT_PRIORITY

    def raw(self, pulse_us: float) -> int:
        """Pulse width -> normalised int14 command (0 = stop, 8191 = full)."""
        frac = min(1.0, max(0.0, (pulse_us - self.min_us) / (self.max_us - self.min_us)))
        return dc.raw_from_fraction(frac)


class DroneCanEsc(HostGuardedCanEsc):
    """One ESC slot of the RawCommand array (``drivers.contracts.Esc``)."""

    def __init__(self, link: CanLink, settings: DroneCanEscSettings,
                 url: str = "can://dronecan") -> None:
        if not 0 <= settings.esc_index < dc.RAW_MAX_ESCS:
            raise DeviceError(f"{url}: esc_index must be 0..{dc.RAW_MAX_ESCS - 1}")
        self.link = link
        self.settings = settings
        self._raw = 0
        self._tid = {dc.RAW_COMMAND_DTID: 0, dc.NODE_STATUS_DTID: 0}
        self._t_open = time.monotonic()
        self._last_node_status = -math.inf
        super().__init__(url, settings.period_s, settings.host_timeout_s,
                         f"dronecan-esc-{url}")

    def describe(self) -> DeviceInfo:
        s = self.settings
        return DeviceInfo(kind="esc", model="DroneCAN ESC (RawCommand)", url=self.url,
                          channels=(ChannelInfo("throttle_us", "us", 1 / s.period_s, s.min_us,
                                                s.max_us),),
                          extra={"esc_index": s.esc_index, "node_id": s.node_id})

    def _broadcast(self, msg: dc.KnownMessage) -> None:
        tid = self._tid[msg.DTID]
        self._tid[msg.DTID] = (tid + 1) & 0x1F
        for frame in dc.encode(msg, self.settings.node_id, tid, self.settings.priority):
            self.link.send(frame)

    def _send_command(self, raw: int) -> None:
        cmd = [0] * (self.settings.esc_index + 1)
        cmd[self.settings.esc_index] = raw
        self._broadcast(dc.RawCommand(tuple(cmd)))

    def _hold(self, pulse_us: float) -> None:
        self._raw = self.settings.raw(pulse_us)

    def _hold_idle(self) -> None:
        self._raw = 0

    def _send_held(self) -> None:
        self._send_command(self._raw)

    def _send_stop(self) -> None:
        self._send_command(0)

    def _each_period(self, now: float) -> None:
        if now - self._last_node_status >= 1.0:  # the host's NodeStatus, 1 Hz (§4.1)
            self._last_node_status = now
            self._broadcast(dc.NodeStatus(int(now - self._t_open), 0, 0, 0, 0))


TELEMETRY_CHANNELS = ("rpm", "current_a", "voltage_v", "temp_esc_c", "error_count")


class DroneCanEscTelemetry:
    """Status of one ESC index from any node (``Sensor``)."""

    def __init__(self, link: CanLink, esc_index: int, *, clock: Clock | None = None,
                 stale_s: float = 0.5, url: str = "can://dronecan") -> None:
        self.link = link
        self.esc_index = esc_index
        self.clock = clock or MonotonicClock()
        self.stale_s = stale_s
        self.url = url
        self.decoder = dc.DroneCanDecoder()
        self._last_tid: dict[int, int] = {}  # esc.Status transfer id per source node
        self.transfer_id_gaps = 0  # esc.Status transfers missing from the sequence
        self._rows: list[tuple[float, ...]] = []
        self._opened = self.clock.now()
        self._last: float | None = None
        self._lock = threading.Lock()
        link.subscribe(self._on_frame)

    def describe(self) -> DeviceInfo:
        units = ("rpm", "A", "V", "degC", "1")
        return DeviceInfo(kind="esc_telemetry", model="DroneCAN esc.Status", url=self.url,
                          channels=tuple(ChannelInfo(n, u, 0.0)
                                         for n, u in zip(TELEMETRY_CHANNELS, units, strict=True)),
                          extra={"esc_index": self.esc_index})

    def _on_frame(self, frame: CanFrame) -> None:
        with self._lock:
            for rx in self.decoder.feed(frame):
                m = rx.message
                if isinstance(m, dc.EscStatus):
                    self._count_gap(rx.source_node_id, rx.transfer_id)
                if isinstance(m, dc.EscStatus) and m.esc_index == self.esc_index:
                    now = self.clock.now()
                    self._rows.append((now, float(m.rpm), m.current_a, m.voltage_v,
                                       m.temperature_k - KELVIN_AT_0C, float(m.error_count)))
                    self._last = now

    def _count_gap(self, node: int, tid: int) -> None:
        """A node numbers its esc.Status transfers (all ESC indexes) 0..31 cyclically; a
        jump counts the transfers lost (a gap of a full 32 cannot be seen)."""
        last = self._last_tid.get(node)
        if last is not None and tid != last:  # the same id again: a repeated transfer
            self.transfer_id_gaps += (tid - last - 1) % 32
        self._last_tid[node] = tid

    def link_errors(self) -> dict[str, int]:
        """Transfers lost on the bus: decoder losses and transfer-id gaps."""
        with self._lock:
            out = link_losses(self.decoder.stats)
            if self.transfer_id_gaps:
                out["transfer_id_gaps"] = self.transfer_id_gaps
        return out

    def read_block(self) -> Block:
        now = self.clock.now()
        with self._lock:
            rows, self._rows = self._rows, []
            last = self._last
        ref = self._opened if last is None else last
        if now - ref > self.stale_s:
            raise DeviceError(f"{self.url}: no esc.Status for ESC {self.esc_index} for "
                              f"{now - ref:.3f} s")
        return block_from_rows(rows, TELEMETRY_CHANNELS)

    def close(self) -> None:
        self.link.unsubscribe(self._on_frame)
