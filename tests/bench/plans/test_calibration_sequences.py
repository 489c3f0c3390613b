"""Paper A stages as hexapod sequences: plans, dry runs, limits that only tighten."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bench.errors import RigError
from bench.plans.calibration_sequences import (
    Move,
    Rest,
    SetPivot,
    compile_plan,
    effective_hexapod_limits,
    format_plan,
    paper_a_sequences,
    phase_at,
)
from bench.plans.sequences import Sequence
from drivers.contracts import HexapodLimits
from drivers.hexapod_motions import gyro_sines, lever_arm_motion

LIMITS = HexapodLimits()


def _phase_durations(plan) -> dict[str, float]:
    out: dict[str, float] = {}
    for s in plan.segments:
        out[s.phase] = out.get(s.phase, 0.0) + s.duration_s
    return out


def test_paper_a_stages_cover_every_phase_of_the_log_format() -> None:
    plans = [compile_plan(s, LIMITS) for s in paper_a_sequences()]
    phases = set().union(*(_phase_durations(p) for p in plans))
    assert phases == {"bias", "gyro", "acc", "lever_x", "lever_y", "lever_z", "verify"}
    names = [p.sequence.name for p in plans]
    assert names == ["cal_bias", "cal_gyro", "cal_acc", "cal_lever", "cal_verify"]


def test_bias_hold_is_10000_samples_and_motions_match_paper_a() -> None:
    bias, gyro, acc, lever, verify = [compile_plan(s, LIMITS) for s in paper_a_sequences(100.0)]
    hold = next(s for s in bias.segments if s.kind == "rest")
    assert round(hold.duration_s * 100.0) == 10_000
    move = next(s for s in gyro.segments if s.kind == "move")
    freqs = sorted(t[0][1] for t in move.motion.terms[3:])
    assert freqs == [0.6, 0.65, 0.7]
    amps = [t[0][0] for t in move.motion.terms[3:]]
    assert np.allclose(np.degrees(amps), 4.0)
    # whole 20 s common periods between the fades
    assert (move.duration_s - 2 * move.motion.ramp_s) % 20.0 == pytest.approx(0.0)
    rot = [s.motion for s in acc.segments if s.kind == "move"]
    assert len(rot) == 3 and all(m.duration_s > 100.0 for m in rot)  # 0.01 Hz: one period
    assert [s.phase for s in lever.segments if s.kind == "move"] == \
        ["lever_x", "lever_y", "lever_z"]
    v = next(s for s in verify.segments if s.kind == "move")
    assert v.peaks["position_m"] == pytest.approx(0.1, rel=0.01)
    assert math.degrees(v.peaks["angle_rad"]) == pytest.approx(5.0, rel=0.01)


def test_quick_stages_are_shorter_but_complete() -> None:
    full = sum(compile_plan(s, LIMITS).duration_s for s in paper_a_sequences())
    quick = sum(compile_plan(s, LIMITS).duration_s for s in paper_a_sequences(quick=True))
    assert quick < 0.6 * full
    assert len(paper_a_sequences(quick=True)) == len(paper_a_sequences())


def test_dry_run_lists_steps_phases_and_peaks() -> None:
    text = format_plan(compile_plan(paper_a_sequences()[1], LIMITS))
    assert "cal_gyro" in text and "gyro_sines" in text and "limits:" in text
    assert "4.00" in text  # 4 deg peak angle


def test_sequence_may_tighten_limits_but_never_loosen() -> None:
    seq = replace(paper_a_sequences()[3], limits={"rate_rad_s": 0.5})
    assert compile_plan(seq, LIMITS).limits.rate_rad_s == 0.5
    with pytest.raises(RigError, match="loosen"):
        compile_plan(replace(seq, limits={"rate_rad_s": 2.0}), LIMITS)
    with pytest.raises(RigError, match="unknown hexapod limit"):
        effective_hexapod_limits(LIMITS, {"thrust_n": 1.0})
    # tightened below what the lever-arm motion needs (0.384 rad/s): refused before a run
    with pytest.raises(RigError, match=r"lever_x.*rate_rad_s"):
        compile_plan(replace(seq, limits={"rate_rad_s": 0.3}), LIMITS)


def test_motion_beyond_the_rig_limits_is_refused_at_compile_time() -> None:
    seq = Sequence("fast", (SetPivot(), Move(lever_arm_motion("y", freq_hz=3.0),
                                                        "lever_y")))
    with pytest.raises(RigError, match=r"steps\[1\].*angular_acceleration"):
        compile_plan(seq, LIMITS)


def test_bad_steps_name_the_step() -> None:
    with pytest.raises(RigError, match=r"steps\[0\].*phase 'warmup'"):
        compile_plan(Sequence("x", (Rest(1.0, "warmup"),)), LIMITS)
    with pytest.raises(RigError, match=r"steps\[0\].*duration_s"):
        compile_plan(Sequence("x", (Rest(-1.0, "bias"),)), LIMITS)
    with pytest.raises(RigError, match="nothing to record"):
        compile_plan(Sequence("x", (SetPivot(),)), LIMITS)


def test_phase_lookup_follows_the_segments() -> None:
    seq = Sequence("x", (SetPivot((0, 0, 0.1)), Rest(1.0, "lever_x"),
                                    Move(gyro_sines(beats=1), "gyro")))
    plan = compile_plan(seq, LIMITS)
    assert plan.segments[0].pivot_m == (0.0, 0.0, 0.1)
    assert list(phase_at(plan, np.array([0.0, 0.5, 1.5, 100.0]))) == \
        ["lever_x", "lever_x", "gyro", "gyro"]
    assert seq.to_dict()["steps"][2]["motion"]["name"] == "gyro_sines"
