"""One bench run from rig config to indexed run folder (what the CLI commands call).

Compiles the sequence against the rig (ESC range, static thrust map, limits tightened
by the sequence), creates the run folder and its index row, opens the devices, runs,
and closes the devices and updates the index whatever happened.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bench.indexed_run import indexed_run
from bench.runner import OpenRigLike, Runner, RunOptions, RunResult
from bench.safety import effective_limits, limits_dict
from bench.sequences import EscRange, Plan, Segment, Sequence, compile_plan
from bench.thrust_map import StaticThrustMap

__all__ = ["RunOutcome", "esc_range_of", "plan_for", "rig_summary", "run_sequence"]


@dataclass(frozen=True)
class RunOutcome:
    result: RunResult
    run_dir: Path
    plan: Plan


def esc_range_of(rig: Any) -> EscRange:
    esc = rig.esc
    return EscRange(float(esc.idle_us), float(esc.min_us), float(esc.max_us))


def thrust_to_us_of(rig: Any):
    """The rig's static map as a thrust (N) -> command (us) function, or None."""
    tm = getattr(rig, "thrust_map", None)
    if tm is None:
        return None
    if callable(getattr(tm, "command_for", None)):
        return lambda f: float(tm.command_for(f))
    return StaticThrustMap.from_rig(tm, source=f"{_rig_name(rig)}: thrust_map").command_for


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
    limits = effective_limits(rig.limits, seq.limits, source=f"sequence {seq.name!r}")
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
    with indexed_run(out_root, seq.name, meta) as recorder:
        try:
            devices = open_rig(rig, seed=seed)
        except BaseException as exc:
            recorder.event(float("nan"), "device_error", label="open", detail={"error": str(exc)})
            recorder.finish("fail", f"could not open the rig: {exc}")
            raise
        try:
            try:
                runner = runner_factory(devices, plan, esc_range_of(rig), limits, recorder, options,
                                on_rows=on_rows, on_progress=on_progress, stop_event=stop_event)
            except BaseException as exc:
                recorder.finish("fail", f"runner did not start: {exc}")
                raise
            result = runner.run()
        finally:
            devices.close()
    return RunOutcome(result, recorder.run_dir, plan)
