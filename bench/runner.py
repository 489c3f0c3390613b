"""The runner: carries out a compiled plan on an open rig, safely.

One command loop on the rig clock: set the command, sleep to the next tick, read every
sensor, check the limits on every sample, record, check in with the host watchdog.
Whatever ends the run (the plan's end, a limit trip, the watchdog, an operator stop,
Ctrl-C, a device error or a bug) the ``finally`` of :class:`bench.run_loop.SafeRunLoop`
puts the ESC at idle and disarms it first, then records the exit status (``success``,
``abort`` or ``fail``) and the reason.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bench.alignment import BlockAligner
from bench.errors import RigError
from bench.recorder import BASE_COLUMNS, RunRecorder
from bench.run_loop import EPS, OperatorStop, RunResult, SafeRunLoop
from bench.safety import SafetySupervisor
from bench.sequences import EscRange, Plan, Segment
from bench.watchdog import GuardedEsc, HostWatchdog
from drivers.contracts import Block, Clock, Esc, Sensor
from drivers.errors import DeviceError

__all__ = ["OpenRigLike", "OperatorStop", "RunOptions", "RunResult", "Runner"]

_COMMAND_COLUMNS = ("throttle_us", "thrust_setpoint_n")  # filled from the command history


class OpenRigLike(Protocol):
    """What the runner needs of ``drivers.factory.OpenRig``."""

    clock: Clock
    esc: Esc
    sensors: Mapping[str, Sensor]


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


class Runner(SafeRunLoop):
    """Runs one plan on one open rig; use once."""

    safe_stop_label = "idle + disarm"
    stale_hint = "; limits cannot be checked without data"
    batches = True  # see bench.run_loop: simulated rigs run whole batches of ticks
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
        self.tare_offset_n = 0.0
        self._cmd_t = np.zeros(1)
        self._cmd_us = np.array([esc_range.idle_us])
        self._cmd_sp = np.array([math.nan])
        self._cmd_seg = np.array([-1], dtype=np.int32)
        self._tare_sum = 0.0
        self._tare_n = 0

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
        self._tick_until(seg.t_end_s, lambda now: self._command(seg.command_at(now), seg))
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
        self._cmd_seg = np.append(self._cmd_seg, np.int32(seg.index))

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
        return {r: Block(b.t_s, {**b.values, "thrust_n": b.values["thrust_n"]
                                 - self.tare_offset_n}) if "thrust_n" in b.values else b
                for r, b in blocks.items()}

    def _would_stop(self, raw: Mapping[str, Block]) -> bool:
        if any(len(b) == 0 for b in raw.values()):
            return True  # a silent device: the stale check decides, tick by tick
        latched = self.supervisor.trip
        trip = self.supervisor.check(self._tared(raw))
        self.supervisor.trip = latched
        return trip is not None

    def _loop_state(self) -> tuple[object, ...]:
        return (self._cmd_t, self._cmd_us, self._cmd_sp, self._cmd_seg, self.esc.last_us)

    def _set_loop_state(self, state: tuple[object, ...]) -> None:
        self._cmd_t, self._cmd_us, self._cmd_sp, self._cmd_seg, self.esc.last_us = state  # type: ignore[assignment]

    def _safe_stop(self) -> list[str]:
        return self.esc.safe_stop()

    def _finish_fields(self) -> dict[str, float]:
        return {"tare_offset_n": self.tare_offset_n}

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
