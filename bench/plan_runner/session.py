"""One session/recording path for every bench: a compiled plan becomes one indexed run.

:func:`record_plan` is the only place a run folder is made: it creates the run folder and
its index row (``bench.store.indexed_run``), hands the recorder to the bench's runner (the one
runner module, :mod:`bench.plan_runner.runner`) and records whatever happened. Each bench only says
what goes into ``run.json`` and how its devices are opened:

- :func:`run_sequence` (propulsion stand): compiles the sequence against the rig (ESC
  range, static thrust map, limits tightened by the sequence), opens the devices for the
  run and closes them whatever happened.
- :func:`run_stage` (IMU bench): one calibration stage on a bench opened once for all
  stages (``bench.jobs.calibration_stages``), the IMU keeping its clock across them.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.engine import run_log
from bench.engine.recorder import BASE_COLUMNS, RunRecorder
from bench.engine.safety import effective_limits, limits_dict
from bench.plan_runner.hexapod_parts import RECORD_BASE, ImuBenchLike
from bench.plan_runner.runner import (
    HexapodRunner,
    HexapodRunOptions,
    OpenRigLike,
    Runner,
    RunOptions,
    RunResult,
)
from bench.plans.calibration_sequences import HexapodSegment
from bench.plans.sequences import EscRange, Plan, Segment, Sequence, compile_plan
from bench.plans.thrust_map import StaticThrustMap
from bench.store.indexed_run import indexed_run

__all__ = ["RunOutcome", "esc_range_of", "plan_for", "record_plan", "rig_summary",
           "run_sequence", "run_stage"]


@dataclass(frozen=True)
class RunOutcome:
    """How a recorded run ended, where it is, and the plan it carried out."""

    result: RunResult
    run_dir: Path
    plan: Plan


def record_plan(out_root: Path, name: str, meta: Mapping[str, Any], plan: Plan,
                run: Callable[[RunRecorder], RunResult], *,
                base_columns: tuple[str, ...] = BASE_COLUMNS) -> RunOutcome:
    """Record one run of ``plan`` under ``out_root``: ``run(recorder)`` builds the bench's
    runner and runs it. Device errors, Ctrl-C and bugs propagate after the run has been
    made safe and recorded; a runner that never started is recorded as failed."""
    with indexed_run(out_root, name, meta, base_columns=base_columns) as recorder:
        result = run(recorder)
    return RunOutcome(result, recorder.run_dir, plan)


# --- the propulsion stand -------------------------------------------------------------------
def esc_range_of(rig: Any) -> EscRange:
    esc = rig.esc
    return EscRange(float(esc.idle_us), float(esc.min_us), float(esc.max_us))


def thrust_to_us_of(rig: Any):
    """The rig's static map as a thrust (N) -> command (us) function, or None.

    Memoised: a plan asks it once per thrust step, and a long plan (a typo's 100 000
    repeats, refused by its budget) has few setpoints but hundreds of thousands of steps."""
    tm: Any = getattr(rig, "thrust_map", None)
    if tm is None:
        return None
    if callable(getattr(tm, "command_for", None)):
        return functools.lru_cache(maxsize=1024)(lambda f: float(tm.command_for(f)))
    static = StaticThrustMap.from_rig(tm, source=f"{_rig_name(rig)}: thrust_map")
    assert static is not None  # from_rig gives None for None only
    return functools.lru_cache(maxsize=1024)(static.command_for)


def plan_for(rig: Any, seq: Sequence, dry_run: bool = False) -> Plan:
    """Compile ``seq`` for ``rig`` without touching any device (also the dry run)."""
    return compile_plan(seq, esc_range_of(rig), thrust_to_us_of(rig), allow_unmapped=dry_run)


def _rig_name(rig: Any) -> str:
    name = getattr(rig, "name", None)
    if name:
        return str(name)
    path = getattr(rig, "path", None)
    return Path(path).stem if path else "rig"


def _plain(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, Mapping):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return obj


def rig_summary(rig: Any) -> dict[str, Any]:
    """What run.json says about the rig: name, file, devices, ESC, sim settings."""
    out: dict[str, Any] = {"name": _rig_name(rig)}
    for key in ("path", "devices", "esc", "sim"):
        if getattr(rig, key, None) is not None:
            out[key] = _plain(getattr(rig, key))
    path = getattr(rig, "path", None)
    if path is not None:  # which rig file exactly: the lab catalog lists runs by it
        import hashlib

        try:
            out["sha256"] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            pass
    return out


def run_sequence(
    rig: Any,
    seq: Sequence,
    out_root: Path,
    open_rig: Callable[..., OpenRigLike],
    *,
    seed: int | None = None,
    options: RunOptions | None = None,
    on_rows: Callable[[Mapping[str, np.ndarray]], None] | None = None,
    on_progress: Callable[[float, float, Segment], None] | None = None,
    stop_event: threading.Event | None = None,
    extra_meta: Mapping[str, Any] | None = None,
    runner_factory: Callable[..., Runner] = Runner,
) -> RunOutcome:
    """Run ``seq`` on ``rig`` and record it under ``out_root``; see module docstring.

    Device errors, Ctrl-C and bugs propagate after the run has been made safe and
    recorded (``runner.result`` holds the record); trips return with status abort.
    ``runner_factory`` builds the runner from Runner's arguments (the console passes a
    Runner subclass that follows the operator's throttle).
    """
    options = options or RunOptions()
    plan = plan_for(rig, seq)
    limits = effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}",
                              thrust_setpoints_n=getattr(seq, "thrust_setpoints_n", ()))
    meta = {
        "kind": seq.name,
        "rig": rig_summary(rig),
        "components": _plain(getattr(rig, "components", {})),
        "sequence": seq.to_dict(),
        "plan": {"duration_s": plan.duration_s,
                 "segments": [s.record() for s in plan.segments]},
        "limits": limits,
        "rig_limits": limits_dict(rig.limits),
        "thrust_map": _plain(getattr(rig, "thrust_map", None)),
        "options": dataclasses.asdict(options),
        "seed": seed if seed is not None else getattr(getattr(rig, "sim", None), "seed", None),
        **dict(extra_meta or {}),
    }

    # the devices open before the run folder exists: a rig that cannot be opened (an
    # option misspelt, a port missing) is refused with nothing written, however often it
    # is tried; opening arms nothing (the runner arms the ESC), and the devices are closed
    # whatever happens after. What they said goes into the run's run.log all the same.
    with run_log.capture():
        return _run_opened(rig, seq, out_root, open_rig, plan, limits, meta, seed=seed,
                           options=options, on_rows=on_rows, on_progress=on_progress,
                           stop_event=stop_event, runner_factory=runner_factory)


def _run_opened(rig: Any, seq: Sequence, out_root: Path,
                open_rig: Callable[..., OpenRigLike], plan: Plan, limits: Any,
                meta: Mapping[str, Any], *, seed: int | None, options: RunOptions,
                on_rows: Callable[[Mapping[str, np.ndarray]], None] | None,
                on_progress: Callable[[float, float, Segment], None] | None,
                stop_event: threading.Event | None,
                runner_factory: Callable[..., Runner]) -> RunOutcome:
    """``run_sequence`` from the devices' opening on."""
    devices = open_rig(rig, seed=seed)
    try:
        if getattr(rig, "calibration", None) is not None:  # a propulsion stand's cells
            from bench.plan_runner.cell_calibrations import (
                apply_calibrations,
                declared_cell_dynamics,
            )

            calibrations = apply_calibrations(
                rig, devices, out_root, accept_uncalibrated=options.accept_uncalibrated)
            if calibrations:
                meta = {**meta, "calibrations": calibrations}
            dynamics = declared_cell_dynamics(devices)
            if dynamics:  # what a step fit models instead of reading it as latency
                meta = {**meta, "cell_dynamics": dynamics}

        def run(recorder: RunRecorder) -> RunResult:
            try:
                runner = runner_factory(devices, plan, esc_range_of(rig), limits, recorder,
                                        options, on_rows=on_rows, on_progress=on_progress,
                                        stop_event=stop_event)
            except BaseException as exc:
                recorder.finish("fail", f"runner did not start: {exc}")
                raise
            return runner.run()

        return record_plan(out_root, seq.name, meta, plan, run)
    finally:
        devices.close()


# --- the IMU bench --------------------------------------------------------------------------
def _rig_summary(rig: Any) -> dict[str, Any]:
    return {"name": rig.name, "path": str(rig.path), "kind": "imu",
            "devices": {r: {"url": d.url} for r, d in rig.devices.items()},
            "hexapod": dataclasses.asdict(rig.hexapod), "imu": dataclasses.asdict(rig.imu)}


def run_stage(bench: ImuBenchLike, rig: Any, plan: Plan, out_root: Path, *,
              options: HexapodRunOptions | None = None,
              on_progress: Callable[[float, float, HexapodSegment], None] | None = None,
              on_rows: Callable[[Mapping[str, np.ndarray]], None] | None = None,
              stop_event: threading.Event | None = None,
              extra_meta: Mapping[str, Any] | None = None) -> RunOutcome:
    """Run one calibration stage on an open IMU bench into its own run folder; errors
    propagate after the safe stop (hexapod stopped) and the record."""
    options = options or HexapodRunOptions(trajectory_rate_hz=rig.hexapod.trajectory_rate_hz)
    seq = plan.sequence
    meta = {
        "kind": seq.name,
        "rig": _rig_summary(rig),
        "sequence": json.loads(json.dumps(seq.to_dict(), default=str)),
        "plan": {"duration_s": plan.duration_s,
                 "segments": [{"index": s.index, "kind": s.kind, "label": s.label,
                               "phase": s.phase, "t_start_s": s.t_start_s,
                               "duration_s": s.duration_s, "peaks": dict(s.peaks)}
                              for s in plan.segments]},
        "limits": plan.limits.as_dict(),
        "rig_limits": dict(rig.hexapod.limits),
        "options": dataclasses.asdict(options),
        "seed": rig.sim.seed if rig.is_simulated else None,
        "log_format": "analysis.imu_log calibration log (t_s, phase, ref_*, imu_*)",
        **dict(extra_meta or {}),
    }

    def run(recorder: RunRecorder) -> RunResult:
        runner = HexapodRunner(bench, plan, recorder, options, on_rows=on_rows,
                               on_progress=on_progress, stop_event=stop_event)
        return runner.run()

    return record_plan(out_root, seq.name, meta, plan, run, base_columns=RECORD_BASE)
