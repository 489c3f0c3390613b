"""A simulated VESC on a CAN bus: takes the real commands, broadcasts the real statuses.

Behaviour from protocols.md §3.2: commands SET_DUTY / SET_CURRENT / SET_CURRENT_BRAKE /
SET_RPM addressed to its controller id; the motor is released when no command arrived
for ``timeout_s`` (firmware default 1 s); STATUS 1, 4 and 5 broadcast at ``status_rate_hz``
(the firmware default rate is 50 Hz, the default mask is empty — here they are on).
The motor itself is the ``model`` callable: ``model(t_s, command) -> VescState``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from drivers.backends.can_link import CanLink
from drivers.codecs import vesc_can as vc
from drivers.codecs.can_log import CanFrame
from drivers.errors import DeviceError
from drivers.wire_sim.can_node import SimCanNode


@dataclass(frozen=True)
class VescCommand:
    """The command in force: ``kind`` is duty, current, brake, rpm or release."""

    kind: str = "release"
    value: float = 0.0


@dataclass(frozen=True)
class VescState:
    """What the motor model reports; becomes the status broadcasts."""

    erpm: float
    motor_current_a: float
    duty: float
    input_current_a: float
    voltage_in_v: float
    temp_fet_c: float
    temp_motor_c: float
    tachometer: int = 0


VescModel = Callable[[float, VescCommand], VescState]


@dataclass(frozen=True)
class LinearVescMotor:
    """A stand-in motor (a ``VescModel``): steady erpm and currents proportional to the
    commanded duty, at rest for any other command. A value, so it crosses to a device
    process pickled."""

    erpm_per_duty: float
    motor_current_per_duty_a: float
    input_current_per_duty_a: float
    voltage_in_v: float
    temp_fet_c: float
    temp_motor_c: float
    tachometer: int = 0

    def __call__(self, _t: float, cmd: VescCommand) -> VescState:
        duty = cmd.value if cmd.kind == "duty" else 0.0
        return VescState(self.erpm_per_duty * duty, self.motor_current_per_duty_a * duty, duty,
                         self.input_current_per_duty_a * duty, self.voltage_in_v,
                         self.temp_fet_c, self.temp_motor_c, self.tachometer)


class SimVescDevice(SimCanNode):
    """One simulated VESC on ``link``; ``start()`` begins broadcasting, ``stop()`` ends."""

    def __init__(self, link: CanLink, controller_id: int, model: VescModel, *,
                 status_rate_hz: float = 50.0, timeout_s: float = vc.COMMAND_TIMEOUT_S) -> None:
        self.controller_id = controller_id
        self.model = model
        self.timeout_s = timeout_s
        self.command = VescCommand()
        self.commands_seen: list[VescCommand] = []
        self.timeouts = 0
        self._last_cmd_t = -float("inf")
        super().__init__(link, 1.0 / status_rate_hz, f"sim-vesc-{controller_id}")

    def _on_frame(self, frame: CanFrame) -> None:
        if self._silent.is_set():
            return
        msg = vc.decode(frame)
        if msg is None or getattr(msg, "controller_id", None) != self.controller_id:
            return
        cmd = None
        if isinstance(msg, vc.SetDuty):
            cmd = VescCommand("duty", msg.duty)
        elif isinstance(msg, vc.SetCurrent):
            cmd = VescCommand("current", msg.current_a)
        elif isinstance(msg, vc.SetCurrentBrake):
            cmd = VescCommand("brake", msg.current_a)
        elif isinstance(msg, vc.SetRpm):
            cmd = VescCommand("rpm", msg.erpm)
        if cmd is not None:
            with self._lock:
                self.command = cmd
                self.commands_seen.append(cmd)
                self._last_cmd_t = time.monotonic()

    def _tick(self, now: float) -> None:
        with self._lock:
            if self.command.kind != "release" and now - self._last_cmd_t > self.timeout_s:
                self.command = VescCommand()  # §3.2 timeout: motor released
                self.timeouts += 1
            cmd = self.command
        state = self.model(now - self._t0, cmd)
        if not self._silent.is_set():
            self._broadcast(state)

    def _broadcast(self, s: VescState) -> None:
        cid = self.controller_id
        for msg in (vc.Status1(cid, round(s.erpm), s.motor_current_a, s.duty),
                    vc.Status4(cid, s.temp_fet_c, s.temp_motor_c, s.input_current_a, 0.0),
                    vc.Status5(cid, s.tachometer, s.voltage_in_v)):
            try:
                self.link.send(vc.encode(msg))
            except (DeviceError, ValueError):  # a full bus or an out-of-range model value
                return
