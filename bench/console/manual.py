"""Manual control as a run mode: a plan step whose command comes from the console.

A manual session is an ordinary sequence (arm, tare, a long hold, disarm) run by
:class:`ConsoleRunner`, a :class:`bench.plan_runner.runner.Runner` that, during the hold marked
manual, commands each tick the operator's throttle target moved towards by at most the rate limit.
Everything else is the Runner's: the ESC range clamp and the watchdog (GuardedEsc), limits
checked on every sample, the safe stop in a ``finally``, the record. The runner also asks
``guard`` every tick whether the console still lives, and its limits can be tightened
during the run (never loosened: :func:`bench.engine.safety.effective_limits`).
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from bench.engine.run_loop import EPS, OperatorStop
from bench.engine.safety import SafetySupervisor, Trip, effective_limits
from bench.plan_runner.runner import Runner
from bench.plans.sequences import Arm, Checkpoint, Disarm, EscRange, Hold, Segment, Sequence, Tare
from drivers.errors import DeviceError

__all__ = [
    "DEFAULT_RATE_US_S",
    "MANUAL_MAX_S",
    "ConsoleLost",
    "ConsoleRunner",
    "Setpoint",
    "manual_sequence",
]

DEFAULT_RATE_US_S = 400.0  # full 1000-2000 us range in 2.5 s: no throttle step by hand
MANUAL_MAX_S = 1800.0  # a forgotten session ends by itself (idle, disarmed) after 30 min
MANUAL_LABEL = "manual control"
SPIN_DOWN_S = 0.5  # recorded after a stop, ESC already idle and disarmed


class ConsoleLost(OperatorStop):
    """The console window was closed, crashed or froze during a run."""

    def reason(self) -> str:
        return f"stopped: {self}; ESC idle and disarmed"


def manual_sequence(max_s: float = MANUAL_MAX_S, rate_us_s: float = DEFAULT_RATE_US_S
                    ) -> tuple[Sequence, int]:
    """The manual session and the index of its manual segment (arm, tare, checkpoint: 3)."""
    seq = Sequence(
        name="manual",
        steps=(Arm(0.5), Tare(0.5), Checkpoint(MANUAL_LABEL), Hold(max_s), Disarm()),
        description=f"manual control from the console: throttle rate limit {rate_us_s:g} us/s, "
                    f"at most {max_s:g} s",
    )
    return seq, 3


class Setpoint:
    """The operator's throttle target, shared between the console request handler and the
    run loop. ``fraction`` 0..1 maps to idle (0) or ``min_us + f (max_us - min_us)``."""

    def __init__(self, esc: EscRange, rate_us_s: float = DEFAULT_RATE_US_S) -> None:
        if not rate_us_s > 0:
            raise ValueError("rate limit must be > 0 us/s")
        self.esc = esc
        self.rate_us_s = float(rate_us_s)
        self._lock = threading.Lock()
        self.target_us = esc.idle_us
        self.ended = False

    def set_fraction(self, fraction: float) -> float:
        """Set the target from a 0..1 throttle; returns the target in us."""
        f = min(max(float(fraction), 0.0), 1.0) if math.isfinite(fraction) else 0.0
        us = self.esc.idle_us if f <= 0 else self.esc.min_us + f * (self.esc.max_us
                                                                    - self.esc.min_us)
        with self._lock:
            self.target_us = us
        return us

    def end(self) -> None:
        """Stop: the run loop commands idle at its next tick and disarms."""
        with self._lock:
            self.ended = True
            self.target_us = self.esc.idle_us

    def next_us(self, current_us: float, dt_s: float) -> float:
        """The command one tick later: towards the target by at most rate x dt."""
        with self._lock:
            target = self.target_us
        step = self.rate_us_s * dt_s
        base = current_us
        if target != self.esc.idle_us and current_us < self.esc.min_us:
            base = self.esc.min_us  # from idle below the range: start at its bottom
        us = min(max(target, base - step), base + step)
        if target == self.esc.idle_us and us <= self.esc.min_us:
            us = self.esc.idle_us
        return us


class ConsoleRunner(Runner):
    """A Runner that follows ``setpoint`` during segment ``manual_index``, checks ``guard``
    every tick and accepts tighter limits mid-run."""

    def __init__(self, *args: Any, setpoint: Setpoint | None = None,
                 manual_index: int | None = None,
                 guard: Callable[[], str | None] | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.setpoint = setpoint
        self.manual_index = manual_index
        self.guard = guard
        self.armed = False
        self.in_manual = False
        self._shift = 0.0  # a manual segment ended early moves the later ones forward
        self._limits_lock = threading.Lock()
        self.safe_at: float | None = None

    @property
    def limits(self) -> dict[str, float]:
        return dict(self.supervisor.limits)

    def tighten(self, extra: Mapping[str, float]) -> dict[str, float]:
        """Tighten the running limits (RigError if any would loosen); returns them."""
        with self._limits_lock:
            merged = effective_limits(self.supervisor.limits, extra, source="console")
            self.supervisor = SafetySupervisor(merged)  # one reference swap: atomic
        self._event("limits_tightened", label="console", detail=dict(extra))
        return merged

    def _run_segment(self, seg: Segment) -> None:
        if self._shift:
            seg = dataclasses.replace(seg, t_start_s=seg.t_start_s + self._shift)
        if isinstance(seg.step, Arm):
            self.armed = True
        if isinstance(seg.step, Disarm):
            self.armed = False
        if self.setpoint is None or seg.index != self.manual_index:
            super()._run_segment(seg)
            return
        self._segment = seg
        self._event("step_start", seg.index, MANUAL_LABEL,
                    {"kind": "manual", "rate_us_s": self.setpoint.rate_us_s,
                     "max_s": seg.duration_s})
        self.in_manual = True
        tick = self.options.tick_s
        try:
            while not self.setpoint.ended:
                now = self._now_rel()
                if now >= seg.t_end_s - EPS:
                    break
                deadline = min((math.floor((now + EPS) / tick) + 1) * tick, seg.t_end_s)
                self._command(self.setpoint.next_us(self.esc.last_us, deadline - now), seg)
                self.rig.clock.sleep(deadline - now)
                self._acquire()
        finally:
            self.in_manual = False
        if self.setpoint.ended:  # stop: idle and disarmed now, then record the spin-down
            errors = self.esc.safe_stop()
            self.armed = False
            self._log_command(self.esc_range.idle_us, seg)
            self._event("operator_stop", seg.index, "stop: idle + disarm",
                        {"errors": errors} if errors else None)
            if errors:
                raise DeviceError(f"stop: {'; '.join(errors)}")
            self._tick_until(self._now_rel() + SPIN_DOWN_S)
        self._shift = min(self._now_rel() - seg.t_end_s, 0.0)

    def _deliver(self, rows: Mapping[str, np.ndarray], trip: Trip | None) -> None:
        super()._deliver(rows, trip)
        if self.guard is not None:
            lost = self.guard()
            if lost is not None:
                self._event("console_lost", label=lost)
                raise ConsoleLost(lost)
        if (self.setpoint is not None and self.setpoint.ended and not self.in_manual
                and self.manual_index is not None and self._segment is not None
                and self._segment.index < self.manual_index):
            self._event("operator_stop", label="stop requested")
            raise OperatorStop("stop requested")

    def _safe_stop(self) -> list[str]:
        errors = super()._safe_stop()
        self.armed = False
        self.safe_at = time.monotonic()  # when the ESC was made safe (the tests measure it)
        return errors
