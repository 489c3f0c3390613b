"""Drops counted: every run's run.json has the count of missed or late samples and the
longest gap per device; a fault that drops samples shows them, and ``runs`` marks the run."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.cli import main
from bench.engine.drops import DropCounter
from bench.engine.recorder import RunRecorder
from bench.engine.safety import effective_limits
from bench.plan_runner.runner import Runner, RunOptions
from bench.plan_runner.session import esc_range_of, plan_for
from bench.plans.stand_sequences import step1
from bench.rig.rig import load_rig
from drivers.contracts import Fault
from drivers.factory import open_rig


def test_counter_counts_holes_and_nan_rows_not_bursts():
    c = DropCounter(learn=10)
    t = np.arange(100) * 0.01
    t = np.delete(t, [30, 31, 32, 60])  # 3 missing, then 1 missing
    for k in range(0, t.size, 7):  # in blocks, as reads come
        c.update("a", t[k:k + 7], {"x": np.ones(t[k:k + 7].size)})
    c.update("b", np.arange(20) * 0.1, {"x": np.where(np.arange(20) == 5, np.nan, 1.0)})
    # host-stamped arrival in bursts: 3 samples 1 us apart every 30 ms, stated 100 Hz
    burst = (np.arange(60)[:, None] * 0.03 + np.array([0.0, 1e-6, 2e-6])).ravel()
    c.expect("c", 100.0)
    c.update("c", burst, {"x": np.ones(burst.size)})
    s = c.summary()
    assert s["drops"]["a"]["missing"] == 4
    assert s["drops"]["a"]["longest_gap_s"] == pytest.approx(0.04)
    assert s["drops"]["a"]["period_s"] == pytest.approx(0.01)
    assert s["drops"]["b"]["dropped"] == 1 and s["drops"]["b"]["nan_rows"] == 1
    assert s["drops"]["c"]["dropped"] == 0  # bursts are not losses
    assert s["dropped_samples"] == 5 and s["longest_gap_s"] == pytest.approx(0.1)


def _run(rig, tmp_path, inject=None):
    devices = open_rig(rig)
    if inject:
        inject(devices)
    seq = step1(repeats=1)
    rec = RunRecorder(tmp_path / "run", {"sequence": seq.to_dict()})
    runner = Runner(devices, plan_for(rig, seq), esc_range_of(rig),
                    effective_limits(rig.limits, seq.limits), rec, RunOptions())
    try:
        runner.run()
    finally:
        devices.close()
    return json.loads((tmp_path / "run" / "run.json").read_text())


def test_a_clean_run_records_no_drops(sim_rig_mapped_path, tmp_path):
    meta = _run(load_rig(sim_rig_mapped_path), tmp_path)
    assert meta["dropped_samples"] == 0 and meta["marks"] == []
    assert meta["longest_gap_s"] < 1.5 / 25_000  # stamps jitter a little, nothing lost
    assert set(meta["drops"]) == {"load_cell", "power", "rpm"}


def test_a_dropout_fault_shows_in_run_json_and_in_runs(sim_rig_mapped_path, tmp_path, capsys,
                                                       monkeypatch):
    def dropout(devices):  # the power sensor loses 0.2 s of samples
        devices.sensors["power"].inject(Fault.DROPOUT, at_s=1.0, until_s=1.2)

    meta = _run(load_rig(sim_rig_mapped_path), tmp_path, dropout)
    power = meta["drops"]["power"]
    assert power["missing"] == pytest.approx(0.2 * 25_000, rel=0.01)
    assert power["period_from"] == "device"
    assert power["longest_gap_s"] == pytest.approx(0.2, abs=0.001)
    assert meta["drops"]["load_cell"]["dropped"] == 0
    assert meta["marks"] == ["drops"] and meta["dropped_samples"] == power["dropped"]
    monkeypatch.setenv("COLUMNS", "300")  # one table line per run
    assert main(["runs", "--out", str(tmp_path), "--rebuild"]) == 0
    out = capsys.readouterr().out
    assert f"! {power['dropped']} (gap 0.200 s)" in out


def test_report_marks_a_run_with_drops(sim_rig_mapped_path, tmp_path, capsys, monkeypatch):
    def dropout(devices):
        devices.sensors["rpm"].inject(Fault.DROPOUT, at_s=1.0, until_s=1.1)

    meta = _run(load_rig(sim_rig_mapped_path), tmp_path, dropout)
    monkeypatch.setenv("COLUMNS", "300")
    assert main(["report", str(tmp_path / "run"), "--out", str(tmp_path / "rep")]) == 0
    out = capsys.readouterr().out
    assert f"note: run: {meta['dropped_samples']} samples missed or late (longest gap " \
           "0.100 s" in out
    summary = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert summary["dropped_samples"] == {"run": meta["dropped_samples"]}
