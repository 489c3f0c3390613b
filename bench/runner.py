"""The runner: carries out a compiled plan on an open rig, safely.

One command loop on the rig clock: set the command, sleep to the next tick, read every
sensor, check the limits on every sample, record, check in with the host watchdog.
Whatever ends the run (the plan's end, a limit trip, the watchdog, an operator stop,
Ctrl-C, a device error or a bug) the ``finally`` puts the ESC at idle and disarms it
first, then records the exit status (``success``, ``abort`` or ``fail``) and the reason.
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from bench.alignment import BlockAligner
from bench.errors import RigError
from bench.recorder import BASE_COLUMNS, RunRecorder
from bench.safety import LimitTrip, SafetySupervisor, Trip
from bench.sequences import EscRange, Plan, Segment
from bench.watchdog import GuardedEsc, HostWatchdog, WatchdogTrip
from drivers.contracts import Block, Clock, Esc, Sensor
from drivers.errors import DeviceError

__all__ = ["OpenRigLike", "OperatorStop", "RunOptions", "RunResult", "Runner"]


class OpenRigLike(Protocol):
    """What the runner needs of ``drivers.factory.OpenRig``."""

    clock: Clock
    esc: Esc
    sensors: Mapping[str, Sensor]


class OperatorStop(Exception):
    """The operator asked to stop (stop button, closed live window)."""


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

    def __post_init__(self) -> None:
        if not 0.0 < self.tick_s <= 0.1:
            raise RigError(f"--tick {self.tick_s}: expected 0 < tick <= 0.1 s (the loop "
                           "must react to limits and feed the ESC failsafe)")
        if self.stale_s <= self.tick_s:
            raise RigError(f"stale_s {self.stale_s} must exceed the tick {self.tick_s}")


@dataclass
class RunResult:
    status: str  # success | abort | fail
    reason: str
    trip: Trip | None = None
    t_end_s: float = 0.0
    rows: int = 0
    safe_stop_errors: list[str] = field(default_factory=list)
    error: BaseException | None = None


_EPS = 1e-9


class Runner:
    """Runs one plan on one open rig; use once."""

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
        self.rig = rig
        self.plan = plan
        self.esc_range = esc_range
        self.options = options or RunOptions()
        self.supervisor = SafetySupervisor(limits)
        self.recorder = recorder
        self.on_rows = on_rows
        self.on_progress = on_progress
        self.stop_event = stop_event or threading.Event()
        self.esc = GuardedEsc(rig.esc, esc_range.min_us, esc_range.max_us, esc_range.idle_us)
        self.watchdog = HostWatchdog(self.esc, self.options.watchdog_timeout_s)
        channels = {role: tuple(c.name for c in s.describe().channels)
                    for role, s in rig.sensors.items()}
        self.aligner = BlockAligner(channels, self.options.base_sensor)
        self.tare_offset_n = 0.0
        self.result: RunResult | None = None
        self._t0 = 0.0
        self._wall0 = 0.0
        self._cmd_t = np.zeros(1)
        self._cmd_us = np.array([esc_range.idle_us])
        self._cmd_sp = np.array([math.nan])
        self._cmd_seg = np.array([-1])
        self._tare_sum = 0.0
        self._tare_n = 0
        self._segment: Segment | None = None
        self._heard: dict[str, float] = {}
        self.rows = 0

    # -- public -------------------------------------------------------------------------

    def run(self) -> RunResult:
        """Carry out the plan. Trips and operator stops return a result with status abort;
        device errors, Ctrl-C and bugs are re-raised after the safe stop and the record."""
        status, reason, trip = "fail", "run did not start", None
        pending: BaseException | None = None
        clock = self.rig.clock
        try:
            self._drain()
            self._t0 = clock.now()
            self._wall0 = time.monotonic()
            self._event("run_start", detail={"rig_t0_s": self._t0,
                                             "plan_duration_s": self.plan.duration_s})
            self.watchdog.start()
            for seg in self.plan.segments:
                self._run_segment(seg)
            status, reason = "success", "sequence complete"
        except LimitTrip as exc:
            trip = exc.trip
            status, reason = "abort", trip.message
        except WatchdogTrip as exc:
            status, reason = "abort", str(exc)
        except OperatorStop as exc:
            status, reason = "abort", f"stopped by operator: {exc}" if str(exc) else \
                "stopped by operator"
        except KeyboardInterrupt as exc:
            status, reason, pending = "abort", "interrupted by operator (Ctrl-C or SIGTERM)", exc
        except DeviceError as exc:
            status, reason, pending = "fail", f"device error: {exc}", exc
        except BaseException as exc:
            status, reason, pending = "fail", f"{type(exc).__name__}: {exc}", exc
        finally:
            # Safety first: idle + disarm before anything else can fail. A second Ctrl-C
            # (or SIGTERM) is held until the ESC is safe and the record is written.
            with _signals_deferred():
                errors = self.esc.safe_stop()
                self.watchdog.stop()
                if self.watchdog.tripped and status == "success":
                    status, reason = "abort", self.watchdog.reason
                errors += self.watchdog.errors
                self.result = RunResult(status, reason, trip, self._now_rel(), self.rows,
                                        errors, pending)
                self._finish_record(trip, errors)
        if pending is not None:
            raise pending
        return self.result

    def request_stop(self) -> None:
        self.stop_event.set()

    # -- loop ---------------------------------------------------------------------------

    def _run_segment(self, seg: Segment) -> None:
        self._segment = seg
        self._event("step_start", seg.index, seg.label,
                    {"kind": seg.kind, "us_start": seg.us_start, "us_end": seg.us_end,
                     "setpoint_n": seg.setpoint_n, "duration_s": seg.duration_s})
        if seg.kind == "arm":
            self.esc.arm()
        if seg.kind == "tare":
            self._tare_sum, self._tare_n = 0.0, 0
        if seg.kind == "disarm":
            self.esc.safe_stop()
            self._log_command(seg.us_end, seg)
        else:
            # a zero-length segment (checkpoint) owns no rows: on a real-time rig a row
            # could land between its log entry and the next segment's command
            self._command(seg.command_at(seg.t_start_s), seg, force=seg.duration_s > 0)
        end = seg.t_end_s
        tick = self.options.tick_s
        while True:
            now = self._now_rel()
            if now >= end - _EPS:
                break
            deadline = min((math.floor((now + _EPS) / tick) + 1) * tick, end)
            self._command(seg.command_at(now), seg)
            self.rig.clock.sleep(deadline - now)
            self._acquire()
        if seg.kind == "tare":
            if self._tare_n == 0:
                raise DeviceError("tare: the load cell gave no samples during the tare window")
            self.tare_offset_n = self._tare_sum / self._tare_n
            self._event("tare", seg.index, "tare",
                        {"offset_n": self.tare_offset_n, "samples": self._tare_n})

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
        self._cmd_seg = np.append(self._cmd_seg, seg.index)

    def _drain(self) -> None:
        for sensor in self.rig.sensors.values():
            sensor.read_block()

    def _acquire(self) -> None:
        blocks: dict[str, Block] = {}
        now = self._now_rel()
        for role, sensor in self.rig.sensors.items():
            b = sensor.read_block()
            blocks[role] = Block(b.t_s - self._t0, b.values)
            if len(b):
                self._heard[role] = now
            elif now - self._heard.get(role, 0.0) > self.options.stale_s:
                raise DeviceError(f"{role}: no samples for {now - self._heard.get(role, 0.0):.2f}"
                                  f" s (limit {self.options.stale_s:g} s); limits cannot be "
                                  "checked without data")
        rows = self.aligner.push(blocks)
        n = len(rows["t_s"])
        if n:
            self._complete_rows(rows)
        # Limits on every sample of every sensor (tared thrust), before anything else.
        checked = {r: Block(b.t_s, {**b.values, "thrust_n": b.values["thrust_n"]
                                    - self.tare_offset_n}) if "thrust_n" in b.values else b
                   for r, b in blocks.items()}
        trip = self.supervisor.check(checked)
        if n:
            if self.recorder is not None:
                self.recorder.append(rows)
            if self.on_rows is not None:
                self.on_rows(rows)
            self.rows += n
        if trip is not None:
            self._event("trip", self._segment.index if self._segment else None, trip.limit,
                        trip.to_dict())
            raise LimitTrip(trip)
        self.watchdog.kick()
        if self.stop_event.is_set():
            self._event("operator_stop", label="stop requested")
            raise OperatorStop("stop requested")
        now = self._now_rel()
        if self.options.realtime:
            ahead = (self._wall0 + now) - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
        if self.on_progress is not None and self._segment is not None:
            self.on_progress(now, self.plan.duration_s, self._segment)

    def _complete_rows(self, rows: dict[str, np.ndarray]) -> None:
        t = rows["t_s"]
        for col in BASE_COLUMNS:  # a rig without some sensor still gives every column
            if col not in rows:
                rows[col] = np.full(t.shape, np.nan)
        idx = np.searchsorted(self._cmd_t, t, side="right") - 1
        idx = np.maximum(idx, 0)
        rows["throttle_us"] = self._cmd_us[idx]
        rows["thrust_setpoint_n"] = self._cmd_sp[idx]
        rows["step"] = self._cmd_seg[idx].astype(np.int32)
        if "thrust_n" in rows:
            raw = rows["thrust_n"]  # the tare offset is in run.json and the events
            rows["thrust_n"] = raw - self.tare_offset_n
            seg = self._segment
            if seg is not None and seg.kind == "tare":
                self._tare_sum += float(np.nansum(raw))
                self._tare_n += int(np.count_nonzero(~np.isnan(raw)))
        # keep only the command history still needed for later rows
        keep = max(int(idx[-1]), 0) if len(idx) else 0
        if keep > 0:
            self._cmd_t, self._cmd_us = self._cmd_t[keep:], self._cmd_us[keep:]
            self._cmd_sp, self._cmd_seg = self._cmd_sp[keep:], self._cmd_seg[keep:]

    # -- record -------------------------------------------------------------------------

    def _now_rel(self) -> float:
        return self.rig.clock.now() - self._t0

    def _event(self, kind: str, step: int | None = None, label: str = "",
               detail: Mapping[str, Any] | None = None) -> None:
        if self.recorder is not None:
            self.recorder.event(self._now_rel(), kind, step, label, detail)

    def _finish_record(self, trip: Trip | None, errors: list[str]) -> None:
        res = self.result
        assert res is not None
        if self.recorder is None:
            return
        try:
            self._event("safe_stop", label="idle + disarm",
                        detail={"errors": errors} if errors else None)
            self._event("run_end", label=res.status, detail={"reason": res.reason})
        finally:
            self.recorder.finish(
                res.status, res.reason,
                trip=trip.to_dict() if trip else None,
                tare_offset_n=self.tare_offset_n,
                safe_stop_errors=errors,
                duration_s=res.t_end_s,
            )


@contextlib.contextmanager
def _signals_deferred():
    """Hold SIGINT/SIGTERM while the ESC is made safe (main thread only), then re-deliver."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda num, _frame: got.append(num))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for num in got:
            signal.raise_signal(num)
