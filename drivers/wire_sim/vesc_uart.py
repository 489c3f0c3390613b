"""A simulated VESC on a USB/UART port (a pty): the packet protocol of protocols.md §3.3.

Takes SET_DUTY / SET_CURRENT / SET_CURRENT_BRAKE / SET_RPM (no reply, as the firmware)
and ALIVE (refreshes the command timeout); answers GET_VALUES with the §3.4 fields of
the ``model(t_s, command) -> VescState`` (the CAN simulator's model type). With no
command or ALIVE for ``timeout_s`` (firmware default 1 s, §3.2) the motor is released.
"""

from __future__ import annotations

import threading
import time

from drivers.codecs import vesc_uart as vu
from drivers.wire_sim.pty_port import PtyDevice
from drivers.wire_sim.pty_sim import PtySimulator
from drivers.wire_sim.vesc import VescCommand, VescModel

__all__ = ["SimVescUart"]

_KINDS = {vu.SetDuty: "duty", vu.SetCurrent: "current", vu.SetCurrentBrake: "brake",
          vu.SetRpm: "rpm"}


class SimVescUart(PtySimulator):
    """VESC packet responder on a pty; ``command`` is the command in force."""

    def __init__(self, model: VescModel, *, controller_id: int = 0,
                 timeout_s: float = 1.0) -> None:
        self.model = model
        self.controller_id = controller_id
        self.timeout_s = timeout_s
        self.command = VescCommand()
        self.commands_seen: list[VescCommand] = []
        self.requests: list[vu.VescUartMessage] = []
        self.timeouts = 0
        self._last_cmd_t = -float("inf")
        self._decoder = vu.VescUartDecoder(replies=False)
        self._t0 = time.monotonic()
        self._lock = threading.Lock()
        self.port = PtyDevice(self.handle, tick=self._tick, tick_s=0.005)

    def _tick(self) -> bytes:
        """The firmware's command timeout (§3.2): release the motor."""
        with self._lock:
            if self.command.kind != "release" and \
                    time.monotonic() - self._last_cmd_t > self.timeout_s:
                self.command = VescCommand()
                self.timeouts += 1
        return b""

    def handle(self, data: bytes) -> bytes:
        out = bytearray()
        for m in self._decoder.feed(data):
            self.requests.append(m)
            kind = _KINDS.get(type(m))
            with self._lock:
                if kind is not None:
                    value = getattr(m, "duty", getattr(m, "current_a", getattr(m, "erpm", 0.0)))
                    self.command = VescCommand(kind, float(value))
                    self.commands_seen.append(self.command)
                    self._last_cmd_t = time.monotonic()
                elif isinstance(m, vu.Request) and m.cmd == vu.COMM_ALIVE:
                    self._last_cmd_t = time.monotonic()
                cmd = self.command
            self.applied(cmd)
            if isinstance(m, vu.Request) and m.cmd == vu.COMM_GET_VALUES:
                s = self.model(time.monotonic() - self._t0, cmd)
                out += vu.encode(vu.Values(
                    s.temp_fet_c, s.temp_motor_c, s.motor_current_a, s.input_current_a, 0.0,
                    s.motor_current_a, s.duty, s.erpm, s.voltage_in_v, tachometer=s.tachometer,
                    tachometer_abs=abs(s.tachometer), fault_code=0,
                    controller_id=self.controller_id,
                    timeout_active=cmd.kind == "release"))
        return bytes(out)

    def applied(self, command: VescCommand) -> None:
        """Hook: the command in force after each packet (a plant follows it)."""
