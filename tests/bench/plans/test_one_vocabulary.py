"""Both benches speak one vocabulary: one rig config, one sequence/plan model whose
segments carry their steps, and plans built the same way by the CLI and the console."""

from __future__ import annotations

import argparse

import pytest

from bench.commands.step import build as build_step
from bench.commands.sweep import build as build_sweep
from bench.errors import RigError
from bench.plan_runner.session import plan_for
from bench.plans.calibration_sequences import Move, compile_plan, paper_a_sequences
from bench.plans.plan_specs import plan_sequence
from bench.plans.sequences import Checkpoint, Plan, Sequence
from bench.plans.stand_sequences import step1
from bench.rig.rig import (
    RigConfig,
    default_imu_rig_path,
    default_rig_path,
    load_any_rig,
    load_imu_rig,
    load_rig,
)


def test_one_rig_config_for_both_benches() -> None:
    prop, imu = load_any_rig(default_rig_path()), load_any_rig(default_imu_rig_path())
    assert isinstance(prop, RigConfig) and isinstance(imu, RigConfig)
    assert (prop.kind, imu.kind) == ("propulsion", "imu")
    assert set(prop.devices) == {"esc", "load_cell", "power", "rpm"}
    assert set(imu.devices) >= {"hexapod", "imu"}
    assert prop.hexapod is None and imu.esc is None and imu.limits is None
    assert prop == load_rig(default_rig_path()) and imu == load_imu_rig(default_imu_rig_path())
    with pytest.raises(RigError, match='kind = "imu": an IMU-bench rig'):
        load_rig(default_imu_rig_path())
    assert imu.with_seed(7).sim.seed == 7 and prop.with_seed(7).sim.seed == 7


def test_every_segment_carries_its_step_on_both_benches() -> None:
    rig, imu = load_rig(default_rig_path()), load_imu_rig(default_imu_rig_path())
    seq = step1(repeats=2)
    cal = paper_a_sequences(100.0, quick=True)[2]  # accelerometer stage: moves + checkpoints
    plans = [plan_for(rig, seq, dry_run=True),
             compile_plan(cal, imu.hexapod.hexapod_limits(), imu.hexapod.pivot_m)]
    for plan, source in zip(plans, (seq, cal), strict=True):
        assert isinstance(plan, Plan) and isinstance(plan.sequence, Sequence)
        steps = [s.step for s in plan.segments]
        assert all(any(st is x for x in source.steps) for st in steps)
        assert any(isinstance(st, Checkpoint) for st in steps)  # one Checkpoint class
    moves = [s for s in plans[1].segments if isinstance(s.step, Move)]
    assert moves and all(s.kind == "move" and s.motion is s.step.motion for s in moves)
    assert "step" not in plans[0].segments[0].record()  # run.json keeps its layout


@pytest.mark.parametrize("spec", [
    {"plan": "step2", "repeats": 3, "hold_s": 0.4},
    {"plan": "sweep", "start_us": 1200.0, "end_us": 1800.0, "duration_s": 5.0},
])
def test_console_and_cli_build_the_same_plan(spec: dict) -> None:
    if spec["plan"] == "sweep":
        cli = build_sweep(argparse.Namespace(start_us=1200.0, end_us=1800.0, duration=5.0,
                                             limit=[]))
    else:
        cli = build_step(argparse.Namespace(sequence="step2", repeats=3, hold=0.4, limit=[]))
    assert plan_sequence(spec) == cli
