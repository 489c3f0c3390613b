"""Simulated IMU tumbling through every orientation, with exact truth (for attitude tests).

A hexapod cannot turn a sensor upside down, so this motion is analytic instead: Z-Y-X
angles ``roll(t)`` turning through full revolutions (upside down twice per turn),
``pitch(t)`` swinging ±75°, ``yaw(t)`` swinging ±115°, after a rest of ``rest_s``. Body
rates come from the exact derivatives of the angles, so gyro and truth agree to rounding;
the accelerometer measures the specific force ``Rᵀ(a_lin + g·z)`` with optional linear
acceleration, the magnetometer ``Rᵀ·m`` of an ENU field (north = +y, dipping down). White
noise and constant gyro bias are seeded. Quaternions: scalar-first, sensor to ENU earth.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["EARTH_FIELD_UT", "simulate_angles", "simulate_tumble", "simulate_upside_down",
           "simulate_wrist_turns"]

G = 9.80665
EARTH_FIELD_UT = np.array([0.0, 20.0, -44.0])  # ENU, mid-latitude north, dip ≈ 65°
Array = NDArray[np.float64]
#: A recording's columns: float arrays, and the bool mask ``movement``.
Recording = dict[str, NDArray[Any]]


def _envelope(t: Array, start: float, ramp: float) -> tuple[Array, Array]:
    """0 before ``start``, raised cosine to 1 over ``ramp`` seconds; value and derivative."""
    x = np.clip((t - start) / ramp, 0.0, 1.0)
    e = 0.5 - 0.5 * np.cos(np.pi * x)
    de = np.where((x > 0) & (x < 1), 0.5 * np.pi / ramp * np.sin(np.pi * x), 0.0)
    return e, de


def simulate_angles(t: Array, angles: Array, rates: Array, seed: int = 0,
                    lin_acc: Array | None = None,
                    gyro_bias_rad_s: tuple = (0.01, -0.008, 0.005),
                    gyro_noise_rad_s: float = 0.004, acc_noise_m_s2: float = 0.03,
                    mag_noise_ut: float = 0.3) -> Recording:
    """IMU samples for Z-Y-X angles ``(n, 3)`` (roll, pitch, yaw) and their time derivatives."""
    rng = np.random.default_rng(seed)
    phi, th, psi = angles.T
    dphi, dth, dpsi = rates.T
    sphi, cphi, sth, cth = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
    omega = np.stack([dphi - dpsi * sth,  # Z-Y-X Euler rates to body rates
                      dth * cphi + dpsi * cth * sphi,
                      -dth * sphi + dpsi * cth * cphi], axis=1)
    cr, cp, cy = np.cos(0.5 * phi), np.cos(0.5 * th), np.cos(0.5 * psi)
    sr, sp, sy = np.sin(0.5 * phi), np.sin(0.5 * th), np.sin(0.5 * psi)
    q = np.stack([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                  cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy], axis=1)
    w, x, y, z = q.T
    rot = np.stack([  # body -> earth rotation matrices
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)
    f_earth = np.array([0.0, 0.0, G]) + (0.0 if lin_acc is None else lin_acc)
    acc = np.einsum("nji,nj->ni", rot, np.broadcast_to(f_earth, (len(t), 3)))  # Rᵀ f
    mag = np.einsum("nji,j->ni", rot, EARTH_FIELD_UT)
    n = len(t)
    gyro = omega + np.asarray(gyro_bias_rad_s) + gyro_noise_rad_s * rng.standard_normal((n, 3))
    return {
        "t_s": t,
        "gyro": gyro,
        "acc": acc + acc_noise_m_s2 * rng.standard_normal((n, 3)),
        "mag": mag + mag_noise_ut * rng.standard_normal((n, 3)),
        "quat": q,
        "movement": np.ones(n, dtype=bool),
    }


def simulate_tumble(duration_s: float = 60.0, rate_hz: float = 285.714, seed: int = 0,
                    rest_s: float = 3.0, roll_rate_rad_s: float = 1.2,
                    lin_acc_m_s2: float = 0.5, **noise) -> Recording:
    """``t_s, gyro (rad/s), acc (m/s²), mag (µT), quat (truth), movement`` arrays.

    ``noise``: keyword arguments of :func:`simulate_angles` (bias and noise levels).
    """
    t = np.arange(round(duration_s * rate_hz)) / rate_hz
    e, de = _envelope(t, rest_s, 2.0)
    tm = t - rest_s
    w1, w2 = 2 * np.pi * 0.05, 2 * np.pi * 0.037
    f = np.stack([roll_rate_rad_s * tm + 0.8 * np.sin(0.9 * tm),
                  1.31 * np.sin(w1 * tm), 2.0 * np.sin(w2 * tm + 0.3)], axis=1)
    df = np.stack([roll_rate_rad_s + 0.72 * np.cos(0.9 * tm),
                   1.31 * w1 * np.cos(w1 * tm), 2.0 * w2 * np.cos(w2 * tm + 0.3)], axis=1)
    a_lin = lin_acc_m_s2 * e[:, None] * np.stack(
        [np.sin(2 * np.pi * 0.31 * t), np.sin(2 * np.pi * 0.23 * t + 1.0),
         np.sin(2 * np.pi * 0.17 * t + 2.0)], axis=1)
    out = simulate_angles(t, e[:, None] * f, de[:, None] * f + e[:, None] * df, seed,
                          a_lin, **noise)
    out["movement"] = e > 0
    return out


def simulate_upside_down(duration_s: float = 60.0, rate_hz: float = 285.714, seed: int = 0,
                         rest_s: float = 3.0, yaw_rate_rad_s: float = 0.5,
                         wobble_rad: float = 0.05, **noise) -> Recording:
    """Upside down (roll 180°): at rest, then wobbling by ``wobble_rad`` and turning about
    the vertical.

    The case where Paper B's body-frame accelerometer quaternion is singular: its heading
    follows the noise of the small horizontal acceleration components.
    """
    t = np.arange(round(duration_s * rate_hz)) / rate_hz
    e, de = _envelope(t, rest_s, 2.0)
    tm = t - rest_s
    w1, w2 = 2 * np.pi * 0.3, 2 * np.pi * 0.23
    f = np.stack([wobble_rad * np.sin(w1 * tm), wobble_rad * np.sin(w2 * tm),
                  yaw_rate_rad_s * tm], axis=1)
    df = np.stack([wobble_rad * w1 * np.cos(w1 * tm), wobble_rad * w2 * np.cos(w2 * tm),
                   np.full_like(t, yaw_rate_rad_s)], axis=1)
    ang = e[:, None] * f + [np.pi, 0.0, 0.0]
    out = simulate_angles(t, ang, de[:, None] * f + e[:, None] * df, seed, **noise)
    out["movement"] = e > 0
    return out


def simulate_wrist_turns(duration_s: float = 40.0, rate_hz: float = 285.714, seed: int = 0,
                         rest_s: float = 3.0, amp_rad: tuple[float, float, float] = (1.0, 0.7,
                                                                                 1.5),
                         freq_hz: tuple[float, float, float] = (1.3, 0.9, 0.6), **noise
                         ) -> Recording:
    """Fast hand-like turning: roll, pitch, yaw swinging by ``amp_rad`` at ``freq_hz``
    (random phases), 7 rad/s typical, 12 rad/s peak, after a rest of ``rest_s``. The sensor
    turns about itself; :func:`drivers.sim.imu_disturbances.add_swing` moves the pivot."""
    t = np.arange(round(duration_s * rate_hz)) / rate_hz
    e, de = _envelope(t, rest_s, 2.0)
    phase = np.random.default_rng(seed).uniform(0.0, 2 * np.pi, 3)
    amp, w = np.asarray(amp_rad), 2 * np.pi * np.asarray(freq_hz)
    f = amp * np.sin(w * t[:, None] + phase)
    df = amp * w * np.cos(w * t[:, None] + phase)
    out = simulate_angles(t, e[:, None] * f, de[:, None] * f + e[:, None] * df, seed, **noise)
    out["movement"] = e > 0
    return out


def orientation_tour_targets(seed: int = 0) -> Array:
    """26 orientations whose "up" in the sensor frame covers the sphere evenly: the 6 faces
    (upside down and pitch ±90° among them), 12 edges and 8 corners of a cube, each with a
    random heading; scalar-first, sensor to earth."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    dirs = [np.array(v, dtype=float) for v in np.ndindex(3, 3, 3)]
    ups = [(d - 1.0) / np.linalg.norm(d - 1.0) for d in dirs if np.any(d != 1.0)]
    out = []
    for up in ups:  # the rotation taking the sensor's `up` to earth z, then a heading
        tilt = Rotation.align_vectors([[0.0, 0.0, 1.0]], [up])[0]
        r = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)) * tilt
        out.append(r.as_quat()[[3, 0, 1, 2]])
    return np.array(out)


def simulate_orientation_tour(rate_hz: float = 285.714, seed: int = 0, rest_s: float = 3.0,
                              hold_s: float = 1.5, turn_s: float = 1.5,
                              targets: Array | None = None,
                              gyro_bias_rad_s: tuple = (0.01, -0.008, 0.005),
                              gyro_noise_rad_s: float = 0.004, acc_noise_m_s2: float = 0.03,
                              mag_noise_ut: float = 0.3) -> Recording:
    """A sensor visiting ``targets`` (default :func:`orientation_tour_targets`) in turn.

    It rests ``rest_s`` level, then turns to each target at a constant body rate in
    ``turn_s`` (the shortest way, up to 180°) and holds it ``hold_s``. The body rate of a
    constant-rate turn from q_a to q_b is the rotation vector of q_a* ⊗ q_b over the turn
    time, so gyro and truth agree exactly. Same arrays as :func:`simulate_tumble`; the
    movement mask starts with the first turn.
    """
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    goals = orientation_tour_targets(seed) if targets is None else np.asarray(targets, float)
    dt = 1.0 / rate_hz
    n_rest, n_turn, n_hold = round(rest_s * rate_hz), round(turn_s * rate_hz), round(
        hold_s * rate_hz)
    rots: list[Rotation] = [Rotation.identity(n_rest)]
    rates: list[Array] = [np.zeros((n_rest, 3))]
    cur = Rotation.identity()
    for g in goals:
        goal = Rotation.from_quat(np.asarray(g)[[1, 2, 3, 0]])
        step = (cur.inv() * goal).as_rotvec()  # body-frame turn, |step| <= π
        s = (np.arange(1, n_turn + 1) / n_turn)[:, None]
        rots += [cur * Rotation.from_rotvec(s * step), goal * Rotation.identity(n_hold)]
        rates += [np.tile(step / (n_turn * dt), (n_turn, 1)), np.zeros((n_hold, 3))]
        cur = goal
    r = Rotation.concatenate(rots)
    omega = np.concatenate(rates)
    n = len(omega)
    acc = r.inv().apply(np.array([0.0, 0.0, G]))
    mag = r.inv().apply(EARTH_FIELD_UT)
    movement = np.arange(n) >= n_rest
    return {
        "t_s": np.arange(n) * dt,
        "gyro": omega + np.asarray(gyro_bias_rad_s)
        + gyro_noise_rad_s * rng.standard_normal((n, 3)),
        "acc": acc + acc_noise_m_s2 * rng.standard_normal((n, 3)),
        "mag": mag + mag_noise_ut * rng.standard_normal((n, 3)),
        "quat": r.as_quat()[:, [3, 0, 1, 2]],
        "movement": movement,
    }
