"""Paper B's estimator: its building blocks, simulated hexapod motion, and the BROAD trial."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from analysis import quaternion as quat
from analysis.attitude import (
    accelerometer_quaternion,
    attitude_errors,
    estimate_attitude,
    lowpass_acc,
)
from drivers.sim.imu_attitude_log import simulate_attitude_log


def test_accelerometer_quaternion_is_tilt_b15_b16() -> None:
    roll, pitch = np.radians(20.0), np.radians(-15.0)
    q_true = quat.from_euler([roll, pitch, 0.0])
    acc = quat.rotate(quat.conjugate(q_true), [0, 0, 9.81])  # gravity reaction, body frame
    qa = accelerometer_quaternion(acc * 3.0)  # magnitude does not matter
    # the shortest arc has no yaw component and gives the same gravity direction
    assert abs(qa[3]) < 1e-12
    assert np.allclose(quat.rotate(qa, acc / 9.81), [0, 0, 1])


def test_accelerometer_quaternion_upside_down_is_finite() -> None:
    qa = accelerometer_quaternion(np.array([[0.0, 0.0, -9.81], [0.0, 1e-12, -9.81]]))
    assert np.all(np.isfinite(qa))
    assert np.allclose(quat.rotate(qa[0], [0, 0, -1]), [0, 0, 1])


def test_lowpass_b28_step_response() -> None:
    a = np.r_[np.zeros((1, 3)), np.ones((10, 3))]
    out = lowpass_acc(a, 0.5)
    assert np.allclose(out[1:, 0], 1 - 0.5 ** np.arange(1, 11))
    with pytest.raises(ValueError):
        lowpass_acc(a, 1.0)


def test_gain_limits_select_gyro_or_accelerometer() -> None:
    t = np.arange(200) * 0.01
    gyro = np.tile([0.5, 0.0, 0.0], (200, 1))  # rolling at 0.5 rad/s
    acc = np.tile([0.0, 0.0, 9.81], (200, 1))  # accelerometer says level
    q_gyro = estimate_attitude(t, gyro, acc, gain=0.0)
    q_acc = estimate_attitude(t, gyro, acc, gain=1.0)
    assert math.isclose(quat.to_euler(q_gyro[-1])[0], 0.5 * t[-1], rel_tol=1e-3)
    assert np.allclose(q_acc, [1, 0, 0, 0])


def test_filter_removes_an_initial_error_and_converges() -> None:
    t = np.arange(4000) * 0.0025  # 400 Hz, 10 s at rest, tilted 10° in roll
    q_true = quat.from_euler([np.radians(10), 0, 0])
    acc = np.tile(quat.rotate(quat.conjugate(q_true), [0, 0, 9.81]), (len(t), 1))
    q = estimate_attitude(t, np.zeros((len(t), 3)), acc, gain=0.002, q0=[1, 0, 0, 0])
    err = np.degrees(quat.angle_between(q, q_true))
    assert err[0] > 9.9
    assert err[-1] < 0.01  # time constant ts/P = 1.25 s (Paper B: P = 0.002 at 400 Hz)


@pytest.fixture(scope="module")
def sim_log() -> dict[str, np.ndarray]:
    return simulate_attitude_log(seed=3)


def _arrays(c: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    g = np.c_[c["gyro_x_rad_s"], c["gyro_y_rad_s"], c["gyro_z_rad_s"]]
    a = np.c_[c["acc_x_m_s2"], c["acc_y_m_s2"], c["acc_z_m_s2"]]
    q = np.c_[c["ref_qw"], c["ref_qx"], c["ref_qy"], c["ref_qz"]]
    return c["t_s"], g, a, q


def test_simulated_hexapod_motion_roll_pitch_rms(sim_log: dict[str, np.ndarray]) -> None:
    """Paper B's Stewart test (0.17 rad, 0.2 Hz) plus pitch, yaw and translations at 400 Hz.

    Translations of 0.05 m at 0.3-0.4 Hz and the 0.4 m lever arm disturb the accelerometer
    by up to ~0.3 m/s² (~2° of false tilt); the blend must keep roll and pitch within 1°
    (measured ~0.5°) and clearly beat both the accelerometer alone and the gyro alone.
    """
    t, g, a, qr = _arrays(sim_log)
    e = attitude_errors(estimate_attitude(t, g, a, gain=0.002), qr)
    e_acc = attitude_errors(estimate_attitude(t, g, a, gain=1.0), qr)
    assert math.degrees(e.roll_rms) < 1.0
    assert math.degrees(e.pitch_rms) < 1.0
    assert e.inclination_rms < 0.5 * e_acc.inclination_rms


def test_broad_trial_07_roll_pitch_rms(shared_data: Path) -> None:
    """Real data: BROAD trial 07 (fast rotation, up to 25 rad/s), optical reference.

    Thresholds 4° roll and 2.5° pitch RMS over the movement phase. On this trial the
    gyro of this IMU alone (P_err = 0, bias removed) drifts to 3.1° / 2.0° RMS and the
    accelerometer alone (P_err = 1) is off by 24° / 13° (fast rotation), so Paper B's
    fixed small gain cannot do much better than the gyro; the bound is that gyro level
    plus ~25 % margin for seeds/platforms (measured with the former one-sample-late gyro;
    the estimator now integrates the current sample and does better). A broken filter
    (quaternion order, frame or sign) lands at tens of degrees. The BROAD-scored
    comparison with the peers is tests/analysis/test_attitude_broad.py.
    """
    h5py = pytest.importorskip("h5py")
    path = shared_data / "broad" / "07_undisturbed_fast_rotation_B.hdf5"
    with h5py.File(path, "r") as f:
        gyr, acc = f["imu_gyr"][:], f["imu_acc"][:]
        q_ref, moving = f["opt_quat"][:], f["movement"][:].astype(bool)
        fs = float(f.attrs["sampling_rate"])
    t = np.arange(len(gyr)) / fs
    rest = slice(0, int(np.argmax(moving)))  # Paper B: bias measured at rest before use
    gyr = gyr - gyr[rest].mean(axis=0)
    e = attitude_errors(estimate_attitude(t, gyr, acc, gain=0.002), q_ref, moving)
    e_acc = attitude_errors(estimate_attitude(t, gyr, acc, gain=1.0), q_ref, moving)
    assert math.degrees(e.roll_rms) < 4.0
    assert math.degrees(e.pitch_rms) < 2.5
    assert e.inclination_rms < e_acc.inclination_rms / 5
