"""Measured constants in the selection: they change the choice when they should, every
design says where its numbers come from, the measured top thrust is a feasibility check,
and hover currents are never extrapolated beyond the measured thrusts."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bench.cli import main
from bench.store.constants_store import ActuatorKey, ConstantsStore
from optimizer.catalogs.catalog import load_catalog
from optimizer.errors import RequestError
from optimizer.model.design_model import (
    MODEL_SOURCES,
    design_sources,
    evaluate_design,
    evaluate_grid,
)
from optimizer.model.measured import MeasuredActuator
from optimizer.solve.objectives import single
from optimizer.solve.selection import Requirements, optimize
from tests.conftest import CATALOGS

SOURCE_KEYS = {*MODEL_SOURCES, "max_thrust"}


@pytest.fixture
def cat(fixtures_dir):
    return load_catalog(CATALOGS / "thesis-e")


def _select(cat, objective, overrides, actuators=(4,), payload=0.0, esc_mode=None):
    grids = {}

    def build(c, n, p):
        grids[n] = evaluate_grid(c, n, p, overrides=overrides, esc_mode=esc_mode)
        return grids[n]

    res = optimize(cat, single(objective), actuators, Requirements(payload_kg=payload), "milp",
                   build_grid=build)
    return res, grids


def _pick(res, n=4):
    d = next(d for d in res.designs if d.actuators == n)
    return (d.propeller, d.motor, d.battery) if d.feasible else None


def test_a_faster_measured_actuator_wins_the_time_constant_case(cat):
    base, _ = _select(cat, "time-constant", None)
    assert _pick(base) == ("P1", "M1", "B3")  # model: 38.3 ms
    fast = MeasuredActuator("P2", "M1", time_constant_s=0.020, time_constant_source="run-fast")
    res, grids = _select(cat, "time-constant", [fast])
    d = res.designs[0]
    assert (d.propeller, d.motor) == ("P2", "M1")
    assert d.metrics["time_constant_ms"] == pytest.approx(20.0)
    src = design_sources(grids[4], *d.index)
    assert set(src) == SOURCE_KEYS
    assert src["time_constant_ms"] == "measured: run run-fast"
    assert src["flight_time_min"] == MODEL_SOURCES["flight_time_min"]


def test_a_slower_measured_actuator_does_not_change_the_choice(cat):
    slow = MeasuredActuator("P2", "M1", time_constant_s=0.5)
    res, _ = _select(cat, "time-constant", [slow])
    assert _pick(res) == ("P1", "M1", "B3")


def test_measured_current_changes_the_flight_time_choice(cat):
    base, grids0 = _select(cat, "flight-time", None)
    assert _pick(base) == ("P4", "M1", "B3")
    # P3 on M1 measured at half the model's current over every hover thrust it meets
    hover = grids0[4].extras["hover_thrust_n"][2, 0, :]
    model_i = grids0[4].metrics["current_a"][2, 0, :] / 4
    thrust = np.array([0.5 * hover.min(), 1.5 * hover.max()])
    current = 0.5 * np.interp(thrust, np.sort(hover), np.sort(model_i))
    lean = MeasuredActuator("P3", "M1", hover_thrust_n=tuple(thrust),
                            hover_current_a=tuple(current), current_source="run-sweep")
    res, grids = _select(cat, "flight-time", [lean])
    d = res.designs[0]
    assert (d.propeller, d.motor) == ("P3", "M1")
    src = design_sources(grids[4], *d.index)
    for key in ("current_a", "power_w", "flight_time_min"):
        assert src[key] == "measured: run run-sweep"
    assert src["time_constant_ms"] == MODEL_SOURCES["time_constant_ms"]
    assert src["max_thrust"].startswith("measured: run run-sweep")


def test_measured_max_thrust_makes_designs_infeasible_with_a_named_reason(cat, fixtures_dir):
    # P1 on M1 tops out at 2.9 N; 4 actuators hover at 4.3 N with B3, 2.0 N with B1
    top = MeasuredActuator("P1", "M1", time_constant_s=0.04, hover_thrust_n=(0.5, 2.9),
                           hover_current_a=(0.3, 3.0), supply_voltage_v=12.0,
                           current_source="run-top")
    g = evaluate_grid(cat, 4, overrides=[top])
    check = next(c for c in g.checks if c.label == "measured max thrust")
    assert check.unit == "N"
    hover = g.extras["hover_thrust_n"][0, 0, :]
    assert (hover > 2.9).any() and (hover < 2.9).any()
    np.testing.assert_array_equal(g.feasible()[0, 0, :], hover <= 2.9)
    # other actuators have no sweep: no limit there, feasibility as without overrides
    base = evaluate_grid(cat, 4)
    np.testing.assert_array_equal(g.feasible()[1:], base.feasible()[1:])
    rec = evaluate_design(cat, 4, "P1", "M1", "B3", overrides=[top])
    assert not rec["feasible"] and "measured max thrust 4.3" in rec["reason"]
    # only P1 and M1 in the catalog, with the heavy battery: no design can hover
    only = load_catalog(CATALOGS / "thesis-e")
    only = type(only)(only.propellers.iloc[[0]].reset_index(drop=True),
                      only.motors.iloc[[0]].reset_index(drop=True),
                      only.batteries.iloc[[2]].reset_index(drop=True), only.constants,
                      only.source)
    res = optimize(only, single("time-constant"), (4,), Requirements(), "milp",
                   build_grid=lambda c, n, p: evaluate_grid(c, n, p, overrides=[top]))
    d = res.designs[0]
    assert not d.feasible and res.best is None
    assert "measured max thrust" in d.reason and "closest design P1+M1+B3" in d.reason
    assert d.closest["violations"][0]["check"] == "measured max thrust"


def test_max_thrust_is_not_checked_for_a_much_higher_battery_voltage(cat):
    low_bench = MeasuredActuator("P1", "M1", hover_thrust_n=(0.5, 2.9),
                                 hover_current_a=(0.3, 3.0), supply_voltage_v=6.0)
    g = evaluate_grid(cat, 4, overrides=[low_bench])  # batteries fly at 12 V
    assert not any(c.label == "measured max thrust" for c in g.checks)
    src = design_sources(g, 0, 0, 2)
    assert src["max_thrust"].startswith("not checked: battery 12 V above the bench's 6 V")


def test_hover_current_is_never_extrapolated(cat):
    base = evaluate_grid(cat, 4)
    hover = base.extras["hover_thrust_n"][3, 0, :]  # P4 on M1, every battery
    lo, hi = float(np.sort(hover)[1]), float(np.sort(hover)[2])  # two batteries inside
    item = MeasuredActuator("P4", "M1", hover_thrust_n=(lo, hi), hover_current_a=(9.0, 10.0),
                            max_thrust_n=100.0, current_source="run-narrow")
    g = evaluate_grid(cat, 4, overrides=[item])
    inside = (hover >= lo) & (hover <= hi)
    assert inside.sum() == 2 and (hover < lo).any() and (hover > hi).any()
    mask = g.measured["current_a"][3, 0, :]
    np.testing.assert_array_equal(mask, inside)
    out = ~inside
    np.testing.assert_allclose(g.metrics["current_a"][3, 0, out],
                               base.metrics["current_a"][3, 0, out])
    np.testing.assert_allclose(g.metrics["flight_time_min"][3, 0, out],
                               base.metrics["flight_time_min"][3, 0, out])
    k_below = int(np.flatnonzero(hover < lo)[0])
    k_above = int(np.flatnonzero(hover > hi)[0])
    below, above = design_sources(g, 3, 0, k_below), design_sources(g, 3, 0, k_above)
    assert "below the measured" in below["flight_time_min"]
    assert "above the measured" in above["current_a"]
    assert "not extrapolated" in above["current_a"]
    assert below["flight_time_min"].startswith(MODEL_SOURCES["flight_time_min"])
    # the top-thrust limit may not sit below the measured current points
    with pytest.raises(RequestError, match="max_thrust_n"):
        MeasuredActuator("P4", "M1", hover_thrust_n=(1.0, 2.0), hover_current_a=(1.0, 2.0),
                         max_thrust_n=1.5)


# --------------------------------------------------------------- the CLI (--measured)


def _store(root, tau_s=0.02, top=2.9):
    """A constants store as the bench writes it: P2/M1 step and sweep, P1/M1 sweep."""
    store = ConstantsStore(root)
    key = ActuatorKey("M1", "P2", "sim-f30a", "complementary", "3s", catalog="thesis-e")
    store.put(key, "step", "run-step-p2", "runs/run-step-p2",
              {"tau_up_s": tau_s, "tau_down_s": tau_s, "latency_s": 0.01})
    key1 = ActuatorKey("M1", "P1", "sim-f30a", "complementary", "3s", catalog="thesis-e")
    store.put(key1, "static", "run-sweep-p1", "runs/run-sweep-p1",
              {"hover_thrust_n": [0.5, top], "hover_current_a": [0.3, 3.0], "voltage_v": 12.0,
               "thrust_max_n": top})


def test_cli_optimize_measured_json_sources_and_table_marks(tmp_path, capsys, fixtures_dir):
    cat = str(CATALOGS / "thesis-e")
    _store(tmp_path / "runs")
    code = main(["optimize", "--catalog", cat, "--objective", "time-constant", "--actuators",
                 "4", "--measured", str(tmp_path), "--json"])  # a demo folder holds runs/
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    d = out["best"]
    assert (d["propeller"], d["motor"]) == ("P2", "M1")
    assert d["sources"]["time_constant_ms"] == "measured: run run-step-p2"
    assert d["sources"]["flight_time_min"] == "model (E.67-E.74)"
    assert set(d["sources"]) == SOURCE_KEYS
    assert out["measured"]["esc_mode"] == "complementary"
    assert main(["optimize", "--catalog", cat, "--objective", "time-constant", "--actuators",
                 "4", "--measured", str(tmp_path / "runs")]) == 0
    table = capsys.readouterr().out
    assert "20 (m)" in table and "(m) measured on the bench" in table
    # without --measured: no sources, the model's choice
    code, plain = main(["optimize", "--catalog", cat, "--objective", "time-constant",
                        "--actuators", "4", "--json"]), json.loads(capsys.readouterr().out)
    assert "sources" not in plain["best"] and plain["best"]["propeller"] == "P1"


def test_cli_evaluate_measured_names_the_max_thrust_check(tmp_path, capsys, fixtures_dir):
    cat = str(CATALOGS / "thesis-e")
    _store(tmp_path)
    assert main(["evaluate", "--catalog", cat, "--actuators", "4", "--propeller", "P1",
                 "--motor", "M1", "--battery", "B3", "--measured", str(tmp_path),
                 "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert not rec["feasible"] and "measured max thrust" in rec["reason"]
    assert rec["sources"]["max_thrust"] == "measured: run run-sweep-p1 (2.9 N)"
    assert "not extrapolated" in rec["sources"]["current_a"]


def test_cli_measured_bad_input_exits_2(tmp_path, capsys, fixtures_dir):
    cat = str(CATALOGS / "thesis-e")
    assert main(["optimize", "--catalog", cat, "--measured", str(tmp_path / "none")]) == 2
    assert "no constants.sqlite" in capsys.readouterr().err
    _store(tmp_path)
    assert main(["optimize", "--catalog", cat, "--measured", str(tmp_path),
                 "--esc-mode", "stock"]) == 2
    assert "not in" in capsys.readouterr().err
    assert main(["optimize", "--catalog", cat, "--esc-mode", "stock"]) == 2
    assert main(["optimize", "--catalog", cat, "--measured", str(tmp_path), "--method",
                 "thesis"]) == 2
    other = tmp_path / "other"
    ConstantsStore(other).put(ActuatorKey("m", "p", "e", "complementary", "b"), "step", "r",
                              "r", {"tau_up_s": 0.03, "tau_down_s": 0.03})
    assert main(["optimize", "--catalog", cat, "--measured", str(other)]) == 2
    assert "no constants stored for catalog 'thesis-e'" in capsys.readouterr().err


def test_cli_paper_e_cases_with_measured_constants(tmp_path, capsys, fixtures_dir):
    cat = str(CATALOGS / "thesis-e")
    _store(tmp_path)
    assert main(["optimize", "--catalog", cat, "--paper-e-cases", "--actuators", "4",
                 "--measured", str(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["measured"]["actuators_measured"] == 2
    case3 = next(c for c in out["cases"] if c["case"] == "III")
    assert case3["best"]["propeller"] == "P2"  # the measured 20 ms actuator
    assert all(set(c["best"]["sources"]) == SOURCE_KEYS for c in out["cases"])
