"""Contracts of the IMU bench (Paper A): a hexapod, the IMU under test, a reference IMU.

* :class:`Hexapod`: a 6-DOF motion platform. The bench sets the pivot point (the UAV's
  centre of gravity), uploads a :class:`Trajectory` of sampled poses, starts it, and reads
  back the controller's log (:data:`HEXAPOD_LOG_CHANNELS`): pose, velocity, acceleration
  and their body-frame form (angular rate, angular acceleration, specific force at the
  pivot, gravity included). ``stop`` must be safe at any time, repeatedly. A trajectory
  outside the limits is refused at upload with :class:`HexapodLimitError`.
* The IMU under test is a plain :class:`drivers.contracts.Sensor` with the columns
  :data:`IMU_CHANNELS`, stamped on the IMU's own clock.
* The reference IMU is a Sensor with :data:`REFERENCE_IMU_CHANNELS`: attitude quaternion
  (scalar-first, body→navigation, z up) and body rates.

Poses are SI: x, y, z in m; roll, pitch, yaw in rad (Z-Y-X Euler about the pivot).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from drivers.contracts import Block, DeviceInfo
from drivers.errors import DeviceError

__all__ = [
    "ACCELERATION_CHANNELS",
    "BODY_CHANNELS",
    "HEXAPOD_LOG_CHANNELS",
    "IMU_CHANNELS",
    "POSE_AXES",
    "POSE_CHANNELS",
    "REFERENCE_IMU_CHANNELS",
    "VELOCITY_CHANNELS",
    "Hexapod",
    "HexapodLimitError",
    "HexapodLimits",
    "Trajectory",
    "limit_violations",
]

XYZ = ("x", "y", "z")
POSE_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
_POSE_UNIT = ("m", "m", "m", "rad", "rad", "rad")
POSE_CHANNELS = tuple(f"hex_{a}_{u}" for a, u in zip(POSE_AXES, _POSE_UNIT, strict=True))
VELOCITY_CHANNELS = tuple(f"hex_v{a}_{u}_s" for a, u in zip(POSE_AXES, _POSE_UNIT, strict=True))
ACCELERATION_CHANNELS = tuple(f"hex_a{a}_{u}_s2"
                              for a, u in zip(POSE_AXES, _POSE_UNIT, strict=True))
# The body-frame channels carry the calibration log's names (analysis.imu_log).
BODY_CHANNELS = (*(f"ref_omega_{a}_rad_s" for a in XYZ), *(f"ref_alpha_{a}_rad_s2" for a in XYZ),
                 *(f"ref_acc_{a}_m_s2" for a in XYZ))
HEXAPOD_LOG_CHANNELS = (*POSE_CHANNELS, *VELOCITY_CHANNELS, *ACCELERATION_CHANNELS,
                        *BODY_CHANNELS)
IMU_CHANNELS = (*(f"imu_gyro_{a}_rad_s" for a in XYZ), *(f"imu_acc_{a}_m_s2" for a in XYZ))
REFERENCE_IMU_CHANNELS = ("ref_qw", "ref_qx", "ref_qy", "ref_qz",
                          *(f"ref_imu_gyro_{a}_rad_s" for a in XYZ))


class HexapodLimitError(DeviceError):
    """A trajectory (or a logged sample) exceeds the hexapod's limits."""


@dataclass(frozen=True)
class HexapodLimits:
    """Limits of a motion-simulator class hexapod (per axis, magnitudes, SI)."""

    velocity_m_s: float = 0.6
    acceleration_m_s2: float = 6.0
    rate_rad_s: float = 0.7
    angular_acceleration_rad_s2: float = 5.0
    position_m: float = 0.25
    angle_rad: float = float(np.radians(25.0))

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    @staticmethod
    def names() -> tuple[str, ...]:
        return tuple(f.name for f in fields(HexapodLimits))


def limit_violations(peaks: dict[str, float], limits: HexapodLimits,
                     tolerance: float = 1e-9) -> list[tuple[str, float, float]]:
    """``(name, value, limit)`` for every peak above its limit (relative tolerance)."""
    out = []
    for name, limit in limits.as_dict().items():
        value = peaks.get(name, 0.0)
        if not math.isfinite(value) or value > limit * (1.0 + tolerance):
            out.append((name, value, limit))
    return out


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Poses sampled at ``rate_hz`` from the moment the trajectory starts, ``(n, 6)``."""

    name: str
    rate_hz: float
    poses: NDArray[np.float64]

    def __post_init__(self) -> None:
        p = np.asarray(self.poses, dtype=float)
        if p.ndim != 2 or p.shape[1] != 6 or p.shape[0] < 2:
            raise DeviceError(f"trajectory {self.name!r}: poses must be (n >= 2, 6), "
                              f"got {p.shape}")
        if not np.isfinite(p).all():
            raise DeviceError(f"trajectory {self.name!r}: poses hold non-finite values")
        if not (self.rate_hz > 0 and math.isfinite(self.rate_hz)):
            raise DeviceError(f"trajectory {self.name!r}: rate {self.rate_hz!r} Hz")
        object.__setattr__(self, "poses", p)

    @property
    def duration_s(self) -> float:
        return (len(self.poses) - 1) / self.rate_hz

    @property
    def t_s(self) -> NDArray[np.float64]:
        return np.arange(len(self.poses)) / self.rate_hz

    @staticmethod
    def from_motion(motion: object, rate_hz: float) -> Trajectory:
        """Sample anything with ``name``, ``duration_s`` and ``evaluate(t) -> (pose, ...)``."""
        n = max(2, round(motion.duration_s * rate_hz) + 1)  # type: ignore[attr-defined]
        pose, *_ = motion.evaluate(np.arange(n) / rate_hz)  # type: ignore[attr-defined]
        return Trajectory(str(motion.name), float(rate_hz), pose)  # type: ignore[attr-defined]


@runtime_checkable
class Hexapod(Protocol):
    """A 6-DOF motion platform that runs uploaded trajectories and logs what it did."""

    def describe(self) -> DeviceInfo:
        """Kind ``hexapod``; ``extra['limits']`` holds the :class:`HexapodLimits` as a dict."""
        ...

    def limits(self) -> HexapodLimits: ...

    def set_pivot(self, pivot_m: tuple[float, float, float]) -> None:
        """Rotation centre in platform coordinates (m); refused while moving."""
        ...

    def upload(self, trajectory: Trajectory) -> None:
        """Check and store a trajectory; raises :class:`HexapodLimitError` naming the limit
        it would exceed, or ``DeviceError`` if it does not start at the present pose."""
        ...

    def start(self) -> None:
        """Run the uploaded trajectory from now on; refused while moving."""
        ...

    def is_moving(self) -> bool: ...

    def read_log(self) -> Block:
        """Logged samples (``HEXAPOD_LOG_CHANNELS``) since the previous call, rig clock."""
        ...

    def stop(self) -> None:
        """Stop all motion now. Safe at any time and repeatedly."""
        ...

    def close(self) -> None:
        """Stop and release the device; never leaves the platform moving."""
        ...
