"""Simulated attitude log: a calibrated IMU on the hexapod with the hexapod's attitude as
the reference (a perfect reference IMU), in the format ``rotorbench attitude`` reads.

Columns ``t_s, gyro_{x,y,z}_rad_s, acc_{x,y,z}_m_s2, ref_qw, ref_qx, ref_qy, ref_qz``;
the reference quaternion is scalar-first, body→navigation (z up), from the platform's
Z-Y-X Euler angles.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivers.hexapod_motions import DOF, Motion
from drivers.sim.hexapod import SimHexapod
from drivers.sim.imu import ImuModel, SimImu

__all__ = ["CALIBRATED_IMU", "paper_b_motion", "simulate_attitude_log"]

CALIBRATED_IMU = ImuModel(
    mounting_deg=(0.0, 0.0, 0.0), gyro_scale=(1.0, 1.0, 1.0), acc_scale=(1.0, 1.0, 1.0),
    gyro_nonorth_deg=(0.0, 0.0, 0.0), acc_nonorth_deg=(0.0, 0.0, 0.0),
    gyro_bias_rad_s=(2e-4, -1e-4, 1.5e-4), acc_bias_m_s2=(0.0, 0.0, 0.0),
    clock_offset_s=0.0, rate_hz=400.0,
)


def paper_b_motion(duration_s: float = 60.0) -> Motion:
    """Paper B section 7.1's Stewart-platform test (0.17 rad roll sine at 0.2 Hz), with
    pitch, yaw and translations added so every axis moves."""
    terms = {
        "roll": ((0.17, 0.2, 0.0),),
        "pitch": ((0.12, 0.27, 0.5),),
        "yaw": ((0.20, 0.13, 1.0),),
        "x": ((0.05, 0.31, 0.0),),
        "y": ((0.05, 0.37, 0.3),),
        "z": ((0.03, 0.43, 0.6),),
    }
    return Motion("paper_b", duration_s, tuple(terms.get(d, ()) for d in DOF), ramp_s=1.0)


def _euler_to_quat(rpy: NDArray) -> NDArray:
    cr, cp, cy = (np.cos(0.5 * rpy[:, i]) for i in range(3))
    sr, sp, sy = (np.sin(0.5 * rpy[:, i]) for i in range(3))
    return np.stack([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy], axis=1)


def simulate_attitude_log(motion: Motion | None = None, model: ImuModel = CALIBRATED_IMU,
                          seed: int = 0, hexapod: SimHexapod | None = None
                          ) -> dict[str, NDArray]:
    """Run ``motion`` (default :func:`paper_b_motion`) and return the log's columns."""
    motion = motion or paper_b_motion()
    hexapod = hexapod or SimHexapod()
    hexapod.check(motion)
    t = np.arange(round(motion.duration_s * model.rate_hz)) / model.rate_hz
    truth = hexapod.follow(motion, t)
    gyro, acc = SimImu(model, np.random.default_rng(seed)).measure(truth)
    q = _euler_to_quat(truth.euler_rad)
    cols: dict[str, NDArray] = {"t_s": t}
    for i, a in enumerate("xyz"):
        cols[f"gyro_{a}_rad_s"] = gyro[:, i]
    for i, a in enumerate("xyz"):
        cols[f"acc_{a}_m_s2"] = acc[:, i]
    for i, c in enumerate("wxyz"):
        cols[f"ref_q{c}"] = q[:, i]
    return cols
