"""What both runners share: the always-safe end of a run, the tick loop and the record glue.

:class:`SafeRunLoop` carries a compiled plan's segments out on the rig clock. Whatever ends
the run (the plan's end, a limit trip, the watchdog, an operator stop, Ctrl-C, a device
error or a bug) its ``finally`` makes the actuators safe first (the subclass's
:meth:`SafeRunLoop._safe_stop`: ESC idle + disarmed, hexapod stopped) with a second Ctrl-C
or SIGTERM held until that is done and the record written, then stops the watchdog and
records the exit status (``success``, ``abort`` or ``fail``) and the reason.
:class:`bench.plan_runner.runner.Runner` (ESC) and
:class:`bench.plan_runner.runner.HexapodRunner` (hexapod) fill in the devices: what to
drain, what one segment does, how to read and check a tick.

A simulated rig run flat out (not paced, no live window) is carried out in batches of
ticks: commands and sleeps tick by tick as always, but the devices are read, checked and
recorded once per batch (about 1 s of rig time), which is where the time of a tick went.
The batch is speculative: the rig is checkpointed first, and when anything in it would
have ended or changed the run (a limit, a silent device, a device error, a stop request,
the watchdog) the rig is put back and the batch is run again tick by tick, so the run
ends on the same tick and sample as without batches. The simulation gives the same
samples however they are sliced into reads, so the record is the same bit for bit.
"""

from __future__ import annotations

import contextlib
import logging
import math
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, cast

import numpy as np

from bench.engine.drops import DropCounter
from bench.engine.frozen_heap import FrozenHeap
from bench.engine.host_priority import HostPriority
from bench.engine.recorder import RunRecorder
from bench.engine.safety import LimitTrip, Trip
from bench.engine.watchdog import HostWatchdog, WatchdogTrip
from bench.errors import RecordingError
from drivers.contracts import Block, Clock, MonotonicClock
from drivers.errors import DeviceError

__all__ = ["EPS", "OperatorStop", "RunResult", "SafeRunLoop", "signals_deferred"]

log = logging.getLogger(__name__)

EPS = 1e-9


class OperatorStop(Exception):
    """The operator asked to stop (stop button, closed live window)."""

    def reason(self) -> str:
        """The run's recorded reason."""
        return f"stopped by operator: {self}" if str(self) else "stopped by operator"


@dataclass
class RunResult:
    status: str  # success | abort | fail
    reason: str
    trip: Trip | None = None
    t_end_s: float = 0.0
    rows: int = 0
    safe_stop_errors: list[str] = field(default_factory=list)
    error: BaseException | None = None


class _Clocked(Protocol):
    @property
    def clock(self) -> Clock: ...


class _Plan(Protocol):
    @property
    def duration_s(self) -> float: ...

    @property
    def segments(self) -> Sequence[Any]: ...


class _LoopOptions(Protocol):
    @property
    def tick_s(self) -> float: ...

    @property
    def realtime(self) -> bool: ...

    @property
    def stale_s(self) -> float: ...


class SafeRunLoop:
    """Base of the runners; use once. A subclass builds ``self.watchdog`` (on its guarded
    actuator) after calling ``__init__`` and implements ``_drain``, ``_run_segment``,
    ``_acquire`` and ``_safe_stop``."""

    safe_stop_label = "safe stop"  # the label of the ``safe_stop`` event
    stale_hint = ""  # appended to the error of a silent device
    batch_s = 1.0  # rig time per batch of ticks on a simulated rig run flat out
    batches = False  # a subclass that fills in the batch hooks below sets this
    watchdog: HostWatchdog

    def __init__(self, rig: _Clocked, plan: _Plan, recorder: RunRecorder | None,
                 options: _LoopOptions,
                 on_rows: Callable[[Mapping[str, np.ndarray]], None] | None,
                 on_progress: Callable[[float, float, Any], None] | None,
                 stop_event: threading.Event | None) -> None:
        self.rig = rig
        self.plan = plan
        self.recorder = recorder
        self.options = options
        self.on_rows = on_rows
        self.on_progress = on_progress
        self.stop_event = stop_event or threading.Event()
        self.result: RunResult | None = None
        self.rows = 0
        self._t0 = 0.0
        self._wall0 = 0.0
        self._segment: Any = None
        self._heard: dict[str, float] = {}
        self.drops = DropCounter()  # missed or late samples per role, for run.json
        # in a batch: the end of each tick and the samples taken by then (see _read_times)
        self._batch_ticks: tuple[list[float], list[int]] | None = None

    # -- what a subclass fills in -------------------------------------------------------

    def _expected_rates(self) -> dict[str, float]:
        """Sample rates the devices state, per role (for counting drops); none known here."""
        return {}

    def _drain(self) -> None:
        """Discard what the sensors buffered before the run."""
        raise NotImplementedError

    def _run_segment(self, seg: Any) -> None:
        raise NotImplementedError

    def _acquire(self) -> None:
        """Read every device once, check the limits, then :meth:`_deliver` the rows."""
        raise NotImplementedError

    def _safe_stop(self) -> list[str]:
        """Make the actuators safe; never raises, returns the errors."""
        raise NotImplementedError

    # -- batch hooks (with ``batches = True``): _acquire = _process(_read_devices()) -------

    def _read_devices(self) -> dict[str, Block]:
        """One raw block per device role, as read (no bookkeeping)."""
        raise NotImplementedError

    def _would_stop(self, raw: Mapping[str, Block]) -> bool:
        """Whether processing these blocks would end the run (no side effects)."""
        raise NotImplementedError

    def _process(self, raw: Mapping[str, Block]) -> None:
        """Everything :meth:`_acquire` does after the reads."""
        raise NotImplementedError

    def _loop_state(self) -> Any:
        """What the tick callbacks change in the runner, for a batch taken back."""
        return None

    def _set_loop_state(self, state: Any) -> None:
        pass

    def _finish_fields(self) -> dict[str, Any]:
        """Extra fields for run.json at the end of the run."""
        return {}

    def _progress_time(self, now: float) -> float:
        """Where the plan stands at ``now`` (a runner whose schedule fell behind the plan
        reports plan time, so progress never passes the plan's duration)."""
        return now

    # -- public -------------------------------------------------------------------------

    def run(self) -> RunResult:
        """Carry out the plan. Trips and operator stops return a result with status abort;
        device errors, Ctrl-C and bugs are re-raised after the safe stop and the record."""
        # no full collection walks the imported modules mid-run, and a run on the wall
        # clock runs ahead of the machine's other work
        with FrozenHeap(), HostPriority(self.on_wall_clock):
            return self._carry_out()

    @property
    def on_wall_clock(self) -> bool:
        """Whether the run keeps time with the wall: a real rig (``MonotonicClock``), a
        paced simulated bench (``time_scale``) or a real-time run."""
        clock = self.rig.clock
        return (self.options.realtime or isinstance(clock, MonotonicClock)
                or getattr(clock, "time_scale", None) is not None)

    def _carry_out(self) -> RunResult:
        status, reason, trip = "fail", "run did not start", None
        pending: BaseException | None = None
        try:
            if self.recorder is not None and self._batch_sim() is not None:
                self.recorder.write_behind()  # nothing real spins: see write_behind
            self._drain()
            for role, rate in self._expected_rates().items():
                self.drops.expect(role, rate)
            self._t0 = self.rig.clock.now()
            self._wall0 = time.monotonic()
            self._event("run_start", detail={"rig_t0_s": self._t0,
                                             "plan_duration_s": self.plan.duration_s})
            log.info("run started: %d segments, %.3f s planned, tick %g s, watchdog %g s",
                     len(self.plan.segments), self.plan.duration_s, self.options.tick_s,
                     self.watchdog.timeout_s)
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
            status, reason = "abort", exc.reason()
        except KeyboardInterrupt as exc:
            status, reason, pending = "abort", "interrupted by operator (Ctrl-C or SIGTERM)", exc
        except RecordingError as exc:  # disk full: stop, keep what is on disk
            status, reason, pending = "abort", f"recording failed: {exc}", exc
        except DeviceError as exc:
            status, reason, pending = "fail", f"device error: {exc}", exc
        except BaseException as exc:
            status, reason, pending = "fail", f"{type(exc).__name__}: {exc}", exc
        finally:
            # Safety first: actuators safe before anything else can fail. A second Ctrl-C
            # (or SIGTERM) is held until they are safe and the record is written.
            with signals_deferred():
                errors = self._safe_stop()
                log.info("safe stop (%s) done%s", self.safe_stop_label,
                         f" with errors: {'; '.join(errors)}" if errors else "")
                self.watchdog.stop()
                if self.watchdog.tripped and status == "success":
                    status, reason = "abort", self.watchdog.reason
                errors += self.watchdog.errors
                self.result = RunResult(status, reason, trip, self._now_rel(), self.rows,
                                        errors, pending)
                log.info("run ended: %s: %s (%.3f s of the run, %d rows)", status, reason,
                         self.result.t_end_s, self.result.rows)
                self._finish_record(trip, errors)
        if pending is not None:
            raise pending
        return self.result

    def request_stop(self) -> None:
        self.stop_event.set()

    # -- loop ---------------------------------------------------------------------------

    def _tick_until(self, end: float, each_tick: Callable[[float], None] | None = None) -> None:
        """Acquire on every tick of the rig clock until ``end`` (s since the start);
        ``each_tick(now)`` runs before each sleep (the ESC command heartbeat)."""
        sim = self._batch_sim()
        if sim is None:
            self._ticks(end, end, each_tick, acquire=True)
            return
        while (now := self._now_rel()) < end - EPS:
            if sim.runs_alone(self.rig.clock, self._devices()):
                self._batch(sim, min(end, now + self.batch_s), end, each_tick)
            else:  # a fault was switched on: tick by tick from here
                self._ticks(end, end, each_tick, acquire=True)

    def _ticks(self, stop: float, end: float, each_tick: Callable[[float], None] | None,
               acquire: bool, after: Callable[[], None] | None = None) -> None:
        """Ticks until ``stop``; each one ends at the next multiple of the tick or ``end``.
        ``acquire`` reads the devices after each sleep, ``after()`` runs there instead."""
        tick = self.options.tick_s
        while True:
            now = self._now_rel()
            if now >= stop - EPS:
                break
            deadline = min((math.floor((now + EPS) / tick) + 1) * tick, end)
            if each_tick is not None:
                each_tick(now)
            self.rig.clock.sleep(deadline - now)
            if acquire:
                self._acquire()
            elif after is not None:
                after()

    def _read_times(self, n: int, now: float) -> np.ndarray | float:
        """When each of the last ``n`` samples read was read: ``now`` tick by tick; in a
        batch, the end of the tick whose read would have taken it (a command sent at the
        end of a tick must not reach a sample of that tick stamped a hair after it)."""
        if self._batch_ticks is None:
            return now
        ends, taken = self._batch_ticks
        first = taken[-1] - n
        counts = np.diff(np.maximum([first, *taken], first))
        return np.repeat(np.asarray(ends), counts)

    def _devices(self) -> list[Any]:
        rig: Any = self.rig
        return [d for d in (getattr(rig, "esc", None), *getattr(rig, "sensors", {}).values())
                if d is not None]

    def _batch_sim(self) -> Any:
        """The simulated rig to run batches of ticks on, or None (tick by tick)."""
        if not self.batches or self.options.realtime or self.on_rows is not None:
            return None
        sim = getattr(self.rig, "sim", None)
        if sim is None or not hasattr(sim, "checkpoint"):
            return None
        return sim if sim.runs_alone(self.rig.clock, self._devices()) else None

    def _batch(self, sim: Any, stop: float, end: float,
               each_tick: Callable[[float], None] | None) -> None:
        """Ticks until ``stop`` with one read at the end; taken back and run tick by tick
        when the read (or anything before it) would have ended the run."""
        checkpoint, state = sim.checkpoint(), self._loop_state()
        ends: list[float] = []
        taken: list[int] = []

        def tick_end() -> None:
            ends.append(self._now_rel())
            taken.append(sim.samples_taken())

        raw: dict[str, Block] = {}
        try:
            self._ticks(stop, end, each_tick, acquire=False, after=tick_end)
            raw = self._read_devices()
            clean = not (self.stop_event.is_set() or self.watchdog.tripped
                         or self._would_stop(raw))
        except Exception:  # the tick-by-tick run raises it on the right tick
            clean = False
        if clean:
            self._batch_ticks = (ends, taken)
            try:
                self._process(raw)
            finally:
                self._batch_ticks = None
            return
        sim.restore(checkpoint)
        self._set_loop_state(state)
        self._ticks(stop, end, each_tick, acquire=True)

    def _read(self, role: str, read: Callable[[], Block], now: float) -> Block:
        """One block from a device, stamped relative to the run start; a device silent for
        longer than ``stale_s`` ends the run."""
        return self._stamp(role, read(), now)

    @property
    def stale_limit_s(self) -> float:
        """How long (rig time) a device may be silent: ``stale_s``. A simulated bench paced
        by the wall clock (``PacedClock``, ``time_scale`` x real time) is served by
        processes of its own (the world's, a firmware), so a hiccup of the host lasts
        ``time_scale`` times as long in rig time: there the limit is ``stale_s`` of wall
        time, scaled. (A floor of 2 s of wall time went with the devices that were threads
        of the bench's own process: CI saw them starved for 0.2-1 s.)"""
        scale = getattr(self.rig.clock, "time_scale", None)
        if scale is None:
            return self.options.stale_s
        return self.options.stale_s * max(1.0, float(scale))

    def _stamp(self, role: str, b: Block, now: float) -> Block:
        """The bookkeeping of one block read at ``now``: drops, the stale check and the
        time base relative to the run start."""
        self.drops.update(role, b.t_s, b.values)
        if len(b):
            self._heard[role] = now
        elif now - self._heard.get(role, 0.0) > self.stale_limit_s:
            raise DeviceError(f"{role}: no samples for {now - self._heard.get(role, 0.0):.2f} s "
                              f"(limit {self.stale_limit_s:g} s){self.stale_hint}")
        return Block(b.t_s - self._t0, b.values)

    def _deliver(self, rows: Mapping[str, np.ndarray], trip: Trip | None) -> None:
        """The rest of a tick once the limits were checked: record and show the rows, end
        the run on a trip, check in with the watchdog, honour a stop request, pace a
        real-time run and report progress."""
        n = len(rows.get("t_s", ()))
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
            self.on_progress(self._progress_time(now), self.plan.duration_s, self._segment)

    # -- record -------------------------------------------------------------------------

    def _now_rel(self) -> float:
        return self.rig.clock.now() - self._t0

    def _event(self, kind: str, step: int | None = None, label: str = "",
               detail: Mapping[str, Any] | None = None) -> None:
        if self.recorder is not None:
            self.recorder.event(self._now_rel(), kind, step, label, detail)

    def _add_link_errors(self, drops: dict[str, Any]) -> None:
        """Frames lost on each device's link (bad checksums, truncated frames, CAN
        transfer-id gaps: ``link_errors()`` of the backends that decode a byte or frame
        stream) beside the samples missing from the time stamps; ``link_errors`` is the
        total in ``run.json``."""
        total = 0
        devices = getattr(self.rig, "devices", None)
        if not isinstance(devices, Mapping):
            devices = {"esc": getattr(self.rig, "esc", None),
                       **dict(getattr(self.rig, "sensors", {}) or {})}
        for role, dev in devices.items():
            count = getattr(dev, "link_errors", None)
            if not callable(count):
                continue
            try:
                counts = cast("Mapping[str, Any]", count())
                errors = {k: int(v) for k, v in counts.items() if v}
            except Exception:  # a counter must never cost the run its record
                continue
            if errors:
                drops["drops"].setdefault(role, {})["link_errors"] = errors
                total += sum(errors.values())
        drops["link_errors"] = total

    def _finish_record(self, trip: Trip | None, errors: list[str]) -> None:
        res = self.result
        assert res is not None
        if self.recorder is None:
            return
        try:
            self._event("safe_stop", label=self.safe_stop_label,
                        detail={"errors": errors} if errors else None)
            self._event("run_end", label=res.status, detail={"reason": res.reason})
        finally:
            drops = self.drops.summary()
            self._add_link_errors(drops)
            marks = ["drops"] if drops["dropped_samples"] or drops["link_errors"] else []
            figures: dict[str, Any] = {}  # what a device measured over the run
            devices = getattr(self.rig, "devices", None)
            for dev in devices.values() if isinstance(devices, Mapping) else ():
                with contextlib.suppress(Exception):  # never costs the run its record
                    figures.update(getattr(dev, "run_figures", dict)())
            self.recorder.finish(res.status, res.reason, trip=trip.to_dict() if trip else None,
                                 safe_stop_errors=errors, duration_s=res.t_end_s,
                                 **drops, marks=marks, **figures, **self._finish_fields())


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT/SIGTERM while the actuators are made safe (main thread only), then
    re-deliver them."""
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
