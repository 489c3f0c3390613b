"""Verification (A.19, Table A.2) on a log whose rows are unevenly spaced.

Through a real serial IMU (MSP polled by the host) rows arrive with varying spacing and
some are missing. The verification's angular acceleration (the derivative of the corrected
gyro, for the lever-arm term of A.18) must follow the stamps, not assume one period.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.imu_calibration import angular_acceleration, calibrate
from drivers.sim.hexapod_motions import paper_a_protocol
from drivers.sim.imu import ADIS16400
from drivers.sim.imu_calibration_log import simulate_calibration_log


@pytest.fixture(scope="module")
def logs() -> tuple[pd.DataFrame, pd.DataFrame]:
    even = pd.DataFrame(simulate_calibration_log(
        ADIS16400, paper_a_protocol(ADIS16400.rate_hz, short=True), seed=3))
    even.attrs["path"] = "sim.csv"
    rng = np.random.default_rng(7)
    verify = (even["phase"] == "verify").to_numpy()
    drop = verify & (rng.random(len(even)) < 0.3)  # 30 % of the verification rows lost
    uneven = even.loc[~drop].reset_index(drop=True)
    uneven.attrs["path"] = "uneven.csv"
    return even, uneven


def test_uneven_verification_rows_verify_like_even_ones(logs) -> None:
    even, uneven = logs
    dt = np.diff(uneven.loc[uneven["phase"] == "verify", "t_s"].to_numpy())
    assert dt.max() > 2.5 * dt.min()  # really uneven
    v_even = calibrate(even).verification_rms
    v_uneven = calibrate(uneven).verification_rms
    for kind in ("acc_m_s2", "gyro_rad_s"):
        e = np.asarray(v_even[kind]["corrected"])
        u = np.asarray(v_uneven[kind]["corrected"])
        assert np.all(u < 1.3 * e), (kind, e, u)


def _alpha_error(jitter_s: float, lost: float) -> float:
    """RMS error of the derivative of a 0.7 Hz sine sampled at 100 Hz."""
    rng = np.random.default_rng(1)
    t = np.arange(1000) * 0.01 + rng.uniform(-jitter_s, jitter_s, 1000)
    t = t[rng.random(1000) >= lost]
    w = np.sin(2 * np.pi * 0.7 * t)[:, None] * np.ones(3)
    err = angular_acceleration(t, w)[:, 0] - 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t)
    inner = (t > 0.2) & (t < 9.8)
    return float(np.sqrt(np.mean(err[inner] ** 2)))


def test_derivative_follows_uneven_stamps() -> None:
    even = _alpha_error(0.0, 0.0)  # the Savitzky-Golay bias alone (~1 % of 4.4 rad/s²)
    assert even < 0.05
    assert _alpha_error(0.003, 0.2) < 1.5 * even  # stamps jittered ±3 ms, 20 % rows lost
