"""Hexapod pose, velocity and acceleration → body-frame truth (Paper A section 2.2).

A hexapod controller logs the platform pose (x, y, z of the pivot in the navigation frame,
z up; roll, pitch, yaw as Z-Y-X Euler angles about the pivot) and, by differentiation,
its velocity and acceleration. The calibration needs them in the body frame: angular
rate, angular acceleration and the specific force at the pivot (gravity included). This
is device-free physics shared by the simulated hexapod and any real backend.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # scipy is imported where a spline is built: rig files of either
    from scipy.interpolate import CubicSpline  # bench load this module's neighbours

__all__ = ["GRAVITY_M_S2", "HexapodState", "body_frame_state", "body_rates", "euler_to_matrix",
           "follower_spline", "motion_peaks", "spline_peaks"]

GRAVITY_M_S2 = 9.80665
Array = NDArray[np.float64]


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


def body_rates(e: Array, de: Array, dde: Array) -> tuple[Array, Array]:
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


def body_frame_state(t_s: ArrayLike, pose: Array, vel: Array, acc: Array,
                     gravity: float = GRAVITY_M_S2) -> HexapodState:
    """Body-frame truth from ``(n, 6)`` pose, velocity and acceleration (SI, Z-Y-X Euler)."""
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    e, de, dde = pose[:, 3:], vel[:, 3:], acc[:, 3:]
    omega, alpha = body_rates(e, de, dde)
    rot = euler_to_matrix(e)
    f_n = acc[:, :3] + np.array([0.0, 0.0, gravity])
    f_b = np.einsum("nji,nj->ni", rot, f_n)  # Rᵀ·(p̈ - g_n), g_n = [0, 0, -g]
    return HexapodState(t, pose[:, :3], e, omega, alpha, f_b)


def motion_peaks(pose: Array, vel: Array, acc: Array, state: HexapodState) -> dict[str, float]:
    """Largest magnitude of each limited quantity, by ``HexapodLimits`` field name."""

    def peak(x: Array) -> float:
        return float(np.abs(x).max()) if x.size else 0.0

    return {
        "position_m": peak(pose[:, :3]),
        "angle_rad": peak(pose[:, 3:]),
        "velocity_m_s": peak(vel[:, :3]),
        "acceleration_m_s2": peak(acc[:, :3]),
        "rate_rad_s": peak(state.omega_b_rad_s),
        "angular_acceleration_rad_s2": peak(state.alpha_b_rad_s2),
    }


def follower_spline(t_s: ArrayLike, poses: ArrayLike) -> CubicSpline:
    """The path a platform runs through sampled ``(n, 6)`` poses: the clamped cubic spline
    (at rest at both ends), as the simulated hexapod follows it."""
    from scipy.interpolate import CubicSpline

    return CubicSpline(np.asarray(t_s, float), np.asarray(poses, float), axis=0,
                       bc_type="clamped")


def spline_peaks(spline: CubicSpline, duration_s: float, n_points: int,
                 gravity: float = GRAVITY_M_S2) -> dict[str, float]:
    """``motion_peaks`` of a follower spline checked densely at ``n_points`` points; what
    every hexapod (simulated or real backend) checks before it accepts a trajectory."""
    u = np.linspace(0.0, duration_s, max(2, int(n_points)))
    pose, vel, acc = spline(u), spline(u, 1), spline(u, 2)
    return motion_peaks(pose, vel, acc, body_frame_state(u, pose, vel, acc, gravity))
