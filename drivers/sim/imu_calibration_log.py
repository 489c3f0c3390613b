"""Simulate a full hexapod calibration log in the analysis' log format (the columns;
``rotorbench calibrate --simulate-log`` writes them with ``analysis.imu_log.write_table``).

Columns: ``t_s, phase, ref_omega_{x,y,z}_rad_s, ref_alpha_{x,y,z}_rad_s2,
ref_acc_{x,y,z}_m_s2`` (body-frame specific force at the centre of gravity, gravity
included) and ``imu_gyro_{x,y,z}_rad_s, imu_acc_{x,y,z}_m_s2``. The phases follow each
other on one continuous hexapod clock; the IMU columns of the row stamped ``t`` hold the
sample the IMU took at hexapod time ``t - clock_offset_s``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivers.hexapod_motions import Phase, paper_a_protocol
from drivers.sim.hexapod import SimHexapod
from drivers.sim.imu import ADIS16400, ImuModel, SimImu

__all__ = ["LOG_COLUMNS", "simulate_calibration_log"]

_XYZ = ("x", "y", "z")
LOG_COLUMNS = (
    "t_s",
    "phase",
    *(f"ref_omega_{a}_rad_s" for a in _XYZ),
    *(f"ref_alpha_{a}_rad_s2" for a in _XYZ),
    *(f"ref_acc_{a}_m_s2" for a in _XYZ),
    *(f"imu_gyro_{a}_rad_s" for a in _XYZ),
    *(f"imu_acc_{a}_m_s2" for a in _XYZ),
)


def simulate_calibration_log(
    model: ImuModel = ADIS16400,
    phases: list[Phase] | None = None,
    hexapod: SimHexapod | None = None,
    seed: int = 0,
) -> dict[str, NDArray]:
    """Run every phase on the simulated hexapod and IMU; return the log's columns."""
    hexapod = hexapod or SimHexapod()
    phases = phases if phases is not None else paper_a_protocol(model.rate_hz)
    imu = SimImu(model, np.random.default_rng(seed))
    dt = 1.0 / model.rate_hz
    parts: dict[str, list[NDArray]] = {c: [] for c in LOG_COLUMNS}
    start = 0.0
    for phase in phases:
        hexapod.check(phase.motion)
        n = round(phase.motion.duration_s * model.rate_hz)
        local = np.arange(n) * dt
        ref = hexapod.follow(phase.motion, local)
        seen = hexapod.follow(phase.motion, local - model.clock_offset_s)
        gyro, acc = imu.measure(seen)
        parts["t_s"].append(start + local)
        parts["phase"].append(np.full(n, phase.label, dtype=object))
        for i, a in enumerate(_XYZ):
            parts[f"ref_omega_{a}_rad_s"].append(ref.omega_b_rad_s[:, i])
            parts[f"ref_alpha_{a}_rad_s2"].append(ref.alpha_b_rad_s2[:, i])
            parts[f"ref_acc_{a}_m_s2"].append(ref.specific_force_b_m_s2[:, i])
            parts[f"imu_gyro_{a}_rad_s"].append(gyro[:, i])
            parts[f"imu_acc_{a}_m_s2"].append(acc[:, i])
        start += n * dt
    return {c: np.concatenate(v) for c, v in parts.items()}
