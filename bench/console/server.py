"""The bench side of the console: owns the rig and every run, answers the window.

:class:`ConsoleBench` runs in the ``rotorbench console`` process. Its :meth:`serve` loop
(main thread) reads the window's requests, sends state ten times a second and watches the
window; each run (manual session, plan, tare) goes through
:func:`bench.plan_runner.session.run_sequence` on a worker thread with a
:class:`bench.console.manual.ConsoleRunner`, so it is recorded and indexed like any CLI run and ends
safe whatever happens. The window can only ask; limits can only be tightened; a lost window (closed,
crashed, frozen) stops the run at its next tick (ESC idle and disarmed) and ends :meth:`serve`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench.console.link import BenchLink
from bench.console.manual import DEFAULT_RATE_US_S, ConsoleRunner, Setpoint, manual_sequence
from bench.engine.safety import LIMIT_FIELDS, effective_limits, limits_dict
from bench.errors import RigError
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import esc_range_of, plan_for, run_sequence
from bench.plans.plan_specs import plan_sequence
from bench.plans.sequences import Segment, Sequence, Tare

__all__ = ["ActiveRun", "ConsoleBench"]

STATE_PERIOD_S = 0.1
TARE_S = 0.5


@dataclasses.dataclass
class ActiveRun:
    """One run on its worker thread and what the window needs to know of it."""

    kind: str
    seq: Sequence | None
    stop: threading.Event
    setpoint: Setpoint | None = None
    runner: ConsoleRunner | None = None
    thread: threading.Thread | None = None
    progress: tuple[float, float, str, int] = (0.0, 0.0, "", -1)
    result: dict[str, Any] | None = None
    ended_at: float | None = None  # time.monotonic() when the run (and its safe stop) ended
    imu: Any = None  # an IMU-bench calibration (bench.console.imu_bench.ImuCalibration)
    cell: Any = None  # a load-cell calibration (bench.console.cell_calibration)


class ConsoleBench:
    """See module docstring. ``open_rig`` defaults to :func:`drivers.factory.open_rig`."""

    def __init__(self, rig: Any, out: Path, link: BenchLink, *, seed: int | None = None,
                 options: RunOptions | None = None, rate_us_s: float = DEFAULT_RATE_US_S,
                 open_rig: Callable[..., Any] | None = None) -> None:
        self.rig = rig
        self.imu = getattr(rig, "hexapod", None) is not None  # an IMU-bench rig
        self.out = Path(out)
        self.link = link
        self.seed = seed
        self.options = options or RunOptions(realtime=True)
        self.rate_us_s = rate_us_s
        self.esc = esc_range_of(rig) if not self.imu else None
        self.rig_limits = limits_dict(rig.limits) if not self.imu else {}
        self.limits = dict(self.rig_limits)
        self._open_rig = open_rig
        self.run: ActiveRun | None = None
        self.finished: list[dict[str, Any]] = []
        self.lost_reason: str | None = None
        self.fatal: str | None = None  # the window could not start (e.g. a faulty binding)
        self.selftest: dict[str, Any] | None = None
        self._lock = threading.Lock()
        self._last_state = 0.0

    # -- requests -----------------------------------------------------------------------

    def handle(self, kind: str, payload: Any) -> None:
        """One request of the window; problems go back as an ``error`` message."""
        try:
            handler = getattr(self, f"_on_{kind}", None)
            if handler is None:
                raise RigError(f"unknown console request {kind!r}")
            handler(payload)
        except RigError as exc:
            self.link.send("error", str(exc))

    def _propulsion(self, what: str) -> None:
        if self.imu:
            raise RigError(f"{what}: {self.rig.name} is an IMU-bench rig (hexapod and IMUs); "
                           "calibrate it from the IMU tab")

    def _on_calibrate(self, payload: Any) -> None:
        from bench.console.imu_bench import ImuCalibration

        if not self.imu:
            raise RigError("calibrate: this is a propulsion rig; the IMU tab calibrates "
                           "IMU-bench rigs ([rig] kind = \"imu\")")
        self._refuse_if_busy("calibrate")
        run = ActiveRun("calibration", None, threading.Event())
        run.imu = ImuCalibration(self.rig, self.out, bool((payload or {}).get("quick", True)),
                                 run.stop, self.link.lost)
        run.thread = threading.Thread(target=self._work, args=(run, run.imu.run),
                                      name="rotorbench-console-calibration", daemon=True)
        self.run = run
        run.thread.start()
        self.send_state(force=True)

    def _on_calibrate_cell(self, payload: Any) -> None:
        from bench.console.cell_calibration import CellCalibration, plan_of

        self._propulsion("calibrate the load cell")
        self._refuse_if_busy("calibrate the load cell")
        spec = dict(payload or {})
        plan = plan_of(spec)
        run = ActiveRun("cell calibration", None, threading.Event())
        run.cell = CellCalibration(self.rig, self.out, plan, bool(spec.get("automatic")),
                                   run.stop, self.link.send, self.link.lost,
                                   self._opener(), self.seed)
        run.thread = threading.Thread(target=self._work, args=(run, run.cell.run),
                                      name="rotorbench-console-cell-calibration", daemon=True)
        self.run = run
        run.thread.start()
        self.send_state(force=True)

    def _on_cell_placed(self, _payload: Any) -> None:
        run = self.run
        if run is None or run.cell is None or run.ended_at is not None:
            raise RigError("weight placed: no load-cell calibration is asking for one")
        run.cell.placed()

    def _on_arm(self, _payload: Any) -> None:
        self._propulsion("arm")
        assert self.esc is not None  # a propulsion rig has its ESC range
        seq, index = manual_sequence(rate_us_s=self.rate_us_s)
        setpoint = Setpoint(self.esc, self.rate_us_s)
        self._start("manual", seq, setpoint=setpoint, manual_index=index,
                    meta={"console": {"manual_segment": index, "rate_us_s": self.rate_us_s}})

    def _on_throttle(self, fraction: Any) -> None:
        run = self.run
        if run is None or run.setpoint is None or run.ended_at is not None:
            raise RigError("throttle: arm first (the throttle acts only in a manual session)")
        run.setpoint.set_fraction(float(fraction))

    def _on_stop(self, _payload: Any = None) -> None:
        """Stop: ESC idle and disarmed, whatever runs (a manual session ends normally, a
        plan is aborted)."""
        run = self.run
        if run is None:
            return
        if run.setpoint is not None:
            run.setpoint.end()
        else:
            run.stop.set()

    _on_abort = _on_stop

    def _on_start_plan(self, spec: Any) -> None:
        self._propulsion("plan")
        seq = plan_sequence(dict(spec))
        self._start(str(seq.name), seq, meta={"console": {"plan": dict(spec)}})

    def _on_preview(self, spec: Any) -> None:
        if self.imu:
            return
        seq = plan_sequence(dict(spec))
        seq = dataclasses.replace(seq, limits={**seq.limits, **self._tighter()})
        effective_limits(self.rig.limits, seq.limits, source=f"sequence {seq.name!r}")
        plan = plan_for(self.rig, seq, dry_run=True)
        self.link.send("preview", {"name": seq.name, "description": seq.description,
                                   "duration_s": plan.duration_s,
                                   "segments": [_segment_row(s) for s in plan.segments]})

    def _on_tare(self, _payload: Any) -> None:
        self._propulsion("tare")
        self._start("tare", Sequence("tare", (Tare(TARE_S),),
                                     description="console: load-cell tare, motor stopped"))

    def _on_tighten(self, payload: Any) -> None:
        self._propulsion("tighten")
        name, value = payload
        if name not in LIMIT_FIELDS:
            raise RigError(f"limit {name!r}: expected one of {', '.join(LIMIT_FIELDS)}")
        merged = effective_limits(self.limits, {name: float(value)}, source="console")
        self.limits = merged
        run = self.run
        if run is not None and run.runner is not None and run.ended_at is None:
            run.runner.tighten({name: float(value)})
        self.send_state(force=True)

    def _on_check(self, _payload: Any) -> None:
        if self.busy:
            raise RigError("check: stop the run first (a check opens every device)")
        threading.Thread(target=self._check, name="rotorbench-check", daemon=True).start()

    def _on_closed(self, _payload: Any) -> None:
        self.link.closed_by_operator = True
        self._on_stop()

    def _on_quit(self, _payload: Any) -> None:
        self._on_closed(None)

    def _on_hello(self, _payload: Any) -> None:
        self.link.send("rig", self.rig_info())

    def _on_selftest(self, payload: Any) -> None:
        self.selftest = dict(payload)

    def _on_fatal(self, problem: Any) -> None:
        self.fatal = str(problem)
        self._on_closed(None)

    # -- runs ---------------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        return self.run is not None and self.run.ended_at is None

    def _refuse_if_busy(self, what: str) -> None:
        run = self.run
        if run is not None and run.ended_at is None:  # busy
            raise RigError(f"{what}: a {run.kind} run is going on; stop it first")

    def _opener(self) -> Callable[..., Any]:
        """How a run opens the rig's devices: the given ``open_rig``, else the factory's."""
        if self._open_rig is not None:
            return self._open_rig
        from drivers.factory import open_rig

        return open_rig

    def _tighter(self) -> dict[str, float]:
        return {k: v for k, v in self.limits.items() if self.rig_limits.get(k) != v}

    def _start(self, kind: str, seq: Sequence, *, setpoint: Setpoint | None = None,
               manual_index: int | None = None, meta: dict[str, Any] | None = None) -> None:
        self._refuse_if_busy(kind)
        if self.link.lost() is not None:
            raise RigError("the console is gone; nothing starts")
        seq = dataclasses.replace(seq, limits={**seq.limits, **self._tighter()})
        effective_limits(self.rig.limits, seq.limits, source=f"sequence {seq.name!r}")
        plan_for(self.rig, seq)  # a plan that cannot compile is refused here, in one line
        run = ActiveRun(kind, seq, threading.Event(), setpoint)

        def factory(*args: Any, **kwargs: Any) -> ConsoleRunner:
            run.runner = ConsoleRunner(*args, setpoint=setpoint, manual_index=manual_index,
                                       guard=self.link.lost, **kwargs)
            return run.runner

        def on_progress(t: float, total: float, seg: Segment) -> None:
            run.progress = (t, total, seg.label, seg.index)

        work = functools.partial(
            run_sequence, self.rig, seq, self.out, self._opener(), seed=self.seed,
            options=self.options, on_rows=self.link.ring.push, on_progress=on_progress,
            stop_event=run.stop, extra_meta={"command_line": ["rotorbench", "console"],
                                             **(meta or {})},
            runner_factory=factory)
        run.thread = threading.Thread(target=self._work, args=(run, work),
                                      name=f"rotorbench-console-{kind}", daemon=True)
        self.run = run
        run.thread.start()
        self.send_state(force=True)

    def _work(self, run: ActiveRun, work: Callable[[], Any]) -> None:
        outcome, error = None, None
        try:
            outcome = work()
        except BaseException as exc:  # the run was made safe and recorded by its finally
            error = exc
        run.ended_at = time.monotonic()
        if isinstance(outcome, dict):  # an IMU calibration says itself how it went
            self._finished(run, outcome)
            return
        runner = run.runner
        res = outcome.result if outcome is not None else (runner.result if runner else None)
        info: dict[str, Any] = {"kind": run.kind, "status": "fail",
                                "reason": f"{type(error).__name__}: {error}" if error else "",
                                "run_dir": str(outcome.run_dir) if outcome else "",
                                "trip": None, "rows": 0, "t_end_s": 0.0}
        if res is not None:
            info.update(status=res.status, reason=res.reason, rows=res.rows,
                        t_end_s=res.t_end_s, trip=res.trip.to_dict() if res.trip else None,
                        safe_stop_errors=res.safe_stop_errors)
        if runner is not None:
            info["tare_offset_n"] = runner.tare_offset_n
            if runner.recorder is not None:
                info["run_dir"] = str(runner.recorder.run_dir)
        if (run.imu is not None or run.cell is not None) and error is not None:
            info["reason"] = f"calibration: {type(error).__name__}: {error}"
        self._finished(run, info)

    def _finished(self, run: ActiveRun, info: dict[str, Any]) -> None:
        run.result = info
        with self._lock:
            self.finished.append(info)
        self.link.send("finished", info)

    def _check(self) -> None:
        from drivers.check import check_rig

        try:
            reports = [dataclasses.asdict(r) for r in check_rig(self.rig)]
        except Exception as exc:  # a device error is an answer, not a crash of the bench
            reports = [{"role": "rig", "url": "", "ok": False, "detail": str(exc)}]
        self.link.send("devices", reports)

    # -- state --------------------------------------------------------------------------

    def rig_info(self) -> dict[str, Any]:
        base = {"name": self.rig.name, "path": str(getattr(self.rig, "path", "")),
                "kind": "imu" if self.imu else "propulsion", "rate_us_s": self.rate_us_s,
                "out": str(self.out)}
        if self.imu:
            from bench.console.imu_bench import imu_rig_info

            return {**base, **imu_rig_info(self.rig)}
        assert self.esc is not None  # a propulsion rig has its ESC range
        tm = getattr(self.rig, "thrust_map", None)
        thrust_cap_us = None
        if tm is not None and "thrust_n" in self.rig_limits:
            try:
                thrust_cap_us = float(tm.command_for(self.rig_limits["thrust_n"]))
            except Exception:
                thrust_cap_us = None
        return {"name": self.rig.name, "path": str(getattr(self.rig, "path", "")),
                "kind": getattr(self.rig, "kind", "propulsion"),
                "devices": {r: d.url for r, d in getattr(self.rig, "devices", {}).items()},
                "esc": dataclasses.asdict(self.esc), "rig_limits": self.rig_limits,
                "components": dataclasses.asdict(self.rig.components)
                if dataclasses.is_dataclass(getattr(self.rig, "components", None)) else {},
                "rate_us_s": self.rate_us_s, "thrust_cap_us": thrust_cap_us,
                "out": str(self.out)}

    def state(self) -> dict[str, Any]:
        run = self.run
        idle = self.esc.idle_us if self.esc is not None else 1000.0
        out: dict[str, Any] = {"limits": dict(self.limits), "busy": self.busy,
                               "kind": None, "armed": False, "command_us": idle,
                               "target_us": idle, "manual": False, "progress": None,
                               "imu": None}
        if run is not None and run.ended_at is None and run.imu is not None:
            out.update(kind=run.kind, imu=run.imu.snapshot())
        elif run is not None and run.ended_at is None and run.cell is not None:
            out.update(kind=run.kind, cell_prompt=run.cell.prompt)
        elif run is not None and run.ended_at is None:
            runner = run.runner
            out.update(kind=run.kind, progress=run.progress)
            if runner is not None:
                out.update(armed=runner.armed, command_us=runner.esc.last_us,
                           manual=runner.in_manual, limits=runner.limits)
            if run.setpoint is not None:
                out["target_us"] = run.setpoint.target_us
        return out

    def send_state(self, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_state >= STATE_PERIOD_S:
            self._last_state = now
            self.link.send("state", self.state())

    def serve(self, poll_s: float = 0.02, ready_timeout_s: float = 60.0) -> str:
        """Answer the window until it quits, closes or is lost; returns why. A run going
        on is stopped (it also stops itself at its next tick) and waited for."""
        started = time.monotonic()
        self.link.send("rig", self.rig_info())
        try:
            while True:
                for kind, payload in self.link.receive():
                    self.handle(kind, payload)
                # a frozen window is the run's business (its guard stops it at once);
                # the console goes on if the window recovers, ends if it closes or dies
                lost = self.link.lost(frozen=False)
                if lost is None and self.link.heartbeat_age_s() is None and \
                        time.monotonic() - started > ready_timeout_s:
                    lost = f"the console window did not start within {ready_timeout_s:g} s"
                if lost is not None:
                    self.lost_reason = lost
                    break
                self.send_state()
                time.sleep(poll_s)
        finally:
            self._on_stop()
            self.wait()
        return self.lost_reason

    def wait(self, timeout_s: float = 30.0) -> None:
        run = self.run
        if run is not None and run.thread is not None:
            run.thread.join(timeout_s)


def _segment_row(s: Segment) -> list[Any]:
    def num(x: float) -> float | None:
        return None if math.isnan(x) else round(float(x), 3)

    return [s.index, round(s.t_start_s, 3), round(s.duration_s, 3), s.kind, num(s.us_start),
            num(s.us_end), num(s.setpoint_n), s.label]
