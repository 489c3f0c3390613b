"""Paper A's calibration stages as hexapod sequences (data), and their compiled plans.

The IMU bench's own steps (set pivot, rest, move) beside the shared ones of
:mod:`bench.plans.sequences` (``Checkpoint``); every compiled segment carries its step, and the
one runner (:mod:`bench.plan_runner.runner`) dispatches on the step's type.

A sequence (:class:`bench.plans.sequences.Sequence`, one class for every bench) is a list of
small steps: set the pivot, rest (record with
the platform still), move (run one of :mod:`drivers.hexapod_motions`' trajectories),
checkpoint. Every step that takes time carries the calibration log's ``phase`` label
(``bias, gyro, acc, lever_x, lever_y, lever_z, verify``), so the recorded rows are the
log :mod:`analysis.imu_log` reads. A sequence holds no device: :func:`compile_plan` checks
every motion against the rig's hexapod limits (tightened by the sequence, never loosened)
and :func:`format_plan` prints it (the dry run).

Stages (Paper A sections 3-4): a static hold for the gyro bias (10 000 samples, A.12); the
gyro sines about x, y, z at 0.6, 0.65, 0.7 Hz, 4°, over whole 20 s common periods; the
accelerometer motion (translations at 1.1-1.5 Hz with one slow 0.01 Hz rotation about each
axis in turn); the lever-arm motions (5° at 0.7 Hz about x, y, z in turn); the independent
verification motion (0.1-1 Hz, 5°, 0.1 m).
"""

# Hexapod steps (SetPivot, Rest, Move) ride in plans.sequences.Sequence, whose steps are
# typed as the propulsion bench's: the checker refuses each such Sequence(...) call.
# pyright: reportArgumentType=false

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.errors import RigError
from bench.plans.sequences import Checkpoint, Plan, Sequence
from drivers.contracts import HexapodLimits, limit_violations
from drivers.hexapod_kinematics import body_frame_state, motion_peaks
from drivers.hexapod_motions import (
    Motion,
    acc_motion,
    gyro_sines,
    lever_arm_motion,
    verification_motion,
)

__all__ = [
    "Checkpoint",
    "HexapodSegment",
    "Move",
    "Rest",
    "SetPivot",
    "compile_plan",
    "effective_hexapod_limits",
    "format_plan",
    "paper_a_sequences",
    "phase_at",
    "step_at",
]

PHASES = ("bias", "gyro", "acc", "lever_x", "lever_y", "lever_z", "verify")
SETTLE_S = 0.5  # rest before and after motions: the record brackets every motion at rest


@dataclass(frozen=True)
class SetPivot:
    """Set the hexapod's pivot (m, platform coordinates); None = the rig's pivot (the CG)."""

    pivot_m: tuple[float, float, float] | None = None
    kind: str = "set_pivot"


@dataclass(frozen=True)
class Rest:
    """Keep the platform still for ``duration_s`` while recording ``phase``."""

    duration_s: float
    phase: str
    kind: str = "rest"


@dataclass(frozen=True)
class Move:
    """Upload and run ``motion`` (starts and ends at rest at home) recording ``phase``."""

    motion: Motion
    phase: str
    kind: str = "move"


HexStep = SetPivot | Rest | Move | Checkpoint


@dataclass(frozen=True)
class HexapodSegment:
    """One timed piece of a plan; ``peaks`` are the motion's largest values (moves)."""

    index: int
    kind: str
    label: str
    phase: str
    t_start_s: float
    duration_s: float
    motion: Motion | None = None
    pivot_m: tuple[float, float, float] | None = None
    peaks: Mapping[str, float] = field(default_factory=dict)
    #: the step this segment carries out: the runner dispatches on its type
    step: Any = field(default=None, compare=False, repr=False)

    @property
    def t_end_s(self) -> float:
        return self.t_start_s + self.duration_s


def _timed(plan: Plan) -> tuple[list[HexapodSegment], np.ndarray]:
    timed = [s for s in plan.segments if s.duration_s > 0]
    return timed, np.array([s.t_start_s for s in timed])


def phase_at(plan: Plan, t_s: np.ndarray) -> np.ndarray:
    """The phase label of the (timed) segment the plan schedules at each time."""
    timed, starts = _timed(plan)
    i = np.clip(np.searchsorted(starts, t_s, side="right") - 1, 0, len(timed) - 1)
    return np.array([s.phase for s in timed], dtype=object)[i]


def step_at(plan: Plan, t_s: np.ndarray) -> np.ndarray:
    """The index of the (timed) segment the plan schedules at each time."""
    timed, starts = _timed(plan)
    i = np.clip(np.searchsorted(starts, t_s, side="right") - 1, 0, len(timed) - 1)
    return np.array([s.index for s in timed], dtype=np.int32)[i]


def effective_hexapod_limits(rig_limits: HexapodLimits, tighter: Mapping[str, float],
                             source: str = "sequence") -> HexapodLimits:
    """The rig's hexapod limits with a sequence's tighter values; loosening is refused."""
    base = rig_limits.as_dict()
    out = dict(base)
    for key, value in tighter.items():
        if key not in base:
            raise RigError(f"{source}: limits.{key}: unknown hexapod limit; expected one of "
                           f"{', '.join(base)}")
        v = float(value)
        if not (math.isfinite(v) and v > 0):
            raise RigError(f"{source}: limits.{key}: expected a positive number, got {value!r}")
        if v > base[key]:
            raise RigError(f"{source}: limits.{key} = {v:g} would loosen the rig's limit "
                           f"{base[key]:g}; a sequence may only tighten limits")
        out[key] = v
    return HexapodLimits(**out)


def peaks_of(motion: Motion, step_s: float = 0.002) -> dict[str, float]:
    """Largest position, angle, velocity, acceleration, body rate and angular acceleration."""
    t = np.arange(0.0, motion.duration_s + step_s, step_s)
    pose, vel, acc = motion.evaluate(t)
    return motion_peaks(pose, vel, acc, body_frame_state(t, pose, vel, acc))


def compile_plan(seq: Sequence, rig_limits: HexapodLimits,
                 pivot_m: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Plan:
    """Resolve times, pivots and phases; refuse any motion outside the effective limits."""
    limits = effective_hexapod_limits(rig_limits, seq.limits, f"sequence {seq.name!r}")
    segs: list[HexapodSegment] = []
    t = 0.0
    for i, step in enumerate(seq.steps):
        where = f"sequence {seq.name!r}: steps[{i}] ({step.kind})"
        phase = next((s.phase for s in seq.steps[i:] if isinstance(s, Rest | Move)), "")
        match step:
            case SetPivot(pivot_m=p):
                pv = tuple(float(v) for v in (pivot_m if p is None else p))
                if len(pv) != 3 or not all(math.isfinite(v) for v in pv):
                    raise RigError(f"{where}: pivot_m: expected three finite numbers (m)")
                segs.append(HexapodSegment(len(segs), "set_pivot", "pivot " + _vec(pv), phase,
                                           t, 0.0, pivot_m=pv, step=step))  # type: ignore[arg-type]
            case Rest(duration_s=d, phase=ph):
                _check_phase(ph, where)
                if not (d > 0 and math.isfinite(d)):
                    raise RigError(f"{where}: duration_s must be > 0 s, got {d!r}")
                segs.append(HexapodSegment(len(segs), "rest", f"rest {d:g} s", ph, t, float(d),
                                           step=step))
            case Move(motion=m, phase=ph):
                _check_phase(ph, where)
                peaks = peaks_of(m)
                bad = limit_violations(peaks, limits)
                if bad:
                    text = "; ".join(f"{n} = {v:.4g} > {lim:.4g}" for n, v, lim in bad)
                    raise RigError(f"{where}: motion {m.name!r} exceeds the hexapod limits: "
                                   f"{text}")
                segs.append(HexapodSegment(len(segs), "move", m.name, ph, t, float(m.duration_s),
                                           motion=m, peaks=peaks, step=step))
            case Checkpoint(label=label):
                segs.append(HexapodSegment(len(segs), "checkpoint", label, phase, t, 0.0,
                                           step=step))
            case _:
                raise RigError(f"{where}: unknown step {step!r}")
        t = segs[-1].t_end_s
    if not any(s.duration_s > 0 for s in segs):
        raise RigError(f"sequence {seq.name!r}: no step takes time; nothing to record")
    return Plan(seq, tuple(segs), limits)


def _check_phase(phase: str, where: str) -> None:
    if phase not in PHASES:
        raise RigError(f"{where}: phase {phase!r}: expected one of {', '.join(PHASES)}")


def _vec(v: tuple[float, ...]) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"


def format_plan(plan: Plan) -> str:
    """The dry-run listing: one line per step with times, phase and the motion's peaks."""
    seq = plan.sequence
    lim = plan.limits
    lines = [f"sequence {seq.name}: {seq.description}".rstrip(": "),
             f"{len(plan.segments)} steps, {plan.duration_s:.2f} s"]
    if seq.limits:
        lines.append("tighter limits: " + ", ".join(f"{k}={v:g}" for k, v in seq.limits.items()))
    lines.append(f"{'#':>3} {'t_start_s':>9} {'dur_s':>7} {'kind':<10} {'phase':<8} "
                 f"{'pos mm':>7} {'ang deg':>7} {'v m/s':>6} {'a m/s2':>6} {'w rad/s':>7} "
                 f"{'dw rad/s2':>9}  label")
    for s in plan.segments:
        p = s.peaks
        peaks = (f"{p['position_m'] * 1e3:>7.1f} {math.degrees(p['angle_rad']):>7.2f} "
                 f"{p['velocity_m_s']:>6.3f} {p['acceleration_m_s2']:>6.2f} "
                 f"{p['rate_rad_s']:>7.3f} {p['angular_acceleration_rad_s2']:>9.3f}"
                 if p else f"{'':>7} {'':>7} {'':>6} {'':>6} {'':>7} {'':>9}")
        lines.append(f"{s.index:>3} {s.t_start_s:>9.2f} {s.duration_s:>7.2f} {s.kind:<10} "
                     f"{s.phase:<8} {peaks}  {s.label}")
    lines.append(f"limits: {lim.position_m * 1e3:g} mm, {math.degrees(lim.angle_rad):.1f} deg, "
                 f"{lim.velocity_m_s:g} m/s, {lim.acceleration_m_s2:g} m/s2, "
                 f"{lim.rate_rad_s:g} rad/s, {lim.angular_acceleration_rad_s2:g} rad/s2")
    return "\n".join(lines)


# --- Paper A ---------------------------------------------------------------------------------


def bias_sequence(samples: int = 10_000, rate_hz: float = 100.0) -> Sequence:
    """Paper A section 4.1: the platform holds still for ``samples`` IMU samples (A.12)."""
    if samples < 2:
        raise RigError(f"bias hold: expected at least 2 samples, got {samples}")
    return Sequence(
        "cal_bias", (SetPivot(), Rest(samples / rate_hz, "bias"), Rest(0.1, "bias")),
        description=f"Paper A 4.1: static hold, {samples} samples at {rate_hz:g} Hz")


def gyro_sequence(beats: int = 2) -> Sequence:
    """Paper A section 4.2: sines about x, y, z at 0.6/0.65/0.7 Hz, 4°, whole 20 s periods."""
    m = gyro_sines(beats=beats)
    return Sequence(
        "cal_gyro", (SetPivot(), Rest(SETTLE_S, "gyro"), Move(m, "gyro"),
                     Rest(SETTLE_S, "gyro")),
        description=f"Paper A 4.2: 4 deg sines at 0.6, 0.65, 0.7 Hz, {beats} x 20 s")


def acc_sequence(rotation_hz: float = 0.01) -> Sequence:
    """Paper A section 3.2: rapid translations with one slow rotation about each axis."""
    steps: list[HexStep] = [SetPivot(), Rest(SETTLE_S, "acc")]
    for a in "xyz":
        steps += [Checkpoint(f"slow rotation about {a}"),
                  Move(acc_motion(a, rotation_hz=rotation_hz), "acc"), Rest(SETTLE_S, "acc")]
    return Sequence(
        "cal_acc", tuple(steps),
        description=f"Paper A 3.2: translations 1.1-1.5 Hz, {rotation_hz:g} Hz rotation "
                    "about x, y, z in turn")


def lever_sequence(duration_s: float = 30.0) -> Sequence:
    """Paper A section 4.3: 5° at 0.7 Hz about x, y and z in turn."""
    steps: list[HexStep] = [SetPivot()]
    for a in "xyz":
        steps += [Rest(SETTLE_S, f"lever_{a}"),
                  Move(lever_arm_motion(a, duration_s=duration_s), f"lever_{a}")]
    steps.append(Rest(SETTLE_S, "lever_z"))
    return Sequence(
        "cal_lever", tuple(steps),
        description=f"Paper A 4.3: 5 deg at 0.7 Hz about x, y, z, {duration_s:g} s each")


def verify_sequence(duration_s: float = 60.0) -> Sequence:
    """Paper A section 4.4: the independent multi-sine, 0.1-1 Hz, 5° and 0.1 m."""
    return Sequence(
        "cal_verify", (SetPivot(), Rest(SETTLE_S, "verify"),
                       Move(verification_motion(duration_s=duration_s), "verify"),
                       Rest(SETTLE_S, "verify")),
        description=f"Paper A 4.4: independent verification motion, {duration_s:g} s")


def paper_a_sequences(rate_hz: float = 100.0, quick: bool = False) -> list[Sequence]:
    """Every stage of Paper A in order. ``quick`` shortens the stages for tests (3000-sample
    hold, 0.02 Hz slow rotation, 20 s lever-arm and 30 s verification motions; the gyro
    sines keep their two 20 s beats) as ``paper_a_protocol(short=True)`` does."""
    if quick:
        return [bias_sequence(3000, rate_hz), gyro_sequence(2), acc_sequence(0.02),
                lever_sequence(20.0), verify_sequence(30.0)]
    return [bias_sequence(10_000, rate_hz), gyro_sequence(2), acc_sequence(0.01),
            lever_sequence(30.0), verify_sequence(60.0)]
