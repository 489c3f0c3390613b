"""Orientation errors scored as the BROAD benchmark does.

Laidig et al., BROAD, Data 6(7), 2021, section "error metrics", and its reference code
(dlaidig/broad ``example_code/broad_utils.py``, MIT/CC BY 4.0): the error quaternion is
expressed in the earth frame, ``q_err = q_est ⊗ q_ref⁻¹``; its rotation angle is the total
error, its rotation about the earth's vertical the heading error
``2·atan(|z/w|)``, and what is left the inclination error ``2·acos(√(w² + z²))``, the angle
between the true and the estimated vertical. RMSE over the ``movement`` samples, ignoring
samples whose reference is missing (NaN during optical marker loss).

A 6D estimate (no magnetometer) has an arbitrary heading; its heading and total errors are
only meaningful up to a constant offset, so :func:`score` can remove the one constant
earth-frame heading offset (circular mean over the scored samples) first. The
inclination error does not depend on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis import quaternion as quat

__all__ = [
    "AttitudeScore",
    "error_angles",
    "error_quaternion_earth",
    "heading_offset",
    "score",
]

Array = NDArray[np.float64]


def error_quaternion_earth(q_est: ArrayLike, q_ref: ArrayLike) -> Array:
    """``q_est ⊗ q_ref⁻¹``: the estimation error as a rotation of the earth frame."""
    qe, qr = quat.normalize(q_est), quat.normalize(q_ref)
    return quat.normalize(quat.multiply(qe, quat.conjugate(qr)))


def error_angles(q_err_earth: ArrayLike) -> tuple[Array, Array, Array]:
    """Total, heading and inclination error (rad) of earth-frame error quaternions."""
    q = np.asarray(q_err_earth, dtype=float)
    w, z = np.abs(q[..., 0]), np.abs(q[..., 3])
    total = 2.0 * np.arccos(np.clip(w, 0.0, 1.0))
    heading = 2.0 * np.arctan2(z, w)  # 2·atan(|z/w|), also where w = 0
    incl = 2.0 * np.arccos(np.clip(np.sqrt(w**2 + z**2), 0.0, 1.0))
    return total, heading, incl


def heading_offset(q_est: ArrayLike, q_ref: ArrayLike) -> float:
    """Constant earth-frame heading offset (rad) of an estimate: circular mean of the errors."""
    e = error_quaternion_earth(q_est, q_ref)
    e = e * np.where(e[:, :1] < 0, -1.0, 1.0)
    psi = 2.0 * np.arctan2(e[:, 3], e[:, 0])  # signed rotation about the earth's z
    return float(np.arctan2(np.mean(np.sin(psi)), np.mean(np.cos(psi))))


@dataclass(frozen=True)
class AttitudeScore:
    """RMSE (rad) over ``samples`` scored samples; ``heading_offset_rad`` was removed first."""

    total_rad: float
    heading_rad: float
    inclination_rad: float
    samples: int
    heading_offset_rad: float = 0.0

    def as_deg(self) -> dict[str, float | int]:
        """The BROAD result names (``*_rmse_deg``) and the sample count."""
        return {"total_rmse_deg": math.degrees(self.total_rad),
                "heading_rmse_deg": math.degrees(self.heading_rad),
                "inclination_rmse_deg": math.degrees(self.inclination_rad),
                "samples": self.samples,
                "heading_offset_removed_deg": math.degrees(self.heading_offset_rad)}


def score(q_est: ArrayLike, q_ref: ArrayLike, movement: ArrayLike | None = None,
          remove_heading_offset: bool = False) -> AttitudeScore:
    """RMSE of total, heading and inclination error over ``movement`` (BROAD scoring).

    Rows with a non-finite reference or estimate are skipped. ``remove_heading_offset``
    (for 6D estimates) first turns the estimate about the earth's z by the constant offset.
    """
    qe = np.asarray(q_est, dtype=float)
    qr = np.asarray(q_ref, dtype=float)
    if qe.shape != qr.shape or qe.ndim != 2 or qe.shape[1] != 4:
        raise ValueError(f"estimate {qe.shape} and reference {qr.shape} must both be (n, 4)")
    ok = np.all(np.isfinite(qr), axis=1) & np.all(np.isfinite(qe), axis=1)
    if movement is not None:
        mov = np.asarray(movement, dtype=bool)
        if mov.shape != ok.shape:
            raise ValueError(f"movement mask {mov.shape} does not match {ok.shape[0]} samples")
        ok &= mov
    if not ok.any():
        raise ValueError("no samples with a finite reference to score")
    qe, qr = qe[ok], qr[ok]
    offset = 0.0
    if remove_heading_offset:
        offset = heading_offset(qe, qr)
        qe = quat.multiply(quat.from_axis_angle([0.0, 0.0, 1.0], -offset), qe)
    total, heading, incl = error_angles(error_quaternion_earth(qe, qr))

    def rmse(x: Array) -> float:
        return float(np.sqrt(np.mean(x**2)))

    return AttitudeScore(rmse(total), rmse(heading), rmse(incl), int(ok.sum()), offset)
