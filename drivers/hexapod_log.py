"""What every hexapod device (simulated or PI over TCP) does with the platform's motion.

``checked_spline`` is the upload check: the cubic spline the platform will follow through
a trajectory's poses, checked densely (4 points per uploaded pose) against the limits.
``log_block`` turns logged pose, velocity and acceleration into the controller-log block:
the pose channels and the body-frame truth from :mod:`drivers.hexapod_kinematics`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from drivers.contracts import (
    ACCELERATION_CHANNELS,
    BODY_CHANNELS,
    POSE_CHANNELS,
    VELOCITY_CHANNELS,
    Block,
    HexapodLimitError,
    HexapodLimits,
    Trajectory,
    limit_violations,
)
from drivers.hexapod_kinematics import body_frame_state, follower_spline, spline_peaks

__all__ = ["checked_spline", "log_block"]

Array = NDArray[np.float64]


def checked_spline(trajectory: Trajectory, limits: HexapodLimits, gravity: float,
                   who: str) -> CubicSpline:
    """The spline through ``trajectory``; raises ``HexapodLimitError`` (naming ``who``) if
    any point of it exceeds ``limits``."""
    spline = follower_spline(trajectory.t_s, trajectory.poses)
    peaks = spline_peaks(spline, trajectory.duration_s, 4 * len(trajectory.poses), gravity)
    bad = limit_violations(peaks, limits)
    if bad:
        text = "; ".join(f"{n} = {v:.4g} above the limit {lim:.4g}" for n, v, lim in bad)
        raise HexapodLimitError(f"{who}: trajectory {trajectory.name!r} refused: {text}")
    return spline


def log_block(t_s: ArrayLike, pose: Array, vel: Array, acc: Array, gravity: float) -> Block:
    """The log rows at ``t_s``: pose, velocity, acceleration and the body-frame truth."""
    s = body_frame_state(t_s, pose, vel, acc, gravity)
    values: dict[str, Array] = {}
    for names, data in ((POSE_CHANNELS, pose), (VELOCITY_CHANNELS, vel),
                        (ACCELERATION_CHANNELS, acc)):
        values.update({n: data[:, j] for j, n in enumerate(names)})
    body = np.hstack([s.omega_b_rad_s, s.alpha_b_rad_s2, s.specific_force_b_m_s2])
    values.update({n: body[:, j] for j, n in enumerate(BODY_CHANNELS)})
    return Block(np.asarray(t_s, float), values)
