"""A design as the plant of an outside flight controller: motor commands in, sensors out.

``maneuvers.fly`` closes the loop with the thesis' cascade; here the controller is someone
else's (Betaflight's firmware through its SITL, ``bench.jobs.betaflight_flight``), so the
plant is stepped from the outside: each tick takes the controller's normalised motor
commands, runs them through the rotors (``actuators.RotorBank``: quantisation, ESC frame,
latency, lag), the thrust and drag torques of (2.43)/(B.11) and one rigid-body step
(``vehicle.step``), and gives back what an IMU on the body measures.

Frames. The model's body axes are forward-left-up and its navigation z axis points up
(``vehicle``); the sensors are returned in those axes, the body rate as the model's omega,
the specific force (what an accelerometer reads: +g up at rest) in the body, and the
attitude body -> navigation. Turning them into a firmware's frames is the codec's job.

Rotor order and spin are Betaflight's QUADX with its default mixer (props in):
motor 1 rear right, 2 front right, 3 rear left, 4 front left; 1 and 4 turn clockwise seen
from above, 2 and 3 counter-clockwise. The arms are the design's (``Vehicle.arm_m``) at
+-45 deg and +-135 deg: the model's X layout, its rotors taken in that order.

Motor command to rotor speed: a command u in [0, 1] (Betaflight's (us - 1000) / 1000)
asks for u x full-throttle speed. An ESC's duty is its command and the motor's steady
speed is close to proportional to its voltage at light load ((E.4)-(E.7)); the rotor
bank then holds that speed within idle .. full as it does for the cascade.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from optimizer.errors import RequestError
from optimizer.flight.actuators import ActuatorModel, RotorBank
from optimizer.flight.vehicle import Vehicle, hover_state, step

__all__ = ["QUADX_ANGLES_DEG", "QUADX_SPIN", "ExternalPlant", "Sensors", "tilt_authority"]

#: Betaflight QUADX motors 1..4: angle of each arm from forward (counter-clockwise, deg)
QUADX_ANGLES_DEG = (-135.0, -45.0, 135.0, 45.0)
#: and their spin seen from above, +1 counter-clockwise (props in: 1 and 4 clockwise)
QUADX_SPIN = (-1.0, 1.0, 1.0, -1.0)


@dataclass(frozen=True)
class Sensors:
    """What an IMU on the body reads at one instant, in the model's frames (module doc)."""

    gyro_rad_s: tuple[float, float, float]  # body rates, forward-left-up
    specific_force_m_s2: tuple[float, float, float]  # body, +g up at rest
    attitude: tuple[float, float, float, float]  # body -> navigation (w, x, y, z)


class ExternalPlant:
    """One design stepped by an outside controller at a fixed tick ``dt``.

    ``held`` pins the body level at rest (a hand holding it, or the ground) while the
    rotors still follow their commands: the controller arms and spins up before release.
    """

    def __init__(self, vehicle: Vehicle, actuator: ActuatorModel, dt: float) -> None:
        if vehicle.n_rotors != 4 or vehicle.layout != "x":
            raise RequestError(f"Betaflight flies this design's frame as its QUADX: 4 rotors, "
                               f"layout x (got {vehicle.n_rotors}, {vehicle.layout})")
        self.vehicle = vehicle
        self.dt = dt
        self.xs = [vehicle.arm_m * math.cos(math.radians(a)) for a in QUADX_ANGLES_DEG]
        self.ys = [vehicle.arm_m * math.sin(math.radians(a)) for a in QUADX_ANGLES_DEG]
        idle = actuator.idle_fraction * vehicle.omega_max_rad_s
        self.rotors = RotorBank(actuator, 4, vehicle.omega_max_rad_s, dt, idle)
        self.state = hover_state()
        self.held = True
        self.t_s = 0.0
        self.omega = [idle] * 4  # each rotor's mean speed over the last tick
        self._thrust = 0.0
        self._force = (0.0, 0.0, 0.0)  # navigation-frame force of the last tick

    def step(self, commands: list[float] | tuple[float, ...],
             force_n: tuple[float, float, float] = (0.0, 0.0, 0.0),
             moment_nm: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        """One tick with the motor commands (0..1, motors 1..4) held, plus an outside
        force (navigation frame) and moment (body), e.g. a gust."""
        v = self.vehicle
        w_max = v.omega_max_rad_s
        w = self.rotors.step([min(1.0, max(0.0, u)) * w_max for u in commands])
        self.omega = w
        k_f, k_m = v.k_f, v.k_m
        # (2.43)/(B.11): thrusts and drag torques of the rotor speeds
        f_tot, m_x, m_y, m_z = 0.0, moment_nm[0], moment_nm[1], moment_nm[2]
        for i in range(4):
            w2 = w[i] * w[i]
            f = k_f * w2
            f_tot += f
            m_x += self.ys[i] * f
            m_y -= self.xs[i] * f
            m_z -= QUADX_SPIN[i] * k_m * w2
        self._thrust, self._force = f_tot, force_n
        self.t_s += self.dt
        if self.held:
            self.state = hover_state(self.state[2])
            return
        ixx, iyy, izz = v.inertia_kgm2
        self.state = step(self.state, self.dt, f_tot, m_x, m_y, m_z, *force_n,
                          1.0 / v.mass_kg, ixx, iyy, izz, v.gravity_m_s2, v.drag_n_s_m)

    def sensors(self) -> Sensors:
        """The IMU's reading now: body rates, specific force, attitude (module doc)."""
        s = self.state
        qw, qx, qy, qz = s[6], s[7], s[8], s[9]
        if self.held:
            return Sensors((0.0, 0.0, 0.0), (0.0, 0.0, self.vehicle.gravity_m_s2),
                           (qw, qx, qy, qz))
        v = self.vehicle
        cd = v.drag_n_s_m
        # what is not gravity, per kg: the outside force and drag (navigation frame), turned
        # into the body by R(q)^T, plus the thrust along body z (2.40)-(2.41)
        ax = (self._force[0] - cd * s[3]) / v.mass_kg
        ay = (self._force[1] - cd * s[4]) / v.mass_kg
        az = (self._force[2] - cd * s[5]) / v.mass_kg
        r = _rotation(qw, qx, qy, qz)
        bx = r[0][0] * ax + r[1][0] * ay + r[2][0] * az
        by = r[0][1] * ax + r[1][1] * ay + r[2][1] * az
        bz = r[0][2] * ax + r[1][2] * ay + r[2][2] * az + self._thrust / v.mass_kg
        return Sensors((s[10], s[11], s[12]), (bx, by, bz), (qw, qx, qy, qz))


def tilt_authority(vehicle: Vehicle) -> float:
    """The roll or pitch acceleration (rad/s^2, the larger) per unit of a QUADX mixer's
    differential command at hover: what an outside controller's rate-loop gain multiplies.

    A command u asks for u x full speed, so a rotor's thrust is k_f (u w_max)^2 and its slope
    at hover, with k_f w_hover^2 = m g / 4, is m g / (2 u_hover). Four rotors at arm r,
    +-45 deg, each moved by +-d: torque = sqrt(2) r m g d / u_hover (2.43), and
    1 / u_hover = sqrt(thrust-to-weight): an over-powered design is a hotter plant.
    """
    u_hover = vehicle.hover_speed_rad_s / vehicle.omega_max_rad_s
    torque = math.sqrt(2.0) * vehicle.arm_m * vehicle.mass_kg * vehicle.gravity_m_s2 / u_hover
    return torque / min(vehicle.inertia_kgm2[0], vehicle.inertia_kgm2[1])


def _rotation(qw: float, qx: float, qy: float, qz: float) -> list[list[float]]:
    """R(q), body -> navigation, of a unit quaternion (scalar first)."""
    return [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
            [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
            [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]]
