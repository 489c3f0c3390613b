"""Safety supervisor: checks every sample of every block against the run's limits.

Limits come from the rig file; a sequence may only tighten them (:func:`effective_limits`).
A trip names the limit, the channel, the value and the whole triggering sample, so the
run record says exactly why the motor was stopped. Checks are vectorised per block.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.errors import RigError
from drivers.contracts import Block

__all__ = ["LIMIT_FIELDS", "LimitTrip", "SafetySupervisor", "Trip", "check_room",
           "effective_limits",
           "limits_dict"]

# channel -> (limit field, test). "abs_above": |x| > limit; "above": x > limit; "below": x < limit.
_CHECKS: dict[str, tuple[tuple[str, str], ...]] = {
    "thrust_n": (("thrust_n", "abs_above"),),
    "current_a": (("current_a", "abs_above"),),
    "rpm": (("rpm", "above"),),
    "voltage_v": (("voltage_min_v", "below"), ("voltage_max_v", "above")),
    "temperature_c": (("temperature_c", "above"),),
}
LIMIT_FIELDS = ("thrust_n", "current_a", "rpm", "voltage_min_v", "voltage_max_v", "temperature_c")
_LOWEST_LIMIT = {"temperature_c": -50.0}  # every other limit is >= 0 (as in a rig file)
_LOWER_BOUNDS = {"voltage_min_v"}  # tightening raises these; every other limit is lowered
#: limits on a magnitude that is about 0 at idle (the ESC armed, the motor still): 0 would
#: trip on the first sample, so the run would arm the ESC only to stop at t = 0
_ABOVE_IDLE = {"thrust_n": "N", "current_a": "A", "rpm": "rpm"}


@dataclass(frozen=True)
class Trip:
    """Why and on which sample the supervisor stopped the run."""

    limit: str
    channel: str
    sensor: str
    t_s: float
    value: float
    limit_value: float
    sample: dict[str, float] = field(default_factory=dict)

    @property
    def message(self) -> str:
        op = "<" if self.limit in _LOWER_BOUNDS else ">"
        return (f"limit trip: {self.channel} = {self.value:.4g} {op} {self.limit} "
                f"{self.limit_value:.4g} at t = {self.t_s:.4f} s ({self.sensor})")

    def to_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "message": self.message}


class LimitTrip(Exception):
    """Raised by the supervisor; the runner turns it into a safe stop with status abort."""

    def __init__(self, trip: Trip) -> None:
        super().__init__(trip.message)
        self.trip = trip


def limits_dict(limits: Any) -> dict[str, float]:
    """The finite limit values of a Limits object or mapping, by field name."""
    raw = limits if isinstance(limits, Mapping) else {
        f: getattr(limits, f, None) for f in LIMIT_FIELDS
    }
    out: dict[str, float] = {}
    for key, value in raw.items():
        if value is None:
            continue
        value = float(value)
        if not math.isnan(value):
            out[key] = value
    return out


def effective_limits(rig_limits: Any, sequence_limits: Mapping[str, float],
                     source: str = "sequence",
                     thrust_setpoints_n: Iterable[float] = ()) -> dict[str, float]:
    """The rig's limits tightened by the sequence's; loosening raises RigError.

    Uses the rig's own ``Limits.tightened`` when it has one (the rig file's rule), and
    checks the result again here, so a sequence can never widen a limit. The result must
    leave the plan room (:func:`check_room`; ``thrust_setpoints_n``: the plan's targets).
    """
    base = limits_dict(rig_limits)
    for key, value in sequence_limits.items():
        if key not in LIMIT_FIELDS:
            raise RigError(f"{source}: limits.{key}: unknown limit; expected one of "
                           f"{', '.join(LIMIT_FIELDS)}")
        if not math.isfinite(float(value)):
            raise RigError(f"{source}: limits.{key}: expected a finite number, got {value!r}")
        lowest = _LOWEST_LIMIT.get(key, 0.0)  # the rig file's own lower bounds
        if float(value) < lowest:
            raise RigError(f"{source}: limits.{key}: {float(value):g} is below {lowest:g}; "
                           "a limit is a physical bound, not an offset")
    merged = dict(base)
    tightened = getattr(rig_limits, "tightened", None)
    if callable(tightened) and sequence_limits:
        other = dataclasses.replace(rig_limits, **dict(sequence_limits)) \
            if dataclasses.is_dataclass(rig_limits) and not isinstance(rig_limits, type) \
            else dict(sequence_limits)
        merged = limits_dict(tightened(other))
    else:
        merged.update({k: float(v) for k, v in sequence_limits.items()})
    for key, value in merged.items():
        if key not in base:
            continue
        looser = value < base[key] if key in _LOWER_BOUNDS else value > base[key]
        if looser:
            raise RigError(f"{source}: limits.{key} = {value:g} would loosen the rig's "
                           f"limit {base[key]:g}; a sequence may only tighten limits")
    check_room(merged, source, thrust_setpoints_n)
    return merged


def check_room(limits: Mapping[str, float], source: str,
               thrust_setpoints_n: Iterable[float] = ()) -> None:
    """Refuse limits under which the run could only trip, before anything is armed: a
    magnitude limit of 0 (idle already reaches it), an undervoltage bound at or above the
    overvoltage bound (no supply voltage passes both), a thrust limit at or below a
    thrust setpoint of the plan (the step would trip as it reaches its target)."""
    for key, unit in _ABOVE_IDLE.items():
        if key in limits and limits[key] <= 0:
            raise RigError(f"{source}: limits.{key} = {limits[key]:g}: expected > 0 {unit}; "
                           "the idle reading already reaches it (the run would trip at t = 0)")
    lo, hi = limits.get("voltage_min_v"), limits.get("voltage_max_v")
    if lo is not None and hi is not None and lo >= hi:
        raise RigError(f"{source}: limits.voltage_min_v = {lo:g} V is not below "
                       f"voltage_max_v = {hi:g} V: no supply voltage passes both")
    top = max((abs(float(t)) for t in thrust_setpoints_n), default=None)
    if top is not None and "thrust_n" in limits and limits["thrust_n"] <= top:
        raise RigError(f"{source}: limits.thrust_n = {limits['thrust_n']:g} N leaves no room "
                       f"for the plan's thrust setpoint {top:g} N (the step would trip on "
                       "reaching it); raise the limit above the setpoints or lower them")


class SafetySupervisor:
    """Checks blocks against fixed limits; the first violating sample (earliest) trips."""

    def __init__(self, limits: Mapping[str, float]) -> None:
        self.limits = dict(limits)
        self.trip: Trip | None = None
        # channel -> the (limit name, test, value) that apply, resolved once for the run,
        # and whether any of them needs the block's minimum
        self._checks: dict[str, tuple[tuple[tuple[str, str, float], ...], bool]] = {}
        for channel, tests in _CHECKS.items():
            active = tuple((name, test, self.limits[name]) for name, test in tests
                           if name in self.limits)
            if active:
                self._checks[channel] = (active, any(t != "above" for _, t, _ in active))

    def check(self, blocks: Mapping[str, Block]) -> Trip | None:
        """Return the earliest violation in these blocks (and latch it), or None."""
        best: Trip | None = None
        checks = self._checks
        for role, block in blocks.items():
            if len(block) == 0:
                continue
            for channel, values in block.values.items():
                entry = checks.get(channel)
                if entry is None:
                    continue
                tests, needs_lo = entry
                v = np.asarray(values, dtype=float)
                # NaN-skipping reductions first: the usual block has no violation at all
                hi = np.fmax.reduce(v)
                lo = np.fmin.reduce(v) if needs_lo else hi
                for limit_name, test, limit in tests:
                    if test == "abs_above":
                        if not (hi > limit or lo < -limit):
                            continue
                        bad = np.abs(v) > limit
                    elif test == "above":
                        if not hi > limit:
                            continue
                        bad = v > limit
                    else:
                        if not lo < limit:
                            continue
                        bad = v < limit
                    i = int(np.argmax(bad))
                    t = float(block.t_s[i])
                    if best is None or t < best.t_s:
                        sample = {"t_s": t, **{c: float(block.values[c][i]) for c in block.values}}
                        best = Trip(limit_name, channel, role, t, float(v[i]), limit, sample)
        if best is not None and self.trip is None:
            self.trip = best
        return best

    def raise_if_tripped(self, blocks: Mapping[str, Block]) -> None:
        trip = self.check(blocks)
        if trip is not None:
            raise LimitTrip(trip)
