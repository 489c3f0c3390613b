"""The hexapod runner: carries out a compiled calibration plan on an open IMU bench, safely.

The same loop as :mod:`bench.runner` with a hexapod in place of the ESC: on every tick of
the rig clock it reads the IMU under test, the reference IMU and the hexapod's log, checks
every logged hexapod sample against the limits, records, and checks in with the host
watchdog. Whatever ends the run (the plan's end, a limit trip, the watchdog, an operator
stop, Ctrl-C, a device error or a bug) the ``finally`` of
:class:`bench.run_loop.SafeRunLoop` stops the hexapod first, then records the exit status
and reason. Rows are the IMU's samples (its own stamps, relative to the run start); the
hexapod's body-frame truth and pose, and the reference IMU, are linearly interpolated onto
them from their faster logs, so a row is written once the hexapod log covers it. The
stamps are not corrected: the hexapod-IMU time offset is for the analysis to estimate.

A move's time base is the moment the hexapod is told to start it, after the upload: on a
real controller the upload (hundreds of GCS commands) takes wall time, and the run's
schedule falls behind the plan by that much (``schedule_lag_s`` in run.json); the rows'
``phase``/``step`` follow the realised schedule. Before an upload or a pivot change and
at the end of every move the runner waits (still reading and checking) until the hexapod
reports it has stopped; one still moving ``motion_end_timeout_s`` later ends the run.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bench.calibration_sequences import HexapodPlan, HexapodSegment
from bench.errors import RigError
from bench.recorder import RunRecorder
from bench.run_loop import SafeRunLoop
from bench.safety import Trip
from bench.watchdog import HostWatchdog, WatchdogTrip
from drivers.contracts import (
    ACCELERATION_CHANNELS,
    BODY_CHANNELS,
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
from drivers.errors import DeviceError

__all__ = ["RECORD_BASE", "GuardedHexapod", "HexapodRunOptions", "HexapodRunner",
           "HexapodSupervisor", "ImuBenchLike"]

RECORD_BASE = ("t_s", "phase", "step")


class ImuBenchLike(Protocol):
    """What the runner needs of ``drivers.factory.OpenRig`` (an IMU bench)."""

    clock: Clock
    hexapod: Hexapod
    imu: Sensor
    reference_imu: Sensor | None


@dataclass(frozen=True)
class HexapodRunOptions:
    """Loop settings: ``tick_s`` the read period (rig clock); ``realtime`` paces a simulated
    rig to the wall clock; ``stale_s``: a device silent this long ends the run."""

    tick_s: float = 0.05
    watchdog_timeout_s: float = 1.0
    realtime: bool = False
    stale_s: float = 0.5
    trajectory_rate_hz: float = 200.0
    limit_margin: float = 0.02  # logged samples may exceed a limit by this share (spline)
    motion_end_timeout_s: float = 5.0  # a motion still running this long after its end

    def __post_init__(self) -> None:
        if not 0.0 < self.tick_s <= 0.1:
            raise RigError(f"--tick {self.tick_s}: expected 0 < tick <= 0.1 s")
        if self.stale_s <= self.tick_s:
            raise RigError(f"stale_s {self.stale_s} must exceed the tick {self.tick_s}")
        if not self.motion_end_timeout_s > 0:
            raise RigError(f"motion_end_timeout_s {self.motion_end_timeout_s}: expected > 0 s")


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


class _Merger:
    """IMU rows with the hexapod's log and the reference IMU interpolated onto them."""

    def __init__(self, plan: HexapodPlan, with_reference: bool) -> None:
        self.plan = plan
        self.with_reference = with_reference
        # the realised start (s since the run start) of every timed segment begun so far
        self.starts: list[float] = []
        self.segments: list[HexapodSegment] = []
        self.imu_t = np.empty(0)
        self.imu = {c: np.empty(0) for c in IMU_CHANNELS}
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
            return self.plan.phase_at(t), self.plan.step_at(t)
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
        for c in IMU_CHANNELS:
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


class HexapodRunner(SafeRunLoop):
    """Runs one plan on one open IMU bench; use once."""

    safe_stop_label = "hexapod stop"
    rig: ImuBenchLike
    plan: HexapodPlan
    options: HexapodRunOptions

    def __init__(self, rig: ImuBenchLike, plan: HexapodPlan,
                 recorder: RunRecorder | None = None,
                 options: HexapodRunOptions | None = None,
                 on_rows: Callable[[Mapping[str, np.ndarray]], None] | None = None,
                 on_progress: Callable[[float, float, HexapodSegment], None] | None = None,
                 stop_event: threading.Event | None = None) -> None:
        super().__init__(rig, plan, recorder, options or HexapodRunOptions(), on_rows,
                         on_progress, stop_event)
        self.hexapod = GuardedHexapod(rig.hexapod)
        self.watchdog = HostWatchdog(self.hexapod, self.options.watchdog_timeout_s)  # type: ignore[arg-type]
        self.supervisor = HexapodSupervisor(plan.limits, self.options.limit_margin)
        self.merger = _Merger(plan, rig.reference_imu is not None)
        self._lag = 0.0  # how far the realised schedule runs behind the plan (s)

    # -- loop ---------------------------------------------------------------------------
    def _run_segment(self, seg: HexapodSegment) -> None:
        self._segment = seg
        self._event("step_start", seg.index, seg.label,
                    {"kind": seg.kind, "phase": seg.phase, "duration_s": seg.duration_s,
                     **({"peaks": dict(seg.peaks)} if seg.peaks else {})})
        if seg.kind == "set_pivot" and seg.pivot_m is not None:
            self._await_rest(seg)  # the controller refuses a pivot change while moving
            self.hexapod.set_pivot(seg.pivot_m)
        elif seg.kind == "move" and seg.motion is not None:
            self._await_rest(seg)  # ... and an upload
            traj = Trajectory.from_motion(seg.motion, self.options.trajectory_rate_hz)
            self.hexapod.upload(traj)
            self._catch_up(seg.t_start_s)  # the time base: the start command, after upload
            self.hexapod.start()
            self._event("motion_start", seg.index, seg.label,
                        {"plan_t_s": seg.t_start_s, "schedule_lag_s": self._lag})
        if seg.duration_s > 0:
            self.merger.begin(seg, seg.t_start_s + self._lag)
        self._tick_until(seg.t_end_s + self._lag)
        if seg.kind == "move":
            self._await_rest(seg)

    def _catch_up(self, plan_t_s: float) -> None:
        """Move the schedule's time base to now if the run is behind ``plan_t_s``."""
        late = self._now_rel() - (plan_t_s + self._lag)
        if late > 1e-6:  # not clock rounding
            self._lag += late

    def _await_rest(self, seg: HexapodSegment) -> None:
        """Keep reading (and checking) until the hexapod reports no motion; one still moving
        ``motion_end_timeout_s`` later ends the run (device error, hexapod stopped)."""
        t_wait = self._now_rel()
        while self.hexapod.is_moving():
            now = self._now_rel()
            if now - t_wait > self.options.motion_end_timeout_s:
                raise DeviceError(
                    f"hexapod still moving {now - t_wait:.2f} s after it should have stopped "
                    f"(step {seg.index} {seg.label!r}; limit motion_end_timeout_s = "
                    f"{self.options.motion_end_timeout_s:g} s)")
            self._tick_until(now + self.options.tick_s)
        if seg.kind == "move" and self._now_rel() > t_wait:
            self._catch_up(seg.t_end_s)

    def _progress_time(self, now: float) -> float:
        return now - self._lag

    def _drain(self) -> None:
        self.rig.imu.read_block()
        self.rig.hexapod.read_log()
        if self.rig.reference_imu is not None:
            self.rig.reference_imu.read_block()

    def _acquire(self) -> None:
        now = self._now_rel()
        hexlog = self._read("hexapod", self.hexapod.read_log, now)
        imu = self._read("imu", self.rig.imu.read_block, now)
        ref = (self._read("reference_imu", self.rig.reference_imu.read_block, now)
               if self.rig.reference_imu is not None else None)
        trip = self.supervisor.check(hexlog)  # every logged sample, before anything else
        rows = self.merger.push(imu, hexlog, ref)
        self._deliver(rows, trip)

    def _safe_stop(self) -> list[str]:
        return self.hexapod.safe_stop()

    def _finish_fields(self) -> dict[str, float]:
        return {"rig_t0_s": self._t0, "rows_dropped": self.merger.dropped,
                "schedule_lag_s": self._lag}
