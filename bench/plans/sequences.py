"""Bench sequences as data, and their compilation into a timed command plan.

A sequence is a list of small step records (arm, tare, hold, set/step throttle, ramp,
thrust step, checkpoint, disarm). It holds no devices, so it can be printed, stored in
``run.json`` and checked before anything spins. :func:`compile_plan` turns it into
:class:`Segment`s with start times and ESC commands in microseconds; thrust setpoints
in newtons go through the rig's static thrust map (Paper C section 4.4) at that point.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.errors import RigError, ThrustOutsideMap
from bench.paths.inputs import check_input

G0 = 9.80665  # standard gravity, m/s^2 (grams-force -> newtons)

__all__ = [
    "Arm",
    "Checkpoint",
    "Disarm",
    "EscRange",
    "Hold",
    "Plan",
    "Ramp",
    "Segment",
    "Sequence",
    "SetThrottle",
    "Step",
    "Tare",
    "ThrottleStep",
    "ThrustStep",
    "compile_plan",
    "format_plan",
    "load_sequence",
    "step_duration_s",
]


# --- steps -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Arm:
    """Arm the ESC and keep it at idle for ``hold_s`` (ESC start-up beeps)."""

    hold_s: float = 0.5
    kind: str = "arm"


@dataclass(frozen=True)
class Tare:
    """Motor at idle for ``duration_s``; the mean load-cell force becomes the zero."""

    duration_s: float = 0.5
    kind: str = "tare"


@dataclass(frozen=True)
class Hold:
    """Keep the present command for ``duration_s``."""

    duration_s: float
    kind: str = "hold"


@dataclass(frozen=True)
class SetThrottle:
    """Change the command to ``us`` at once (no time passes)."""

    us: float
    kind: str = "set_throttle"


@dataclass(frozen=True)
class ThrottleStep:
    """Step the command to ``us`` and hold it for ``hold_s``."""

    us: float
    hold_s: float
    kind: str = "throttle_step"


@dataclass(frozen=True)
class Ramp:
    """Move the command linearly to ``end_us`` (idle when None) over ``duration_s``, from
    ``start_us`` or, when that is None, from the present command."""

    end_us: float | None
    duration_s: float
    start_us: float | None = None
    kind: str = "ramp"


@dataclass(frozen=True)
class ThrustStep:
    """Go to the command that gives ``thrust_n`` on the static map (at once, or ramped
    over ``ramp_s`` for a soft start) and hold it ``hold_s``."""

    thrust_n: float
    hold_s: float
    ramp_s: float = 0.0
    kind: str = "thrust_step"


@dataclass(frozen=True)
class Checkpoint:
    """A labelled mark in the run's events (e.g. the start of a repeat); no time passes.
    One class for every bench: the IMU calibration plans use it too."""

    label: str
    kind: str = "checkpoint"


@dataclass(frozen=True)
class Disarm:
    """Command idle and disarm the ESC."""

    kind: str = "disarm"


Step = Arm | Tare | Hold | SetThrottle | ThrottleStep | Ramp | ThrustStep | Checkpoint | Disarm
_STEP_TYPES: dict[str, type] = {
    cls.kind: cls  # type: ignore[attr-defined]
    for cls in (Arm, Tare, Hold, SetThrottle, ThrottleStep, Ramp, ThrustStep, Checkpoint, Disarm)
}


@dataclass(frozen=True)
class Sequence:
    """A named list of steps; ``limits`` may only tighten the rig's limits."""

    name: str
    steps: tuple[Step, ...]
    limits: Mapping[str, float] = field(default_factory=dict)
    description: str = ""
    needs_thrust_map: bool = False
    source: str = field(default="", compare=False)  # the file it was read from, if any

    @property
    def thrust_setpoints_n(self) -> tuple[float, ...]:
        """The thrust targets of its thrust steps (the limits must leave them room)."""
        return tuple(float(s.thrust_n) for s in self.steps if isinstance(s, ThrustStep))

    @property
    def duration_s(self) -> float:
        """The rig time of the compiled plan (the sum of the steps' times), without
        compiling it."""
        return float(sum(map(step_duration_s, self.steps)))

    @property
    def where(self) -> str:
        """How messages name it: ``sequence 'name'``, with its file when it has one."""
        return f"sequence {self.name!r}" + (f" ({self.source})" if self.source else "")

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "limits": dict(self.limits),
            "steps": [dataclasses.asdict(s) for s in self.steps],
        }

    @staticmethod
    def from_dict(data: Mapping[str, Any], source: str = "<sequence>") -> Sequence:
        if not isinstance(data.get("steps"), list) or not data["steps"]:
            raise RigError(f"{source}: steps: expected a non-empty list of steps")
        steps = []
        for i, raw in enumerate(data.get("steps", [])):
            if not isinstance(raw, Mapping):
                raise RigError(f"{source}: steps[{i}]: expected a table with a kind, "
                               f"got {raw!r}")
            kind = raw.get("kind")
            cls = _STEP_TYPES.get(kind) if isinstance(kind, str) else None
            if cls is None:
                raise RigError(f"{source}: steps[{i}].kind: expected one of "
                               f"{sorted(_STEP_TYPES)}, got {kind!r}")
            known = [f.name for f in dataclasses.fields(cls) if f.name != "kind"]
            for key in raw:
                if key != "kind" and key not in known:
                    raise RigError(f"{source}: steps[{i}].{key}: unknown key for a {kind} "
                                   f"step; expected {', '.join(known) or 'none'}")
            for f in dataclasses.fields(cls):
                value = raw.get(f.name)
                if f.name in raw and "float" in str(f.type):
                    number = value if isinstance(value, int | float) \
                        and not isinstance(value, bool) else None
                    if number is None and not (value is None and "None" in str(f.type)):
                        raise RigError(f"{source}: steps[{i}].{f.name}: expected a number, "
                                       f"got {value!r}")
                    if number is not None and not math.isfinite(number):
                        raise RigError(f"{source}: steps[{i}].{f.name}: expected a finite "
                                       f"number, got {value!r}")
                    if number is not None and f.name.endswith("_s") and number < 0:
                        raise RigError(f"{source}: steps[{i}].{f.name}: expected a time "
                                       f">= 0 s, got {value!r}")
            try:
                steps.append(cls(**raw))
            except TypeError as exc:
                raise RigError(f"{source}: steps[{i}] ({kind}): {exc}") from None
        return Sequence(
            name=str(data.get("name", "custom")),
            steps=tuple(steps),
            limits=_limits_from(data.get("limits", {}), source),
            description=str(data.get("description", "")),
            needs_thrust_map=any(isinstance(s, ThrustStep) for s in steps),
            source="" if source == "<sequence>" else source,
        )


def step_duration_s(step: Step) -> float:
    """The rig time one step takes (its hold, duration and soft-start ramp)."""
    return float(sum(getattr(step, name, 0.0) or 0.0
                     for name in ("hold_s", "duration_s", "ramp_s")))


def _limits_from(raw: Any, source: str) -> dict[str, float]:
    """A sequence file's ``limits`` table: known names, finite numbers (whether they
    tighten the rig's limits is checked against the rig, ``safety.effective_limits``)."""
    from bench.engine.safety import LIMIT_FIELDS

    if not isinstance(raw, Mapping):
        raise RigError(f"{source}: limits: expected a table of NAME = number, got {raw!r}")
    out = {}
    for key, value in raw.items():
        if key not in LIMIT_FIELDS:
            raise RigError(f"{source}: limits.{key}: unknown limit; expected one of "
                           f"{', '.join(LIMIT_FIELDS)}")
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if not ok or not math.isfinite(value):
            raise RigError(f"{source}: limits.{key}: expected a finite number, got {value!r}")
        out[key] = float(value)
    return out


# --- sequence files ----------------------------------------------------------------------


def load_sequence(path: Path) -> Sequence:
    """A sequence from a JSON or TOML file (the ``to_dict`` layout: name, limits, steps)."""
    import json
    import tomllib

    check_input(path, "--sequence")
    try:
        text = Path(path).read_text(encoding="utf-8")
        data = tomllib.loads(text) if Path(path).suffix == ".toml" else json.loads(text)
    except FileNotFoundError:
        raise RigError(f"{path}: sequence file not found") from None
    except (OSError, ValueError) as exc:
        raise RigError(f"{path}: not a readable JSON/TOML sequence: {exc}") from None
    if not isinstance(data, dict):
        raise RigError(f"{path}: expected a table with name, limits and steps")
    return Sequence.from_dict(data, str(path))


# --- compiled plan -------------------------------------------------------------------------


@dataclass(frozen=True)
class EscRange:
    """The ESC commands a plan may use: idle (stopped) and the allowed min..max."""

    idle_us: float
    min_us: float
    max_us: float


@dataclass(frozen=True)
class Segment:
    """One timed piece of a plan: the command moves linearly from ``us_start`` to ``us_end``."""

    index: int
    kind: str
    label: str
    t_start_s: float
    duration_s: float
    us_start: float
    us_end: float
    setpoint_n: float = math.nan
    armed: bool = True
    #: the step this segment carries out: the runner dispatches on its type (kept out of
    #: comparisons and of the run record, which has ``kind`` and the sequence's steps)
    step: Any = field(default=None, compare=False, repr=False)

    def record(self) -> dict[str, Any]:
        """The segment as run.json stores it (every field but the step object)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if f.name != "step"}

    @property
    def t_end_s(self) -> float:
        return self.t_start_s + self.duration_s

    def command_at(self, t_s: float) -> float:
        if self.duration_s <= 0.0 or self.us_start == self.us_end:
            return self.us_end
        frac = min(max((t_s - self.t_start_s) / self.duration_s, 0.0), 1.0)
        return self.us_start + frac * (self.us_end - self.us_start)


@dataclass(frozen=True)
class Plan:
    """A compiled sequence, whatever the bench: the sequence it came from, its timed
    segments (each carrying its step: :class:`Segment` for the propulsion stand,
    ``bench.plans.calibration_sequences.HexapodSegment`` for the IMU bench) and the limits it
    was checked against where the bench checks motions before the run (the IMU bench's
    effective ``HexapodLimits``; None on the propulsion stand, whose limits are checked
    on every sample)."""

    sequence: Sequence
    segments: tuple[Any, ...]
    limits: Any = None

    @property
    def duration_s(self) -> float:
        return self.segments[-1].t_end_s if self.segments else 0.0


def compile_plan(
    seq: Sequence,
    esc: EscRange,
    thrust_to_us: Callable[[float], float] | None = None,
    allow_unmapped: bool = False,
) -> Plan:
    """Resolve times and commands; every command is checked against the ESC range.

    ``thrust_to_us`` maps a thrust setpoint (N) to a command (us) through the static map;
    it is needed only if the sequence has thrust steps. ``allow_unmapped`` (dry runs
    only) leaves the commands of thrust steps as NaN when there is no map yet.
    """
    t = 0.0
    us = esc.idle_us
    armed = False
    segs: list[Segment] = []

    step: Step | None = None

    def add(kind: str, label: str, dur: float, u0: float, u1: float, sp: float = math.nan):
        segs.append(Segment(len(segs), kind, label, t, dur, u0, u1, sp, armed, step))

    def check_us(value: float, i: int, what: str) -> float:
        if value == esc.idle_us:
            return value
        if not (esc.min_us <= value <= esc.max_us):
            raise RigError(f"sequence {seq.name!r}: steps[{i}] ({what}): command {value:.1f} us "
                           f"outside the ESC range {esc.min_us:g}-{esc.max_us:g} us")
        return value

    for i, step in enumerate(seq.steps):
        match step:
            case Arm(hold_s=hold):
                armed = True
                us = esc.idle_us
                add("arm", "arm", _dur(hold, i, seq), us, us)
            case Tare(duration_s=dur):
                if us != esc.idle_us:
                    raise RigError(f"sequence {seq.name!r}: steps[{i}] (tare): the motor must "
                                   "be at idle to tare")
                add("tare", "tare", _dur(dur, i, seq), us, us)
            case Hold(duration_s=dur):
                add("hold", "hold", _dur(dur, i, seq), us, us)
            case SetThrottle(us=target):
                us = check_us(target, i, "set_throttle")
                add("set_throttle", f"{us:.1f} us", 0.0, us, us)
            case ThrottleStep(us=target, hold_s=hold):
                us = check_us(target, i, "throttle_step")
                add("throttle_step", f"{us:.1f} us", _dur(hold, i, seq), us, us)
            case Ramp(end_us=end, duration_s=dur, start_us=start):
                u0 = us if start is None else check_us(start, i, "ramp start")
                u1 = esc.idle_us if end is None else check_us(end, i, "ramp end")
                add("ramp", f"ramp to {u1:.1f} us", _dur(dur, i, seq), u0, u1)
                us = u1
            case ThrustStep(thrust_n=target, hold_s=hold, ramp_s=ramp):
                if thrust_to_us is None and not allow_unmapped:
                    raise RigError(f"sequence {seq.name!r}: steps[{i}] (thrust_step) needs the "
                                   "rig's static thrust map; run `rotorbench sweep` first")
                if thrust_to_us is None:
                    target_us = math.nan
                else:
                    try:
                        mapped = float(thrust_to_us(target))
                    except ThrustOutsideMap as exc:  # the setpoint is wrong, not the map
                        raise RigError(f"{seq.where}: steps[{i}].thrust_n: {target:g} N is "
                                       f"outside the rig's static thrust map ({exc.lo:.3f}-"
                                       f"{exc.hi:.3f} N); choose a setpoint inside it or "
                                       "sweep a wider range") from None
                    target_us = check_us(mapped, i, f"thrust_step {target:.3f} N")
                if _dur(ramp, i, seq) > 0:
                    add("ramp", f"ramp to {target:.3f} N", ramp, us, target_us)
                    t = segs[-1].t_end_s
                us = target_us
                add("thrust_step", f"{target:.3f} N", _dur(hold, i, seq), us, us, target)
            case Checkpoint(label=label):
                add("checkpoint", label, 0.0, us, us)
            case Disarm():
                us = esc.idle_us
                add("disarm", "disarm", 0.0, us, us)
                armed = False
            case _:
                raise RigError(f"sequence {seq.name!r}: steps[{i}]: unknown step {step!r}")
        if us != esc.idle_us and not armed and not math.isnan(us):
            raise RigError(f"sequence {seq.name!r}: steps[{i}] ({step.kind}): command before arm")
        t = segs[-1].t_end_s
    return Plan(seq, tuple(segs))


def _dur(value: float, i: int, seq: Sequence) -> float:
    if not (value >= 0.0 and math.isfinite(value)):
        raise RigError(f"sequence {seq.name!r}: steps[{i}]: duration must be >= 0 s, got {value}")
    return float(value)


def format_plan(plan: Plan, max_rows: int | None = None) -> str:
    """The dry-run listing: one line per segment with times, commands and setpoints."""
    seq = plan.sequence
    lines = [f"sequence {seq.name}: {seq.description}".rstrip(": "),
             f"{len(plan.segments)} steps, {plan.duration_s:.2f} s"]
    if seq.limits:
        lines.append("tighter limits: " + ", ".join(f"{k}={v:g}" for k, v in seq.limits.items()))
    lines.append(f"{'#':>4} {'t_start_s':>10} {'dur_s':>7} {'kind':<14} {'us_start':>9} "
                 f"{'us_end':>9} {'setpoint_n':>10}  label")
    rows = plan.segments if max_rows is None else plan.segments[:max_rows]
    for s in rows:
        sp = "" if math.isnan(s.setpoint_n) else f"{s.setpoint_n:.3f}"
        u0 = "(map)" if math.isnan(s.us_start) else f"{s.us_start:.1f}"
        u1 = "(map)" if math.isnan(s.us_end) else f"{s.us_end:.1f}"
        lines.append(f"{s.index:>4} {s.t_start_s:>10.3f} {s.duration_s:>7.3f} {s.kind:<14} "
                     f"{u0:>9} {u1:>9} {sp:>10}  {s.label}")
    if max_rows is not None and len(plan.segments) > max_rows:
        lines.append(f"... {len(plan.segments) - max_rows} more steps")
    return "\n".join(lines)
