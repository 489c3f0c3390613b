"""The simulated hexapod and IMU plant: exact kinematics, limits, error model, seeding."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import DeviceError
from drivers.sim.hexapod import HexapodLimits, SimHexapod, euler_to_matrix
from drivers.sim.hexapod_motions import gyro_sines, paper_a_protocol, verification_motion
from drivers.sim.imu import ADIS16400, SimImu
from drivers.sim.imu_calibration_log import LOG_COLUMNS, simulate_calibration_log


def test_body_rates_match_numerical_differentiation_of_the_attitude() -> None:
    hexa = SimHexapod()
    motion = verification_motion(duration_s=10.0)
    t = np.linspace(2.0, 8.0, 301)
    h = 1e-5
    s = hexa.follow(motion, t)
    rp = euler_to_matrix(hexa.follow(motion, t + h).euler_rad)
    rm = euler_to_matrix(hexa.follow(motion, t - h).euler_rad)
    r = euler_to_matrix(s.euler_rad)
    skew = np.einsum("nji,njk->nik", r, (rp - rm) / (2 * h))  # Rᵀ·Ṙ = [ω]×
    omega = np.c_[skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]]
    assert np.allclose(omega, s.omega_b_rad_s, atol=1e-8)
    alpha = (hexa.follow(motion, t + h).omega_b_rad_s
             - hexa.follow(motion, t - h).omega_b_rad_s) / (2 * h)
    assert np.allclose(alpha, s.alpha_b_rad_s2, atol=1e-6)


def test_at_rest_the_specific_force_is_gravity_up() -> None:
    s = SimHexapod().follow(gyro_sines(), [0.0])
    assert np.allclose(s.specific_force_b_m_s2, [[0, 0, 9.80665]])


def test_motion_beyond_limits_is_refused() -> None:
    slow = SimHexapod(HexapodLimits(rate_rad_s=0.1))
    with pytest.raises(DeviceError, match="rate_rad_s"):
        slow.check(gyro_sines())
    for phase in paper_a_protocol():
        SimHexapod().check(phase.motion)  # Paper A's motions fit the default limits


def test_imu_reads_range_quantised_and_seeded() -> None:
    s = SimHexapod().follow(gyro_sines(), np.arange(0, 5, 0.01))
    g1, _ = SimImu(ADIS16400, np.random.default_rng(1)).measure(s)
    g2, _ = SimImu(ADIS16400, np.random.default_rng(1)).measure(s)
    assert np.array_equal(g1, g2)
    lsb = ADIS16400.gyro_lsb_rad_s
    assert np.allclose(g1 / lsb, np.round(g1 / lsb))
    sg, sa = ADIS16400.noise_std()
    assert 0.005 < sg < 0.007 and 0.03 < sa < 0.04  # 0.05 °/s/√Hz, 0.5 mg/√Hz at 100 Hz


def test_log_columns_and_clock_offset() -> None:
    cols = simulate_calibration_log(phases=paper_a_protocol(short=True)[:2], seed=0)
    assert tuple(cols) == LOG_COLUMNS
    assert np.all(np.diff(cols["t_s"]) > 0)
    assert set(cols["phase"]) == {"bias", "gyro"}
