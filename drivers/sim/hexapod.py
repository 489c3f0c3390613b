"""Simulated 6-DOF hexapod (Stewart platform) as a plant: the truth of the IMU bench.

The platform follows a :class:`~drivers.sim.hexapod_motions.Motion` exactly, provided the
motion stays inside its velocity and acceleration limits (checked before the run), and
reports what a real hexapod's controller logs after transformation to the body frame
(Paper A section 2.2): angular rate, angular acceleration and the specific force at the
pivot (the UAV's centre of gravity), gravity included.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from drivers.errors import DeviceError
from drivers.sim.hexapod_motions import Motion

__all__ = ["GRAVITY_M_S2", "HexapodLimits", "HexapodState", "SimHexapod", "euler_to_matrix"]

GRAVITY_M_S2 = 9.80665
Array = NDArray[np.float64]


@dataclass(frozen=True)
class HexapodLimits:
    """Limits of a motion-simulator class hexapod (per axis, magnitudes)."""

    velocity_m_s: float = 0.6
    acceleration_m_s2: float = 6.0
    rate_rad_s: float = 0.7
    angular_acceleration_rad_s2: float = 5.0
    position_m: float = 0.25
    angle_rad: float = float(np.radians(25.0))


@dataclass(frozen=True)
class HexapodState:
    """Body-frame truth at times ``t_s``; every array is ``(n, 3)`` except ``t_s``."""

    t_s: Array
    position_m: Array  # pivot position, navigation frame (z up)
    euler_rad: Array  # roll, pitch, yaw (Z-Y-X)
    omega_b_rad_s: Array
    alpha_b_rad_s2: Array
    specific_force_b_m_s2: Array  # at the pivot, gravity included (reads +g up at rest)


def euler_to_matrix(rpy: ArrayLike) -> Array:
    """Body→navigation rotation ``Rz(yaw)·Ry(pitch)·Rx(roll)`` for each row, ``(n, 3, 3)``."""
    rpy = np.atleast_2d(np.asarray(rpy, dtype=float))
    cr, cp, cy = np.cos(rpy).T
    sr, sp, sy = np.sin(rpy).T
    return np.stack(
        [
            np.stack([cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy], -1),
            np.stack([cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy], -1),
            np.stack([-sp, sr * cp, cr * cp], -1),
        ],
        axis=-2,
    )


def _body_rates(e: Array, de: Array, dde: Array) -> tuple[Array, Array]:
    """Body angular rate and its derivative from Z-Y-X Euler angles and derivatives."""
    phi, th = e[:, 0], e[:, 1]
    dphi, dth, dpsi = de.T
    ddphi, ddth, ddpsi = dde.T
    sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
    p = dphi - dpsi * st
    q = dth * cf + dpsi * ct * sf
    r = -dth * sf + dpsi * ct * cf
    dp = ddphi - ddpsi * st - dpsi * dth * ct
    dq = (ddth * cf - dth * dphi * sf + ddpsi * ct * sf - dpsi * dth * st * sf
          + dpsi * dphi * ct * cf)
    dr = (-ddth * sf - dth * dphi * cf + ddpsi * ct * cf - dpsi * dth * st * cf
          - dpsi * dphi * ct * sf)
    return np.stack([p, q, r], -1), np.stack([dp, dq, dr], -1)


class SimHexapod:
    """A hexapod that follows trajectories exactly within its limits."""

    def __init__(self, limits: HexapodLimits | None = None, gravity: float = GRAVITY_M_S2):
        self.limits = limits or HexapodLimits()
        self.gravity = gravity

    def check(self, motion: Motion, step_s: float = 0.005) -> None:
        """Raise :class:`DeviceError` naming the limit a motion would exceed."""
        t = np.arange(0.0, motion.duration_s + step_s, step_s)
        pose, vel, acc = motion.evaluate(t)
        lim = self.limits
        state = self.follow(motion, t)
        checks = [
            ("position_m", np.abs(pose[:, :3]).max(), lim.position_m),
            ("angle_rad", np.abs(pose[:, 3:]).max(), lim.angle_rad),
            ("velocity_m_s", np.abs(vel[:, :3]).max(), lim.velocity_m_s),
            ("acceleration_m_s2", np.abs(acc[:, :3]).max(), lim.acceleration_m_s2),
            ("rate_rad_s", np.abs(state.omega_b_rad_s).max(), lim.rate_rad_s),
            ("angular_acceleration_rad_s2", np.abs(state.alpha_b_rad_s2).max(),
             lim.angular_acceleration_rad_s2),
        ]
        for name, value, limit in checks:
            if value > limit:
                raise DeviceError(
                    f"sim hexapod: motion {motion.name!r} needs {name} = {value:.4g}, "
                    f"above the limit {limit:.4g}"
                )

    def follow(self, motion: Motion, t_s: ArrayLike) -> HexapodState:
        """Exact body-frame truth of ``motion`` at times ``t_s`` (s from the motion start)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        pose, vel, acc = motion.evaluate(t)
        e, de, dde = pose[:, 3:], vel[:, 3:], acc[:, 3:]
        omega, alpha = _body_rates(e, de, dde)
        rot = euler_to_matrix(e)
        f_n = acc[:, :3] + np.array([0.0, 0.0, self.gravity])
        f_b = np.einsum("nji,nj->ni", rot, f_n)  # Rᵀ·(p̈ - g_n), g_n = [0, 0, -g]
        return HexapodState(t, pose[:, :3], e, omega, alpha, f_b)
