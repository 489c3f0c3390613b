"""What the IMU bench contributes to the one runner (:mod:`bench.plan_runner.runner`): its actuator
guard, its limit check and its row merging.

- :class:`GuardedHexapod`: the hexapod's commands, shared by the runner and the host
  watchdog under one lock; a watchdog kill latches and stops the platform.
- :class:`HexapodSupervisor`: every logged hexapod sample against the effective limits
  (a small margin for the controller's spline), NaN counting as blind.
- :class:`RowMerger`: rows are the IMU's samples (its own stamps, relative to the run
  start); the hexapod's body-frame truth and pose, and the reference IMU, are linearly
  interpolated onto them from their faster logs, so a row is written once the hexapod
  log covers it. The stamps are not corrected: the hexapod-IMU time offset is for the
  analysis to estimate.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Protocol

import numpy as np

from bench.engine.safety import Trip
from bench.engine.watchdog import WatchdogTrip
from bench.plans.calibration_sequences import HexapodSegment, phase_at, step_at
from bench.plans.sequences import Plan
from drivers.contracts import (
    ACCELERATION_CHANNELS,
    BODY_CHANNELS,
    IMU_ATTITUDE_CHANNELS,
    IMU_CHANNELS,
    POSE_CHANNELS,
    REFERENCE_IMU_CHANNELS,
    VELOCITY_CHANNELS,
    Block,
    Clock,
    Hexapod,
    HexapodLimits,
    Sensor,
    Trajectory,
)

__all__ = ["RECORD_BASE", "GuardedHexapod", "HexapodSupervisor", "ImuBenchLike", "RowMerger",
           "imu_channels"]

RECORD_BASE = ("t_s", "phase", "step")


class ImuBenchLike(Protocol):
    """What the runner needs of ``drivers.factory.OpenRig`` (an IMU bench)."""

    clock: Clock
    hexapod: Hexapod
    imu: Sensor
    reference_imu: Sensor | None


def imu_channels(imu: Sensor) -> tuple[str, ...]:
    """The IMU's recorded columns: ``IMU_CHANNELS``, and its own attitude if it gives it."""
    names = {c.name for c in imu.describe().channels}
    extra = IMU_ATTITUDE_CHANNELS if set(IMU_ATTITUDE_CHANNELS) <= names else ()
    return (*IMU_CHANNELS, *extra)


class GuardedHexapod:
    """Hexapod commands shared by the runner and the watchdog; a kill latches."""

    def __init__(self, hexapod: Hexapod) -> None:
        self.hexapod = hexapod
        self._lock = threading.Lock()
        self.killed_reason: str | None = None

    def _guarded(self, fn: Callable[[], None]) -> None:
        with self._lock:
            if self.killed_reason is not None:
                raise WatchdogTrip(self.killed_reason)
            fn()

    def set_pivot(self, pivot_m: tuple[float, float, float]) -> None:
        self._guarded(lambda: self.hexapod.set_pivot(pivot_m))

    def upload(self, trajectory: Trajectory) -> None:
        self._guarded(lambda: self.hexapod.upload(trajectory))

    def start(self) -> None:
        self._guarded(self.hexapod.start)

    def is_moving(self) -> bool:
        with self._lock:
            if self.killed_reason is not None:
                raise WatchdogTrip(self.killed_reason)
            return bool(self.hexapod.is_moving())

    def read_log(self) -> Block:
        """The log read holds the lock too (one conversation with the controller at a time);
        a kill waits at most 0.1 s for it, then stops anyway."""
        with self._lock:
            return self.hexapod.read_log()

    def safe_stop(self, lock_timeout_s: float = -1) -> list[str]:
        """Stop the hexapod (even if a command holds the lock too long); returns errors."""
        locked = self._lock.acquire(timeout=lock_timeout_s)
        try:
            self.hexapod.stop()
            return []
        except Exception as exc:  # the safe stop reports, never raises
            return [f"{type(exc).__name__}: {exc}"]
        finally:
            if locked:
                self._lock.release()

    def kill(self, reason: str) -> list[str]:
        self.killed_reason = reason
        return self.safe_stop(lock_timeout_s=0.1)


class HexapodSupervisor:
    """Checks every logged hexapod sample against the effective limits."""

    _CHANNELS = (
        ("position_m", POSE_CHANNELS[:3]), ("angle_rad", POSE_CHANNELS[3:]),
        ("velocity_m_s", VELOCITY_CHANNELS[:3]), ("acceleration_m_s2", ACCELERATION_CHANNELS[:3]),
        ("rate_rad_s", BODY_CHANNELS[:3]), ("angular_acceleration_rad_s2", BODY_CHANNELS[3:6]),
    )

    def __init__(self, limits: HexapodLimits, margin: float = 0.02) -> None:
        self.limits = limits.as_dict()
        self.margin = margin
        self.trip: Trip | None = None

    def check(self, block: Block) -> Trip | None:
        if len(block) == 0:
            return None
        best: Trip | None = None
        for name, channels in self._CHANNELS:
            limit = self.limits[name] * (1.0 + self.margin)
            for ch in channels:
                v = np.asarray(block.values[ch], dtype=float)
                bad = ~(np.abs(v) <= limit)  # NaN counts as a violation: blind
                if not bad.any():
                    continue
                i = int(np.argmax(bad))
                t = float(block.t_s[i])
                if best is None or t < best.t_s:
                    sample = {"t_s": t, **{c: float(block.values[c][i]) for c in block.values}}
                    best = Trip(name, ch, "hexapod", t, float(v[i]), self.limits[name], sample)
        if best is not None and self.trip is None:
            self.trip = best
        return best


class RowMerger:
    """IMU rows with the hexapod's log and the reference IMU interpolated onto them."""

    def __init__(self, plan: Plan, with_reference: bool,
                 imu_channels: tuple[str, ...] = IMU_CHANNELS) -> None:
        self.plan = plan
        self.with_reference = with_reference
        self.imu_channels = imu_channels  # IMU_CHANNELS and any the IMU adds (its attitude)
        # the realised start (s since the run start) of every timed segment begun so far
        self.starts: list[float] = []
        self.segments: list[HexapodSegment] = []
        self.imu_t = np.empty(0)
        self.imu = {c: np.empty(0) for c in imu_channels}
        self.hex_cols = (*BODY_CHANNELS, *POSE_CHANNELS)
        self.hex_t = np.empty(0)
        self.hex = {c: np.empty(0) for c in self.hex_cols}
        self.ref_t = np.empty(0)
        self.ref = {c: np.empty(0) for c in REFERENCE_IMU_CHANNELS}
        self.dropped = 0

    def begin(self, seg: HexapodSegment, t_start_s: float) -> None:
        """``seg`` (one that takes time) is in force from ``t_start_s`` on."""
        self.starts.append(t_start_s)
        self.segments.append(seg)

    def _labels(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Phase label and step index of the segment in force at each time."""
        if not self.segments:
            return phase_at(self.plan, t), step_at(self.plan, t)
        i = np.clip(np.searchsorted(np.asarray(self.starts), t, side="right") - 1, 0,
                    len(self.segments) - 1)
        return (np.array([s.phase for s in self.segments], dtype=object)[i],
                np.array([s.index for s in self.segments], dtype=np.int32)[i])

    @staticmethod
    def _add(t: np.ndarray, cols: dict[str, np.ndarray], block: Block
             ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        if len(block) == 0:
            return t, cols
        return (np.concatenate([t, block.t_s]),
                {c: np.concatenate([v, np.asarray(block.values[c], float)])
                 for c, v in cols.items()})

    def push(self, imu: Block, hexlog: Block, ref: Block | None) -> dict[str, np.ndarray]:
        self.imu_t, self.imu = self._add(self.imu_t, self.imu, imu)
        self.hex_t, self.hex = self._add(self.hex_t, self.hex, hexlog)
        if ref is not None:
            self.ref_t, self.ref = self._add(self.ref_t, self.ref, ref)
        return self._emit()

    def _emit(self) -> dict[str, np.ndarray]:
        if self.hex_t.size < 2 or self.imu_t.size == 0:
            return {}
        early = self.imu_t < self.hex_t[0]  # before the log began: cannot be interpolated
        ready = (self.imu_t <= self.hex_t[-1]) & ~early
        self.dropped += int(early.sum())
        n_done = int(np.count_nonzero(early | ready))
        if not ready.any():
            self._consume(n_done)
            return {}
        t = self.imu_t[ready]
        phase, step = self._labels(t)
        rows: dict[str, np.ndarray] = {"t_s": t, "phase": phase, "step": step}
        for c in self.hex_cols:
            rows[c] = np.interp(t, self.hex_t, self.hex[c])
        for c in self.imu_channels:
            rows[c] = self.imu[c][ready]
        if self.with_reference:
            for c in REFERENCE_IMU_CHANNELS:
                rows[c] = (np.interp(t, self.ref_t, self.ref[c], left=np.nan, right=np.nan)
                           if self.ref_t.size >= 2 else np.full(t.shape, np.nan))
        self._consume(n_done)
        return rows

    def _consume(self, n: int) -> None:
        self.imu_t = self.imu_t[n:]
        self.imu = {c: v[n:] for c, v in self.imu.items()}
        # keep the log from just before the oldest pending IMU sample (or the last two)
        t_keep = self.imu_t[0] if self.imu_t.size else self.hex_t[-1]
        for attr_t, attr in (("hex_t", "hex"), ("ref_t", "ref")):
            tt = getattr(self, attr_t)
            if tt.size < 3:
                continue
            k = max(0, min(int(np.searchsorted(tt, t_keep)) - 2, tt.size - 2))
            setattr(self, attr_t, tt[k:])
            setattr(self, attr, {c: v[k:] for c, v in getattr(self, attr).items()})
