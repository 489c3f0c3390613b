"""Robust sweeps (``--samples M``): each design's measured spreads flown M times, seeded
per design, with the nominal actuator's gains; percentiles of the figures."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from bench.cli import main
from optimizer.flight.design import gains_for
from optimizer.flight.maneuvers import MANEUVERS, Maneuver, fly
from optimizer.flight.uncertainty import design_seed, draw, percentile_columns, with_sample
from optimizer.sweep.designs import plan_designs
from optimizer.sweep.flight_params import STD_PREFIX, flight_of
from optimizer.sweep.fly_rows import Chunk, fly_chunk
from optimizer.sweep.rows import percentile_columns as percentile_names
from optimizer.sweep.rows import spread_figures

M = 5
#: a short roll step (the figures' code is the full maneuver's; 0.6 s keeps this fast)
SHORT = Maneuver("roll_step", "roll", math.radians(10.0), 0.6)


@pytest.fixture(scope="module")
def plan(thesis_e) -> pd.DataFrame:
    """Six thesis-e designs; every other one with measured-like spreads."""
    p = plan_designs(thesis_e, [4]).iloc[:6].reset_index(drop=True)
    spread = np.arange(len(p)) % 2 == 0
    p.loc[spread, STD_PREFIX + "tau_up_s"] = 0.1 * p.loc[spread, "actuator_tau_up_s"]
    p.loc[spread, STD_PREFIX + "tau_down_s"] = 0.1 * p.loc[spread, "actuator_tau_down_s"]
    p.loc[spread, STD_PREFIX + "latency_s"] = 0.002
    p.loc[spread, STD_PREFIX + "k_f_n_s2"] = 0.02 * p.loc[spread, "vehicle_k_f"]
    return p


@pytest.fixture(autouse=True)
def short_roll_step(monkeypatch) -> None:
    monkeypatch.setitem(MANEUVERS, "roll_step", SHORT)


def test_nominal_figures_are_the_plain_sweeps_and_percentiles_are_ordered(plan) -> None:
    plain = fly_chunk(Chunk(plan, ("roll_step",)))
    robust = fly_chunk(Chunk(plan, ("roll_step",), samples=M, seed=3))
    for a, b in zip(plain, robust, strict=True):
        assert b["error"] is None
        assert {k: v for k, v in b.items() if k in a} == a  # the nominal flight's figures
        for f in spread_figures("roll_step"):
            lo, mid, hi = (b[f"roll_step_{f}_p{p:02d}"] for p in (5, 50, 95))
            assert lo <= mid <= hi
    # a design without a spread: every percentile is its nominal figure
    fixed = robust[1]
    assert fixed["roll_step_rise_time_ms_p05"] == fixed["roll_step_rise_time_ms_p95"] == \
        fixed["roll_step_rise_time_ms"]
    # a design with one: the samples spread the rise time
    assert robust[0]["roll_step_rise_time_ms_p05"] < robust[0]["roll_step_rise_time_ms_p95"]


def test_percentiles_are_those_of_each_sample_flown_alone(plan) -> None:
    """Design 0's samples drawn with its own seed and flown one by one with the scalar
    loop and the nominal gains give the percentiles the batch wrote."""
    row = fly_chunk(Chunk(plan.iloc[:1], ("roll_step",), samples=M, seed=3))[0]
    design = plan.iloc[0].to_dict()
    vehicle, actuator = flight_of(design)
    quantities = {"tau_up_s": actuator.tau_up_s, "tau_down_s": actuator.tau_down_s,
                  "latency_s": actuator.latency_s, "k_f_n_s2": vehicle.k_f,
                  "k_m_nm_s2": vehicle.k_m}
    std = {q: float(design[STD_PREFIX + q]) for q in quantities}
    samples = draw(quantities, std, M, design_seed(design, 3))
    gains = gains_for(actuator)
    rise = []
    for k in range(M):
        v, a = with_sample(vehicle, actuator, {q: float(s[k]) for q, s in samples.items()})
        rise.append(fly(v, a, SHORT, gains=gains, record=False).figures["rise_time_ms"])
    want = percentile_columns("roll_step_rise_time_ms", [np.nan if r is None else r
                                                         for r in rise])
    for key, value in want.items():
        assert row[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key


def test_draws_do_not_depend_on_the_chunk_or_the_neighbours(plan) -> None:
    whole = fly_chunk(Chunk(plan, ("roll_step",), samples=M, seed=3))
    parts = [r for start in (0, 2, 5) for r in fly_chunk(Chunk(
        plan.iloc[start:{0: 2, 2: 5, 5: 6}[start]].reset_index(drop=True), ("roll_step",),
        samples=M, seed=3))]
    backwards = fly_chunk(Chunk(plan.iloc[::-1].reset_index(drop=True), ("roll_step",),
                                samples=M, seed=3))[::-1]
    assert parts == whole == backwards
    other_seed = fly_chunk(Chunk(plan.iloc[:1], ("roll_step",), samples=M, seed=4))[0]
    assert other_seed["roll_step_rise_time_ms_p95"] != whole[0]["roll_step_rise_time_ms_p95"]


def test_the_cli_writes_percentile_columns_and_says_when_nothing_spreads(tmp_path,
                                                                         capsys) -> None:
    out = tmp_path / "robust.parquet"
    assert main(["fly", "--sweep", "--actuators", "4", "--maneuver", "roll_step",
                 "--samples", "3", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "no design has a measured spread" in err
    table = pq.read_table(out)
    for name in percentile_names(["roll_step"]):
        assert name in table.column_names
    frame = table.to_pandas()
    nominal = frame["roll_step_rise_time_ms"].fillna(math.inf)  # never rose: +inf
    assert (frame["roll_step_rise_time_ms_p50"] == nominal).all()
    # the spec records the samples: another count at the same --out is another sweep
    assert main(["fly", "--sweep", "--actuators", "4", "--maneuver", "roll_step",
                 "--samples", "3", "--seed", "1", "--out", str(out)]) == 0


@pytest.mark.parametrize("flags, words", [
    (["--samples", "0"], "--samples"),
    (["--samples", "3", "--seed", "-1"], "--seed"),
])
def test_bad_sample_options_are_one_line(tmp_path, capsys, flags, words) -> None:
    code = main(["fly", "--sweep", "--actuators", "4", "--out", str(tmp_path / "s.parquet"),
                 *flags])
    out = capsys.readouterr()
    assert code == 2 and words in out.err + out.out
    assert not list(tmp_path.iterdir())


def test_samples_need_the_out_file(capsys) -> None:
    assert main(["fly", "--sweep", "--actuators", "4", "--samples", "3"]) == 2
    assert "--samples" in capsys.readouterr().err


def test_measured_spreads_reach_the_plan_and_the_draws(thesis_e) -> None:
    """A measured actuator with spreads (as the constants store loads it) overrides its
    designs' numbers in the plan, brings its spreads (std_*), and only its designs' samples
    spread; the others keep the model's numbers and no spread."""
    from optimizer.model.design_model import evaluate_grid
    from optimizer.model.measured import MeasuredActuator

    prop, motor = thesis_e.propellers["id"].iloc[0], thesis_e.motors["id"].iloc[0]
    measured = MeasuredActuator(prop, motor, tau_up_s=0.030, tau_down_s=0.045,
                                latency_s=0.004, time_constant_s=0.035, tau_up_std_s=0.004,
                                tau_down_std_s=0.006, latency_std_s=0.001)

    def build(catalog, n, payload):
        return evaluate_grid(catalog, n, payload, overrides=[measured])

    plan = plan_designs(thesis_e, [4], build_grid=build)
    mine = (plan["propeller"] == prop) & (plan["motor"] == motor)
    assert mine.any() and (~mine).any()
    assert (plan.loc[mine, "actuator_tau_up_s"] == 0.030).all()
    assert (plan.loc[mine, STD_PREFIX + "tau_up_s"] == 0.004).all()
    assert (plan.loc[~mine, plan.columns.str.startswith(STD_PREFIX)].to_numpy() == 0).all()
    both = pd.concat([plan[mine].iloc[:2], plan[~mine].iloc[:2]], ignore_index=True)
    rows = fly_chunk(Chunk(both, ("roll_step",), samples=M))
    spread = [r["roll_step_rise_time_ms_p95"] - r["roll_step_rise_time_ms_p05"] for r in rows]
    assert spread[0] > 0 and spread[1] > 0 and spread[2] == spread[3] == 0
