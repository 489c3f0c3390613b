"""The rigid-body multirotor: parameters of one design and its 6-DOF equations of motion.

Equations (thesis introduction 2.39-2.43 = Paper B B.7-B.11), written for plain floats
because one step is sequential and tiny (numpy's per-call cost would dominate):

- state: position p and velocity v in the navigation frame, attitude quaternion
  q = [w, x, y, z] (body to navigation, scalar first), body rates omega;
- (2.39)/(B.5) q_dot = 1/2 q (x) [0, omega];
- (2.40)-(2.41)/(B.7)-(B.8) m v_dot = R(q) [0, 0, sum F_i] + m g_n - c_d v, written in the
  navigation frame (the thesis writes it in the body frame, identical after B.8). The
  navigation z axis points up here, so gravity is g_n = [0, 0, -g] and lifting thrust
  is positive;
- (2.42)/(B.10) I omega_dot = M - omega x (I omega);
- (2.43)/(B.11) M from the rotor thrusts through the allocation matrix of
  ``optimizer.flight.mixer`` plus the rotors' drag torques (T_q = k_m / k_f).

Like Paper B, the reaction torque of accelerating rotors and rotor gyroscopic torques
are neglected. Integration: ``step``, second order in dt, with the rotor thrusts held over
a tick (its order is tested against ``optimizer.flight.reference``).

Design parameters come from the optimizer's model (``optimizer.model.design_model.evaluate_grid``):
take-off mass, roll and pitch inertia (E.58-E.59), arm length (D.4), hover speed; rotor
constants k_f = C_t rho D^4 / (2 pi)^2 and k_m = C_p rho D^5 / (2 pi)^3 follow from
(E.1)-(E.3) via ``optimizer.model.physics``. The yaw inertia is roll + pitch (perpendicular-axis
theorem: the model's masses all lie in the rotor plane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from optimizer.catalogs.catalog import Catalog
from optimizer.errors import RequestError
from optimizer.model import physics
from optimizer.model.design_model import ModelGrid

LAYOUTS = ("x", "plus")
#: Actuator counts the flight model flies (alternating spin needs an even count).
FLIGHT_ACTUATORS = (4, 6, 8)


@dataclass(frozen=True)
class Vehicle:
    """Everything the equations of motion need, in SI units."""

    mass_kg: float
    inertia_kgm2: tuple[float, float, float]  # principal: roll, pitch, yaw
    n_rotors: int
    arm_m: float
    layout: str
    k_f: float  # thrust per (rad/s)^2, (E.1)
    k_m: float  # drag torque per (rad/s)^2, (E.2)-(E.3)
    omega_max_rad_s: float  # full-throttle speed, (E.4)-(E.7)
    gravity_m_s2: float = 9.81
    drag_n_s_m: float = 0.0  # optional linear drag c_d
    label: str = ""

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise RequestError(f"layout: expected one of {', '.join(LAYOUTS)}, got "
                               f"{self.layout!r}")
        if self.n_rotors not in FLIGHT_ACTUATORS:
            raise RequestError(f"actuators: the flight model flies N = 4, 6 or 8 (alternating "
                               f"spin), got {self.n_rotors}")
        for name in ("mass_kg", "arm_m", "k_f", "k_m", "omega_max_rad_s", "gravity_m_s2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise RequestError(f"vehicle {self.label}: {name} must be > 0, got {value!r}")
        if not all(math.isfinite(i) and i > 0 for i in self.inertia_kgm2):
            raise RequestError(f"vehicle {self.label}: inertias must be > 0, got "
                               f"{self.inertia_kgm2}")

    @property
    def hover_speed_rad_s(self) -> float:
        """Rotor speed at which N k_f omega^2 = m g (E.1, E.19-E.20)."""
        return math.sqrt(self.mass_kg * self.gravity_m_s2 / (self.n_rotors * self.k_f))

    def hover_shortfall(self) -> str:
        """Why the rotors cannot hold the weight (hover speed above full throttle), or ""
        when they can: a catalog may have no thrust-to-weight check, so a design the
        optimizer accepts can still be unable to hover."""
        if self.hover_speed_rad_s <= self.omega_max_rad_s:
            return ""
        rpm = 60.0 / (2.0 * math.pi)
        return (f"cannot hover: needs {self.hover_speed_rad_s * rpm:.0f} rpm, full throttle "
                f"{self.omega_max_rad_s * rpm:.0f} rpm")

    @property
    def torque_ratio_m(self) -> float:
        """T_q of (B.11): drag torque per newton of thrust, k_m / k_f."""
        return self.k_m / self.k_f

    def rotor_positions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x, y (m) of each rotor and its spin (+1 counter-clockwise seen from above).

        X layout: rotors at (2i + 1) pi / N, as the optimizer's inertia sums; plus layout:
        at 2 i pi / N (rotor 0 on the roll axis). Spins alternate around the frame.
        """
        cos, sin, spin = rotor_directions(self.n_rotors, self.layout)
        return self.arm_m * cos, self.arm_m * sin, spin

    def with_constants(self, k_f: float | None = None, k_m: float | None = None,
                       omega_max_rad_s: float | None = None) -> Vehicle:
        """The same vehicle with measured rotor constants where given."""
        changes: dict[str, Any] = {}
        if k_f is not None:
            changes["k_f"] = float(k_f)
        if k_m is not None:
            changes["k_m"] = float(k_m)
        if omega_max_rad_s is not None:
            changes["omega_max_rad_s"] = float(omega_max_rad_s)
        return replace(self, **changes)


def rotor_directions(n_rotors: int, layout: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """cos and sin of each rotor's angle and its spin (``Vehicle.rotor_positions`` at a
    unit arm; the batch flight scales them by each design's arm)."""
    i = np.arange(n_rotors)
    offset = 1.0 if layout == "x" else 0.0
    angle = (2 * i + offset) * np.pi / n_rotors
    spin = np.where(i % 2 == 0, 1.0, -1.0)
    return np.cos(angle), np.sin(angle), spin


def rotor_constants(ct: float, cp: float, rho: float, diameter_m: float) -> tuple[float, float]:
    """k_f, k_m with F = k_f omega^2, Q = k_m omega^2 from (E.1)-(E.3)."""
    return (float(physics.thrust_per_omega2(ct, rho, diameter_m)),
            float(physics.torque_per_omega2(cp, rho, diameter_m)))


def vehicle_from_grid(catalog: Catalog, grid: ModelGrid, index: tuple[int, int, int],
                      layout: str = "x", drag_n_s_m: float = 0.0) -> Vehicle:
    """The ``Vehicle`` of design ``index`` (propeller, motor, battery) of a model grid."""
    i, j, k = index
    prop = catalog.propellers.iloc[i]
    mot = catalog.motors.iloc[j]
    c = catalog.constants
    roll = float(grid.metrics["roll_inertia_kgm2"][i, j, k])
    pitch = float(grid.metrics["pitch_inertia_kgm2"][i, j, k])
    k_f, k_m = rotor_constants(float(prop["ct"]), float(prop["cp"]), c.air_density_kg_m3,
                               float(prop["diameter_m"]))
    voltage = float(grid.extras["voltage_v"][i, j, k])
    omega_max = float(physics.full_throttle_speed_rad_s(
        voltage, physics.torque_constant(float(mot["kv_rad_s_per_v"])),
        float(mot["resistance_ohm"]), float(prop["cp"]), c.air_density_kg_m3,
        float(prop["diameter_m"])))
    label = f"{grid.n_actuators}x {grid.propeller_ids[i]}+{grid.motor_ids[j]}+" \
            f"{grid.battery_ids[k]}"
    return Vehicle(
        mass_kg=float(grid.metrics["total_mass_kg"][i, j, k]),
        inertia_kgm2=(roll, pitch, roll + pitch),
        n_rotors=grid.n_actuators,
        arm_m=float(grid.extras["arm_length_m"][i, j, k]),
        layout=layout,
        k_f=k_f,
        k_m=k_m,
        omega_max_rad_s=omega_max,
        gravity_m_s2=c.gravity_m_s2,
        drag_n_s_m=drag_n_s_m,
        label=label,
    )


# ------------------------------------------------------------------ equations of motion
#: State layout of the 13 floats: p(3), v(3), q(4), omega(3).
STATE_SIZE = 13


def hover_state(z_m: float = 0.0) -> list[float]:
    """Level, at rest, at height ``z_m``."""
    return [0.0, 0.0, z_m, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]


def derivative(s: list[float], thrust: float, mx: float, my: float, mz: float,
               fx: float, fy: float, fz: float, inv_m: float,
               ixx: float, iyy: float, izz: float, g: float, cd: float) -> list[float]:
    """d/dt of the state under total thrust, body moments and a navigation-frame force."""
    vx, vy, vz = s[3], s[4], s[5]
    qw, qx, qy, qz = s[6], s[7], s[8], s[9]
    wx, wy, wz = s[10], s[11], s[12]
    # (2.40)-(2.41): R(q) [0, 0, T] is T times the third column of R(q)
    ax = (thrust * 2.0 * (qx * qz + qw * qy) + fx - cd * vx) * inv_m
    ay = (thrust * 2.0 * (qy * qz - qw * qx) + fy - cd * vy) * inv_m
    az = (thrust * (1.0 - 2.0 * (qx * qx + qy * qy)) + fz - cd * vz) * inv_m - g
    # (2.39)/(B.5): q_dot = 1/2 q (x) [0, omega]
    dqw = 0.5 * (-qx * wx - qy * wy - qz * wz)
    dqx = 0.5 * (qw * wx + qy * wz - qz * wy)
    dqy = 0.5 * (qw * wy + qz * wx - qx * wz)
    dqz = 0.5 * (qw * wz + qx * wy - qy * wx)
    # (2.42)/(B.10): I omega_dot = M - omega x (I omega), principal inertia
    dwx = (mx + (iyy - izz) * wy * wz) / ixx
    dwy = (my + (izz - ixx) * wz * wx) / iyy
    dwz = (mz + (ixx - iyy) * wx * wy) / izz
    return [vx, vy, vz, ax, ay, az, dqw, dqx, dqy, dqz, dwx, dwy, dwz]


def step(s: list[float], dt: float, thrust: float, mx: float, my: float, mz: float,
         fx: float, fy: float, fz: float, inv_m: float, ixx: float, iyy: float,
         izz: float, g: float, cd: float) -> list[float]:
    """One integration step with the inputs held (second order, cheap for 1 kHz):
    Euler's equation (2.42) by the explicit midpoint rule, attitude (2.39) by the exact
    quaternion exponential of the mean body rate over the step, translation (2.40)-(2.41)
    by the trapezoid rule (Heun) on the accelerations at the step's start and end (the
    thrust turns with the attitude during the step: the start's alone is first order)."""
    qw, qx, qy, qz = s[6], s[7], s[8], s[9]
    vx, vy, vz = s[3], s[4], s[5]
    # (2.40)-(2.41) as in ``derivative``, at the step's start
    ax = (thrust * 2.0 * (qx * qz + qw * qy) + fx - cd * vx) * inv_m
    ay = (thrust * 2.0 * (qy * qz - qw * qx) + fy - cd * vy) * inv_m
    az = (thrust * (1.0 - 2.0 * (qx * qx + qy * qy)) + fz - cd * vz) * inv_m - g
    h = 0.5 * dt
    wx, wy, wz = s[10], s[11], s[12]
    # (2.42) by the midpoint rule
    mxx = wx + h * (mx + (iyy - izz) * wy * wz) / ixx
    myy = wy + h * (my + (izz - ixx) * wz * wx) / iyy
    mzz = wz + h * (mz + (ixx - iyy) * wx * wy) / izz
    nx = wx + dt * (mx + (iyy - izz) * myy * mzz) / ixx
    ny = wy + dt * (my + (izz - ixx) * mzz * mxx) / iyy
    nz = wz + dt * (mz + (ixx - iyy) * mxx * myy) / izz
    # q <- q (x) exp(1/2 omega_mean dt)
    ox, oy, oz = 0.5 * (wx + nx), 0.5 * (wy + ny), 0.5 * (wz + nz)
    rate = math.sqrt(ox * ox + oy * oy + oz * oz)
    half = 0.5 * rate * dt
    c = math.cos(half)
    k = math.sin(half) / rate if rate > 0.0 else 0.5 * dt
    rx, ry, rz = k * ox, k * oy, k * oz
    pw = qw * c - qx * rx - qy * ry - qz * rz
    px = qw * rx + qx * c + qy * rz - qz * ry
    py = qw * ry - qx * rz + qy * c + qz * rx
    pz = qw * rz + qx * ry - qy * rx + qz * c
    norm = 1.0 / math.sqrt(pw * pw + px * px + py * py + pz * pz)
    pw, px, py, pz = pw * norm, px * norm, py * norm, pz * norm
    # (2.40)-(2.41) at the step's end: the new attitude, drag on the Euler-predicted velocity
    ex = vx + dt * ax
    ey = vy + dt * ay
    ez = vz + dt * az
    bx = (thrust * 2.0 * (px * pz + pw * py) + fx - cd * ex) * inv_m
    by = (thrust * 2.0 * (py * pz - pw * px) + fy - cd * ey) * inv_m
    bz = (thrust * (1.0 - 2.0 * (px * px + py * py)) + fz - cd * ez) * inv_m - g
    # v: trapezoid; p: exact for an acceleration linear over the step
    d6 = dt * dt / 6.0
    return [s[0] + dt * vx + d6 * (2.0 * ax + bx), s[1] + dt * vy + d6 * (2.0 * ay + by),
            s[2] + dt * vz + d6 * (2.0 * az + bz),
            vx + h * (ax + bx), vy + h * (ay + by), vz + h * (az + bz),
            pw, px, py, pz, nx, ny, nz]


def roll_angle(qw: Any, qx: Any, qy: Any, qz: Any) -> Any:
    """Roll (rad) of quaternion components (arrays of any one shape), (B.6)."""
    return np.arctan2(2.0 * (qw * qx + qy * qz), 1.0 - 2.0 * (qx * qx + qy * qy))


def pitch_angle(qw: Any, qx: Any, qy: Any, qz: Any) -> Any:
    """Pitch (rad) of quaternion components, (B.6)."""
    return np.arcsin(np.clip(2.0 * (qw * qy - qz * qx), -1.0, 1.0))


def yaw_angle(qw: Any, qx: Any, qy: Any, qz: Any) -> Any:
    """Yaw (rad) of quaternion components, (B.6)."""
    return np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


def euler_angles(q: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad) of quaternions (..., 4), (B.6)."""
    parts = np.moveaxis(np.asarray(q, float), -1, 0)
    return np.stack([roll_angle(*parts), pitch_angle(*parts), yaw_angle(*parts)], axis=-1)
