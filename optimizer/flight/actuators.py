"""Rotor actuators: Paper C's first-order-plus-delay model on the rotor speed.

Paper C (section 3.2, C.2-C.4; Table C.1) describes thrust setpoint -> thrust as a delay
and a first-order lag, with different time constants for rising and falling steps
(braking depends on the ESC mode, section 3.3). Here each rotor's speed follows its
commanded speed through, in order:

1. command quantisation: the ESC resolves ``levels`` steps between idle and full speed
   (1 us of a 1000-2000 us PWM frame = 1000 levels);
2. the ESC frame: a new command is taken only every ``frame_s`` (sample and hold);
3. the latency L: a pure delay, whole control ticks;
4. the lag: d omega / dt = (omega_cmd - omega) / tau, tau = ``tau_up_s`` while speeding
   up, ``tau_down_s`` while slowing down, discretised exactly over a tick. The speed a
   tick applies (held by the rigid-body step) is the exact mean of the response over the
   tick, not its end value: the end value leads the continuous lag by half a tick;
5. speed limits: idle ``omega_min`` .. full throttle ``omega_max``.

The lag acts on the rotor speed as (E.35) does; for a measured time constant (fitted on
the thrust, Paper C) this is the small-step reading: thrust = k_f omega^2 linearised at
hover has the same pole as the speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from optimizer.errors import RequestError

#: Catalog defaults where the catalog has no number (the datasheet model gives tau only).
DEFAULT_FRAME_RATE_HZ = 400.0  # standard PWM ESC input rate
DEFAULT_LEVELS = 1000  # 1 us steps of a 1000-2000 us PWM command
DEFAULT_LATENCY_S = 0.0  # no delay in the datasheet model (Paper C measures one)
DEFAULT_IDLE_FRACTION = 0.05  # ESC idle speed as a fraction of full speed


@dataclass(frozen=True)
class ActuatorModel:
    """Dynamics of one rotor (all rotors of a design are alike)."""

    tau_up_s: float
    tau_down_s: float
    latency_s: float = DEFAULT_LATENCY_S
    frame_s: float = 1.0 / DEFAULT_FRAME_RATE_HZ
    levels: int = DEFAULT_LEVELS
    idle_fraction: float = DEFAULT_IDLE_FRACTION
    source: str = "model (E.35)"

    def __post_init__(self) -> None:
        for name in ("tau_up_s", "tau_down_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise RequestError(f"actuator ({self.source}): {name} must be > 0 s, got {v!r}")
        for name in ("latency_s", "frame_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise RequestError(f"actuator ({self.source}): {name} must be >= 0 s, got "
                                   f"{v!r}")
        if self.levels < 2:
            raise RequestError(f"actuator ({self.source}): levels must be >= 2, got "
                               f"{self.levels}")
        if not 0.0 <= self.idle_fraction < 1.0:
            raise RequestError(f"actuator ({self.source}): idle_fraction must be in [0, 1), "
                               f"got {self.idle_fraction}")

    @property
    def tau_mean_s(self) -> float:
        """The mean of rising and falling time constants (what Table E.13 compares)."""
        return 0.5 * (self.tau_up_s + self.tau_down_s)

    def effective_delay_s(self, dt: float) -> float:
        """Delay of the linear model: latency, half an ESC frame and half a control tick
        (each sample-and-hold delays by half its period on average)."""
        return self.latency_s + 0.5 * self.frame_s + 0.5 * dt


class RotorBank:
    """The N rotors of one vehicle, stepped once per control tick (plain floats)."""

    def __init__(self, model: ActuatorModel, n: int, omega_max: float, dt: float,
                 omega0: float) -> None:
        self.n = n
        self.omega_max = omega_max
        self.omega_min = model.idle_fraction * omega_max
        self.a_up = -math.expm1(-dt / model.tau_up_s)
        self.a_down = -math.expm1(-dt / model.tau_down_s)
        # share of the tick's approach to the target that its mean speed makes:
        # 1/dt int_0^dt (1 - exp(-t / tau)) dt = 1 - tau a / dt (about dt / (2 tau))
        self.m_up = 1.0 - model.tau_up_s * self.a_up / dt
        self.m_down = 1.0 - model.tau_down_s * self.a_down / dt
        self.quantum = (self.omega_max - self.omega_min) / (model.levels - 1)
        self.frame_ticks = max(1, round(model.frame_s / dt))
        self.delay = max(0, round(model.latency_s / dt))
        self.omega = [omega0] * n
        held = [omega0] * n
        self.held = held
        self.queue = [list(held) for _ in range(self.delay)]
        self.tick = 0

    def step(self, command: list[float]) -> list[float]:
        """Advance one tick with the commanded speeds; returns each rotor's mean speed
        over the tick (``self.omega`` holds the speeds at its end)."""
        if self.tick % self.frame_ticks == 0:  # the ESC takes a new frame
            lo, q = self.omega_min, self.quantum
            hi = self.omega_max
            self.held = [lo + round((min(hi, max(lo, c)) - lo) / q) * q for c in command]
        self.tick += 1
        if self.delay:
            self.queue.append(self.held)
            target = self.queue.pop(0)
        else:
            target = self.held
        omega = self.omega
        a_up, a_down, m_up, m_down = self.a_up, self.a_down, self.m_up, self.m_down
        mean = []
        for i, c in enumerate(target):
            w = omega[i]
            d = c - w
            if d > 0.0:
                omega[i] = w + d * a_up
                mean.append(w + d * m_up)
            else:
                omega[i] = w + d * a_down
                mean.append(w + d * m_down)
        return mean
