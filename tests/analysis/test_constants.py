"""Constants store: fitted constants of sim runs, keyed by the run's components, read back
as the optimizer's measured overrides."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from bench.cli import main
from bench.errors import RigError
from bench.plan_runner.runner import RunOptions
from bench.plan_runner.session import run_sequence
from bench.plans.stand_sequences import hover_band_n, step1, sweep
from bench.rig.rig import default_rig_path, load_rig
from bench.store.constants_store import ConstantsStore
from bench.store.measured_constants import load_measured
from drivers.factory import open_rig
from tests.conftest import run_bad


def test_store_fits_and_overrides(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "240")  # the table's cells unwrapped, whatever the terminal
    rig = load_rig(default_rig_path())
    opts = RunOptions(tick_s=0.02)
    sw = run_sequence(rig, sweep(duration_s=6.0), tmp_path, open_rig, options=opts).run_dir
    runs = {}
    for mode in ("complementary", "diode"):
        r = rig.with_esc_mode(mode)
        runs[mode] = run_sequence(r, step1(repeats=3, band_n=hover_band_n()), tmp_path,
                                  open_rig, options=opts).run_dir
    assert main(["constants", "--out", str(tmp_path), "--add", str(sw), str(runs["diode"]),
                 str(runs["complementary"])]) == 0
    out = capsys.readouterr().out
    assert "stored static constants" in out and "measured constants" in out
    rows = ConstantsStore(tmp_path).rows()
    assert sorted((r.key.esc_mode, r.kind) for r in rows) == [
        ("complementary", "static"), ("complementary", "step"), ("diode", "step")]
    assert all(r.key.motor == "dji-2212-920kv" and r.key.propeller == "8x4.5" for r in rows)
    step = next(r for r in rows if r.kind == "step" and r.key.esc_mode == "diode")
    assert step.run_id == runs["diode"].name and step.data["tau_down_s"] > step.data["tau_up_s"]
    # the spread of one edge (3 repeats per direction) and of one speed level of the sweep
    static = next(r for r in rows if r.kind == "static")
    spreads = {k: step.data[k] for k in ("tau_up_std_s", "tau_down_std_s", "latency_std_s")}
    assert all(0 < v < 0.2 * step.data["tau_up_s"] for v in spreads.values()), spreads
    assert 0 < static.data["k_f_std_n_s2"] < 0.05 * static.data["k_f_n_s2"]
    assert static.data["k_q_std_nm_s2"] is None  # the sim stand logs no torque
    # the table shows each with its expanded uncertainty, the value to U's last digit
    found = [re.search(r"latency (\d+\.\d+) ± (\d+\.\d+) ms \(k = 2\)", line)
             for line in out.splitlines() if runs["diode"].name in line]
    shown = [m for m in found if m]
    assert shown, out
    for m in shown:
        assert abs(float(m[1]) - step.data["latency_s"] * 1e3) < 0.01
        assert len(m[1].split(".")[1]) == len(m[2].split(".")[1])
    # storing a newer fit of the same kind replaces the row
    assert main(["constants", "--out", str(tmp_path), "--add", str(runs["diode"])]) == 0
    assert len(ConstantsStore(tmp_path).rows()) == 3

    measured = {m.esc_mode: m for m in load_measured(tmp_path)}
    comp, diode = measured["complementary"], measured["diode"]
    assert comp.time_constant_s == pytest.approx(
        0.5 * sum(next(r for r in rows if r.kind == "step" and r.key.esc_mode ==
                       "complementary").data[k] for k in ("tau_up_s", "tau_down_s")))
    assert diode.time_constant_s > comp.time_constant_s
    assert comp.has_current and diode.has_current  # the diode mode borrows the sweep
    i, inside = comp.current_at(np.array([2.45]), np.array([comp.supply_voltage_v]))
    assert inside[0] and 1.0 < i[0] < 4.0
    assert "static: " in diode.source and "step: " in diode.source
    # what the optimizer samples: each constant's standard uncertainty from its budget
    budgets = step.data["uncertainty"] | static.data["uncertainty"]
    assert diode.latency_std_s == budgets["latency_s"]["u"] > 0
    assert diode.k_f_std_n_s2 == budgets["k_f_n_s2"]["u"] > 0 and diode.k_m_std_nm_s2 is None
    assert load_measured(tmp_path, catalog="thesis-e") == []


def test_runs_without_components_are_refused(tmp_path, capsys):
    run = tmp_path / "imp"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"kind": "sweep", "components": {}}),
                                  encoding="utf-8")
    import pandas as pd

    pd.DataFrame({"t_s": [0.0, 1.0], "rpm": [0.0, 1.0]}).to_parquet(run / "samples.parquet")
    assert main(["constants", "--out", str(tmp_path), "--add", str(run)]) == 2
    assert "components lack" in capsys.readouterr().err
    with pytest.raises(ValueError):
        ConstantsStore(tmp_path).put(None, "other", "x", "y", {})  # type: ignore[arg-type]
    assert RigError.exit_code == 2


def test_json_of_a_folder_that_does_not_exist_is_refused(tmp_path, capsys):
    line = run_bad(capsys, "constants", "--json", "--out", str(tmp_path / "nope"))
    assert "no such folder" in line and capsys.readouterr().out == ""
    assert main(["constants", "--json", "--out", str(tmp_path)]) == 0  # empty: []
    assert json.loads(capsys.readouterr().out) == []
