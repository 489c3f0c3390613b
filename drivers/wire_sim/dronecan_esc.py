"""A simulated DroneCAN ESC node: takes RawCommand, publishes esc.Status and NodeStatus.

Behaviour from protocols.md §4: RawCommand ``cmd[esc_index]`` (int14, 0 = stop) drives
the ``model(t_s, raw) -> EscStatus``; Status goes out every ``status_period_s`` as a
three-frame transfer, NodeStatus once a second. With no RawCommand for ``timeout_s`` the
command falls back to 0 (the real timeout is ESC firmware specific; this is the sim's).
``drivers.wire_sim.can_socket.node_process`` runs one on a CAN cable to a host in another
process.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

from drivers.backends.can_link import CanLink
from drivers.codecs import dronecan as dc
from drivers.codecs.can_log import CanFrame
from drivers.errors import DeviceError
from drivers.wire_sim.can_node import SimCanNode

EscModel = Callable[[float, int], dc.EscStatus]


@dataclass(frozen=True)
class LinearEscMotor:
    """A stand-in motor (an ``EscModel``): the ``rest`` status plus rpm and current
    proportional to the raw command (``current_at_max_a`` more at ``RAW_MAX``). A value,
    so it crosses to a device process pickled."""

    rest: dc.EscStatus
    rpm_per_raw: float = 0.0
    current_at_max_a: float = 0.0

    def __call__(self, _t: float, raw: int) -> dc.EscStatus:
        return replace(self.rest, rpm=self.rest.rpm + round(raw * self.rpm_per_raw),
                       current_a=self.rest.current_a + raw / dc.RAW_MAX * self.current_at_max_a)


class SimDroneCanEsc(SimCanNode):
    def __init__(self, link: CanLink, node_id: int, esc_index: int, model: EscModel, *,
                 status_period_s: float = 0.01, timeout_s: float = 0.5) -> None:
        self.node_id = node_id
        self.esc_index = esc_index
        self.model = model
        self.timeout_s = timeout_s
        self.raw = 0
        self.commands_seen: list[tuple[int, ...]] = []
        self.host_node_status = 0
        self.timeouts = 0
        self.decoder = dc.DroneCanDecoder()
        self._last_cmd = -float("inf")
        self._tid = {dc.STATUS_DTID: 0, dc.NODE_STATUS_DTID: 0}
        self._next_ns: float | None = None  # NodeStatus: at the first tick, then 1 Hz
        super().__init__(link, status_period_s, f"sim-dronecan-{node_id}")

    def _on_frame(self, frame: CanFrame) -> None:
        if self._silent.is_set():
            return
        with self._lock:
            for rx in self.decoder.feed(frame):
                m = rx.message
                if isinstance(m, dc.NodeStatus):
                    self.host_node_status += 1
                if isinstance(m, dc.RawCommand):
                    self.commands_seen.append(m.cmd)
                    if self.esc_index < len(m.cmd):
                        self.raw = m.cmd[self.esc_index]
                        self._last_cmd = time.monotonic()

    def _publish(self, msg: dc.KnownMessage) -> None:
        tid = self._tid[msg.DTID]
        self._tid[msg.DTID] = (tid + 1) & 0x1F
        for f in dc.encode(msg, self.node_id, tid):
            self.link.send(f)

    def _tick(self, now: float) -> None:
        if self._next_ns is None:
            self._next_ns = now
        with self._lock:
            if self.raw and now - self._last_cmd > self.timeout_s:
                self.raw = 0
                self.timeouts += 1
            raw = self.raw
        if not self._silent.is_set():
            try:
                self._publish(self.model(now - self._t0, raw))
                if now >= self._next_ns:
                    self._next_ns += 1.0
                    self._publish(dc.NodeStatus(int(now - self._t0), 0, 0, 0, 0))
            except (DeviceError, ValueError):
                pass
