"""Paper B's filter with the accelerometer low-passed in the earth frame (robust to motion).

Paper B's correction (B.15-B.19) pulls the estimate towards each sample's *normalised*
accelerometer. Normalising first is not linear: a non-gravity acceleration that averages to
zero in the earth frame (a sensor swung at a lever arm, translated back and forth) does not
average out after it (its large samples count like small ones, a centripetal part that
always points to the pivot wins), and the estimate tilts by 10-20° over a long lively phase
(docs/attitude.md, "Paper B's filter on long, lively motion").

The literature's remedy, here as VQF does it (Laidig & Seel, "VQF: Highly accurate IMU
orientation estimation with bias estimation and magnetic disturbance rejection",
Information Fusion 91, 2023, doi:10.1016/j.inffus.2022.10.014; reference code
``vqf.PyVQF.updateAcc``, "filter acc in inertial frame"): express the specific force in
the earth frame of the estimate, ``a_E = q^g ⊗ a ⊗ q^g*``, low-pass it there (time
constant ``tau_lp_s``; the true acceleration of a sensor that stays in the room averages
to zero, gravity does not), and only then take its direction. The correction quaternion
is Paper B's shortest arc (B.15-B.16), written in the earth frame from the filtered
direction ``u`` to z, ``c = [1 + u_z, u_y, -u_x, 0] / sqrt(2(1 + u_z))`` (VQF's
inclination correction is the same formula), blended with gain ``P`` as (B.17-B.19),
``d = 1 + P(c - 1)``,
and applied on the earth side, ``q = d ⊗ q^g`` (B.20 normalises). The filtered vector is
turned by the same ``d``, so that it stays expressed in the corrected frame: this is VQF's
split ``q = δ ⊗ q_gyr`` with the low-pass in the gyro-only frame, without keeping
``q_gyr``. The low-pass and the blend are two first-order poles (VQF: a second-order
Butterworth low-pass and a full correction). Heading is never corrected (6D).

Gating the printed correction by ``||a| - g|/g`` instead (the adaptive gain of Valenti,
Dryanovski & Xiao, "Keeping a good attitude", Sensors 15(8), 2015: full gain below 0.1,
none above 0.2) did not do it here: it drops the samples in which the tangential
acceleration cancels the centripetal one and keeps the others (docs/attitude.md).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis import quaternion as quat
from analysis.attitude import accelerometer_quaternion

__all__ = ["estimate_attitude_inertial"]

Array = NDArray[np.float64]


def estimate_attitude_inertial(t_s: ArrayLike, gyro: ArrayLike, acc: ArrayLike, gain: float,
                               tau_lp_s: float, q0: ArrayLike | None = None) -> Array:
    """Quaternions ``(n, 4)``, sensor to earth (z up), from gyro (rad/s) and accelerometer.

    ``gain`` is P of (B.17-B.19) per sample; ``tau_lp_s`` the earth-frame low-pass time
    constant (0: none, i.e. each sample's own direction as in the printed filter, but
    corrected on the earth side). The first estimate is the accelerometer quaternion
    (B.15-B.16) of the first sample unless ``q0`` is given.
    """
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(gyro, dtype=float)
    a = np.asarray(acc, dtype=float)
    if not 0.0 <= gain <= 1.0:
        raise ValueError(f"P_err must be in [0, 1], got {gain}")
    if not (math.isfinite(tau_lp_s) and tau_lp_s >= 0.0):
        raise ValueError(f"earth-frame low-pass time constant must be >= 0 s, got {tau_lp_s}")
    n = len(t)
    out = np.empty((n, 4))
    q = quat.normalize(accelerometer_quaternion(a[0]) if q0 is None
                       else np.asarray(q0, dtype=float))
    out[0] = q
    if n < 2:
        return out
    dts = np.diff(t)
    hw = 0.5 * dts[:, None] * w[1:]  # (B.12): q^g = q ⊗ [1, ½ t_s ω]
    scale = 1.0 / np.sqrt(1.0 + np.sum(hw * hw, axis=1))  # 1/‖q^g‖ for a unit q
    alpha = 1.0 - np.exp(-dts / tau_lp_s) if tau_lp_s > 0 else np.ones_like(dts)
    s0, s1, s2, s3 = (float(v) for v in q)
    lx, ly, lz = (float(v) for v in quat.rotate(q, a[0]))  # the low-pass starts at a_0
    cols = (*hw.T, scale, *a[1:].T, alpha)
    out[1:] = np.array(_loop(s0, s1, s2, s3, lx, ly, lz, [c.tolist() for c in cols],
                             float(gain))).T
    return out


def _loop(s0: float, s1: float, s2: float, s3: float, lx: float, ly: float, lz: float,
          cols: list[list[float]], p: float) -> tuple[list[float], ...]:
    """The sequential part on Python floats (everything else is computed before).

    ``cols`` are the per-sample inputs as flat lists (½t_s·ω x, y, z; 1/‖q^g‖; a x, y, z;
    the low-pass α) and the result is one list per quaternion component: plain floats, no
    per-sample tuple or list, which the garbage collector would otherwise keep scanning
    (it cost as much as the arithmetic in a test session's heap).
    """
    sqrt = math.sqrt
    q1p = 1.0 - p
    r0: list[float] = []
    r1: list[float] = []
    r2: list[float] = []
    r3: list[float] = []
    for hx, hy, hz, k, ax, ay, az, al in zip(*cols, strict=True):
        # (B.5), (B.12) as q ⊗ [1, ½t_s·ω], normalised
        g0 = (s0 - s1 * hx - s2 * hy - s3 * hz) * k
        g1 = (s1 + s0 * hx + s2 * hz - s3 * hy) * k
        g2 = (s2 + s0 * hy - s1 * hz + s3 * hx) * k
        g3 = (s3 + s0 * hz + s1 * hy - s2 * hx) * k
        # a_E = q^g ⊗ a ⊗ q^g*  (t = 2 v × a, a + g0 t + v × t)
        tx = 2.0 * (g2 * az - g3 * ay)
        ty = 2.0 * (g3 * ax - g1 * az)
        tz = 2.0 * (g1 * ay - g2 * ax)
        ex = ax + g0 * tx + g2 * tz - g3 * ty
        ey = ay + g0 * ty + g3 * tx - g1 * tz
        ez = az + g0 * tz + g1 * ty - g2 * tx
        # first-order low-pass in the earth frame
        lx += al * (ex - lx)
        ly += al * (ey - ly)
        lz += al * (ez - lz)
        nl = sqrt(lx * lx + ly * ly + lz * lz)
        # (B.15)-(B.16) in the earth frame: the arc from u = l/‖l‖ to z, blended (B.17-B.19)
        c0 = 1.0 + lz / nl
        if c0 > 1e-9:
            m = p / sqrt(2.0 * c0)
            d0, d1, d2 = q1p + c0 * m, ly / nl * m, -lx / nl * m
        else:  # filtered vertical opposite to z: half turn about x (as VQF)
            d0, d1, d2 = q1p, p, 0.0
        nd = 1.0 / sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        d0 *= nd
        d1 *= nd
        d2 *= nd
        # q = d ⊗ q^g (d has no z part); (B.20)
        s0 = d0 * g0 - d1 * g1 - d2 * g2
        s1 = d0 * g1 + d1 * g0 + d2 * g3
        s2 = d0 * g2 + d2 * g0 - d1 * g3
        s3 = d0 * g3 + d1 * g2 - d2 * g1
        nq = 1.0 / sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
        s0 *= nq
        s1 *= nq
        s2 *= nq
        s3 *= nq
        # turn the filtered vector with the correction: l ← d ⊗ l ⊗ d*
        tx = 2.0 * d2 * lz
        ty = -2.0 * d1 * lz
        tz = 2.0 * (d1 * ly - d2 * lx)
        lx, ly, lz = (lx + d0 * tx + d2 * tz, ly + d0 * ty - d1 * tz,
                      lz + d0 * tz + d1 * ty - d2 * tx)
        r0.append(s0)
        r1.append(s1)
        r2.append(s2)
        r3.append(s3)
    return r0, r1, r2, r3
