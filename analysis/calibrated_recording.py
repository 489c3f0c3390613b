"""Apply a Paper A calibration (bias, K matrices, mounting, lever arm) to a recording.

The calibration chain before any attitude filter: ``ω_b = K_ω(ω̃ - b_ω)`` (A.17) and the
specific force at the centre of gravity ``f = K_a(ã - b_a) - ω×(ω×R) - α×R`` (A.18), the
IMU samples moved by the calibration's time offset and put back on the recording's rows
(:func:`analysis.imu_calibration.apply_to_frame`). K contains the mounting rotation, so the
result is in the body frame the calibration was made for; a magnetometer is moved and
turned with them (see :func:`~analysis.imu_calibration.apply_to_frame`).

A calibration that does not fit the recording's sensor is refused (:class:`LogError`,
exit 2) before anything is computed: K far from a rotation with unit scale (a unit
mismatch), a gyro beyond the calibrated sensor's range, or a corrected accelerometer whose
magnitude is not gravity (the log is in g, or the calibration is for another unit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from analysis.errors import LogError
from analysis.imu_calibration import Calibration, apply_to_frame
from analysis.imu_log import IMU_ACC, IMU_GYRO, MAG_COLUMNS
from analysis.imu_recording import ImuRecording

__all__ = ["G", "calibrate_recording", "check_fit"]

G = 9.80665
_SCALE_RANGE = (0.5, 2.0)  # singular values of K: a few % from 1 for a real sensor
_GRAVITY_RANGE = (0.8 * G, 1.2 * G)  # median corrected |f| over a whole recording


def check_fit(rec: ImuRecording, cal: Calibration, cal_path: str | Path) -> None:
    """Refuse a calibration whose units or sensor do not match the recording."""
    where = f"{cal_path}: calibration does not fit {rec.source}"
    for name, k in (("k_gyro", cal.kg), ("k_acc", cal.ka)):
        sv = np.linalg.svd(k, compute_uv=False)
        if sv.min() < _SCALE_RANGE[0] or sv.max() > _SCALE_RANGE[1]:
            raise LogError(f"{where}: field {name} scales by {sv.min():.3g}..{sv.max():.3g}; "
                           "a calibration of this unit's sensor scales by about 1 "
                           "(another unit, e.g. deg/s or g?)")
    rng = float(cal.ranges.get("gyro_rad_s", np.inf)) if cal.ranges else np.inf
    peak = float(np.abs(rec.gyro_rad_s).max())
    if peak > 1.05 * rng:
        raise LogError(f"{where}: the gyro reaches {peak:.3g} rad/s, beyond the calibrated "
                       f"sensor's range ±{rng:.3g} rad/s (another sensor, or not rad/s)")
    f = (rec.acc_m_s2 - np.asarray(cal.acc_bias_m_s2)) @ cal.ka.T
    g = float(np.median(np.linalg.norm(f, axis=1)))
    if not _GRAVITY_RANGE[0] <= g <= _GRAVITY_RANGE[1]:
        raise LogError(f"{where}: the corrected accelerometer reads {g:.3g} m/s² (median "
                       f"magnitude), not gravity {G} m/s² (log in g, or a calibration for "
                       "another unit?)")


def calibrate_recording(rec: ImuRecording, cal: Calibration, cal_path: str | Path
                        ) -> ImuRecording:
    """The recording with corrected gyro and accelerometer (rows without data dropped)."""
    check_fit(rec, cal, cal_path)
    cols = {"t_s": rec.t_s, "_row": np.arange(len(rec.t_s))}
    for i, c in enumerate(IMU_GYRO):
        cols[c] = rec.gyro_rad_s[:, i]
    for i, c in enumerate(IMU_ACC):
        cols[c] = rec.acc_m_s2[:, i]
    if rec.mag_ut is not None:
        for i, c in enumerate(MAG_COLUMNS):
            cols[c] = rec.mag_ut[:, i]
    out = apply_to_frame(cal, pd.DataFrame(cols))
    if len(out) < 2:
        raise LogError(f"{cal_path}: after its time offset ({cal.time_offset_s:g} s) fewer "
                       f"than 2 samples of {rec.source} are left")
    keep = np.zeros(len(rec.t_s), dtype=bool)
    keep[out["_row"].to_numpy()] = True
    gyro = out[[f"gyro_{a}_rad_s" for a in "xyz"]].to_numpy(dtype=float)
    acc = out[[f"acc_{a}_m_s2" for a in "xyz"]].to_numpy(dtype=float)
    mag = None if rec.mag_ut is None else out[list(MAG_COLUMNS)].to_numpy(dtype=float)
    return rec.with_imu(out["t_s"].to_numpy(dtype=float), gyro, acc, keep, mag_ut=mag)
