"""The trig-free quaternion attitude estimator of Paper B and its evaluation.

Per sample: the gyro quaternion by one Euler step of (B.5) from the previous estimate
(B.12); the accelerometer quaternion as the shortest arc from the (low-passed, B.28)
specific force to the navigation z axis (B.15-B.16, the 180° case handled); the
component-wise blend with gain ``P_err`` (B.17-B.19); normalisation (B.20). Quaternions
are scalar-first and map body to navigation frame (z up, along the specific force at rest).

The paper's accelerometer quaternion has zero yaw, so the blend also pulls the yaw towards
zero; with fast yaw motion that leaks into roll and pitch. ``yaw_aligned=True`` (not in the
paper) gives the accelerometer quaternion the current heading first, trig-free, so that the
blend corrects only the tilt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from analysis import quaternion as quat

__all__ = [
    "AttitudeErrors",
    "accelerometer_quaternion",
    "attitude_errors",
    "estimate_attitude",
    "lowpass_acc",
]

Array = NDArray[np.float64]


def lowpass_acc(acc: ArrayLike, g_a: float) -> Array:
    """First-order low-pass ``â_n = â_(n-1)·G_a + a_n·(1 - G_a)`` (B.28), started at a_0."""
    acc = np.asarray(acc, dtype=float)
    if not 0.0 <= g_a < 1.0:
        raise ValueError(f"accelerometer filter gain G_a must be in [0, 1), got {g_a}")
    if g_a == 0.0:
        return acc.copy()
    zi = (g_a * acc[0])[None, :]  # steady state at the first sample
    out, _ = lfilter([1.0 - g_a], [1.0, -g_a], acc, axis=0, zi=zi)
    return out


def accelerometer_quaternion(acc: ArrayLike, eps: float = 1e-9) -> Array:
    """Shortest arc from the measured specific force to ``[0, 0, 1]`` (B.15-B.16).

    At exactly upside down (ã_z = -1) there is no shortest arc; the half turn about body x
    is returned (the if-else workaround Paper B mentions).
    """
    a = np.asarray(acc, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    one_plus = 1.0 + a[..., 2]
    safe = np.maximum(one_plus, eps)
    q0 = np.sqrt(0.5 * safe)  # (B.15)
    k = 1.0 / np.sqrt(2.0 * safe)  # (B.16)
    q = np.stack([q0, k * a[..., 1], -k * a[..., 0], np.zeros_like(q0)], axis=-1)
    flipped = one_plus < eps
    q[flipped] = [0.0, 1.0, 0.0, 0.0]
    return quat.normalize(q)


TILT_MODES = ("estimate", "body", "yaw-aligned")


def estimate_attitude(
    t_s: ArrayLike,
    gyro: ArrayLike,
    acc: ArrayLike,
    gain: float = 0.002,
    acc_lowpass: float = 0.0,
    q0: ArrayLike | None = None,
    yaw_aligned: bool = False,
    tilt: str = "body",
    gyro_lag: bool = False,
) -> Array:
    """Attitude quaternions ``(n, 4)`` from gyro (rad/s) and accelerometer samples.

    ``gain`` is P_err per sample (Paper B used 0.002 at 400 Hz). The first estimate is the
    accelerometer quaternion unless ``q0`` is given. ``tilt`` chooses the accelerometer
    quaternion q^a that the blend (B.17-B.19) pulls towards:

    * ``"body"``: Paper B as printed, the shortest arc from the measured specific force to
      the navigation z axis (B.15-B.16). Its heading is zero, so the blend also pulls the
      heading to zero, and near upside down that heading swings wildly (singular at 180°).
    * ``"yaw-aligned"`` (``yaw_aligned=True``): that arc given the heading of q^g first.
      Still singular upside down, where the heading of q^g is undefined.
    * ``"estimate"``: (B.15-B.16) with the navigation z axis replaced by the vertical that
      q^g predicts in the body frame, ``v = q^g* ⊗ z ⊗ q^g``; then ``q^a = q^g ⊗ arc(a → v)``.
      q^a maps the measured force onto z like Paper B's and is the one closest to q^g, so
      the blend corrects only the tilt, never the heading, in every orientation. The only
      degenerate case is an estimate 180° from the measured vertical (a half turn about a
      horizontal axis is used then). Trig-free, as the paper's.

    (B.12) integrates the gyro sample read in the same cycle (``ω_k`` from q_(k-1) to q_k,
    as a flight controller's loop and every peer do); ``gyro_lag=True`` uses the previous
    sample instead, one sample late (on BROAD trial 07 that alone costs 0.7° of gyro-only
    inclination error).

    The loop is sequential by nature; it runs on Python floats (about 1 µs per
    operation), fast enough for IMU rates.
    """
    if yaw_aligned:
        tilt = "yaw-aligned"
    if tilt not in TILT_MODES:
        raise ValueError(f"tilt must be one of {', '.join(TILT_MODES)}, got {tilt!r}")
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(gyro, dtype=float)
    if not 0.0 <= gain <= 1.0:
        raise ValueError(f"P_err must be in [0, 1], got {gain}")
    acc_f = lowpass_acc(acc, acc_lowpass)
    n = len(t)
    out = np.empty((n, 4))
    p = float(gain)
    shift = 1 if gyro_lag else 0
    if tilt == "estimate":
        q = quat.normalize(accelerometer_quaternion(acc_f[0]) if q0 is None
                           else np.asarray(q0, dtype=float))
        out[0] = q
        s0, s1, s2, s3 = (float(v) for v in q)
        return _estimate_frame_loop(out, s0, s1, s2, s3, t, w, acc_f, p, shift)
    qa_all = accelerometer_quaternion(acc_f)
    q = quat.normalize(qa_all[0] if q0 is None else np.asarray(q0, dtype=float))
    out[0] = q
    s0, s1, s2, s3 = (float(v) for v in q)
    cols = [c.tolist() for c in (np.diff(t), *w[1 - shift:n - shift].T, *qa_all[1:].T)]
    rows = _printed_loop(s0, s1, s2, s3, cols, p, tilt == "yaw-aligned")
    if rows[0]:
        out[1:] = np.array(rows).T
    return out


def _printed_loop(s0: float, s1: float, s2: float, s3: float, cols: list[list[float]],
                  p: float, yaw_aligned: bool) -> tuple[list[float], ...]:
    """The ``tilt="body"`` and ``"yaw-aligned"`` loop of :func:`estimate_attitude`.

    ``cols``: per sample t_s, ω x, y, z and q^a w, x, y, z as flat lists of floats; the
    result is one list per quaternion component. No per-sample tuple or list: the garbage
    collector would keep scanning those (as costly as the arithmetic in a large heap).
    """
    r0: list[float] = []
    r1: list[float] = []
    r2: list[float] = []
    r3: list[float] = []
    for dt, wx, wy, wz, a0, a1, a2, a3 in zip(*cols, strict=True):
        h = 0.5 * dt
        # (B.5), (B.12): q^g = q + ts·½ q ⊗ [0, ω]
        g0 = s0 + h * (-s1 * wx - s2 * wy - s3 * wz)
        g1 = s1 + h * (s0 * wx + s2 * wz - s3 * wy)
        g2 = s2 + h * (s0 * wy - s1 * wz + s3 * wx)
        g3 = s3 + h * (s0 * wz + s1 * wy - s2 * wx)
        if yaw_aligned:  # q^a ← h(q^g) ⊗ q^a, h = [g0, 0, 0, g3]/‖·‖
            nh = math.sqrt(g0 * g0 + g3 * g3)
            if nh > 0.0:
                c, s = g0 / nh, g3 / nh
                a0, a1, a2, a3 = c * a0 - s * a3, c * a1 - s * a2, c * a2 + s * a1, c * a3 + s * a0
        if g0 * a0 + g1 * a1 + g2 * a2 + g3 * a3 < 0.0:  # same hemisphere as q^g
            a0, a1, a2, a3 = -a0, -a1, -a2, -a3
        # (B.17)-(B.19): q = q^g + P_err (q^a - q^g)
        s0 = g0 + p * (a0 - g0)
        s1 = g1 + p * (a1 - g1)
        s2 = g2 + p * (a2 - g2)
        s3 = g3 + p * (a3 - g3)
        nq = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)  # (B.20)
        s0, s1, s2, s3 = s0 / nq, s1 / nq, s2 / nq, s3 / nq
        r0.append(s0)
        r1.append(s1)
        r2.append(s2)
        r3.append(s3)
    return r0, r1, r2, r3


def _estimate_frame_loop(out: Array, s0: float, s1: float, s2: float, s3: float, t: Array,
                         w: Array, acc: Array, p: float, shift: int) -> Array:
    """The ``tilt="estimate"`` loop of :func:`estimate_attitude`, on plain floats.

    Per sample k (all that does not depend on the state is computed before, vectorised):
    ``e = [1, ½·t_s·ω]`` so that (B.12) is ``q^g = q ⊗ e``; ``r = 1/‖q^g‖² = 1/(1 + ‖½t_sω‖²)``
    normalises the predicted vertical; the measured direction ``â`` is a unit vector.
    (B.17)-(B.19), ``q = q^g + P(q^a - q^g)`` with ``q^a = q^g ⊗ c``, is computed as the
    identical ``q^g ⊗ (1 + P(c - 1))``: one product instead of a product and a blend.
    """
    dts = np.diff(t)
    hw = 0.5 * dts[:, None] * (w[1:] if shift == 0 else w[:-1])
    inv2 = 1.0 / (1.0 + np.sum(hw * hw, axis=1))
    al = acc[1:] / np.linalg.norm(acc[1:], axis=1, keepdims=True)
    sqrt = math.sqrt
    q1p = 1.0 - p
    # flat lists of floats in and out, no per-sample tuple or list: the garbage collector
    # would keep scanning those (as costly as the arithmetic in a test session's heap)
    cols = [c.tolist() for c in (*hw.T, *al.T, inv2)]
    r0: list[float] = []
    r1: list[float] = []
    r2: list[float] = []
    r3: list[float] = []
    for hx, hy, hz, ax, ay, az, r in zip(*cols, strict=True):
        # (B.5), (B.12): q^g = q + ts·½ q ⊗ [0, ω] = q ⊗ [1, ½ts·ω]
        g0 = s0 - s1 * hx - s2 * hy - s3 * hz
        g1 = s1 + s0 * hx + s2 * hz - s3 * hy
        g2 = s2 + s0 * hy - s1 * hz + s3 * hx
        g3 = s3 + s0 * hz + s1 * hy - s2 * hx
        # predicted vertical in the body frame (third row of the rotation of q^g), unit
        vx = 2.0 * (g1 * g3 - g0 * g2) * r
        vy = 2.0 * (g2 * g3 + g0 * g1) * r
        vz = (g0 * g0 - g1 * g1 - g2 * g2 + g3 * g3) * r
        # (B.15)-(B.16) with z replaced by v: c = [1 + â·v, â × v] / sqrt(2(1 + â·v))
        c0 = 1.0 + ax * vx + ay * vy + az * vz
        if c0 > 1e-9:
            m = p / sqrt(2.0 * c0)
            d0 = q1p + c0 * m
            d1 = (ay * vz - az * vy) * m
            d2 = (az * vx - ax * vz) * m
            d3 = (ax * vy - ay * vx) * m
        else:  # measured vertical opposite to the estimate: half turn about an axis ⟂ v
            d1, d2, d3 = (vy, -vx, 0.0) if abs(vz) < 0.9 else (0.0, vz, -vy)
            m = p / sqrt(d1 * d1 + d2 * d2 + d3 * d3)
            d0, d1, d2, d3 = q1p, d1 * m, d2 * m, d3 * m
        # (B.17)-(B.19) as q^g ⊗ d (B.3); then (B.20)
        s0 = g0 * d0 - g1 * d1 - g2 * d2 - g3 * d3
        s1 = g0 * d1 + g1 * d0 + g2 * d3 - g3 * d2
        s2 = g0 * d2 - g1 * d3 + g2 * d0 + g3 * d1
        s3 = g0 * d3 + g1 * d2 - g2 * d1 + g3 * d0
        nq = 1.0 / sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
        s0 *= nq
        s1 *= nq
        s2 *= nq
        s3 *= nq
        r0.append(s0)
        r1.append(s1)
        r2.append(s2)
        r3.append(s3)
    if r0:
        out[1:] = np.array((r0, r1, r2, r3)).T
    return out


@dataclass(frozen=True)
class AttitudeErrors:
    """RMS errors (rad) over the compared samples; inclination is yaw-free (tilt angle)."""

    roll_rms: float
    pitch_rms: float
    inclination_rms: float
    samples: int


def attitude_errors(q_est: ArrayLike, q_ref: ArrayLike, mask: ArrayLike | None = None
                    ) -> AttitudeErrors:
    """Roll and pitch RMS error (B.6 angles, yaw-independent) and inclination RMS error.

    Rows whose reference is not finite are skipped, as are rows outside ``mask``.
    """
    qe = np.asarray(q_est, dtype=float)
    qr = np.asarray(q_ref, dtype=float)
    ok = np.isfinite(qr).all(axis=1) & np.isfinite(qe).all(axis=1)
    if mask is not None:
        ok &= np.asarray(mask, dtype=bool)
    if not ok.any():
        raise ValueError("no samples with a finite reference to compare")
    qe, qr = quat.normalize(qe[ok]), quat.normalize(qr[ok])
    ee, er = quat.to_euler(qe), quat.to_euler(qr)
    d = ee[:, :2] - er[:, :2]
    d = (d + np.pi) % (2 * np.pi) - np.pi
    up = np.array([0.0, 0.0, 1.0])
    ue = quat.rotate(quat.conjugate(qe), up)
    ur = quat.rotate(quat.conjugate(qr), up)
    incl = np.arccos(np.clip(np.sum(ue * ur, axis=1), -1.0, 1.0))
    rms = np.sqrt(np.mean(d**2, axis=0))
    return AttitudeErrors(float(rms[0]), float(rms[1]), float(np.sqrt(np.mean(incl**2))),
                          int(ok.sum()))
