"""The runner: one module, one loop, for every bench.

:class:`PlanRunner` carries a compiled plan out on the rig clock on the safe run loop
(:class:`bench.engine.run_loop.SafeRunLoop`: whatever ends the run, its ``finally`` makes the
actuators safe first, then records the exit status and the reason). Every segment of a
plan carries the step it came from; the runner dispatches on the step's *type* to the
handlers the bench registered (``STEP_BEGIN``/``STEP_END``), never on a string kind.

A bench contributes only what is its own:

- the propulsion stand (:class:`Runner`): the ESC behind :class:`bench.engine.watchdog.GuardedEsc`,
  its steps (arm, tare, disarm; every other step commands the ESC on every tick, the
  failsafe's heartbeat), the limits of :class:`bench.engine.safety.SafetySupervisor` on every
  sample (tared thrust), rows aligned by :class:`bench.engine.alignment.BlockAligner` with the
  command history; safe state: ESC idle and disarmed.
- the IMU bench (:class:`HexapodRunner`): the hexapod behind
  :class:`bench.plan_runner.hexapod_parts.GuardedHexapod`, its steps (set pivot, move), every logged
  hexapod sample against :class:`bench.plan_runner.hexapod_parts.HexapodSupervisor`, rows merged by
  :class:`bench.plan_runner.hexapod_parts.RowMerger`; safe state: hexapod stopped.

A move's time base is the moment the hexapod is told to start it, after the upload: on a
real controller the upload (hundreds of GCS commands) takes wall time, and the run's
schedule falls behind the plan by that much (``schedule_lag_s`` in run.json); the rows'
``phase``/``step`` follow the realised schedule. Before an upload or a pivot change and
at the end of every move the runner waits (still reading and checking) until the hexapod
reports it has stopped; one still moving ``motion_end_timeout_s`` later ends the run.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np

from bench.engine.alignment import BlockAligner
from bench.engine.recorder import BASE_COLUMNS, RunRecorder
from bench.engine.run_loop import EPS, OperatorStop, RunResult, SafeRunLoop
from bench.engine.safety import SafetySupervisor
from bench.engine.watchdog import GuardedEsc, HostWatchdog
from bench.errors import RigError
from bench.plan_runner.hexapod_parts import (
    RECORD_BASE,
    GuardedHexapod,
    HexapodSupervisor,
    ImuBenchLike,
    RowMerger,
    imu_channels,
)
from bench.plan_runner.zero_tare import TARED_CHANNELS, ZeroTare
from bench.plans.calibration_sequences import HexapodSegment, Move, SetPivot
from bench.plans.sequences import Arm, Disarm, EscRange, Plan, Segment, Tare
from drivers.contracts import Block, Clock, Esc, Sensor, Trajectory
from drivers.errors import DeviceError

__all__ = ["RECORD_BASE", "HexapodRunOptions", "HexapodRunner", "ImuBenchLike", "OpenRigLike",
           "OperatorStop", "PlanRunner", "RunOptions", "RunResult", "Runner"]

_COMMAND_COLUMNS = ("throttle_us", "thrust_setpoint_n")  # filled from the command history

StepHandler = Callable[[Any, Any], None]  # (runner, segment) -> None

log = logging.getLogger(__name__)


class OpenRigLike(Protocol):
    """What the runner and its session need of ``drivers.factory.OpenRig`` (read-only)."""

    @property
    def clock(self) -> Clock: ...
    @property
    def esc(self) -> Esc: ...
    @property
    def sensors(self) -> Mapping[str, Sensor]: ...
    def close(self) -> object: ...


#: the shortest command/read period: the loop is Python on a desktop OS, which does not
#: keep a period below about 1 ms (the sensors' samples come in blocks either way); a
#: shorter tick only starves the host watchdog (``--tick 1e-9`` armed, then aborted)
MIN_TICK_S = 1e-3
#: the longest: the ESC failsafe wants a command at least this often
MAX_TICK_S = 0.1


def check_tick(tick_s: float, watchdog_timeout_s: float) -> None:
    """Refuse a loop period outside [MIN_TICK_S, MAX_TICK_S] or longer than the host
    watchdog's timeout (the loop checks in once per tick: it would trip every time)."""
    if not MIN_TICK_S <= tick_s <= MAX_TICK_S:
        raise RigError(f"--tick {tick_s:g}: expected {MIN_TICK_S:g} <= tick <= {MAX_TICK_S:g} s "
                       "(the loop must keep its period, react to limits and feed the ESC "
                       "failsafe)")
    if tick_s > watchdog_timeout_s:
        raise RigError(f"--tick {tick_s:g}: expected at most the watchdog timeout "
                       f"{watchdog_timeout_s:g} s")


@dataclass(frozen=True)
class RunOptions:
    """Loop settings. ``tick_s`` is the command/read period on the rig clock; limits are
    still checked on every sample of every block. ``realtime`` paces a simulated rig to
    the wall clock (for watching it live)."""

    tick_s: float = 0.02
    watchdog_timeout_s: float = 0.5
    realtime: bool = False
    base_sensor: str = "load_cell"
    stale_s: float = 0.25  # a sensor silent this long (rig time) ends the run: limits blind
    accept_uncalibrated: bool = False  # run although the cells' calibration failed

    def __post_init__(self) -> None:
        check_tick(self.tick_s, self.watchdog_timeout_s)
        if self.stale_s <= self.tick_s:
            raise RigError(f"stale_s {self.stale_s} must exceed the tick {self.tick_s}")


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
        check_tick(self.tick_s, self.watchdog_timeout_s)
        if self.stale_s <= self.tick_s:
            raise RigError(f"stale_s {self.stale_s} must exceed the tick {self.tick_s}")
        if not self.motion_end_timeout_s > 0:
            raise RigError(f"motion_end_timeout_s {self.motion_end_timeout_s}: expected > 0 s")


class PlanRunner(SafeRunLoop):
    """Runs one plan; use once. A segment runs as: ``step_start`` event, the handler
    registered for its step's type in ``STEP_BEGIN`` (else :meth:`_begin_other`), the
    ticks up to its end (:meth:`_hold`), the handler in ``STEP_END``. A bench subclass
    registers its steps' handlers and implements the loop's device hooks."""

    STEP_BEGIN: ClassVar[Mapping[type, StepHandler]] = {}
    STEP_END: ClassVar[Mapping[type, StepHandler]] = {}

    def _run_segment(self, seg: Any) -> None:
        self._segment = seg
        log.debug("segment %d %s (%s, %.3f s) at %.3f s of the run", seg.index, seg.label,
                 seg.kind, seg.duration_s, self._now_rel())
        self._event("step_start", seg.index, seg.label, self._step_detail(seg))
        begin = self.STEP_BEGIN.get(type(seg.step))
        if begin is None:
            self._begin_other(seg)
        else:
            begin(self, seg)
        self._hold(seg)
        end = self.STEP_END.get(type(seg.step))
        if end is not None:
            end(self, seg)

    def _step_detail(self, seg: Any) -> dict[str, Any]:
        """The ``step_start`` event's detail."""
        return {"kind": seg.kind, "duration_s": seg.duration_s}

    def _begin_other(self, seg: Any) -> None:
        """What a step without a registered begin handler does first (nothing)."""

    def _hold(self, seg: Any) -> None:
        """Read and check on every tick until the segment's end."""
        self._tick_until(seg.t_end_s)


class Runner(PlanRunner):
    """The propulsion stand: runs one plan on one open rig (ESC + sensors); use once."""

    safe_stop_label = "idle + disarm"
    stale_hint = "; limits cannot be checked without data"
    batches = True  # see bench.engine.run_loop: simulated rigs run whole batches of ticks
    rig: OpenRigLike
    plan: Plan
    options: RunOptions

    def __init__(
        self,
        rig: OpenRigLike,
        plan: Plan,
        esc_range: EscRange,
        limits: Mapping[str, float],
        recorder: RunRecorder | None = None,
        options: RunOptions | None = None,
        on_rows: Callable[[Mapping[str, np.ndarray]], None] | None = None,
        on_progress: Callable[[float, float, Segment], None] | None = None,
        stop_event: threading.Event | None = None,
    ) -> None:
        super().__init__(rig, plan, recorder, options or RunOptions(), on_rows, on_progress,
                         stop_event)
        self.esc_range = esc_range
        self.supervisor = SafetySupervisor(limits)
        self.esc = GuardedEsc(rig.esc, esc_range.min_us, esc_range.max_us, esc_range.idle_us)
        self.watchdog = HostWatchdog(self.esc, self.options.watchdog_timeout_s)
        channels = {role: tuple(c.name for c in s.describe().channels)
                    for role, s in rig.sensors.items()}
        self.aligner = BlockAligner(channels, self.options.base_sensor)
        self.tare = ZeroTare()
        self._cmd_t: np.ndarray = np.zeros(1)
        self._cmd_us: np.ndarray = np.array([esc_range.idle_us])
        self._cmd_sp: np.ndarray = np.array([math.nan])
        self._cmd_seg: np.ndarray = np.array([-1], dtype=np.int32)

    # -- the ESC's steps ---------------------------------------------------------------

    def _step_detail(self, seg: Segment) -> dict[str, Any]:
        return {"kind": seg.kind, "us_start": seg.us_start, "us_end": seg.us_end,
                "setpoint_n": seg.setpoint_n, "duration_s": seg.duration_s}

    def _begin_other(self, seg: Segment) -> None:
        # a zero-length segment (checkpoint) owns no rows: on a real-time rig a row
        # could land between its log entry and the next segment's command
        self._command(seg.command_at(seg.t_start_s), seg, force=seg.duration_s > 0)

    def _begin_arm(self, seg: Segment) -> None:
        self.esc.arm()
        self._begin_other(seg)

    @property
    def tare_offset_n(self) -> float:
        """The thrust channel's zero, subtracted from every thrust sample after the tare."""
        return self.tare.offset("thrust_n")

    def _begin_tare(self, seg: Segment) -> None:
        self.tare.begin()
        self._begin_other(seg)

    def _begin_disarm(self, seg: Segment) -> None:
        self.esc.safe_stop()
        self._log_command(seg.us_end, seg)

    def _end_tare(self, seg: Segment) -> None:
        zeros = self.tare.end()
        if "thrust_n" not in zeros:
            raise DeviceError("tare: the load cell gave no samples during the tare window")
        self._event("tare", seg.index, "tare",
                    {"offset_n": self.tare_offset_n, "samples": zeros["thrust_n"]["samples"],
                     "channels": zeros})

    STEP_BEGIN: ClassVar[Mapping[type, StepHandler]] = {
        Arm: _begin_arm, Tare: _begin_tare, Disarm: _begin_disarm}
    STEP_END: ClassVar[Mapping[type, StepHandler]] = {Tare: _end_tare}

    def _hold(self, seg: Segment) -> None:
        self._tick_until(seg.t_end_s, lambda now: self._command(seg.command_at(now), seg))

    def _command(self, us: float, seg: Segment, force: bool = False) -> None:
        # Sent on every tick, changed or not: ESCs with a command timeout (failsafe) need
        # the heartbeat. The history used for the samples table only logs changes.
        changed = force or us != self.esc.last_us
        self.esc.set_pulse_us(us)
        if changed:
            self._log_command(self.esc.last_us, seg)

    def _log_command(self, us: float, seg: Segment) -> None:
        self._cmd_t = np.append(self._cmd_t, self._now_rel())
        self._cmd_us = np.append(self._cmd_us, us)
        self._cmd_sp = np.append(self._cmd_sp, seg.setpoint_n)
        self._cmd_seg = np.append(self._cmd_seg, np.int32(seg.index))

    # -- the loop's device hooks -------------------------------------------------------

    def _drain(self) -> None:
        for sensor in self.rig.sensors.values():
            sensor.read_block()

    def _expected_rates(self) -> dict[str, float]:
        out = {}
        for role, sensor in self.rig.sensors.items():
            rates = [c.rate_hz for c in sensor.describe().channels if c.rate_hz > 0]
            if rates:
                out[role] = max(rates)
        return out

    def _acquire(self) -> None:
        self._process(self._read_devices())

    def _read_devices(self) -> dict[str, Block]:
        return {role: sensor.read_block() for role, sensor in self.rig.sensors.items()}

    def _process(self, raw: Mapping[str, Block]) -> None:
        now = self._now_rel()
        blocks = {role: self._stamp(role, b, now) for role, b in raw.items()}
        rows = self.aligner.push(blocks)
        n = len(rows["t_s"])
        if n:
            self._complete_rows(rows, self._read_times(n, now))
        # Limits on every sample of every sensor (tared thrust), before anything else.
        trip = self.supervisor.check(self._tared(blocks))
        self._deliver(rows, trip)

    def _tared(self, blocks: Mapping[str, Block]) -> dict[str, Block]:
        return {r: Block(b.t_s, self.tare.apply(b.values)) for r, b in blocks.items()}

    def _would_stop(self, raw: Mapping[str, Block]) -> bool:
        if any(len(b) == 0 for b in raw.values()):
            return True  # a silent device: the stale check decides, tick by tick
        latched = self.supervisor.trip
        trip = self.supervisor.check(self._tared(raw))
        self.supervisor.trip = latched
        return trip is not None

    def _loop_state(self) -> tuple[object, ...]:
        return (self._cmd_t, self._cmd_us, self._cmd_sp, self._cmd_seg, self.esc.last_us,
                self.tare.state())

    def _set_loop_state(self, state: tuple[object, ...]) -> None:
        *cmd, tare = state
        self._cmd_t, self._cmd_us, self._cmd_sp, self._cmd_seg, self.esc.last_us = cmd  # type: ignore[assignment]
        self.tare.set_state(tare)  # type: ignore[arg-type]

    def _safe_stop(self) -> list[str]:
        return self.esc.safe_stop()

    def _finish_fields(self) -> dict[str, Any]:
        return {"tare": self.tare.record()}  # the thrust's offset is tare.thrust_n.offset

    def _complete_rows(self, rows: dict[str, np.ndarray], read_at: np.ndarray | float) -> None:
        t = rows["t_s"]
        for col in BASE_COLUMNS:  # a rig without some sensor still gives every column
            if col not in rows and col not in _COMMAND_COLUMNS:
                rows[col] = np.full(t.shape, np.nan)
        # the command in force at each sample among those sent before its read
        idx = np.searchsorted(self._cmd_t, np.minimum(t, read_at - EPS), side="right") - 1
        np.maximum(idx, 0, out=idx)
        rows["throttle_us"] = self._cmd_us[idx]
        rows["thrust_setpoint_n"] = self._cmd_sp[idx]
        rows["step"] = self._cmd_seg[idx]  # int32 history
        seg = self._segment
        if seg is not None and isinstance(seg.step, Tare):
            self.tare.add(rows)  # raw: the offsets are in run.json and the events
        rows.update(self.tare.apply({ch: rows[ch] for ch in TARED_CHANNELS if ch in rows}))
        # keep only the command history still needed for later rows
        keep = max(int(idx[-1]), 0) if len(idx) else 0
        if keep > 0:
            self._cmd_t, self._cmd_us = self._cmd_t[keep:], self._cmd_us[keep:]
            self._cmd_sp, self._cmd_seg = self._cmd_sp[keep:], self._cmd_seg[keep:]


class HexapodRunner(PlanRunner):
    """The IMU bench: runs one plan on one open bench (hexapod + IMUs); use once."""

    safe_stop_label = "hexapod stop"
    rig: ImuBenchLike
    plan: Plan
    options: HexapodRunOptions

    def __init__(self, rig: ImuBenchLike, plan: Plan,
                 recorder: RunRecorder | None = None,
                 options: HexapodRunOptions | None = None,
                 on_rows: Callable[[Mapping[str, np.ndarray]], None] | None = None,
                 on_progress: Callable[[float, float, HexapodSegment], None] | None = None,
                 stop_event: threading.Event | None = None) -> None:
        super().__init__(rig, plan, recorder, options or HexapodRunOptions(), on_rows,
                         on_progress, stop_event)
        self.hexapod = GuardedHexapod(rig.hexapod)
        self.watchdog = HostWatchdog(self.hexapod, self.options.watchdog_timeout_s,  # type: ignore[arg-type]
                                     stops="hexapod stopped")
        self.supervisor = HexapodSupervisor(plan.limits, self.options.limit_margin)
        self.merger = RowMerger(plan, rig.reference_imu is not None, imu_channels(rig.imu))
        self._lag = 0.0  # how far the realised schedule runs behind the plan (s)

    # -- the hexapod's steps -----------------------------------------------------------

    def _step_detail(self, seg: HexapodSegment) -> dict[str, Any]:
        return {"kind": seg.kind, "phase": seg.phase, "duration_s": seg.duration_s,
                **({"peaks": dict(seg.peaks)} if seg.peaks else {})}

    def _begin_pivot(self, seg: HexapodSegment) -> None:
        if seg.pivot_m is not None:
            self._await_rest(seg)  # the controller refuses a pivot change while moving
            self.hexapod.set_pivot(seg.pivot_m)

    def _begin_move(self, seg: HexapodSegment) -> None:
        if seg.motion is not None:
            self._await_rest(seg)  # ... and an upload
            traj = Trajectory.from_motion(seg.motion, self.options.trajectory_rate_hz)
            with self.watchdog.at_rest():  # a real controller takes seconds for a long one
                self.hexapod.upload(traj)
            self._catch_up(seg.t_start_s)  # the time base: the start command, after upload
            self.hexapod.start()
            self._event("motion_start", seg.index, seg.label,
                        {"plan_t_s": seg.t_start_s, "schedule_lag_s": self._lag})

    def _end_move(self, seg: HexapodSegment) -> None:
        self._await_rest(seg)

    STEP_BEGIN: ClassVar[Mapping[type, StepHandler]] = {SetPivot: _begin_pivot,
                                                          Move: _begin_move}
    STEP_END: ClassVar[Mapping[type, StepHandler]] = {Move: _end_move}

    def _hold(self, seg: HexapodSegment) -> None:
        if seg.duration_s > 0:
            self.merger.begin(seg, seg.t_start_s + self._lag)
        self._tick_until(seg.t_end_s + self._lag)

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
        if isinstance(seg.step, Move) and self._now_rel() > t_wait:
            self._catch_up(seg.t_end_s)

    # -- the loop's device hooks -------------------------------------------------------

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
