"""Device contracts of every bench: the small protocols each backend (real, simulated,
replayed) fills. One vocabulary for the propulsion stand and the IMU bench.

A sensor hands out timestamped blocks of samples; an actuator takes commands and
always knows how to make itself safe. Column names carry their unit
(``thrust_n``, ``current_a``, ``voltage_v``, ``rpm``, ``throttle_us``), so blocks can
go straight into a run record. Timestamps are seconds on the rig clock.

* :class:`Sensor` (load cell, power sensor, RPM sensor, IMU under test, reference IMU) and
  :class:`Esc` (the propulsion stand's actuator);
* :class:`Hexapod` (the IMU bench's actuator, Paper A): a 6-DOF motion platform. The bench
  sets the pivot point (the UAV's centre of gravity), uploads a :class:`Trajectory` of
  sampled poses, starts it, and reads back the controller's log
  (:data:`HEXAPOD_LOG_CHANNELS`): pose, velocity, acceleration and their body-frame form
  (angular rate, angular acceleration, specific force at the pivot, gravity included).
  ``stop`` must be safe at any time, repeatedly. A trajectory outside the limits is
  refused at upload with :class:`HexapodLimitError`.
* The IMU under test is a plain :class:`Sensor` with the columns :data:`IMU_CHANNELS`,
  stamped on the IMU's own clock; the reference IMU a Sensor with
  :data:`REFERENCE_IMU_CHANNELS`: attitude quaternion (scalar-first, body→navigation,
  z up) and body rates.

Poses are SI: x, y, z in m; roll, pitch, yaw in rad (Z-Y-X Euler about the pivot).
"""

from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, field, fields
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from drivers.errors import DeviceError


@dataclass(frozen=True)
class ChannelInfo:
    """One recorded column: its name (with unit suffix), unit, rate and valid range."""

    name: str
    unit: str
    rate_hz: float
    low: float = -np.inf
    high: float = np.inf


@dataclass(frozen=True)
class DeviceInfo:
    """What a device is and what it produces or accepts."""

    kind: str  # "load_cell", "power_sensor", "rpm_sensor", "esc", "hexapod", "imu", ...
    model: str
    url: str
    channels: tuple[ChannelInfo, ...] = ()
    extra: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Block:
    """Samples that arrived since the previous read: ``t_s`` and one array per channel."""

    t_s: np.ndarray
    values: dict[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @staticmethod
    def empty(names: tuple[str, ...]) -> Block:
        return Block(np.empty(0), {n: np.empty(0) for n in names})


class Clock(Protocol):
    """Rig time. Real rigs use the host's monotonic clock; the simulated rig its own."""

    def now(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


@runtime_checkable
class Sensor(Protocol):
    """A device that produces timestamped blocks (load cell, power sensor, RPM sensor, IMU)."""

    def describe(self) -> DeviceInfo: ...

    def read_block(self) -> Block:
        """Return every sample that arrived since the last call (possibly none).

        Raises ``drivers.errors.DeviceError`` when the device is gone or timed out.
        """
        ...

    def close(self) -> None: ...


@runtime_checkable
class Esc(Protocol):
    """The ESC's command input: pulse width in microseconds at a fixed frame rate."""

    def describe(self) -> DeviceInfo: ...

    def arm(self) -> None: ...

    def set_pulse_us(self, pulse_us: float) -> None:
        """Command a pulse width (clamped by the caller's limits, 1000-2000 us)."""
        ...

    def disarm(self) -> None:
        """Command idle and disarm. Must be safe to call at any time, repeatedly."""
        ...

    def close(self) -> None: ...


class Fault(enum.Enum):
    """Fault switches a simulated (or test) device can be set to, see ``drivers.sim.faults``.

    DROPOUT: samples go missing; SPIKES: single samples jump to full scale; STUCK: the
    reading freezes; TIMEOUT: reads/commands raise ``DeviceError`` while it lasts;
    DISCONNECT: the device is gone until cleared (reads/commands raise ``DeviceError``).
    """

    DROPOUT = "dropout"
    SPIKES = "spikes"
    STUCK = "stuck"
    TIMEOUT = "timeout"
    DISCONNECT = "disconnect"


class MonotonicClock:
    """Real rig time: the host's monotonic clock, zero at construction.

    ``sleep`` really waits; the simulated rig uses ``drivers.sim.clock.SimClock`` instead.
    """

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


# -- the IMU bench (Paper A) -------------------------------------------------------------
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
#: optional columns of an IMU under test that estimates its own attitude (a flight
#: controller): quaternion forward-left-up body -> east-north-up earth, scalar first
IMU_ATTITUDE_CHANNELS = ("imu_qw", "imu_qx", "imu_qy", "imu_qz")


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
