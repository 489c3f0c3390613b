"""Simulated 6-DOF hexapod (Stewart platform) as a plant: the truth of the IMU bench.

The platform follows a :class:`~drivers.sim.hexapod_motions.Motion` exactly, provided the
motion stays inside its velocity and acceleration limits (checked before the run), and
reports what a real hexapod's controller logs after transformation to the body frame
(Paper A section 2.2): angular rate, angular acceleration and the specific force at the
pivot (the UAV's centre of gravity), gravity included.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from drivers.contracts import HexapodLimits
from drivers.errors import DeviceError
from drivers.hexapod_kinematics import (
    GRAVITY_M_S2,
    HexapodState,
    body_frame_state,
    euler_to_matrix,
)
from drivers.hexapod_motions import Motion

# The limits, the state and the kinematics moved to device-free modules (real hexapods
# share them); they are re-exported here so existing imports keep working.
__all__ = ["GRAVITY_M_S2", "HexapodLimits", "HexapodState", "SimHexapod", "euler_to_matrix"]


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
        return body_frame_state(t, pose, vel, acc, self.gravity)
