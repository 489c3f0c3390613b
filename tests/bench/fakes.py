"""Small stand-ins for an open rig, for unit tests of the runner, safety and recorder.

A quadratic propeller on a first-order motor, sampled on a virtual clock; faults are
plain switches (raise at a time, stall the host at a time). End-to-end tests use the
real simulated rig from ``drivers``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from drivers.contracts import Block, ChannelInfo, DeviceInfo
from drivers.errors import DeviceError


class FakeClock:
    def __init__(self, rig: FakeRig) -> None:
        self.rig = rig
        self.t = 100.0  # not zero: the runner must not assume the rig clock starts at 0

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            self.rig.advance(seconds)


class FakeEsc:
    def __init__(self, rig: FakeRig) -> None:
        self.rig = rig
        self.armed = False
        self.pulse_us = 1000.0
        self.history: list[tuple[float, str, float]] = []
        self.fail_set_after_s: float | None = None

    def describe(self) -> DeviceInfo:
        return DeviceInfo("esc", "fake", "fake://esc", (ChannelInfo("throttle_us", "us", 400.0,
                                                                    1000.0, 2000.0),))

    def arm(self) -> None:
        self.armed = True
        self.history.append((self.rig.clock.t, "arm", self.pulse_us))

    def set_pulse_us(self, pulse_us: float) -> None:
        if self.fail_set_after_s is not None and self.rig.clock.t >= self.fail_set_after_s:
            raise DeviceError("fake://esc: no answer")
        self.pulse_us = float(pulse_us)
        self.history.append((self.rig.clock.t, "set", self.pulse_us))

    def disarm(self) -> None:
        self.armed = False
        self.pulse_us = 1000.0
        self.history.append((self.rig.clock.t, "disarm", self.pulse_us))

    def close(self) -> None:
        pass


class FakeSensor:
    def __init__(self, rig: FakeRig, role: str, names: tuple[str, ...], rate_hz: float) -> None:
        self.rig, self.role, self.names, self.rate_hz = rig, role, names, rate_hz
        self.pending_t: list[np.ndarray] = []
        self.pending_v: list[dict[str, np.ndarray]] = []

    def describe(self) -> DeviceInfo:
        return DeviceInfo(self.role, "fake", f"fake://{self.role}",
                          tuple(ChannelInfo(n, n.rsplit("_", 1)[-1], self.rate_hz)
                                for n in self.names))

    def read_block(self) -> Block:
        self.rig.before_read(self.role)
        f = self.rig.faults
        if f.silent_role == self.role and f.silent_at_s is not None \
                and self.rig.clock.t >= f.silent_at_s:
            self.pending_t, self.pending_v = [], []
        if not self.pending_t:
            return Block.empty(self.names)
        t = np.concatenate(self.pending_t)
        v = {n: np.concatenate([p[n] for p in self.pending_v]) for n in self.names}
        self.pending_t, self.pending_v = [], []
        return Block(t, v)

    def close(self) -> None:
        pass


@dataclass
class Faults:
    device_error_at_s: float | None = None
    interrupt_at_s: float | None = None
    bug_at_s: float | None = None
    stall_at_s: float | None = None
    stall_wall_s: float = 0.0
    silent_role: str = ""  # this sensor stops delivering samples at silent_at_s
    silent_at_s: float | None = None
    spike: dict[str, tuple[float, float]] = field(default_factory=dict)  # channel: (t, value)
    seen_during_stall: list[bool] = field(default_factory=list)


class FakeRig:
    """Motor speed follows the command with a 30 ms lag; thrust and current ~ speed^2."""

    def __init__(self, rate_hz: float = 2500.0, voltage_v: float = 12.0) -> None:
        self.clock = FakeClock(self)
        self.esc = FakeEsc(self)
        self.rate_hz = rate_hz
        self.voltage_v = voltage_v
        self.sensors = {
            "load_cell": FakeSensor(self, "load_cell", ("thrust_n",), rate_hz),
            "power": FakeSensor(self, "power", ("current_a", "voltage_v"), rate_hz),
            "rpm": FakeSensor(self, "rpm", ("rpm",), 400.0),
        }
        self.rpm = 0.0
        self.faults = Faults()
        self.thrust_offset_n = 0.05
        self.closed = False
        self._next_rpm_t = self.clock.t
        self._stalled = False

    def target_rpm(self) -> float:
        us = self.esc.pulse_us if self.esc.armed else 1000.0
        return max(0.0, us - 1050.0) * 12.0

    def advance(self, dt: float) -> None:
        t0 = self.clock.t
        k0 = math.floor(t0 * self.rate_hz + 1e-6)
        k1 = math.floor((t0 + dt) * self.rate_hz + 1e-6)
        n = k1 - k0
        if n:
            t = np.arange(k0 + 1, k1 + 1) / self.rate_hz
            alpha = 1.0 - np.exp(-(t - t0) / 0.03)
            rpm = self.rpm + (self.target_rpm() - self.rpm) * alpha
            thrust = 1.0e-7 * rpm**2 + self.thrust_offset_n
            current = 2.0e-7 * rpm**2
            volt = self.voltage_v - 0.05 * current
            for ch, (ts, value) in self.faults.spike.items():
                width = 1.0 / 400.0 if ch == "rpm" else 1.0 / self.rate_hz  # rpm: 400 Hz
                hit = (t >= ts) & (t < ts + width)
                {"thrust_n": thrust, "current_a": current, "voltage_v": volt, "rpm": rpm}[ch][
                    hit] = value
            self.sensors["load_cell"].pending_t.append(t)
            self.sensors["load_cell"].pending_v.append({"thrust_n": thrust})
            self.sensors["power"].pending_t.append(t.copy())
            self.sensors["power"].pending_v.append({"current_a": current, "voltage_v": volt})
            rpm_t = np.arange(self._next_rpm_t, t[-1] + 1e-12, 1 / 400.0)
            if rpm_t.size:
                idx = np.clip(np.searchsorted(t, rpm_t), 0, n - 1)
                self.sensors["rpm"].pending_t.append(rpm_t)
                self.sensors["rpm"].pending_v.append({"rpm": rpm[idx]})
                self._next_rpm_t = rpm_t[-1] + 1 / 400.0
            self.rpm = float(rpm[-1])
        self.clock.t = t0 + dt

    def before_read(self, role: str) -> None:
        t = self.clock.t
        f = self.faults
        if role != "load_cell":
            return
        if f.device_error_at_s is not None and t >= f.device_error_at_s:
            raise DeviceError("fake://load_cell: timeout")
        if f.interrupt_at_s is not None and t >= f.interrupt_at_s:
            f.interrupt_at_s = None
            raise KeyboardInterrupt
        if f.bug_at_s is not None and t >= f.bug_at_s:
            raise ZeroDivisionError("a bug in a driver")
        if f.stall_at_s is not None and t >= f.stall_at_s and not self._stalled:
            self._stalled = True
            time.sleep(f.stall_wall_s)
            f.seen_during_stall.append(self.esc.armed)

    def close(self) -> None:
        self.closed = True


def write_truth_map(rig_path) -> None:
    """A static map for a copied sim rig from the plant's own steady state (no sweep)."""
    from bench.rig.rig import load_rig, save_thrust_map
    from drivers.factory import open_rig

    rig = load_rig(rig_path)
    devices = open_rig(rig)
    try:
        truth = devices.truth()
        grid = np.arange(1100.0, 1951.0, 10.0)
        thrust = np.array([truth.steady_thrust_n(u) for u in grid])
    finally:
        devices.close()
    save_thrust_map(rig, grid.tolist(), thrust.tolist())
