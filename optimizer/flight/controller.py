"""Paper B's cascade controller (Fig. B.4) with altitude hold, and the gain rule.

Cascade: quaternion attitude error -> body-rate setpoint (P, gain k_a) -> rate loop
(PI, k_p and integral corner w_i) -> body moments -> mixer (B.27). Paper B feeds the
vector part of the quaternion straight to the P gain, using q_1:3 = angles / 2 (B.26);
here the error quaternion q_e = q_d^-1 (x) q gives omega_sp = -2 k_a sign(q_e0) q_e1:3, so
k_a is in 1/s and the shorter way round is taken. Paper B's rate loop is P only; the
integral part (small, see the rule) holds the attitude against a gust torque. Altitude
hold uses the same cascade on height: z error -> climb-rate setpoint -> PI -> thrust
m (g + a) / cos(tilt).

Rate setpoints are limited so that the vehicle can still stop at the setpoint
(square-root limit): |omega_sp| <= sqrt(2 a |angle error|) per axis, with a =
``STOP_SHARE`` of the angular acceleration the mixer can give at hover
(``mixer.authority`` / inertia). The climb-rate setpoint is limited the same way with
the vertical acceleration the thrust margin gives (``mixer.authority`` / mass). It only
bites when the authority is small (yaw; designs hovering near full throttle; a 1 m climb
of a fast actuator, whose attitude gain asks metres per second); small steps stay linear.

Gain rule (every design flies without hand tuning). Each axis, with the actuator's mean
time constant tau and delay L (latency + half an ESC frame + half a tick), is
    acceleration / command = exp(-L s) / (tau s + 1),  rate = acceleration / s,
once the command is multiplied by the axis inertia (moment = I u) or mass. So one
normalised design serves roll, pitch, yaw and height:
1. rate loop, C(s) = k_p (1 + w_i / s) with w_i = w_c / ``INTEGRAL_RATIO``: the crossover
   w_c is where the open loop's phase is -180 deg + ``RATE_PHASE_MARGIN_DEG``; k_p makes
   |C P(j w_c)| = 1;
2. attitude loop, k_a / s times the closed rate loop T(s): crossover where the outer
   phase margin is ``ATTITUDE_PHASE_MARGIN_DEG``; k_a makes the outer loop gain 1 there.
The delay is exact in these frequency responses; ``closed_loop`` (scipy.signal, Pade
delay) gives the linearised poles and step for comparison with the simulation.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from scipy.optimize import brentq

from optimizer.errors import RequestError

if TYPE_CHECKING:  # scipy.signal (1.5 s of CPU to import) loads only for closed_loop:
    # every process that flies (a sweep's workers, each CLI run) needs the gains only
    from scipy import signal

RATE_PHASE_MARGIN_DEG = 50.0
ATTITUDE_PHASE_MARGIN_DEG = 65.0
STOP_SHARE = 0.5  # plan stops with half the available angular acceleration
INTEGRAL_RATIO = 10.0  # integral corner a tenth of the rate crossover (5.7 deg of phase)


@dataclass(frozen=True)
class Gains:
    """Normalised cascade gains (multiply the rate-loop output by the inertia or mass)."""

    k_p: float  # rate loop proportional, 1/s
    w_i: float  # rate loop integral corner, rad/s
    k_a: float  # attitude (and height) loop, 1/s
    rate_crossover_rad_s: float
    attitude_crossover_rad_s: float
    tau_s: float
    delay_s: float

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _rate_loop(w: np.ndarray | float, k_p: float, w_i: float, tau: float,
               delay: float) -> Any:
    s = 1j * np.asarray(w, float)
    return k_p * (1.0 + w_i / s) * np.exp(-delay * s) / (s * (tau * s + 1.0))


def design_gains(tau_s: float, delay_s: float) -> Gains:
    """The gain rule of the module docstring for time constant ``tau_s``, delay ``delay_s``."""
    if not (math.isfinite(tau_s) and tau_s > 0 and math.isfinite(delay_s) and delay_s >= 0):
        raise RequestError(f"gain rule: needs tau > 0 and delay >= 0, got {tau_s}, {delay_s}")
    pm = math.radians(RATE_PHASE_MARGIN_DEG)
    lag_i = math.atan(1.0 / INTEGRAL_RATIO)

    def phase_excess(w: float) -> float:  # open-loop phase + 180 deg - margin
        return math.pi / 2 - math.atan(w * tau_s) - w * delay_s - lag_i - pm

    hi = 1.0
    while phase_excess(hi) > 0:
        hi *= 2.0
    w_c = cast(float, brentq(phase_excess, 1e-6, hi, xtol=1e-9))  # a root, no full_output
    w_i = w_c / INTEGRAL_RATIO
    k_p = w_c * math.sqrt(1.0 + (w_c * tau_s) ** 2) / math.sqrt(1.0 + (w_i / w_c) ** 2)

    def closed_phase(w: float) -> float:  # phase of T(jw) + (90 deg - outer margin)
        loop = _rate_loop(w, k_p, w_i, tau_s, delay_s)
        t = loop / (1.0 + loop)
        return float(np.angle(t)) + math.pi / 2 - math.radians(ATTITUDE_PHASE_MARGIN_DEG)

    w_o = cast(float, brentq(closed_phase, 1e-3 * w_c, w_c, xtol=1e-9))
    loop = _rate_loop(w_o, k_p, w_i, tau_s, delay_s)
    k_a = w_o / abs(loop / (1.0 + loop))
    return Gains(float(k_p), float(w_i), float(k_a), float(w_c), float(w_o), float(tau_s),
                 float(delay_s))


def _pade(delay: float) -> tuple[np.ndarray, np.ndarray]:
    """Second-order Pade approximation of exp(-L s): numerator, denominator."""
    a = delay * delay / 12.0
    return np.array([a, -delay / 2.0, 1.0]), np.array([a, delay / 2.0, 1.0])


def closed_loop(g: Gains) -> signal.TransferFunction:
    """Linearised attitude (or height) closed loop: setpoint -> angle, Pade delay."""
    from scipy import signal

    pn, pd = _pade(g.delay_s)
    num_l = g.k_p * np.polymul([1.0, g.w_i], pn)  # k_p (s + w_i) Pade_num
    den_l = np.polymul(np.polymul([1.0, 0.0, 0.0], [g.tau_s, 1.0]), pd)  # s^2 (tau s+1) ...
    inner = np.polyadd(den_l, num_l)  # T = num_l / inner
    num = g.k_a * num_l
    den = np.polyadd(np.polymul([1.0, 0.0], inner), num)
    return signal.TransferFunction(num, den)


def phase_margins(g: Gains) -> dict[str, float]:
    """Phase margins (deg) of the rate and attitude loops at their crossovers (exact delay)."""
    w_c, w_o = g.rate_crossover_rad_s, g.attitude_crossover_rad_s
    rate = _rate_loop(w_c, g.k_p, g.w_i, g.tau_s, g.delay_s)
    inner = _rate_loop(w_o, g.k_p, g.w_i, g.tau_s, g.delay_s)
    outer = g.k_a * inner / (1.0 + inner) / (1j * w_o)
    return {"rate": math.degrees(float(np.angle(rate))) + 180.0,
            "attitude": math.degrees(float(np.angle(outer))) + 180.0}


class CascadeController:
    """Attitude, rate and altitude loops of one vehicle, run once per tick (plain floats)."""

    def __init__(self, gains: Gains, inertia: tuple[float, float, float], mass: float,
                 gravity: float, dt: float,
                 authority: tuple[float, float, float, float] | None = None) -> None:
        self.g = gains
        big = math.inf
        # 2 a of the square-root limits: roll, pitch, yaw (moment / inertia), climb
        # (thrust / mass)
        self.stop = tuple(2.0 * STOP_SHARE * m / i for m, i in zip(
            authority, (*inertia, mass), strict=True)) \
            if authority is not None else (big, big, big, big)
        self.ixx, self.iyy, self.izz = inertia
        self.mass = mass
        self.gravity = gravity
        self.dt = dt
        self.i_rate = [0.0, 0.0, 0.0]
        self.i_climb = 0.0

    def update(self, s: list[float], qd: tuple[float, float, float, float], z_d: float,
               hold: bool) -> tuple[float, float, float, float]:
        """Moments and total thrust for state ``s``; ``hold`` freezes the integrators
        (the mixer saturated last tick: conditional integration against wind-up)."""
        g = self.g
        qw, qx, qy, qz = s[6], s[7], s[8], s[9]
        dw, dx, dy, dz = qd
        # q_e = q_d^-1 (x) q  (B.2, B.3)
        ew = dw * qw + dx * qx + dy * qy + dz * qz
        ex = dw * qx - dx * qw - dy * qz + dz * qy
        ey = dw * qy + dx * qz - dy * qw - dz * qx
        ez = dw * qz - dx * qy + dy * qx - dz * qw
        sign = -2.0 if ew >= 0.0 else 2.0  # 2 q_e1:3 ~ angle error (B.26)
        ka, (sx, sy, sz, sv) = g.k_a, self.stop
        ax, ay, az = sign * ex, sign * ey, sign * ez
        wx, wy, wz = ka * ax, ka * ay, ka * az
        cap = math.sqrt(sx * abs(ax))  # square-root limit, per axis
        if abs(wx) > cap:
            wx = math.copysign(cap, wx)
        cap = math.sqrt(sy * abs(ay))
        if abs(wy) > cap:
            wy = math.copysign(cap, wy)
        cap = math.sqrt(sz * abs(az))
        if abs(wz) > cap:
            wz = math.copysign(cap, wz)
        er = (wx - s[10], wy - s[11], wz - s[12])
        i_rate = self.i_rate
        if not hold:
            dt = self.dt
            i_rate[0] += er[0] * dt
            i_rate[1] += er[1] * dt
            i_rate[2] += er[2] * dt
        kp, wi = g.k_p, g.w_i
        mx = self.ixx * kp * (er[0] + wi * i_rate[0])
        my = self.iyy * kp * (er[1] + wi * i_rate[1])
        mz = self.izz * kp * (er[2] + wi * i_rate[2])
        # altitude hold: z error -> climb-rate setpoint -> PI -> vertical acceleration
        ez_m = z_d - s[2]
        climb = ka * ez_m
        cap = math.sqrt(sv * abs(ez_m))  # square-root limit on the climb rate
        if abs(climb) > cap:
            climb = math.copysign(cap, climb)
        ev = climb - s[5]
        if not hold:
            self.i_climb += ev * self.dt
        accel = kp * (ev + wi * self.i_climb)
        tilt = max(0.5, 1.0 - 2.0 * (qx * qx + qy * qy))
        thrust = self.mass * (self.gravity + accel) / tilt
        return mx, my, mz, thrust
