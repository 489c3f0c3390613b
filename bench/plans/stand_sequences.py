"""Paper C's sequences for the propulsion stand: Step 1, Step 2 and the slow sweep.

Built from the step records of :mod:`bench.plans.sequences`; a repeated sequence is
checked against the run's bounds from one repeat, before its steps exist (a huge
``--repeats`` would otherwise fill the memory before the budget could refuse it).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from bench.errors import RigError
from bench.plans.run_budget import check_duration
from bench.plans.sequences import (
    G0,
    Arm,
    Checkpoint,
    Disarm,
    Hold,
    Ramp,
    Sequence,
    Step,
    Tare,
    ThrustStep,
    step_duration_s,
)

__all__ = ["MAX_PLAN_STEPS", "hover_band_n", "step1", "step2", "sweep"]


def hover_band_n(
    mass_kg: float = 1.0, rotors: int = 4, margin: float = 0.30
) -> tuple[float, float]:
    """Thrust per rotor at hover -margin and +margin, in newtons.

    Paper C section 4: a 1.0 kg quadcopter needs 250 g per propeller in hover; the
    standard 30 % control margin gives the 175 g - 325 g band of Step 1 and Step 2.
    """
    hover_n = mass_kg * G0 / rotors
    return hover_n * (1.0 - margin), hover_n * (1.0 + margin)


def _spin_up(low_n: float, settle_s: float) -> list[Step]:
    # Tare with the motor stopped, then a soft start to the low level and time to settle.
    return [Arm(), Tare(0.5), ThrustStep(low_n, hold_s=settle_s, ramp_s=1.0)]


def _spin_down(idle_ramp_s: float = 1.0) -> list[Step]:
    return [Checkpoint("spin-down"), Ramp(end_us=None, duration_s=idle_ramp_s),
            Hold(0.5), Disarm()]


def step1(
    repeats: int = 20,
    hold_s: float = 0.5,
    settle_s: float = 1.0,
    band_n: tuple[float, float] | None = None,
) -> Sequence:
    """Paper C Step 1: a thrust step from hover -30 % to +30 % and back, ``repeats`` times.

    Each level is held ``hold_s``: the slowest mode of Table C.1 (standard firmware,
    20 ms delay, tau_dn 78 ms) has settled to within 0.2 % after 0.5 s.
    """
    low, high = band_n or hover_band_n()
    _check_repeats(repeats)
    _check_hold(hold_s)

    def repeat(i: int) -> list[Step]:
        return [Checkpoint(f"repeat {i + 1}"), ThrustStep(high, hold_s), ThrustStep(low, hold_s)]

    return _repeated("step1", low, settle_s, repeat, repeats,
                     f"Paper C Step 1: {low:.3f} N <-> {high:.3f} N, {repeats} repeats, "
                     f"{hold_s:g} s per level")


def step2(
    repeats: int = 20,
    hold_s: float = 0.5,
    dwell_s: float = 0.1,
    fractions: tuple[float, ...] = (0.75, 0.5, 0.25),
    settle_s: float = 1.0,
    band_n: tuple[float, float] | None = None,
) -> Sequence:
    """Paper C Step 2: decreasing amplitude, the same stationary values as Step 1.

    The thesis text gives only this description (the figure is not in the text), so the
    shape is our reading of it: the rising part steps from the low to the high level and
    then dips back towards the low level by ``fractions`` of the band (each excursion held
    ``dwell_s``, shorter than the settling time), ending settled at the high level; the
    falling part mirrors it and ends settled at the low level.
    """
    low, high = band_n or hover_band_n()
    _check_repeats(repeats)
    _check_hold(hold_s)
    span = high - low

    def repeat(i: int) -> list[Step]:
        steps: list[Step] = [Checkpoint(f"repeat {i + 1} rising"), ThrustStep(high, dwell_s)]
        for f in fractions:
            steps += [ThrustStep(high - f * span, dwell_s), ThrustStep(high, dwell_s)]
        steps += [Hold(hold_s), Checkpoint(f"repeat {i + 1} falling"), ThrustStep(low, dwell_s)]
        for f in fractions:
            steps += [ThrustStep(low + f * span, dwell_s), ThrustStep(low, dwell_s)]
        return [*steps, Hold(hold_s)]

    return _repeated("step2", low, settle_s, repeat, repeats,
                     f"Paper C Step 2: decreasing amplitude {fractions} between {low:.3f} N "
                     f"and {high:.3f} N, {repeats} repeats")


def _repeated(name: str, low: float, settle_s: float, repeat: Callable[[int], list[Step]],
              repeats: int, description: str) -> Sequence:
    """Spin up to ``low``, ``repeats`` times ``repeat(i)``, spin down: a thrust-step plan,
    its length checked from one repeat before the steps are built (a huge ``repeats`` is
    refused without building them)."""
    _check_length(name, _spin_up(low, settle_s), repeat(0), repeats, _spin_down())
    steps: list[Step] = _spin_up(low, settle_s)
    for i in range(repeats):
        steps += repeat(i)
    steps += _spin_down()
    return Sequence(name=name, steps=tuple(steps), description=description,
                    needs_thrust_map=True)


def sweep(start_us: float = 1100.0, end_us: float = 1900.0, duration_s: float = 20.0) -> Sequence:
    """Slow ramp for the static maps (Paper C section 4.4, Fig. C.13 and C.14).

    The command rises slowly so the dynamics hardly matter (about 40 us/s by default,
    against time constants of 30-80 ms), while thrust, current and speed are recorded.
    """
    if not end_us > start_us:
        raise RigError(f"sweep: end_us ({end_us}) must be above start_us ({start_us})")
    if not (math.isfinite(duration_s) and duration_s > 0):
        # a zero-length ramp would be a full-range throttle step, not a sweep
        raise RigError(f"sweep: duration must be a time > 0 s, got {duration_s:g}")
    steps: tuple[Step, ...] = (
        Arm(),
        Tare(0.5),
        Ramp(end_us=start_us, duration_s=1.0),
        Hold(1.0),
        Checkpoint("sweep up"),
        Ramp(end_us=end_us, duration_s=duration_s),
        Checkpoint("spin-down"),
        Ramp(end_us=None, duration_s=2.0),
        Hold(0.5),
        Disarm(),
    )
    return Sequence(
        name="sweep",
        steps=steps,
        description=f"slow ramp {start_us:g} -> {end_us:g} us over {duration_s:g} s",
    )


#: The most steps a repeated sequence may build: a day of Step 1 at its 0.5 s holds is
#: 259 000; --repeats 3000000 --hold 1e-3 (under 2 h) used to take 2.6 GB.
MAX_PLAN_STEPS = 300_000


def _check_length(name: str, head: list[Step], one: list[Step], repeats: int,
                  tail: list[Step]) -> None:
    """Refuse a repeated sequence longer than a run may last before its steps exist: the
    length is projected from one repeat, in constant memory (``--repeats 100000000``
    built 16 GB of steps before the budget check could refuse it)."""
    duration = (sum(map(step_duration_s, head)) + repeats * sum(map(step_duration_s, one))
                + sum(map(step_duration_s, tail)))
    check_duration(duration, f"sequence {name!r} ({repeats} repeats)")
    steps = len(head) + repeats * len(one) + len(tail)
    if steps > MAX_PLAN_STEPS:  # short holds: a short plan of very many steps
        raise RigError(f"sequence {name!r} ({repeats} repeats): {steps} steps, more than "
                       f"the {MAX_PLAN_STEPS} a plan may hold (about 1.4 kB of memory each "
                       "with its segment); lower --repeats or split it into several runs")


def _check_repeats(repeats: int) -> None:
    if repeats < 1:
        raise RigError(f"--repeats: expected a positive integer, got {repeats}")


def _check_hold(hold_s: float) -> None:
    if not (math.isfinite(hold_s) and hold_s > 0):
        raise RigError(f"--hold: expected a time > 0 s per level, got {hold_s:g}")
