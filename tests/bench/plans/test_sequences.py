"""Sequences are data: Paper C's Step 1 / Step 2 shapes, compilation, dry-run listing."""

from __future__ import annotations

import math

import pytest

from bench.errors import RigError
from bench.plans.sequences import (
    G0,
    Arm,
    Disarm,
    EscRange,
    Ramp,
    Sequence,
    ThrottleStep,
    ThrustStep,
    compile_plan,
    format_plan,
)
from bench.plans.stand_sequences import hover_band_n, step1, step2, sweep

ESC = EscRange(idle_us=1000.0, min_us=1000.0, max_us=2000.0)


def linear_map(thrust_n: float) -> float:
    return 1100.0 + 200.0 * thrust_n  # 0..4.5 N over 1100..2000 us


def test_hover_band_is_the_papers_175_to_325_grams():
    low, high = hover_band_n()  # 1 kg quad, 4 rotors, 30 % margin (Paper C section 4)
    assert low / G0 * 1000 == pytest.approx(175.0)
    assert high / G0 * 1000 == pytest.approx(325.0)
    assert hover_band_n(2.0, 4, 0.3)[0] == pytest.approx(2 * low)


def test_step1_alternates_between_the_two_levels_repeats_times():
    low, high = hover_band_n()
    seq = step1(repeats=20)
    levels = [s.thrust_n for s in seq.steps if isinstance(s, ThrustStep)]
    assert levels[0] == low  # spin-up to the low level
    assert levels[1:] == [high, low] * 20
    assert all(s.hold_s >= 0.5 for s in seq.steps if isinstance(s, ThrustStep))
    assert isinstance(seq.steps[0], Arm) and isinstance(seq.steps[-1], Disarm)


def test_step2_amplitude_decreases_and_ends_on_step1_values():
    low, high = hover_band_n()
    plan = compile_plan(step2(repeats=2), ESC, linear_map)
    sp = [s.setpoint_n for s in plan.segments if s.kind == "thrust_step"]
    assert min(sp) == pytest.approx(low) and max(sp) == pytest.approx(high)
    rising = sp[1:8]  # first repeat, rising half: high, dip, high, dip, high, dip, high
    assert rising[0] == high and rising[-1] == high
    dips = [high - x for x in rising[1::2]]
    assert dips == sorted(dips, reverse=True) and dips[-1] > 0
    # each half ends with a settled hold at a stationary value
    holds = [s for s in plan.segments if s.kind == "hold"]
    assert {round(h.us_start, 6) for h in holds[:2]} == {round(linear_map(high), 6),
                                                         round(linear_map(low), 6)}


def test_compile_times_are_contiguous_and_commands_in_range():
    plan = compile_plan(step1(repeats=3), ESC, linear_map)
    t = 0.0
    for seg in plan.segments:
        assert seg.t_start_s == pytest.approx(t)
        t = seg.t_end_s
        assert seg.us_start == ESC.idle_us or ESC.min_us <= seg.us_start <= ESC.max_us
    assert plan.duration_s == pytest.approx(t)
    assert plan.segments[-1].kind == "disarm" and plan.segments[-1].us_end == ESC.idle_us


def test_ramp_interpolates_the_command():
    plan = compile_plan(sweep(1200.0, 1800.0, 10.0), ESC)
    ramp = max((s for s in plan.segments if s.kind == "ramp"), key=lambda s: s.duration_s)
    assert ramp.command_at(ramp.t_start_s + 5.0) == pytest.approx(1500.0)
    assert ramp.command_at(ramp.t_end_s + 1.0) == pytest.approx(1800.0)


def test_command_outside_the_esc_range_names_the_step():
    seq = Sequence("bad", (Arm(), ThrottleStep(2100.0, 1.0), Disarm()))
    with pytest.raises(RigError, match=r"steps\[1\].*2100.0 us"):
        compile_plan(seq, ESC)


def test_command_before_arm_is_refused():
    with pytest.raises(RigError, match="before arm"):
        compile_plan(Sequence("bad", (ThrottleStep(1500.0, 1.0),)), ESC)


def test_thrust_steps_need_a_map_except_in_a_dry_run():
    with pytest.raises(RigError, match="thrust map"):
        compile_plan(step1(repeats=1), ESC, None)
    plan = compile_plan(step1(repeats=1), ESC, None, allow_unmapped=True)
    assert any(math.isnan(s.us_end) for s in plan.segments)
    assert "(map)" in format_plan(plan)


def test_negative_duration_and_bad_repeats_are_refused():
    with pytest.raises(RigError, match="duration"):
        compile_plan(Sequence("bad", (Arm(), Ramp(1500.0, -1.0))), ESC)
    with pytest.raises(RigError, match="repeats"):
        step1(repeats=0)


def test_dict_round_trip_keeps_every_step():
    seq = step2(repeats=2)
    back = Sequence.from_dict(seq.to_dict())
    assert back.steps == seq.steps and back.name == seq.name


def test_from_dict_names_a_bad_step():
    with pytest.raises(RigError, match=r"steps\[1\]\.kind"):
        Sequence.from_dict({"steps": [{"kind": "arm"}, {"kind": "fly"}]}, "my.json")


def test_format_plan_lists_every_step_with_times_and_commands():
    plan = compile_plan(step1(repeats=2), ESC, linear_map)
    text = format_plan(plan)
    lines = text.splitlines()
    assert len(lines) == 3 + len(plan.segments)
    assert f"{linear_map(hover_band_n()[1]):.1f}" in text
    assert f"{plan.duration_s:.2f} s" in lines[1]
