"""Closed-loop flight: the named maneuvers and the 1 kHz simulation loop.

Every maneuver starts level at rest in hover equilibrium (rotors at the hover speed,
thrust = weight) and holds altitude 0 unless it commands height:

- ``roll_step`` / ``pitch_step``: 10 deg attitude step at ``STEP_TIME_S``;
- ``yaw_step``: 30 deg heading step;
- ``altitude_step``: 1 m climb;
- ``gust``: a 1 - cos gust of ``GUST_S`` seconds: a horizontal force of
  ``GUST_FORCE_G`` x weight and a roll/pitch torque of ``GUST_TORQUE_FRACTION`` x one
  rotor's hover thrust x arm; the figure is how far the attitude is pushed and when it is
  back within 0.2 deg (2 % of the 10 deg step);
- ``hover``: 3 s from rotors at 90 % of the model's hover speed (the plot, the altitude
  error). Its figures are the trim the closed loop settles to (N k_f omega^2 = m g, shaft
  power N k_m omega^3): a 3 s run of a slow actuator has not settled yet (its last 0.5 s
  read +4e-4 high on a 123 ms design; 30 s of flight end on the trim, tested).

One tick: controller (on the state) -> mixer -> speed commands -> rotors (quantise, ESC
frame, latency, lag) -> thrusts and moments -> one step of the rigid body
(``vehicle.step``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from optimizer.errors import RequestError
from optimizer.flight import metrics
from optimizer.flight.actuators import ActuatorModel, RotorBank
from optimizer.flight.controller import CascadeController, Gains, design_gains
from optimizer.flight.mixer import Mixer, allocation_matrix, authority
from optimizer.flight.vehicle import Vehicle, euler_angles, hover_state, step

DT_S = 1e-3  # 1 kHz control and integration rate
STEP_TIME_S = 0.1
GUST_S = 0.5
GUST_FORCE_G = 0.2
GUST_TORQUE_FRACTION = 0.1
GUST_BAND_DEG = 0.2


@dataclass(frozen=True)
class Maneuver:
    """A setpoint or disturbance history: what is commanded, how much, for how long."""

    name: str
    axis: str  # roll, pitch, yaw, altitude, gust, hover
    amplitude: float  # rad or m (gust: unused)
    duration_s: float


MANEUVERS: dict[str, Maneuver] = {
    m.name: m
    for m in (
        Maneuver("roll_step", "roll", math.radians(10.0), 4.0),
        Maneuver("pitch_step", "pitch", math.radians(10.0), 4.0),
        Maneuver("yaw_step", "yaw", math.radians(30.0), 4.0),
        Maneuver("altitude_step", "altitude", 1.0, 4.0),
        Maneuver("gust", "gust", 0.0, 8.0),
    )
}
HOVER = Maneuver("hover", "hover", 0.0, 3.0)


def maneuver(name: str) -> Maneuver:
    """The named maneuver; a wrong name lists the known ones."""
    if name == "hover":
        return HOVER
    try:
        return MANEUVERS[name]
    except KeyError:
        raise RequestError(f"--maneuver {name!r}: expected one of "
                           f"{', '.join(MANEUVERS)}") from None


@dataclass
class Flight:
    """The recorded flight (arrays over ticks) and its figures."""

    maneuver: Maneuver
    t: np.ndarray
    euler: np.ndarray  # (T, 3) roll, pitch, yaw rad
    position: np.ndarray  # (T, 3) m
    omega: np.ndarray  # (T, N) rotor speeds rad/s
    setpoint: np.ndarray  # (T,) the commanded quantity of the maneuver axis
    saturated: np.ndarray  # (T,) bool, the mixer rule changed the demand
    figures: dict[str, Any] = field(default_factory=dict)


def _euler_quaternion(roll: float, pitch: float, yaw: float
                      ) -> tuple[float, float, float, float]:
    """(B.21) quaternion of roll, pitch, yaw (Z-Y-X rotation, scalar first)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def step_quaternion(man: Maneuver) -> tuple[float, float, float, float]:
    """The attitude setpoint after the step (level for a maneuver of no attitude axis)."""
    command = {"roll": (man.amplitude, 0.0, 0.0), "pitch": (0.0, man.amplitude, 0.0),
               "yaw": (0.0, 0.0, man.amplitude)}.get(man.axis)
    return _euler_quaternion(*command) if command else (1.0, 0.0, 0.0, 0.0)


def gust_load(vehicle: Vehicle, since_s: float) -> tuple[float, float]:
    """The gust at ``since_s`` after it starts, in continuous time (an outside controller's
    plant, ``optimizer.flight.plant``): the sideways force (N, navigation y) and the
    torque on roll and on pitch (N m) that ``fly`` applies tick by tick."""
    if not 0.0 <= since_s < GUST_S:
        return 0.0, 0.0
    g = vehicle.gravity_m_s2
    shape = 0.5 * (1.0 - math.cos(2.0 * math.pi * since_s / GUST_S))
    return (GUST_FORCE_G * vehicle.mass_kg * g * shape,
            GUST_TORQUE_FRACTION * vehicle.mass_kg * g / vehicle.n_rotors * vehicle.arm_m
            * shape)


def fly(vehicle: Vehicle, actuator: ActuatorModel, man: Maneuver, *,
        gains: Gains | None = None, dt: float = DT_S, record: bool = True) -> Flight:
    """Fly one maneuver; ``record=False`` keeps only the maneuver axis (faster sweeps)."""
    if gains is None:
        gains = design_gains(actuator.tau_mean_s, actuator.effective_delay_s(dt))
    n = vehicle.n_rotors
    k_f, k_m = vehicle.k_f, vehicle.k_m
    x, y, spin = vehicle.rotor_positions()
    alloc = allocation_matrix(x, y, spin, vehicle.torque_ratio_m)
    idle = actuator.idle_fraction * vehicle.omega_max_rad_s
    mixer = Mixer(alloc, k_f * idle * idle, k_f * vehicle.omega_max_rad_s ** 2)
    w_hover = vehicle.hover_speed_rad_s
    start = 0.9 * w_hover if man.axis == "hover" else w_hover
    rotors = RotorBank(actuator, n, vehicle.omega_max_rad_s, dt, start)
    hover_f = vehicle.mass_kg * vehicle.gravity_m_s2 / n
    ctrl = CascadeController(gains, vehicle.inertia_kgm2, vehicle.mass_kg,
                             vehicle.gravity_m_s2, dt,
                             authority(alloc, mixer.f_min, mixer.f_max, hover_f))
    ixx, iyy, izz = vehicle.inertia_kgm2
    inv_m, g, cd = 1.0 / vehicle.mass_kg, vehicle.gravity_m_s2, vehicle.drag_n_s_m
    xs, ys, spins = x.tolist(), y.tolist(), spin.tolist()
    inv_kf = 1.0 / k_f

    steps = round(man.duration_s / dt)
    t_arr = np.arange(steps) * dt
    sp = np.zeros(steps)
    level = (1.0, 0.0, 0.0, 0.0)
    q_step = step_quaternion(man)
    z_step = man.amplitude if man.axis == "altitude" else 0.0
    k_step = round(STEP_TIME_S / dt)
    if man.axis in ("roll", "pitch", "yaw", "altitude"):
        sp[k_step:] = man.amplitude
    gust_f = GUST_FORCE_G * vehicle.mass_kg * g
    gust_m = GUST_TORQUE_FRACTION * vehicle.mass_kg * g / n * vehicle.arm_m
    k_gust = round(GUST_S / dt)
    gusty = man.axis == "gust"

    s = hover_state()
    states: list[list[float]] = []
    speeds: list[tuple[float, ...]] = []
    sat = np.zeros(steps, bool)
    saturated = False
    for k in range(steps):
        qd, z_d = (q_step, z_step) if k >= k_step else (level, 0.0)
        mx, my, mz, thrust = ctrl.update(s, qd, z_d, saturated)
        forces, saturated = mixer.mix(mx, my, mz, thrust)
        sat[k] = saturated
        w = rotors.step([math.sqrt(f * inv_kf) if f > 0.0 else 0.0 for f in forces])
        # (2.43)/(B.11): thrusts and drag torques of the rotor speeds
        f_tot = m_x = m_y = m_z = 0.0
        for i in range(n):
            w2 = w[i] * w[i]
            f = k_f * w2
            f_tot += f
            m_x += ys[i] * f
            m_y -= xs[i] * f
            m_z -= spins[i] * k_m * w2
        fx = fy = 0.0
        if gusty and k_step <= k < k_step + k_gust:
            shape = 0.5 * (1.0 - math.cos(2.0 * math.pi * (k - k_step) / k_gust))
            fy = gust_f * shape
            m_x += gust_m * shape
            m_y += gust_m * shape
        s = step(s, dt, f_tot, m_x, m_y, m_z, fx, fy, 0.0, inv_m, ixx, iyy, izz, g, cd)
        states.append(s)
        if record:
            speeds.append(tuple(w))
    t_arr = t_arr + dt  # the state after each tick
    traj = np.array(states)
    omegas = np.array(speeds) if record else np.empty((0, n))
    flight = Flight(man, t_arr, euler_angles(traj[:, 6:10]), traj[:, 0:3], omegas, sp, sat)
    flight.figures = figures(flight, vehicle, actuator, rotors)
    return flight


def figures(f: Flight, vehicle: Vehicle, actuator: ActuatorModel,
            rotors: RotorBank) -> dict[str, Any]:
    """The maneuver's JSON figures (issue keys first)."""
    man = f.maneuver
    if man.axis == "hover":
        return trim_figures(vehicle.hover_speed_rad_s, rotors.omega_min, rotors.omega_max,
                            vehicle.n_rotors, vehicle.k_m, float(abs(f.position[-1, 2])))
    axis_col = {"roll": 0, "pitch": 1, "yaw": 2}
    if man.axis in axis_col:
        signal = f.euler[:, axis_col[man.axis]]
    elif man.axis == "altitude":
        signal = f.position[:, 2]
    else:
        signal = gust_tilt(f.euler[:, 0], f.euler[:, 1])
    return response_figures(man, f.t, signal, f.saturated)


def gust_tilt(roll: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """How far a gust tilts the vehicle (rad), what the gust's figures read."""
    return np.hypot(roll, pitch)


def response_figures(man: Maneuver, t: np.ndarray, signal: np.ndarray,
                     saturated: np.ndarray) -> dict[str, Any]:
    """Figures of a step or gust from what its axis reads (T,): the commanded angle, the
    height, or the gust's tilt; and the saturation flags (T,)."""
    t_step = STEP_TIME_S
    out: dict[str, Any] = {}
    if man.axis == "gust":
        d = metrics.disturbance_metrics(t, signal, t_step, math.radians(GUST_BAND_DEG))
        peak = d["peak"]
        assert peak is not None  # always a number (the settling time may be None)
        out.update({"rise_time_ms": None, "overshoot_pct": None,
                    "settling_time_ms": d["settling_time_ms"],
                    "peak_tilt_deg": math.degrees(peak)})
    else:
        out.update(metrics.step_metrics(t, signal, t_step, 0.0, man.amplitude))
    out["saturation_pct"] = 100.0 * float(np.mean(saturated))
    return metrics.summary(out)


def trim_figures(hover_speed_rad_s: float, omega_min: float, omega_max: float, n_rotors: int,
                 k_m: float, altitude_error_m: float) -> dict[str, Any]:
    """Hover's figures: the trim (E.19-E.20), as far as the rotors reach (full throttle when
    they cannot), and the height lost or gained at the end of the run."""
    w = min(max(hover_speed_rad_s, omega_min), omega_max)
    span = omega_max - omega_min
    # (E.60)-(E.63): shaft power of one rotor C_p rho n^3 D^5 = k_m omega^3
    shaft = n_rotors * k_m * w ** 3
    return metrics.summary({"rpm": w * 60.0 / (2.0 * math.pi),
                            "throttle": (w - omega_min) / span,
                            "shaft_power_w": shaft,
                            "model_rpm": hover_speed_rad_s * 60.0 / (2.0 * math.pi),
                            "altitude_error_m": altitude_error_m})
