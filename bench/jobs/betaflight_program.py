"""What the pilot of a Betaflight flight does with the sticks: the maneuvers and the height.

The maneuvers are the thesis' (``optimizer.flight.maneuvers``) flown as stick inputs in
Betaflight's ANGLE mode, where the roll and pitch sticks command angles: ``roll_step`` and
``pitch_step`` (10 deg at ``STEP_TIME_S`` into a 4 s window) and ``gust`` (sticks centred,
the gust pushed on the plant). ``yaw_step`` and ``altitude_step`` have no stick of their
own in ANGLE mode (yaw is a rate there; Betaflight holds no height) and are not flown.
Then, for the firmware's own log, a train of roll and pitch rate steps in rate (acro)
mode: clean setpoint steps, from which a log's step response is read both directly and by
deconvolution (``rotorbench flight-report``).

Stick to setpoint. The bench's CLI preamble makes the roll and pitch rates linear
(``*_rc_rate`` = ``*_srate``: centre sensitivity = top rate, ``RATE_TOP_DPS``), so a
stick deflection d (of 500 us) asks ``d x RATE_TOP_DPS`` in rate mode and, in ANGLE mode,
``d x angle_limit`` (``ANGLE_LIMIT_DEG``; pid.c scales the angle by setpoint over top rate).

Height. Betaflight holds no height, so the pilot does, as a person would with the throttle:
a PID on the height with a feed-forward of the hover command over sqrt(cos tilt)
(thrust ~ command^2, so the vertical share of the thrust stays the weight).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from optimizer.flight.maneuvers import MANEUVERS, STEP_TIME_S, Maneuver

__all__ = ["ANGLE_LIMIT_DEG", "BETAFLIGHT_MANEUVERS", "RATE_PERIOD_S", "RATE_TOP_DPS", "SPIN_UP_S",
           "HeightPilot", "Segment", "angle_stick", "program", "rate_stick"]

ANGLE_LIMIT_DEG = 60.0  # angle_limit, Betaflight's default
RATE_TOP_DPS = 670.0  # the preamble's linear rate: 67 x 10 deg/s
STICK_HALF_US = 500.0
#: the thesis maneuvers a Betaflight flight flies as stick inputs (module doc)
BETAFLIGHT_MANEUVERS = ("roll_step", "pitch_step", "gust")
SPIN_UP_S = 0.6  # armed and held while the rotors reach the hover command
HOVER_S = 1.5  # released: the pilot settles the height before the first maneuver
SETTLE_S = 1.5  # between maneuvers: sticks centred, not measured
RATE_STEP_DPS = 100.0  # 25 deg of tilt per step: the pilot keeps the height
RATE_HOLD_S = 0.25  # a rate step's length; then as long at zero rate
RATE_PAUSE_S = 0.35
RATE_PERIOD_S = RATE_HOLD_S + RATE_PAUSE_S  # one rate step and its pause
END_S = 0.5  # level before disarming


def angle_stick(angle_rad: float) -> tuple[int, float]:
    """The stick (us) nearest to an ANGLE-mode angle and the angle it really asks (rad)."""
    d = round(math.degrees(angle_rad) / ANGLE_LIMIT_DEG * STICK_HALF_US)
    return 1500 + d, math.radians(d / STICK_HALF_US * ANGLE_LIMIT_DEG)


def rate_stick(rate_dps: float) -> int:
    """The stick (us) of a rate-mode setpoint (deg/s)."""
    return 1500 + round(rate_dps / RATE_TOP_DPS * STICK_HALF_US)


@dataclass(frozen=True)
class Segment:
    """A stretch of the flight: its sticks (roll, pitch, yaw in us) from ``start_s`` on
    (plant time), whether ANGLE mode is on, and, for a measured maneuver, which one."""

    start_s: float
    duration_s: float
    roll_us: int = 1500
    pitch_us: int = 1500
    angle: bool = True
    maneuver: Maneuver | None = None  # amplitude: what the stick really asks
    gust: bool = False
    label: str = ""

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s


def program(maneuvers: list[str], rate_steps_s: float, release_s: float) -> list[Segment]:
    """The segments after release (plant time ``release_s``), in order: hover, each
    maneuver (its level lead-in, the step, the rest of its window) with a settle after
    it, the rate-step train, a level end. The caller disarms after the last."""
    t = release_s
    out = [Segment(t, HOVER_S, label="hover")]
    t += HOVER_S
    for name in maneuvers:
        man = MANEUVERS[name]
        out.append(Segment(t, STEP_TIME_S, label=f"{name} lead-in"))
        if man.axis in ("roll", "pitch"):
            stick, real = angle_stick(man.amplitude)
            real_man = Maneuver(man.name, man.axis, real, man.duration_s)
            roll, pitch = (stick, 1500) if man.axis == "roll" else (1500, stick)
            out.append(Segment(t + STEP_TIME_S, man.duration_s - STEP_TIME_S, roll, pitch,
                               maneuver=real_man, label=name))
        else:
            out.append(Segment(t + STEP_TIME_S, man.duration_s - STEP_TIME_S,
                               maneuver=man, gust=man.axis == "gust", label=name))
        t += man.duration_s
        out.append(Segment(t, SETTLE_S, label="settle"))
        t += SETTLE_S
    period = RATE_PERIOD_S
    for k in range(int(rate_steps_s / period + 1e-9)):
        # +roll, +pitch, -roll, -pitch, ...: each tilt is taken back by the step after next
        rate = rate_stick((1 if (k // 2) % 2 == 0 else -1) * RATE_STEP_DPS)
        roll, pitch = (rate, 1500) if k % 2 == 0 else (1500, rate)
        out.append(Segment(t, RATE_HOLD_S, roll, pitch, angle=False, label="rate step"))
        out.append(Segment(t + RATE_HOLD_S, RATE_PAUSE_S, angle=False, label="rate pause"))
        t += period
    out.append(Segment(t, END_S, label="end"))
    return out


class HeightPilot:
    """The throttle a pilot gives to hold height 0 (module doc): a PID with the natural
    frequency ``W_N`` on the acceleration, over a hover feed-forward."""

    W_N = 3.0  # rad/s: well inside the rotors' and the firmware's loops
    ZETA = 1.0
    KI = 2.0  # 1/s^3

    def __init__(self, hover_command: float, gravity_m_s2: float) -> None:
        self.u_hover = hover_command
        self.g = gravity_m_s2
        self.integral = 0.0

    def command(self, z_m: float, vz_m_s: float, cos_tilt: float, dt: float) -> float:
        """The motor command (0..1 of full speed) the throttle stick should ask for."""
        self.integral += -z_m * dt
        a = -self.W_N ** 2 * z_m - 2 * self.ZETA * self.W_N * vz_m_s + self.KI * self.integral
        # thrust ~ u^2: d(thrust)/du = 2 m g / u_hover at hover, so du = u_hover a / (2 g)
        return self.u_hover / math.sqrt(max(0.5, cos_tilt)) + self.u_hover * a / (2 * self.g)
