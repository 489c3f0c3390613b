"""The simulated ESC: frame-sampled pulse input, firmware latency/filter, failsafe, schemes.

``EscModel`` is the firmware inside the ESC: once per PWM frame it latches the pulse width
the host last sent, maps it to a motor duty cycle, optionally low-pass filters it (stock
firmware) and drops to idle when no command arrived for ``timeout_s`` (failsafe, like
VESC's timeout or an RC ESC's signal-loss). The switching scheme (Paper C sections 2, 3.3)
is applied by the plant, which knows the winding current.

``SimEsc`` is the host-side device (``drivers.contracts.Esc``) that sends the pulses.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Unpack

from drivers.contracts import ChannelInfo, DeviceInfo, Fault
from drivers.errors import DeviceError
from drivers.sim.clock import SimClock
from drivers.sim.faults import FaultOptions, FaultsSnapshot, FaultSwitches
from drivers.sim.plant import EscFrameSource, EscScheme, PlantParams


@dataclass(frozen=True)
class EscSettings:
    """Pulse protocol of the ESC input (rig file section ``[esc]``)."""

    frame_rate_hz: float = 400.0  # cRIO updates the ESC at 400 Hz (Paper C section 2.2)
    min_us: float = 1000.0
    max_us: float = 2000.0
    idle_us: float = 1000.0
    arm_us: float = 1000.0
    timeout_s: float = 0.5  # failsafe: no command for this long -> idle

    def duty(self, pulse_us: float) -> float:
        """Throttle pulse -> duty cycle, linear between min_us and max_us."""
        d = (pulse_us - self.min_us) / (self.max_us - self.min_us)
        return min(1.0, max(0.0, d))


class EscModel(EscFrameSource):
    """ESC firmware: per-frame latch of the last pulse, failsafe and (stock) input filter."""

    def __init__(self, settings: EscSettings, scheme: EscScheme, params: PlantParams) -> None:
        self.settings = settings
        self.scheme = scheme
        self.frame_ns = round(1e9 / settings.frame_rate_hz)
        self.timeout_ns = round(settings.timeout_s * 1e9)
        tau = params.filter_tau_for(scheme)
        frame_s = self.frame_ns * 1e-9
        self.alpha = 1.0 - math.exp(-frame_s / tau) if tau > 0 else 1.0
        self.events: deque[tuple[int, str, float]] = deque()
        self.armed = False
        self.pulse_us = settings.idle_us
        self.last_ns = 0
        self.failsafe = False
        self.failsafe_count = 0
        self.duty_filtered = 0.0
        self._duty_cmd = 0.0

    def steady_frames(self, k: int, limit: int) -> int:
        """How many frames from ``k`` on (at most ``limit``) latch the same duty as frame
        ``k`` did, given the commands sent so far. Call right after ``latch(k)``."""
        if self.armed and self.duty_filtered != self._duty_cmd:
            return 1  # the stock filter is still moving
        end = k + limit
        last_ns = self.last_ns
        watch = self.armed and not self.failsafe
        for t_e, kind, value in self.events:
            latch_k = -(-t_e // self.frame_ns)  # first frame that latches this command
            if watch and (last_ns + self.timeout_ns) // self.frame_ns + 1 < latch_k:
                break  # the failsafe fires before this command arrives
            if kind != "pulse" or value != self.pulse_us or self.failsafe:
                end = min(end, latch_k)  # this command changes the duty
                break
            last_ns = t_e  # a refresh of the same pulse changes nothing but the timeout
        if watch:  # first frame past the failsafe timeout
            end = min(end, (last_ns + self.timeout_ns) // self.frame_ns + 1)
        return max(1, end - k)

    _STATE = ("armed", "pulse_us", "last_ns", "failsafe", "failsafe_count", "duty_filtered",
              "_duty_cmd")

    def snapshot(self) -> tuple[object, ...]:
        return (tuple(self.events), *(getattr(self, name) for name in self._STATE))

    def restore(self, snap: tuple[object, ...]) -> None:
        """Back to a ``snapshot`` (a simulated rig's checkpoint)."""
        self.events = deque(snap[0])  # type: ignore[call-overload]
        for name, value in zip(self._STATE, snap[1:], strict=True):
            setattr(self, name, value)

    def push(self, t_ns: int, kind: str, value: float = 0.0) -> None:
        """A command leaves the host at ``t_ns`` ("pulse", "arm" or "disarm")."""
        self.events.append((t_ns, kind, value))

    def latch(self, k: int) -> float:
        t_k = k * self.frame_ns
        ev = self.events
        while ev and ev[0][0] <= t_k:
            t, kind, value = ev.popleft()
            if kind == "pulse":
                self.pulse_us = value
                self.last_ns = t
            elif kind == "arm":
                self.armed = True
                self.pulse_us = self.settings.arm_us
                self.last_ns = t
            else:  # disarm
                self.armed = False
                self.pulse_us = self.settings.idle_us
        timed_out = self.armed and t_k - self.last_ns > self.timeout_ns
        if timed_out and not self.failsafe:
            self.failsafe_count += 1
        self.failsafe = timed_out
        if not self.armed:
            self.duty_filtered = 0.0
            return -1.0  # transistors off: the motor coasts
        pulse = self.settings.idle_us if timed_out else self.pulse_us
        duty = self.settings.duty(pulse)
        self.duty_filtered += self.alpha * (duty - self.duty_filtered)
        if abs(self.duty_filtered - duty) < 1e-9:
            self.duty_filtered = duty  # the filter has settled
        self._duty_cmd = duty
        if duty <= 0.0 and self.duty_filtered < 1e-3:
            self.duty_filtered = 0.0
            return -1.0  # zero throttle: firmware switches the bridge off
        return self.duty_filtered


class SimEsc:
    """Host-side ESC output on the simulated rig (fills ``drivers.contracts.Esc``)."""

    def __init__(self, url: str, model: EscModel, clock: SimClock, faults: FaultSwitches) -> None:
        self.url = url
        self.model = model
        self.clock = clock
        self.faults = faults
        self.last_pulse_us = model.settings.idle_us
        self.closed = False

    def describe(self) -> DeviceInfo:
        s = self.model.settings
        return DeviceInfo(
            kind="esc",
            model=f"simulated F30A ({self.model.scheme.value})",
            url=self.url,
            channels=(ChannelInfo("throttle_us", "us", s.frame_rate_hz, s.min_us, s.max_us),),
            extra={
                "frame_rate_hz": s.frame_rate_hz,
                "idle_us": s.idle_us,
                "arm_us": s.arm_us,
                "timeout_s": s.timeout_s,
                "esc_mode": self.model.scheme.value,
            },
        )

    def snapshot(self) -> tuple[float, bool, FaultsSnapshot]:
        return self.last_pulse_us, self.closed, self.faults.snapshot()

    def restore(self, snap: tuple[float, bool, FaultsSnapshot]) -> None:
        self.last_pulse_us, self.closed, faults = snap
        self.faults.restore(faults)

    def _check(self, what: str) -> None:
        if self.closed:
            raise DeviceError(f"{self.url}: ESC is closed ({what})")
        if self.faults.switches:  # none switched on: nothing to check (every tick)
            self.faults.check(self.clock.now(), what)

    def arm(self) -> None:
        self._check("arm")
        self.model.push(self.clock.now_ns(), "arm")
        self.last_pulse_us = self.model.settings.arm_us

    def set_pulse_us(self, pulse_us: float) -> None:
        pulse = float(pulse_us)
        if not math.isfinite(pulse):
            raise DeviceError(f"{self.url}: pulse width must be finite, got {pulse_us!r}")
        self._check("set_pulse_us")
        s = self.model.settings
        pulse = min(s.max_us, max(s.min_us, pulse))
        self.model.push(self.clock.now_ns(), "pulse", pulse)
        self.last_pulse_us = pulse

    def disarm(self) -> None:
        """Idle + disarm. Never raises: a disconnected ESC falls back to its own failsafe."""
        if self.closed or self.faults.blocked(self.clock.now()):
            return
        self.model.push(self.clock.now_ns(), "disarm")
        self.last_pulse_us = self.model.settings.idle_us

    def close(self) -> None:
        if not self.closed:
            self.disarm()
            self.closed = True

    def inject(self, fault: Fault | str, **kwargs: Unpack[FaultOptions]) -> None:
        """Switch a fault on (TIMEOUT or DISCONNECT), see ``FaultSwitches.inject``."""
        self.faults.inject(fault, **kwargs)

    def clear(self, fault: Fault | str | None = None) -> None:
        self.faults.clear(fault)
