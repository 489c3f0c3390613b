"""Batches of ticks on the simulated rig (``bench.engine.run_loop``): the same record as tick by
tick, and a run that ends inside a batch ends on the same tick and sample."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pandas as pd
import pytest

from bench.engine.recorder import RunRecorder
from bench.engine.safety import effective_limits
from bench.plan_runner.runner import Runner, RunOptions
from bench.plan_runner.session import esc_range_of, plan_for
from bench.plans.stand_sequences import step1
from bench.rig.rig import load_rig
from drivers.factory import open_rig


class TickByTick(Runner):
    batches = False


@pytest.fixture(scope="module")
def rig(tmp_path_factory, fakes):
    from bench.rig.rig import default_rig_path

    path = tmp_path_factory.mktemp("batches") / "sim.toml"
    path.write_text(default_rig_path().read_text(encoding="utf-8"), encoding="utf-8")
    fakes.write_truth_map(path)
    return load_rig(path)


def _run(rig, seq, out: Path, runner_class: type[Runner], seen: list | None = None):
    devices = open_rig(rig)
    rec = RunRecorder(out, {"sequence": seq.to_dict()})
    runner = runner_class(devices, plan_for(rig, seq), esc_range_of(rig),
                          effective_limits(rig.limits, seq.limits), rec, RunOptions())
    if seen is not None:
        seen.append(runner._batch_sim() is not None)
    result = runner.run()
    truth = devices.truth()
    devices.close()
    samples = pd.read_parquet(out / "samples.parquet")
    events = pd.read_csv(out / "events.csv").drop(columns=["utc"])
    return result, samples, events, truth, runner.drops.summary()


def _same_record(a, b) -> None:
    ra, sa, ea, ta, da = a
    rb, sb, eb, tb, db = b
    assert (ra.status, ra.reason, ra.t_end_s, ra.rows) == (rb.status, rb.reason, rb.t_end_s,
                                                           rb.rows)
    assert ra.trip == rb.trip
    pd.testing.assert_frame_equal(sa, sb, check_exact=True)
    pd.testing.assert_frame_equal(ea, eb, check_exact=True)
    assert ta == tb  # the plant ends in the same state
    assert da == db


def test_batches_record_the_same_run_as_tick_by_tick(rig, tmp_path: Path) -> None:
    seq = step1(repeats=2)
    seen: list[bool] = []
    batched = _run(rig, seq, tmp_path / "batched", Runner, seen)
    ticked = _run(rig, seq, tmp_path / "ticked", TickByTick, seen)
    assert seen == [True, False]
    assert batched[0].status == "success" and batched[4]["dropped_samples"] == 0
    _same_record(batched, ticked)


@pytest.mark.parametrize("limit", ["thrust_n", "rpm"])
def test_a_trip_inside_a_batch_ends_on_the_same_tick_and_sample(rig, tmp_path: Path,
                                                                limit: str) -> None:
    value = {"thrust_n": 2.6, "rpm": 6200.0}[limit]  # between hover -30 % and +30 %
    seq = dataclasses.replace(step1(repeats=2), limits={limit: value})
    batched = _run(rig, seq, tmp_path / "batched", Runner)
    ticked = _run(rig, seq, tmp_path / "ticked", TickByTick)
    assert batched[0].status == "abort" and batched[0].trip.limit == limit
    _same_record(batched, ticked)


def test_a_fault_switched_on_runs_tick_by_tick(rig, tmp_path: Path) -> None:
    seq = step1(repeats=2)
    devices = open_rig(rig)
    devices.sensors["load_cell"].inject("spikes", at_s=50.0)  # never reached
    runner = Runner(devices, plan_for(rig, seq), esc_range_of(rig),
                    effective_limits(rig.limits, seq.limits), None, RunOptions())
    assert runner._batch_sim() is None
    devices.close()
