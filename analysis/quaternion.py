"""Quaternion operations of thesis section 2.1 and Paper B, scalar-first ``[w, x, y, z]``.

Every function works on a single quaternion ``(4,)`` or on stacks ``(..., 4)`` with numpy
broadcasting. A quaternion ``q`` used as an attitude maps body-frame vectors to the
navigation frame: ``v_n = q ⊗ v_b ⊗ q⁻¹`` (B.4). scipy's ``Rotation`` is scalar-last; the
only crossings are :func:`to_scipy` and :func:`from_scipy`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

__all__ = [
    "angle_between",
    "conjugate",
    "controller_input",
    "derivative",
    "from_axis_angle",
    "from_euler",
    "from_scipy",
    "integrate",
    "multiply",
    "normalize",
    "rotate",
    "shortest_arc",
    "to_euler",
    "to_scipy",
    "yaw_part",
]

Array = NDArray[np.float64]


def _q(q: ArrayLike) -> Array:
    arr = np.asarray(q, dtype=float)
    if arr.shape[-1] != 4:
        raise ValueError(f"quaternion arrays need a last axis of length 4, got {arr.shape}")
    return arr


def multiply(q: ArrayLike, r: ArrayLike) -> Array:
    """Hamilton product ``q ⊗ r`` (B.3; equivalently (2.16)-(2.17))."""
    q, r = _q(q), _q(r)
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    r0, r1, r2, r3 = np.moveaxis(r, -1, 0)
    return np.stack(
        [
            r0 * q0 - r1 * q1 - r2 * q2 - r3 * q3,  # (B.3)
            r0 * q1 + r1 * q0 - r2 * q3 + r3 * q2,
            r0 * q2 + r1 * q3 + r2 * q0 - r3 * q1,
            r0 * q3 - r1 * q2 + r2 * q1 + r3 * q0,
        ],
        axis=-1,
    )


def conjugate(q: ArrayLike) -> Array:
    """Conjugate; the inverse of a unit quaternion (B.2)."""
    return _q(q) * np.array([1.0, -1.0, -1.0, -1.0])


def normalize(q: ArrayLike) -> Array:
    """Scale to unit length (B.20, 2.30)."""
    q = _q(q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def nlerp(q: ArrayLike, r: ArrayLike, u: ArrayLike) -> Array:
    """Normalised linear interpolation from ``q`` (u = 0) to ``r`` (u = 1), the short way.

    Between neighbouring samples of an attitude (a few degrees apart) it differs from slerp
    by far less than any filter's error, at a fraction of the cost.
    """
    q, r = _q(q), _q(r)
    u = np.asarray(u, dtype=float)[..., None]
    r = np.where(np.sum(q * r, axis=-1, keepdims=True) < 0.0, -r, r)
    return normalize((1.0 - u) * q + u * r)


def rotate(q: ArrayLike, v: ArrayLike) -> Array:
    """Rotate 3-vectors: vector part of ``q ⊗ [0; v] ⊗ q⁻¹`` (B.4, 2.8)."""
    v = np.asarray(v, dtype=float)
    v4 = np.concatenate([np.zeros((*v.shape[:-1], 1)), v], axis=-1)
    return multiply(multiply(q, v4), conjugate(q))[..., 1:]


def from_axis_angle(axis: ArrayLike, angle: ArrayLike) -> Array:
    """Unit quaternion for a rotation by ``angle`` (rad) about ``axis`` (B.1, 2.18)."""
    unit = np.asarray(axis, dtype=np.float64)
    unit = unit / np.linalg.norm(unit, axis=-1, keepdims=True)
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * unit], axis=-1)


def derivative(q: ArrayLike, omega_b: ArrayLike) -> Array:
    """Time derivative for body-frame angular rate: ``½ q ⊗ [0; ω_b]`` (B.5).

    (2.19) writes the rate on the left, which is the same law for a rate given in the
    navigation frame; the estimator uses body rates, so (B.5) is the one used here.
    """
    w = np.asarray(omega_b, dtype=float)
    w4 = np.concatenate([np.zeros((*w.shape[:-1], 1)), w], axis=-1)
    return 0.5 * multiply(q, w4)


def integrate(q: ArrayLike, omega_b: ArrayLike, dt: float) -> Array:
    """One Euler step ``q + dt·q̇`` (2.20, B.12), normalised (B.20)."""
    q = _q(q)
    return normalize(q + dt * derivative(q, omega_b))


def shortest_arc(v1: ArrayLike, v2: ArrayLike, eps: float = 1e-9) -> Array:
    """Quaternion of the shortest rotation taking direction ``v1`` onto ``v2`` (2.29-2.30).

    ``q* = [1 + v̂1·v̂2, v̂1 × v̂2]``, normalised (2.29)-(2.30). When the vectors are opposite
    (180°) there is no unique shortest arc; the result is then the half turn about the
    axis perpendicular to ``v1`` closest to body x (falling back to y).
    """
    a = np.asarray(v1, dtype=float)
    b = np.asarray(v2, dtype=float)
    a, b = np.broadcast_arrays(a, b)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    w = 1.0 + np.sum(a * b, axis=-1, keepdims=True)  # (2.29)
    q = np.concatenate([w, np.cross(a, b)], axis=-1)
    opposite = w[..., 0] < eps
    if np.any(opposite):
        ao = a[opposite]
        ex = np.array([1.0, 0.0, 0.0])
        ey = np.array([0.0, 1.0, 0.0])
        use_y = np.abs(ao @ ex) > 0.9
        ref = np.where(use_y[:, None], ey, ex)
        axis = ref - np.sum(ref * ao, axis=-1, keepdims=True) * ao
        q[opposite] = np.concatenate([np.zeros((len(ao), 1)), axis], axis=-1)
    return normalize(q)  # (2.30)


def to_euler(q: ArrayLike) -> Array:
    """Roll, pitch, yaw (rad), Z-Y-X convention of (B.6)."""
    q0, q1, q2, q3 = np.moveaxis(_q(q), -1, 0)
    roll = np.arctan2(2 * (q0 * q1 + q2 * q3), 1 - 2 * (q1**2 + q2**2))  # (B.6)
    pitch = np.arcsin(np.clip(2 * (q0 * q2 - q3 * q1), -1.0, 1.0))
    yaw = np.arctan2(2 * (q0 * q3 + q1 * q2), 1 - 2 * (q2**2 + q3**2))
    return np.stack([roll, pitch, yaw], axis=-1)


def from_euler(rpy: ArrayLike) -> Array:
    """Quaternion from roll, pitch, yaw (rad), the inverse of (B.6); (B.21)."""
    rpy = np.asarray(rpy, dtype=float)
    cr, cp, cy = (np.cos(0.5 * rpy[..., i]) for i in range(3))
    sr, sp, sy = (np.sin(0.5 * rpy[..., i]) for i in range(3))
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,  # (B.21)
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def controller_input(q: ArrayLike) -> Array:
    """Vector part ``q[1:3]`` used directly as the attitude-controller input (B.26).

    For small angles it equals half of roll, pitch and yaw (B.22)-(B.26).
    """
    return _q(q)[..., 1:4].copy()


def yaw_part(q: ArrayLike) -> Array:
    """Heading quaternion ``h`` with ``q = h ⊗ t`` and ``t`` a tilt with zero z part.

    Trig-free: ``h = [q0, 0, 0, q3] / ‖·‖``. Used by the yaw-aligned estimator option.
    """
    q = _q(q)
    h = q * np.array([1.0, 0.0, 0.0, 1.0])
    return normalize(h)


def angle_between(q: ArrayLike, r: ArrayLike) -> Array:
    """Rotation angle (rad) between two attitudes, insensitive to the sign of q."""
    d = np.abs(np.sum(normalize(q) * normalize(r), axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def to_scipy(q: ArrayLike) -> Rotation:
    """scipy Rotation from scalar-first quaternions (reordered explicitly to scalar-last)."""
    q = _q(q)
    return Rotation.from_quat(q[..., [1, 2, 3, 0]])


def from_scipy(rot: Rotation) -> Array:
    """Scalar-first quaternions from a scipy Rotation (scipy's own order is scalar-last)."""
    xyzw = rot.as_quat()
    return np.asarray(xyzw, dtype=float)[..., [3, 0, 1, 2]]
